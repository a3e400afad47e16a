//! The upper builder (S616, every level at once:
//! `rtl_gen::merge::upper_builder_unit`, SPEC.md section 8.11) against
//! `golden::merge::upper_builder::unit::builder_transaction` (golden's
//! `build_levels`, grouping and lift rule), bit for bit on every `level{d}`
//! stream and on `done`. Stimulus: random bases
//! (`golden::merge::upper_builder::unit::random_base`: every top rule, empty
//! bases, leaves above the merging level, small-I overflows) and the bases
//! of real merges (golden-built soups, translated, walked and merged by
//! S614 at every candidate level: `fixed_level_base`). One level alone
//! (`rtl_gen::merge::upper_level_unit`) has its own bench, [`level`].

pub mod level;

use golden::bits::Bits;
use golden::layout::LayoutError;
use golden::merge::level_choice::candidate_range;
use golden::merge::merge_level::BaseNode;
use golden::merge::stimulus::{place, try_soup};
use golden::merge::upper_builder::unit::{
    builder_transaction, fixed_level_base, random_base, BuilderLayout, BuilderTransaction, LevelOut,
};
use golden::params::Params;
use golden::store::Hierarchy;
use golden::translate::stimulus::SplitMix64;
use golden::translate::Translation;

use super::multi_stream::{packed, MultiSim, StreamSet};
use crate::error::{CosimError, Result};
use crate::tb::{BenchConfig, MultiReport, StreamBeats, Transaction};

/// The unit under test.
pub fn upper_builder_module(p: &Params) -> rtl_gen::Module {
    rtl_gen::merge::upper_builder_unit(p)
}

/// What a list of merges exercised.
#[derive(Clone, Default, Debug)]
pub struct Seen {
    /// Merges.
    pub merges: usize,
    /// Merges with no top (`done.err`).
    pub no_top: usize,
    /// Merges whose top is above the deepest base level but one.
    pub top_above_base: usize,
    /// Merges with several roots.
    pub several_roots: usize,
    /// Merges where a node was lifted.
    pub lifted: usize,
    /// Merges whose root level was cut.
    pub root_cut: usize,
    /// Merges with an overflow (`err` on a level beat).
    pub overflow: usize,
    /// Beats on the `base{d}` streams.
    pub base_beats: usize,
    /// Beats on the `level{d}` streams.
    pub level_beats: usize,
}

/// The builder's streams for a list of merges, with what they exercised.
/// Inputs: `base0`..`base{D}`.
/// Outputs: `level0`..`level{D}`, `done`: the expected beats.
pub type BuilderStreams = StreamSet<Seen>;

fn beat(b: std::result::Result<Bits, LayoutError>) -> Result<Transaction> {
    packed(b, "upper builder")
}

/// The streams of `txs`.
pub fn streams(p: &Params, txs: &[BuilderTransaction]) -> Result<BuilderStreams> {
    let l = BuilderLayout::new(p);
    let d = p.max_lod as usize;
    let mut bases = vec![Vec::new(); d + 1];
    let mut levels = vec![Vec::new(); d + 1];
    let mut done = Vec::new();
    let mut seen = Seen::default();
    for tx in txs {
        count(&mut seen, tx);
        for (s, beats) in bases.iter_mut().zip(&tx.base) {
            for b in beats {
                s.push(beat(b.pack(&l.base))?);
            }
        }
        for (s, beats) in levels.iter_mut().zip(&tx.levels) {
            for b in beats {
                s.push(beat(b.pack(&l))?);
            }
        }
        done.push(beat(tx.done.pack(&l))?);
    }
    let named = |prefix: &str, all: Vec<Vec<Transaction>>| -> Vec<StreamBeats> {
        all.into_iter()
            .enumerate()
            .map(|(i, beats)| StreamBeats {
                name: format!("{prefix}{i}"),
                beats,
            })
            .collect()
    };
    let mut outputs = named("level", levels);
    outputs.push(StreamBeats {
        name: "done".into(),
        beats: done,
    });
    Ok(StreamSet {
        inputs: named("base", bases),
        outputs,
        seen,
    })
}

