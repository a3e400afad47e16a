//! The merging module's RTL on the frame's own merge (Verilator, or the IR engine), bit
//! for bit against golden: the merging module as one unit
//! (`rtl_gen::merge::merge_module_unit`, SPEC 8.10) with the frame's inputs
//! as its `k` input streams: `cfg` = the candidate levels, the count pass
//! (overlap mode), the choice, which must equal the frame's golden merging
//! level, and the merge pass (S614) against `golden::merge::merge_module`; then S616
//! (one upper level, grouping by parent voxel) on that level's nodes when the
//! scene asks for the upper-level build. Each unit is generated and built the
//! first time a frame needs it. Per-node mode has no single merging level:
//! its merging module (SPEC 8.14) runs every pass of the frame's merge
//! (`per_node_transaction`, bit for bit), and the base it streams out is
//! checked per LOD against golden per-node merging and against the frame's
//! own merge counts (descents, created, reused).

use cosim::tb::{run_multi_stream_bench, run_stream_bench, BenchConfig, StreamBeats, Vector};
use cosim::Engine;
use golden::bits::Bits;
use golden::layout::LayoutError;
use golden::merge::fetcher::walk::{collect, walk_input, PlacedNode, WalkedInput};
use golden::merge::level_choice::candidate_range;
use golden::merge::merge_level::unit::{BaseBeat, BeatLayout, LevelCase};
use golden::merge::merge_module::{top_transaction, Report, TopLayout};
use golden::merge::per_node::unit::{base_by_lod, PerNodeCase, PerNodeLayout};
use golden::merge::upper_builder::level_unit::{upper_transaction, UpperLayout};
use golden::merge::{MergeMode, MergeStats};
use golden::store::{Hierarchy, NodeRecord};
use golden::world::World;
use golden::Params;

use super::engine::RunEngine;

/// What the stages did on one frame's merge.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct MergeRtlFrame {
    /// Stages run, e.g. `S614 merge level`.
    pub stages: Vec<String>,
    pub beats_in: u64,
    pub cycles: u64,
    pub mismatches: u64,
    pub first_mismatch: Option<String>,
    pub build_seconds: f64,
    pub seconds: f64,
    /// Per-node mode: passes the merge made (one per LOD from `lo`); 0 in
    /// level modes.
    pub passes: u32,
    /// Per-node mode: voxels that descended; 0 in level modes.
    pub descents: u64,
}

/// The engines, built on first use: the merging module per input count
/// and mode.
#[derive(Default)]
pub struct MergeRtl {
    /// The simulator every stage is built for.
    pub engine: RunEngine,
    /// One per (input count, mode): merge groups of different sizes each
    /// keep theirs.
    modules: Vec<(usize, MergeMode, Box<dyn Engine>)>,
    upper: Option<Box<dyn Engine>>,
}

/// One stream's beats, each packed by `pack` into a one-word beat; a
/// packing error (a field too wide for its layout) is returned.
fn packed_stream<T>(
    name: String,
    items: &[T],
    pack: impl Fn(&T) -> Result<Bits, LayoutError>,
) -> Result<StreamBeats, String> {
    let beats = items
        .iter()
        .map(|item| Ok(vec![pack(item).map_err(|e| e.to_string())?]))
        .collect::<Result<_, String>>()?;
    Ok(StreamBeats { name, beats })
}

/// A merging module's streams in its port order, the same for every mode:
/// inputs `cfg` (the candidate range `lo..=hi`, one beat) and `in0`..,
/// outputs `report` and `out` (base beats); each beat packed by its layout.
fn module_streams<I, R>(
    p: &Params,
    (lo, hi): (u8, u8),
    inputs: &[Vec<I>],
    pack_in: impl Fn(&I) -> Result<Bits, LayoutError>,
    reports: &[R],
    pack_report: impl Fn(&R) -> Result<Bits, LayoutError>,
    out: &[BaseBeat],
) -> Result<(Vec<StreamBeats>, [StreamBeats; 2]), String> {
    let (tl, ol) = (TopLayout::new(p), BeatLayout::output(p));
    let mut ins = vec![packed_stream("cfg".into(), &[(lo, hi)], |&(lo, hi)| {
        tl.pack_cfg(lo, hi)
    })?];
    for (i, s) in inputs.iter().enumerate() {
        ins.push(packed_stream(format!("in{i}"), s, &pack_in)?);
    }
    let outs = [
        packed_stream("report".into(), reports, pack_report)?,
        packed_stream("out".into(), out, |b| b.pack(&ol))?,
    ];
    Ok((ins, outs))
}

