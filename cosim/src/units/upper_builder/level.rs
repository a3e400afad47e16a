//! S616 one level up (`rtl_gen::merge::upper_level_unit`) against golden's
//! `build::upper::group_by_parent` through
//! `golden::merge::upper_builder::level_unit::upper_transaction`, bit for
//! bit on one stream with an in-order scoreboard
//! ([`crate::tb::run_stream_bench`]). A transaction is one parent group:
//! its children in, its record out; a level's outputs are expected with
//! its first beat.

use golden::merge::upper_builder::level_unit::{
    random_upper_level, upper_transaction, UpperBeat, UpperLayout,
};
use golden::params::Params;
use golden::translate::stimulus::SplitMix64;

use crate::error::{CosimError, Result};
use crate::tb::Vector;

/// The unit under test.
pub fn upper_level_module(p: &Params) -> rtl_gen::Module {
    rtl_gen::merge::upper_level_unit(p)
}

/// Bench vectors of random levels, with what they reached.
#[derive(Clone, Debug)]
pub struct LevelVectors {
    /// One vector per input beat.
    pub vectors: Vec<Vector>,
    /// Parent groups (transactions).
    pub groups: usize,
    /// Groups whose record has `err` (an index overflow).
    pub errs: usize,
    /// Where each level ends: the index just past its last vector, so that
    /// a run can stop between levels...
    pub ends: Vec<usize>,
    /// ...and the groups up to there.
    pub groups_at_end: Vec<usize>,
}

fn layout_err(e: impl std::fmt::Display) -> CosimError {
    CosimError::Design {
        what: format!("upper level beat: {e}"),
    }
}

/// Random levels of 1 to 40 children from `seed` until `groups` parent
/// groups.
pub fn vectors(p: &Params, seed: u64, groups: usize) -> Result<LevelVectors> {
    let l = UpperLayout::new(p);
    let mut rng = SplitMix64(seed);
    let mut out = LevelVectors {
        vectors: Vec::new(),
        groups: 0,
        errs: 0,
        ends: Vec::new(),
        groups_at_end: Vec::new(),
    };
    while out.groups < groups {
        let size = 1 + rng.below(40) as usize;
        let level = random_upper_level(&mut rng, p, size);
        let (ins, outs) = upper_transaction(&level, p);
        // The last output beat closes the level; the others are groups.
        out.groups += outs.len() - 1;
        out.errs += outs
            .iter()
            .filter(|b| matches!(b, UpperBeat::Node { err: true, .. }))
            .count();
        let expected = outs
            .iter()
            .map(|b| Ok(vec![b.pack(&l, true).map_err(layout_err)?]))
            .collect::<Result<Vec<_>>>()?;
        for (j, b) in ins.iter().enumerate() {
            out.vectors.push(Vector {
                input: vec![b.pack(&l, false).map_err(layout_err)?],
                outputs: if j == 0 { expected.clone() } else { Vec::new() },
            });
        }
        out.ends.push(out.vectors.len());
        out.groups_at_end.push(out.groups);
    }
    Ok(out)
}