/// Adds what one merge reaches to `seen`.
fn count(seen: &mut Seen, tx: &BuilderTransaction) {
    seen.merges += 1;
    seen.no_top += tx.done.err as usize;
    seen.lifted += (tx.lifted > 0) as usize;
    seen.root_cut += tx.root_cut as usize;
    let top = tx.done.top as usize;
    let n_top = tx.levels[top].len() - 1;
    seen.several_roots += (!tx.done.err && n_top > 1) as usize;
    let deepest_base = tx.base.iter().rposition(|b| b.len() > 1).unwrap_or(0);
    seen.top_above_base += (top + 1 < deepest_base) as usize;
    seen.overflow += tx.levels.iter().flatten().any(|b| {
        matches!(
            b,
            LevelOut::Node { err: true, .. } | LevelOut::End { err: true, .. }
        )
    }) as usize;
    seen.base_beats += tx.base.iter().map(Vec::len).sum::<usize>();
    seen.level_beats += tx.levels.iter().map(Vec::len).sum::<usize>();
}

/// How many base nodes a random merge has: one merge in four at most 2
/// (the empty and one-node bases, where the top rules differ), the others
/// up to `most`.
pub fn random_base_size(rng: &mut SplitMix64, most: u64) -> usize {
    (match rng.below(4) {
        0 => rng.below(3),
        _ => rng.below(most + 1),
    }) as usize
}

/// `merges` random merges from `seed` ([`random_base_size`] base nodes).
pub fn random_merges(p: &Params, seed: u64, merges: usize, most: u64) -> Vec<BuilderTransaction> {
    let mut rng = SplitMix64(seed);
    (0..merges)
        .map(|_| {
            let n = random_base_size(&mut rng, most);
            builder_transaction(&random_base(&mut rng, p, n), p)
        })
        .collect()
}

fn golden_err(what: impl std::fmt::Display) -> CosimError {
    CosimError::Design {
        what: format!("golden upper builder: {what}"),
    }
}

/// Real merges: overlapping soups, disjoint soups, single-triangle inputs
/// with a big one (the first three of
/// `golden::merge::stimulus::real_cases`, translated as there); every
/// candidate level of each.
pub fn real_merges(p: &Params) -> Result<Vec<BuilderTransaction>> {
    let soup = |id: u8, n: usize, size: f32, seed: u64| try_soup(p, id, n, size, seed);
    let same = [0.4, 0.5, 0.6];
    let hs = (1..=3)
        .map(|i| soup(i, 60, 0.2, i as u64))
        .collect::<std::result::Result<Vec<Hierarchy>, _>>()
        .map_err(golden_err)?;
    let mut cases: Vec<Vec<(Hierarchy, Translation)>> = Vec::new();
    cases.push(hs.iter().map(|h| (h.clone(), place(h, same))).collect());
    let apart = |i: usize| [0.1 + 0.3 * i as f64, 0.9 - 0.3 * i as f64, 0.3];
    let disjoint = hs
        .iter()
        .enumerate()
        .map(|(i, h)| (h.clone(), place(h, apart(i))));
    cases.push(disjoint.collect());
    let mut single = Vec::new();
    for i in 1..=2 {
        let h = soup(i, 1, 0.001, 10 + i as u64).map_err(golden_err)?;
        let t = place(&h, if i < 2 { same } else { [0.9, 0.1, 0.2] });
        single.push((h, t));
    }
    let big = soup(3, 80, 0.3, 99).map_err(golden_err)?;
    single.push((big.clone(), place(&big, same)));
    cases.push(single);
    let mut out = Vec::new();
    for c in &cases {
        let refs: Vec<&Hierarchy> = c.iter().map(|(h, _)| h).collect();
        let inputs: Vec<(&Hierarchy, Translation)> = c.iter().map(|(h, t)| (h, *t)).collect();
        let (lo, hi) = candidate_range(&refs);
        for m in lo..=hi {
            let base: Vec<BaseNode> = fixed_level_base(&inputs, m, p).map_err(golden_err)?;
            out.push(builder_transaction(&base, p));
        }
    }
    Ok(out)
}

/// One run of `streams` on `sim` with the stalls of `config`: every output
/// beat compared bit for bit with golden's. The report says whether it
/// passed.
pub fn run(sim: MultiSim, streams: &BuilderStreams, config: &BenchConfig) -> Result<MultiReport> {
    streams.run(sim, config, &[]).map(|r| r.0)
}