/// One transaction's beats as bench vectors: every expected output is due
/// with the first input beat (the bench only checks order).
fn vectors(ins: Vec<Bits>, outs: Vec<Bits>) -> Vec<Vector> {
    let expected: Vec<_> = outs.into_iter().map(|o| vec![o]).collect();
    ins.into_iter()
        .enumerate()
        .map(|(j, b)| Vector {
            input: vec![b],
            outputs: if j == 0 { expected.clone() } else { Vec::new() },
        })
        .collect()
}

/// The stored hierarchies `ids` of `world`, the merge's inputs.
fn stored_inputs<'w>(world: &'w World, ids: &[u8]) -> Result<Vec<&'w Hierarchy>, String> {
    ids.iter()
        .map(|&i| {
            world
                .store
                .get(i)
                .ok_or(format!("merge RTL: no hierarchy {i}"))
        })
        .collect()
}

impl MergeRtl {
    /// No stage built yet; each will be built for `engine`.
    pub fn new(engine: RunEngine) -> MergeRtl {
        MergeRtl {
            engine,
            ..MergeRtl::default()
        }
    }

    /// Runs the stages the scene uses on the merge of `ids` at `level`.
    pub fn run_frame(
        &mut self,
        world: &World,
        ids: &[u8],
        level: u8,
        mode: MergeMode,
        upper_build: bool,
    ) -> Result<MergeRtlFrame, String> {
        let start = std::time::Instant::now();
        let p: Params = world.params;
        let hs = stored_inputs(world, ids)?;
        let (lo, hi) = candidate_range(&hs);
        let walked: Vec<WalkedInput> = hs
            .iter()
            .enumerate()
            .map(|(r, h)| {
                let t = world
                    .table
                    .get(h.id as u32)
                    .ok()
                    .flatten()
                    .ok_or(format!("merge RTL: hierarchy {} has no translation", h.id))?;
                walk_input(h, r as u16, &t, hi.max(level)).map_err(|e| format!("merge RTL: {e}"))
            })
            .collect::<Result<_, _>>()?;
        let (_, at) = collect(&walked, level);
        let mut out = MergeRtlFrame::default();

        // The merging module: every candidate level in overlap mode (its
        // count pass), else the merging level only.
        let counts = matches!(mode, MergeMode::Overlap { .. });
        let levels: Vec<Option<LevelCase>> = (lo..=hi)
            .map(|l| {
                (counts || l == level).then(|| LevelCase {
                    hierarchies: hs.iter().map(|h| (*h).clone()).collect(),
                    at_level: collect(&walked, l).1,
                })
            })
            .collect();
        let k = hs.len();
        let tx = top_transaction(&mode, &p, k, lo, hi, &levels, false)
            .map_err(|e| format!("merge RTL merging module: {e}"))?;
        match tx.reports.last() {
            Some(Report::Chosen { lod, err: 0 }) if *lod == level => {}
            other => {
                return Err(format!(
                    "merge RTL: the merging module's golden choice {other:?} differs from the frame's merging level {level}"
                ))
            }
        }
        let (tl, li) = (TopLayout::new(&p), BeatLayout::input(&p));
        let (ins, outs) = module_streams(
            &p,
            (lo, hi),
            &tx.inputs,
            |b| b.pack(&li),
            &tx.reports,
            |r| r.pack(&tl),
            &tx.out,
        )?;
        let stage = if counts {
            "merging module (S608 count pass, choice, S614)"
        } else {
            "merging module (choice, S614)"
        };
        self.run_module(&p, k, mode, &ins, &outs, stage, &mut out)?;

        if upper_build && level >= 1 {
            let ul = UpperLayout::new(&p);
            let (ins, outs) = upper_transaction(&sorted_level(&at), &p);
            let ins = ins
                .iter()
                .map(|b| b.pack(&ul, false).map_err(|e| e.to_string()));
            let outs = outs
                .iter()
                .map(|b| b.pack(&ul, true).map_err(|e| e.to_string()));
            let v = vectors(
                ins.collect::<Result<_, _>>()?,
                outs.collect::<Result<_, _>>()?,
            );
            if self.upper.is_none() {
                let t = std::time::Instant::now();
                let m = rtl_gen::merge::upper_level_unit(&p);
                self.upper = Some(self.engine.open(&m, "merge RTL S616")?);
                out.build_seconds += t.elapsed().as_secs_f64();
            }
            bench(
                self.upper.as_mut().expect("built").as_mut(),
                &v,
                "S616 upper level",
                &mut out,
            )?;
        }
        out.seconds = start.elapsed().as_secs_f64();
        Ok(out)
    }
    /// Runs one merge's streams (`cfg`, `in*`; `report`, `out`) through the
    /// merging module of `k` inputs in `mode` (built on first use for each
    /// `k` and mode), adding its counts to `out`.
    #[allow(clippy::too_many_arguments)]
    fn run_module(
        &mut self,
        p: &Params,
        k: usize,
        mode: MergeMode,
        ins: &[StreamBeats],
        outs: &[StreamBeats],
        stage: &str,
        out: &mut MergeRtlFrame,
    ) -> Result<(), String> {
        let cached = |ms: &[(usize, MergeMode, Box<dyn Engine>)]| {
            ms.iter().position(|(n, m, _)| *n == k && *m == mode)
        };
        if cached(&self.modules).is_none() {
            let t = std::time::Instant::now();
            let design = golden::merge::merge_module::MergeDesign {
                params: *p,
                inputs: k,
                mode,
                ..Default::default()
            };
            design
                .validate()
                .map_err(|e| format!("merge RTL merging module: {e}"))?;
            let m = rtl_gen::merge::merge_module_unit(&design);
            let e = self.engine.open(&m, "merge RTL merging module")?;
            out.build_seconds += t.elapsed().as_secs_f64();
            self.modules.push((k, mode, e));
        }
        let at = cached(&self.modules).expect("built above");
        let engine = &mut self.modules[at].2;
        let config = BenchConfig {
            stop_on_mismatch: false,
            watchdog_cycles: 10_000,
            ..BenchConfig::default()
        };
        let before = engine.cycle();
        let r = run_multi_stream_bench(engine.as_mut(), ins, outs, &config)
            .map_err(|e| format!("merge RTL merging module: {e}"))?;
        out.stages.push(stage.to_string());
        out.beats_in += r.sent.iter().map(|s| s.1).sum::<u64>();
        out.cycles += engine.cycle() - before;
        let bad = r.mismatches
            + r.hang.is_some() as u64
            + r.missing.iter().map(|m| m.1 as u64).sum::<u64>();
        out.mismatches += bad;
        if bad > 0 && out.first_mismatch.is_none() {
            out.first_mismatch = Some(format!("{stage}: {r}"));
        }
        Ok(())
    }

