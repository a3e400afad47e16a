//! The merging module's stage RTL (`rtl_gen::merge`) on the frame's own
//! merge, under Verilator, bit for bit against the golden stage
//! transactions (`golden::merge::unit`): S614 (merge level) at the frame's
//! merging level; S608 (overlap counter) at that level when the mode is
//! overlap; S616 (one upper level, grouping by parent voxel) on that level's
//! nodes when the scene asks for the upper-level build. Each stage is
//! generated and built the first time a frame needs it. Per-node mode has
//! no single merging level: the stages are not run, and the run says so.

use cosim::from_rtl::design_from_module;
use cosim::tb::{run_stream_bench, BenchConfig, Vector};
use cosim::{open_engine, BitVec, Engine, EngineKind};
use golden::layout::Bits;
use golden::merge::level::candidate_range;
use golden::merge::unit::{
    level_transaction, overlap_transaction, upper_transaction, BeatLayout, OverlapLayout,
    UpperLayout,
};
use golden::merge::walk::{collect, walk_input, PlacedNode, WalkedInput};
use golden::merge::MergeMode;
use golden::store::{Hierarchy, NodeRecord};
use golden::world::World;
use golden::Params;

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
}

/// The stage engines, built on first use.
#[derive(Default)]
pub struct MergeRtl {
    level: Option<Box<dyn Engine>>,
    overlap: Option<(usize, Box<dyn Engine>)>,
    upper: Option<Box<dyn Engine>>,
}

fn bitvec(b: &Bits) -> Result<BitVec, String> {
    BitVec::from_words(b.width() as usize, b.words()).map_err(|e| e.to_string())
}

fn build(m: &rtl_gen::Module) -> Result<Box<dyn Engine>, String> {
    EngineKind::Verilator
        .check_tools()
        .map_err(|e| format!("merge RTL: {e}"))?;
    let dir = tempfile::tempdir().map_err(|e| format!("temporary folder: {e}"))?;
    let d = design_from_module(m, dir.path()).map_err(|e| format!("merge RTL: {e}"))?;
    open_engine(EngineKind::Verilator, &d, false).map_err(|e| format!("merge RTL (Verilator): {e}"))
}

/// One transaction's beats as bench vectors: every expected output is due
/// with the first input beat (the bench only checks order).
fn vectors(ins: Vec<BitVec>, outs: Vec<BitVec>) -> Vec<Vector> {
    let expected: Vec<_> = outs.into_iter().map(|o| vec![o]).collect();
    ins.into_iter()
        .enumerate()
        .map(|(j, b)| Vector {
            input: vec![b],
            outputs: if j == 0 { expected.clone() } else { Vec::new() },
        })
        .collect()
}

impl MergeRtl {
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
        let hs: Vec<&Hierarchy> = ids
            .iter()
            .map(|&i| {
                world
                    .store
                    .get(i)
                    .ok_or(format!("merge RTL: no hierarchy {i}"))
            })
            .collect::<Result<_, _>>()?;
        let (_, hi) = candidate_range(&hs);
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

        let (li, lo) = (BeatLayout::input(&p), BeatLayout::output(&p));
        let tx = level_transaction(&at, &hs, &p).map_err(|e| format!("merge RTL S614: {e}"))?;
        let ins = tx.inputs.iter().map(|b| {
            b.pack(&li)
                .map_err(|e| e.to_string())
                .and_then(|x| bitvec(&x))
        });
        let outs = tx.outputs.iter().map(|b| {
            b.pack(&lo)
                .map_err(|e| e.to_string())
                .and_then(|x| bitvec(&x))
        });
        let v = vectors(
            ins.collect::<Result<_, _>>()?,
            outs.collect::<Result<_, _>>()?,
        );
        if self.level.is_none() {
            let t = std::time::Instant::now();
            self.level = Some(build(&rtl_gen::merge::merge_level_unit(&p))?);
            out.build_seconds += t.elapsed().as_secs_f64();
        }
        bench(
            self.level.as_mut().expect("built").as_mut(),
            &v,
            "S614 merge level",
            &mut out,
        )?;

        if let MergeMode::Overlap { num, den } = mode {
            let ol = OverlapLayout::new(&p, hs.len());
            let voxels: Vec<Vec<_>> = walked
                .iter()
                .map(|w| {
                    w.by_lod[level as usize]
                        .iter()
                        .map(|n| n.record.voxel)
                        .collect()
                })
                .collect();
            let (beats, r) = overlap_transaction(&voxels, &p, num, den);
            let ins = beats.iter().map(|b| {
                b.pack(&ol)
                    .map_err(|e| e.to_string())
                    .and_then(|x| bitvec(&x))
            });
            let v = vectors(
                ins.collect::<Result<_, _>>()?,
                vec![bitvec(&r.pack(&ol).map_err(|e| e.to_string())?)?],
            );
            if self.overlap.as_ref().is_none_or(|(k, _)| *k != hs.len()) {
                let t = std::time::Instant::now();
                let e = build(&rtl_gen::merge::overlap_counter_unit(
                    &p,
                    hs.len(),
                    num,
                    den,
                ))?;
                out.build_seconds += t.elapsed().as_secs_f64();
                self.overlap = Some((hs.len(), e));
            }
            let e = &mut self.overlap.as_mut().expect("built").1;
            bench(e.as_mut(), &v, "S608 overlap counter", &mut out)?;
        }

        if upper_build && level >= 1 {
            let ul = UpperLayout::new(&p);
            let (ins, outs) = upper_transaction(&sorted_level(&at), &p);
            let ins = ins.iter().map(|b| {
                b.pack(&ul, false)
                    .map_err(|e| e.to_string())
                    .and_then(|x| bitvec(&x))
            });
            let outs = outs.iter().map(|b| {
                b.pack(&ul, true)
                    .map_err(|e| e.to_string())
                    .and_then(|x| bitvec(&x))
            });
            let v = vectors(
                ins.collect::<Result<_, _>>()?,
                outs.collect::<Result<_, _>>()?,
            );
            if self.upper.is_none() {
                let t = std::time::Instant::now();
                self.upper = Some(build(&rtl_gen::merge::upper_level_unit(&p))?);
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
        &cosim::units::merge::stream_names(),
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
