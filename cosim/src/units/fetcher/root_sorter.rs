//! The fetcher's root sorter (`rtl_gen::merge::root_sorter_unit`) against
//! golden's `sort_stream` through
//! `golden::merge::fetcher::root_sorter::root_sort_transaction`, bit for
//! bit on one stream with an in-order scoreboard
//! ([`crate::tb::run_stream_bench`]). A transaction is one input's roots,
//! drawn by `random_roots` so that Morton order breaks and, sometimes, more
//! roots come than the sorter holds (which must raise `err`).

use golden::merge::fetcher::root_sorter::{random_roots, root_sort_transaction};
use golden::merge::merge_level::unit::{BeatLayout, LevelBeat};
use golden::params::Params;
use golden::translate::stimulus::SplitMix64;

use crate::error::{CosimError, Result};
use crate::tb::Vector;
use golden::bits::Bits;

/// The unit under test, holding `capacity` roots.
pub fn root_sorter_module(p: &Params, capacity: usize) -> rtl_gen::Module {
    rtl_gen::merge::root_sorter_unit(p, capacity)
}

/// Bench vectors of random root sets, with what they reached.
#[derive(Clone, Debug)]
pub struct SortVectors {
    /// One vector per input beat; a set's expected outputs ride on its
    /// first beat.
    pub vectors: Vec<Vector>,
    /// Where each set ends (the index just past its last vector), so that a
    /// run can stop between sets.
    pub ends: Vec<usize>,
    /// Sets whose roots came out of Morton order.
    pub unsorted: usize,
    /// Sets with more roots than the capacity (`err` raised).
    pub overflow: usize,
}

fn layout_err(e: impl std::fmt::Display) -> CosimError {
    CosimError::Design {
        what: format!("root sorter beat: {e}"),
    }
}

/// `sets` random root sets from `seed` for a sorter of `capacity` roots.
pub fn vectors(p: &Params, capacity: usize, seed: u64, sets: usize) -> Result<SortVectors> {
    let (li, lo) = (BeatLayout::input(p), BeatLayout::output(p));
    let err_bit = lo
        .err
        .ok_or_else(|| layout_err("output beats have no err"))?;
    let mut rng = SplitMix64(seed);
    let mut out = SortVectors {
        vectors: Vec::new(),
        ends: Vec::new(),
        unsorted: 0,
        overflow: 0,
    };
    for _ in 0..sets {
        let roots = random_roots(&mut rng, p, capacity);
        let keys: Vec<_> = roots
            .iter()
            .map(|r| (r.record.voxel.morton(), r.record.leaf))
            .collect();
        out.unsorted += keys.windows(2).any(|w| w[0] > w[1]) as usize;
        let (ins, outs) = root_sort_transaction(&roots, capacity);
        out.overflow += outs.last().is_some_and(|o| o.1) as usize;
        // The output beat is the input beat widened by `err`.
        let expected = outs
            .iter()
            .map(|(b, err): &(LevelBeat, bool)| {
                let bits = b.pack(&li).map_err(layout_err)?;
                let mut v = Bits::from_words(bits.words(), lo.width())?;
                v.set_bit(err_bit.offset, *err)?;
                Ok(vec![v])
            })
            .collect::<Result<Vec<_>>>()?;
        for (j, b) in ins.iter().enumerate() {
            out.vectors.push(Vector {
                input: vec![b.pack(&li).map_err(layout_err)?],
                outputs: if j == 0 { expected.clone() } else { Vec::new() },
            });
        }
        out.ends.push(out.vectors.len());
    }
    Ok(out)
}