    /// Runs the per-node merging module (`per-node:num/den`, SPEC 8.14) on
    /// the merge of `ids`: every pass from the candidate range's `lo`, bit
    /// for bit on `report` and `out`. The `out` beats the RTL matched are
    /// then read as a base per LOD, which must equal golden per-node
    /// merging's (`PerNodeCase::golden_base`), and their descents, created
    /// and reused nodes must equal the frame's merge (`stats`). A
    /// disagreement of golden with itself is an error, not a mismatch.
    pub fn run_per_node_frame(
        &mut self,
        world: &World,
        ids: &[u8],
        (num, den): (u32, u32),
        stats: &MergeStats,
    ) -> Result<MergeRtlFrame, String> {
        let start = std::time::Instant::now();
        let p: Params = world.params;
        let hs = stored_inputs(world, ids)?;
        let (lo, hi) = candidate_range(&hs);
        let case = PerNodeCase {
            hierarchies: hs.iter().map(|h| (*h).clone()).collect(),
            translations: hs
                .iter()
                .map(|h| {
                    world
                        .table
                        .get(h.id as u32)
                        .ok()
                        .flatten()
                        .ok_or(format!("merge RTL: hierarchy {} has no translation", h.id))
                })
                .collect::<Result<_, _>>()?,
            lo,
            hi,
        };
        let golden_err = |e: &dyn std::fmt::Display| format!("merge RTL per-node module: {e}");
        let tx = case.transaction(&p, num, den).map_err(|e| golden_err(&e))?;
        check_against_frame(&case, &tx.out, tx.descents, &p, (num, den), stats)?;
        let pl = PerNodeLayout::new(&p);
        let (ins, outs) = module_streams(
            &p,
            (lo, hi),
            &tx.inputs,
            |b| b.pack(&pl),
            &tx.reports,
            |r| r.pack(&pl),
            &tx.out,
        )?;
        let mut out = MergeRtlFrame {
            passes: tx.passes,
            descents: tx.descents,
            ..MergeRtlFrame::default()
        };
        let stage = format!(
            "per-node merging module ({} passes from LOD {lo}, {} descents)",
            tx.passes, tx.descents
        );
        self.run_module(
            &p,
            hs.len(),
            MergeMode::PerNode { num, den },
            &ins,
            &outs,
            &stage,
            &mut out,
        )?;
        out.seconds = start.elapsed().as_secs_f64();
        Ok(out)
    }
}

/// The per-node merge's `out` beats as a base per LOD against golden
/// per-node merging of the same case, and its counts against the frame's
/// merge: the streams the RTL is checked against are the frame's merge.
fn check_against_frame(
    case: &PerNodeCase,
    beats: &[BaseBeat],
    descents: u64,
    p: &Params,
    (num, den): (u32, u32),
    stats: &MergeStats,
) -> Result<(), String> {
    let fail = |what: String| Err(format!("merge RTL per-node module: {what}"));
    let Some(got) = base_by_lod(beats, p) else {
        return fail("a created node's child count overflowed in the out beats".into());
    };
    let (want, _) = case
        .golden_base(p, num, den)
        .map_err(|e| format!("merge RTL per-node module: {e}"))?;
    if let Some(l) = (0..want.len().max(got.len())).find(|&l| want.get(l) != got.get(l)) {
        return fail(format!(
            "the base at LOD {l} ({} nodes) differs from golden per-node merging's ({} nodes)",
            got.get(l).map_or(0, Vec::len),
            want.get(l).map_or(0, Vec::len)
        ));
    }
    let created = beats
        .iter()
        .filter(|b| matches!(b, BaseBeat::Created { .. }))
        .count() as u64;
    let reused = beats
        .iter()
        .filter(|b| matches!(b, BaseBeat::Reused { .. }))
        .count() as u64;
    let lm = &stats.merge_level;
    let frame = (
        stats.per_node.descents,
        lm.created,
        lm.reused_inner + lm.reused_leaves,
    );
    if (descents, created, reused) != frame {
        return fail(format!(
            "(descents, created, reused) = {:?} differs from the frame's merge {frame:?}",
            (descents, created, reused)
        ));
    }
    Ok(())
}

/// The Morton-sorted nodes of one level (the order of S616's level lists).
fn sorted_level(nodes: &[PlacedNode]) -> Vec<NodeRecord> {
    let mut v: Vec<PlacedNode> = nodes.to_vec();
    v.sort_by_key(|n| n.key());
    v.iter().map(|n| n.record).collect()
}

fn bench(
    engine: &mut dyn Engine,
    v: &[Vector],
    stage: &str,
    out: &mut MergeRtlFrame,
) -> Result<(), String> {
    let config = BenchConfig {
        stop_on_mismatch: false,
        watchdog_cycles: 10_000,
        ..BenchConfig::default()
    };
    let before = engine.cycle();
    let r = run_stream_bench(
        &mut *engine,
        &cosim::tb::StreamNames::single("data"),
        v,
        None,
        &config,
        None,
    )
    .map_err(|e| format!("merge RTL {stage}: {e}"))?;
    out.stages.push(stage.to_string());
    out.beats_in += r.inputs_sent;
    // The engine is reused across frames: count this run's edges only.
    out.cycles += engine.cycle() - before;
    let bad = r.mismatches + r.hang.is_some() as u64 + (!r.accounting.balanced()) as u64;
    out.mismatches += bad;
    if bad > 0 && out.first_mismatch.is_none() {
        out.first_mismatch = Some(format!(
            "{stage}: {} mismatches{}{}",
            r.mismatches,
            if r.hang.is_some() { ", hung" } else { "" },
            if r.accounting.balanced() {
                ""
            } else {
                ", outputs lost or duplicated"
            }
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use golden::translate::stimulus::SplitMix64;

    /// A random multi-pass per-node case, its transaction, and the merge
    /// counts golden `merge` would report for it.
    fn case_with_descents() -> (
        PerNodeCase,
        golden::merge::per_node::unit::PerNodeTransaction,
        MergeStats,
    ) {
        let p = Params::default();
        let mut rng = SplitMix64(3);
        loop {
            let case = golden::merge::per_node::unit::random_per_node_case(&mut rng, &p, 3, 4);
            let tx = case.transaction(&p, 1, 2).unwrap();
            if tx.descents == 0 || tx.passes == 0 {
                continue;
            }
            let count = |f: fn(&BaseBeat) -> bool| tx.out.iter().filter(|b| f(b)).count() as u64;
            let mut stats = MergeStats::default();
            stats.per_node.descents = tx.descents;
            stats.merge_level.created = count(|b| matches!(b, BaseBeat::Created { .. }));
            stats.merge_level.reused_inner = count(|b| matches!(b, BaseBeat::Reused { .. }));
            return (case, tx, stats);
        }
    }

    #[test]
    fn per_node_out_beats_are_checked_per_lod_and_against_the_frame() {
        let p = Params::default();
        let (case, tx, stats) = case_with_descents();
        let check = |out: &[BaseBeat], stats: &MergeStats| {
            check_against_frame(&case, out, tx.descents, &p, (1, 2), stats)
        };
        check(&tx.out, &stats).expect("golden agrees with itself");
        // A base node lost from the stream: its LOD's base differs.
        let at = tx
            .out
            .iter()
            .position(|b| matches!(b, BaseBeat::Reused { .. }))
            .expect("a reused node");
        let mut lost = tx.out.clone();
        lost.remove(at);
        let e = check(&lost, &stats).unwrap_err();
        assert!(e.contains("the base at LOD"), "{e}");
        // The frame's merge created one node more than the stream.
        let mut other = stats.clone();
        other.merge_level.created += 1;
        let e = check(&tx.out, &other).unwrap_err();
        assert!(e.contains("differs from the frame's merge"), "{e}");
    }
}
