//! The hierarchy merger top (fetchers, merging module, upper builder,
//! record writer; `rtl_gen::merge::hierarchy_merger_unit`, SPEC 8.15) on a
//! frame's own merges, back to back on one top from reset in group order,
//! so consecutive merges overlap as they would in a GPU (8.15 step 8). In a
//! scene that places by translation the top is the hierarchy unit
//! (`rtl_gen::merge::hierarchy_unit`, docs/hardware.md 8.16): the frame's
//! determine commands write the translation unit's table and the merger
//! reads its inputs' translations there, its candidate range computed from
//! the inputs' headers; without translation it is the merger top alone.
//! Per merge, golden's transaction of the store's real contents
//! (`merger::merger_transaction` over the group's stored hierarchies
//! and their translation entries, out id the group's merged id), whose
//! written records, references and header must equal the merged
//! hierarchy the frame stored, through cosim's bench of the top
//! (`cosim::units::hierarchy_unit::HierarchySim`, the bench `hiermerge
//! cosim --unit hierarchy` runs, or `cosim::units::merger::MergerSim`),
//! every output beat compared bit for bit.
//!
//! With one shared store port (`--store-port shared[:T]`, the run's
//! default: SPEC 8.15 "The shared store port") the top's reads reach the
//! bench on `store_req` in an order that depends on timing, so cosim's
//! store model answers them after the store latency from the store image
//! of the merges' inputs (their node records and references as the frame
//! stored them, `StoreWords::of_hierarchies`), each read attributed to its
//! merge by its `slot`; each merge must make as many reads as golden's
//! units, none outside the image. The port takes one read a clock, so a
//! run of `r` reads writing `n` records is allowed at most `n / r` records
//! per cycle; the run reports its records per cycle against that, over
//! the merger's cycles (from the first merge command taken).
//!
//! The merger's sizes are derived from the frame's merges (`k` the most
//! inputs of any; a merge of fewer leaves the rest unused): the root sorter holds
//! the inputs' most roots, the frontier FIFO the most inner nodes of one
//! input's level, the writer's buffers the merged hierarchy's largest
//! level and its created references, each leaf FIFO the most leaves of a
//! LOD; each is the merger's default when that suffices, else the power of
//! two that holds it. A merge no buildable size holds is skipped with the
//! reason. A built merger is kept for later merges it can hold.

use cosim::units::hierarchy_unit::{placement_command, write_command, HierarchyCase, HierarchySim};
use cosim::units::merger::{
    MergerEngine, MergerSim, ModuleRunConfig, SceneStore, SimOutcome, VerilogPatch,
};
use golden::merge::fetcher::FetchSizes;
use golden::merge::hierarchy_unit::{hierarchy_merge, merge_cmd};
use golden::merge::merge_module::MergeDesign;
use golden::merge::merger::store_port::{StorePort, StoreWords};
use golden::merge::merger::{merger_transaction, MergerSizes, MergerTransaction, ModulePass};
use golden::merge::record_writer::{writer_err, CrefBeat};
use golden::merge::MergeMode;
use golden::store::Hierarchy;
use golden::translate::model::TranslateModel;
use golden::translate::Axis;
use golden::world::World;
use golden::Params;
use rtl_gen::merge::{
    hierarchy_merger_name, hierarchy_unit_name, HierarchyUnitConfig, MergerConfig,
};
use serde::Serialize;

use super::engine::RunEngine;

/// The test hook of `hiermerge cosim` (SPEC 10.1), honoured by the run's
/// merger top too: the one occurrence of `FROM`'s text in its emitted
/// Verilog replaced by `TO`'s before the simulator reads it (Verilator).
pub const PATCH_FROM_VAR: &str = "HIERMERGE_COSIM_PATCH_FROM";
pub const PATCH_TO_VAR: &str = "HIERMERGE_COSIM_PATCH_TO";

/// The largest frontier the fetcher is built with (`MergerConfig::validate`).
const MOST_FRONTIER: usize = 1 << 16;
/// The largest leaf FIFO (`2^16` leaves per LOD).
const MOST_LEAF_BITS: u32 = 16;

/// How the run's merger top reaches the store (`--store-port`,
/// `--store-latency`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MergerStore {
    /// Per-unit read streams (their answers precomputed by golden), or one
    /// shared read port.
    pub port: StorePort,
    /// A shared port's store answers a read this many clocks after taking
    /// it, at the earliest (`1..`).
    pub latency: u64,
}

impl Default for MergerStore {
    /// One shared read port with a tag FIFO of 8 reads, a store answering
    /// the next clock: `cosim --unit merger --store-port shared`'s defaults.
    fn default() -> Self {
        MergerStore {
            port: StorePort::SHARED,
            latency: 1,
        }
    }
}

impl MergerStore {
    /// `shared:T` or `per-unit`, as `--store-port` takes it.
    pub fn port_name(&self) -> String {
        match self.port {
            StorePort::Shared { tag_bits } => format!("shared:{tag_bits}"),
            StorePort::PerUnit => "per-unit".into(),
        }
    }

    /// The port and, when shared, its store's latency, for the report.
    pub fn label(&self) -> String {
        match self.port {
            StorePort::Shared { .. } => {
                format!("store port {}, latency {}", self.port_name(), self.latency)
            }
            StorePort::PerUnit => "per-unit store ports".into(),
        }
    }
}

/// The merger top on one frame's merges, run back to back on one top from
/// reset, in group order (consecutive merges overlap, SPEC 8.15 step 8).
#[derive(Clone, Debug, Default, Serialize)]
pub struct MergerRtlFrame {
    /// The top simulated (its name carries the configuration).
    pub top: String,
    /// Inputs the merger is built with (`k`).
    pub k: usize,
    /// Merges run.
    pub merges: usize,
    /// Determine commands before them: one per input hierarchy, writing
    /// the table the merges read (docs/hardware.md 8.16).
    pub determines: u64,
    /// Cycles of the run, from reset to the last output beat.
    pub cycles: u64,
    /// Of them, the cycles before the first merge command was taken: the
    /// first determine commands through the translation unit, which the
    /// merge must wait for (0 when not measured: the Icarus batch).
    pub determine_cycles: u64,
    /// The merger's cycles: from the first merge command taken to the
    /// end; the per-node and per-cycle figures below are over them.
    pub merge_cycles: u64,
    /// Node records the RTL wrote (`nodes` beats).
    pub records: u64,
    /// References the RTL wrote (`refs` beats).
    pub refs: u64,
    /// The frame's merged hierarchies: records and references golden stored.
    pub golden_records: u64,
    pub golden_refs: u64,
    /// Store reads the RTL requested: every fetcher's node, reference,
    /// child reference (and probe) requests, and the writer's (a shared
    /// port: its `store_req` beats).
    pub store_reads: u64,
    /// The store reads golden's units make in the merges.
    pub golden_store_reads: u64,
    pub cycles_per_node: f64,
    pub store_reads_per_node: f64,
    pub records_per_cycle: f64,
    /// `shared:T` or `per-unit`.
    pub store_port: String,
    /// A shared port: its store's latency in clocks.
    pub store_latency: Option<u64>,
    /// A shared port: the records per cycle it allows at one read a clock
    /// (`records / store_reads`), and the share of it the run reached
    /// (`records_per_cycle` over it, which is `store_reads / cycles`).
    pub records_allowed_per_cycle: Option<f64>,
    pub of_port: Option<f64>,
    /// Output beats that differ from golden, beats missing, a hang, or
    /// `done`/`idle` wrong (each counted).
    pub mismatches: u64,
    /// The first failure, decoded: stream, beat, cycle and fields.
    pub first_mismatch: Option<String>,
    /// Seconds building (or loading) the top; 0 when it was reused.
    pub build_seconds: f64,
    pub seconds: f64,
}

/// One group's merge in the frame's run on the merger top: what golden's
/// units write and read for it.
#[derive(Clone, Debug, Default, Serialize)]
pub struct MergerGroup {
    /// The top the frame's merges ran on.
    pub top: String,
    /// Inputs merged.
    pub n: usize,
    /// Its place in the frame's run (0: the first merge).
    pub order: usize,
    /// Records and references of its merged hierarchy, and the store
    /// reads golden's units make for it.
    pub golden_records: u64,
    pub golden_refs: u64,
    pub golden_store_reads: u64,
}

/// One group's merge of a frame: its inputs in rank order, and the id of
/// the merged hierarchy the frame stored.
#[derive(Clone, Debug)]
pub struct FrameMerge {
    pub ids: Vec<u8>,
    pub out: u8,
}

/// The merger top on a frame's merges: per merge its part of the run, or
/// why no merger can be built for it; the run, when some merge ran.
#[derive(Clone, Debug, Default)]
pub struct FrameRun {
    pub merges: Vec<Result<MergerGroup, String>>,
    pub run: Option<MergerRtlFrame>,
}

/// A merger built for a configuration, kept for later merges.
struct Built {
    config: MergerConfig,
    /// The hierarchy unit around the merger `config`.
    unit: HierarchyUnitConfig,
    sim: TopSim,
    /// The Verilog the simulator opens for each merge.
    _dir: tempfile::TempDir,
}

/// What a frame's merges run on: the hierarchy unit (the translation unit
/// writes the table the merger reads, docs/hardware.md 8.16), or, in a
/// scene that asks for no translation, the merger top alone (its `cfg`
/// beats carry the world's entries): a run builds only what it asks for.
enum TopSim {
    Hierarchy(HierarchySim),
    Merger(MergerSim),
}

/// The merger tops a run built, one per configuration.
pub struct MergerRtl {
    /// The merger bench's engine: the run's, or Icarus stepped from Rust
    /// (the tests of a patched top: a compile of seconds where Verilator
    /// builds for half a minute, and the IR engine reads no Verilog).
    pub(crate) sim_engine: MergerEngine,
    built: Vec<Built>,
    /// The test hook: bit 0 of each merge's expected `header` beat flipped.
    pub(crate) flip_expected: bool,
    /// The Verilog patch hook ([`PATCH_FROM_VAR`], [`PATCH_TO_VAR`]).
    pub(crate) patch: Option<VerilogPatch>,
    /// How every top built reaches the store.
    store: MergerStore,
    /// The scene places its objects by translation: the tops are
    /// hierarchy units (else merger tops).
    translation: bool,
}

/// The sizes a merge needs, or why no merger can be built for it.
fn needed_sizes(p: &Params, hs: &[&Hierarchy], tx: &MergerTransaction) -> Result<Sizes, String> {
    let roots = hs.iter().map(|h| h.root_count as usize).max().unwrap_or(1);
    // The walk pushes the inner nodes of every LOD above its deepest
    // command's; per-node passes go one LOD deeper each.
    let passes = match &tx.module {
        ModulePass::PerNode(pn) => pn.passes as usize,
        ModulePass::Level(_) => 0,
    };
    let deepest = tx.cmds.iter().map(|c| c.lod as usize).max().unwrap_or(0) + passes;
    let frontier = hs
        .iter()
        .map(|h| most_inner_per_lod(h, deepest))
        .max()
        .unwrap_or(0);
    let b = tx.builder();
    let top = (b.done.top as usize).min(b.levels.len());
    let level = b.levels[top..]
        .iter()
        .map(|l| l.len().saturating_sub(1))
        .max()
        .unwrap_or(0);
    let crefs = tx
        .writer
        .crefs
        .iter()
        .filter(|c| matches!(c, CrefBeat::Ref(_)))
        .count();
    let leaves = match tx.chosen {
        Some(_) => &tx.leaves,
        // Per-node mode: each LOD's FIFO holds its leaves and the module's
        // nodes of that LOD (golden's `leaf_overflow` of the base).
        None => &tx.base,
    };
    let mut per_lod = std::collections::BTreeMap::<u8, usize>::new();
    for n in leaves {
        *per_lod.entry(n.record.voxel.lod).or_default() += 1;
    }
    let leaf = per_lod.values().copied().max().unwrap_or(0);
    let most_c = p.index_bits as u32 - 1;
    let capacity = level.max(crefs);
    let capacity_bits = bits_for(capacity);
    if capacity_bits > most_c {
        return Err(format!(
            "the merged hierarchy has a level of {level} nodes and {crefs} created references: \
             more than the record writer's largest buffer (2^{most_c}, below 2^I)"
        ));
    }
    if frontier > MOST_FRONTIER {
        return Err(format!(
            "an input has {frontier} inner nodes at one LOD: more than the largest frontier FIFO \
             ({MOST_FRONTIER})"
        ));
    }
    let leaf_bits = bits_for(leaf);
    if leaf_bits > MOST_LEAF_BITS {
        return Err(format!(
            "{leaf} leaves at one LOD: more than the largest leaf FIFO (2^{MOST_LEAF_BITS})"
        ));
    }
    Ok(Sizes {
        roots,
        frontier,
        capacity_bits,
        leaf_bits,
    })
}

/// What one merge needs of the merger's sizes.
#[derive(Clone, Copy, Debug)]
struct Sizes {
    roots: usize,
    frontier: usize,
    capacity_bits: u32,
    leaf_bits: u32,
}

impl Sizes {
    /// Sizes that hold both `self` and `o`.
    fn max(self, o: Sizes) -> Sizes {
        Sizes {
            roots: self.roots.max(o.roots),
            frontier: self.frontier.max(o.frontier),
            capacity_bits: self.capacity_bits.max(o.capacity_bits),
            leaf_bits: self.leaf_bits.max(o.leaf_bits),
        }
    }

    /// Whether the merger `c` holds these.
    fn held_by(&self, c: &MergerConfig) -> bool {
        c.design.roots >= self.roots
            && c.sizes.fetch.frontier >= self.frontier
            && c.sizes.capacity_bits >= self.capacity_bits
            && c.sizes.leaf_bits >= self.leaf_bits
    }

    /// The merger of `design` with its default sizes, each grown to the
    /// power of two that holds what is needed.
    fn config(&self, design: MergeDesign) -> MergerConfig {
        let mut c = MergerConfig::new(MergeDesign {
            roots: design.roots.max(self.roots.next_power_of_two()),
            ..design
        });
        let s = &mut c.sizes;
        s.fetch.roots = c.design.roots;
        s.fetch.frontier = s.fetch.frontier.max(self.frontier.next_power_of_two());
        s.capacity_bits = s.capacity_bits.max(self.capacity_bits);
        s.leaf_bits = s.leaf_bits.max(self.leaf_bits);
        c
    }
}

/// Bits of an index that counts up to `n` entries (`2^b >= n`, at least 1).
fn bits_for(n: usize) -> u32 {
    (n.max(2) - 1).ilog2() + 1
}

/// The most inner nodes `h` has at one LOD down to `deepest`: what one
/// level of its walk pushes on the frontier at most.
fn most_inner_per_lod(h: &Hierarchy, deepest: usize) -> usize {
    let mut per_lod = std::collections::BTreeMap::<u8, usize>::new();
    for n in h
        .nodes
        .iter()
        .filter(|n| !n.leaf && n.voxel.lod as usize <= deepest)
    {
        *per_lod.entry(n.voxel.lod).or_default() += 1;
    }
    per_lod.values().copied().max().unwrap_or(0)
}

/// Sizes with room for any merge of `hs` (for the first golden pass, whose
/// streams say what the merge needs).
fn roomy(p: &Params, hs: &[&Hierarchy]) -> MergerSizes {
    MergerSizes {
        fetch: FetchSizes {
            roots: hs.iter().map(|h| h.root_count as usize).max().unwrap_or(1),
            frontier: MOST_FRONTIER,
        },
        capacity_bits: p.index_bits as u32 - 1,
        leaf_bits: MOST_LEAF_BITS,
        store_port: golden::merge::merger::store_port::StorePort::PerUnit,
    }
}

/// The merge of `ids` into `out` through the merger of `c`, from the
/// world's store and table, checked against the merged hierarchy the
/// frame stored: `Ok(Err(why))` when the chain refuses the merge (a
/// fetcher's walk beyond `c`'s sizes), an error when golden disagrees with
/// itself.
fn golden_merge(
    world: &World,
    ids: &[u8],
    out: u8,
    c: &MergerConfig,
) -> Result<Result<MergerTransaction, String>, String> {
    let tx = match merger_transaction(
        &world.store,
        &world.table,
        ids,
        c.design.mode,
        out,
        c.design.inputs,
        c.sizes,
    ) {
        Ok(tx) => tx,
        Err(e) => return Ok(Err(format!("golden's merger chain refuses the merge: {e}"))),
    };
    let merged = world
        .store
        .get(out)
        .ok_or(format!("hierarchy merger RTL: no merged hierarchy {out}"))?;
    let w = &tx.writer;
    let fine = w.header.err == writer_err::NONE
        && !tx.header.leaf_overflow
        && w.nodes == merged.nodes
        && w.refs == merged.refs
        && w.header.roots == merged.root_count as u64
        && w.header.top == merged.top_lod;
    if !fine {
        return Err(format!(
            "hierarchy merger RTL: golden's merger chain (writer err {}, leaf overflow {}, {} \
             records, {} references) differs from the frame's merged hierarchy {out} ({} records, \
             {} references)",
            w.header.err,
            tx.header.leaf_overflow,
            w.nodes.len(),
            w.refs.len(),
            merged.nodes.len(),
            merged.refs.len()
        ));
    }
    Ok(Ok(tx))
}

impl MergerRtl {
    /// No merger built yet; each will be built for `engine` with `store`'s
    /// port (and broken by the Verilog patch hook when both its variables
    /// are set), inside a hierarchy unit when the scene asks for
    /// `translation`.
    pub fn new(engine: RunEngine, store: MergerStore, translation: bool) -> MergerRtl {
        let var = |name| std::env::var(name).ok();
        let patch = match (var(PATCH_FROM_VAR), var(PATCH_TO_VAR)) {
            (Some(from), Some(to)) => Some(VerilogPatch { from, to }),
            _ => None,
        };
        MergerRtl {
            sim_engine: engine.merger(),
            built: Vec::new(),
            flip_expected: false,
            patch,
            store,
            translation,
        }
    }

    /// The engine the tops run on, as the report names it.
    pub fn engine_label(&self) -> &'static str {
        match self.sim_engine {
            MergerEngine::Verilator => "Verilator",
            MergerEngine::Ir => "IR",
            MergerEngine::Iverilog => "Icarus",
        }
    }

    /// The merger on the frame's `merges` in `mode`, back to back on one
    /// top from reset (group order): the top has the most inputs of any
    /// merge (a merge of fewer leaves the rest unused) and sizes that hold
    /// every merge; a merge that no buildable size holds is left out with
    /// the reason.
    pub fn run_frame(
        &mut self,
        world: &World,
        merges: &[FrameMerge],
        mode: MergeMode,
    ) -> Result<FrameRun, String> {
        let start = std::time::Instant::now();
        let p = world.params;
        let k = merges.iter().map(|m| m.ids.len()).max().unwrap_or(0).max(2);
        let design = MergeDesign {
            params: p,
            inputs: k,
            mode,
            ..MergeDesign::default()
        };
        let mut fits: Vec<Result<Vec<&Hierarchy>, String>> = Vec::new();
        let mut need: Option<Sizes> = None;
        for m in merges {
            let hs = inputs_of(world, &m.ids)?;
            match self.needs(world, m, &hs, design)? {
                Ok(s) => {
                    need = Some(need.map_or(s, |n| n.max(s)));
                    fits.push(Ok(hs));
                }
                Err(why) => fits.push(Err(why)),
            }
        }
        let Some(need) = need else {
            // Every merge refused.
            let merges = fits.into_iter().map(|f| f.map(|_| MergerGroup::default()));
            return Ok(FrameRun {
                merges: merges.collect(),
                run: None,
            });
        };
        let mut report = MergerRtlFrame::default();
        let at = self.top_for(design, need, &mut report)?;
        let b = &self.built[at];
        let top = match b.sim {
            TopSim::Hierarchy(_) => hierarchy_unit_name(&b.unit),
            TopSim::Merger(_) => hierarchy_merger_name(&b.config),
        };
        let mut txs = Vec::new();
        let mut ran = Vec::new();
        let mut groups = Vec::new();
        for (m, fit) in merges.iter().zip(&fits) {
            let hs = match fit {
                Ok(hs) => hs,
                Err(why) => {
                    groups.push(Err(why.clone()));
                    continue;
                }
            };
            // Sized from the merges' needs: a refusal now is a sizing bug.
            let tx = golden_merge(world, &m.ids, m.out, &b.config)?.map_err(|e| {
                format!("hierarchy merger RTL ({top}, sized for the frame's merges): {e}")
            })?;
            groups.push(Ok(MergerGroup {
                top: top.clone(),
                n: hs.len(),
                order: txs.len(),
                golden_records: tx.writer.nodes.len() as u64,
                golden_refs: tx.writer.refs.len() as u64,
                golden_store_reads: golden_reads(&tx),
            }));
            txs.push(tx);
            ran.push(m);
        }
        let bench = ModuleRunConfig::default();
        let flip = self.flip_expected.then_some(0);
        let image;
        let store = match b.config.sizes.store_port {
            StorePort::PerUnit => None,
            StorePort::Shared { .. } => {
                let hs = fits.iter().filter_map(|f| f.as_ref().ok()).flatten();
                image = StoreWords::of_hierarchies(hs.copied())
                    .map_err(|e| format!("hierarchy merger RTL: the store image: {e}"))?;
                Some(SceneStore {
                    image: &image,
                    latency: self.store.latency,
                })
            }
        };
        let o = match &b.sim {
            TopSim::Hierarchy(sim) => {
                let cases = frame_cases(world, &b.unit, &ran, txs.clone())?;
                report.determines = cases.iter().map(|c| c.dets.len() as u64).sum();
                sim.run(&cases, &bench, flip, store)
            }
            TopSim::Merger(sim) => sim.run(&txs, &bench, flip, store),
        }
        .map_err(|e| format!("{top}: {e}"))?;
        report.first_mismatch = failure(&o);
        report.top = top;
        let run = frame_of(&o, &txs, &b.unit.merger, self.store, report, start);
        Ok(FrameRun {
            merges: groups,
            run: Some(run),
        })
    }

    /// What merger sizes `m` needs (a top of `design`'s inputs and mode),
    /// or why no merger can be built for it.
    fn needs(
        &self,
        world: &World,
        m: &FrameMerge,
        hs: &[&Hierarchy],
        design: MergeDesign,
    ) -> Result<Result<Sizes, String>, String> {
        let wide = MergerConfig {
            design,
            sizes: MergerSizes {
                store_port: self.store.port,
                ..roomy(&design.params, hs)
            },
        };
        // At the largest sizes: a refusal means no merger can be built.
        Ok(match golden_merge(world, &m.ids, m.out, &wide)? {
            Ok(probe) => needed_sizes(&design.params, hs, &probe),
            Err(why) => Err(why),
        })
    }

    /// The index of a built top of `design`'s parameters and mode with at
    /// least its inputs that holds `need`, built now if there is none
    /// (its build time in `report`).
    fn top_for(
        &mut self,
        design: MergeDesign,
        need: Sizes,
        report: &mut MergerRtlFrame,
    ) -> Result<usize, String> {
        let fits = |b: &Built| {
            let d = &b.config.design;
            (d.params, d.mode) == (design.params, design.mode)
                && d.inputs >= design.inputs
                && need.held_by(&b.config)
        };
        if let Some(at) = self.built.iter().position(fits) {
            return Ok(at);
        }
        let t = std::time::Instant::now();
        let mut config = need.config(design);
        config.sizes.store_port = self.store.port;
        config
            .validate()
            .map_err(|e| format!("hierarchy merger RTL: {e}"))?;
        let unit = HierarchyUnitConfig::new(config.clone());
        unit.validate()
            .map_err(|e| format!("hierarchy unit RTL: {e}"))?;
        let dir = tempfile::tempdir().map_err(|e| format!("temporary folder: {e}"))?;
        let (engine, patch) = (self.sim_engine, self.patch.as_ref());
        let sim = match self.translation {
            true => HierarchySim::new(&unit, engine, dir.path(), patch).map(TopSim::Hierarchy),
            false => MergerSim::new(&config, engine, dir.path(), patch).map(TopSim::Merger),
        }
        .map_err(|e| format!("hierarchy merger RTL ({}): {e}", self.engine_label()))?;
        self.built.push(Built {
            config,
            unit,
            sim,
            _dir: dir,
        });
        report.build_seconds = t.elapsed().as_secs_f64();
        Ok(self.built.len() - 1)
    }
}

/// The frame's merges `ran` (golden's `txs`) as the hierarchy unit `unit`
/// takes them: before each merge command, a determine command per input
/// not yet placed in this run, placing an object as the scene does (its
/// binary64 placement at the LOD its translation settled at) and a merged
/// input by its table entry; golden's translation unit model runs them from
/// reset, and must write the world's table entries, on which golden's
/// hierarchy unit must make the very merges `txs`.
fn frame_cases(
    world: &World,
    unit: &HierarchyUnitConfig,
    ran: &[&FrameMerge],
    txs: Vec<MergerTransaction>,
) -> Result<Vec<HierarchyCase>, String> {
    let err = |e: String| format!("hierarchy unit RTL: {e}");
    let mut model = TranslateModel::new(unit.table).map_err(|e| err(format!("{e:?}")))?;
    let cl = unit.cmd_layout();
    let (k, sizes, mode) = (
        unit.merger.design.inputs,
        unit.merger.sizes,
        unit.merger.design.mode,
    );
    let mut placed = std::collections::BTreeSet::new();
    let mut cases = Vec::new();
    for (m, tx) in ran.iter().zip(txs) {
        let mut dets = Vec::new();
        for &id in m.ids.iter().filter(|&&id| placed.insert(id)) {
            let h = world
                .store
                .get(id)
                .ok_or(err(format!("no hierarchy {id}")))?;
            let want = world.table.get(id as u32).ok().flatten();
            let t = want.ok_or(err(format!("hierarchy {id} has no translation")))?;
            let inp = match world.object(id) {
                Some(o) => {
                    let bits = Axis::ALL.map(|a| o.placement.value_f64(a).to_bits());
                    placement_command(&unit.table, h, t.lod, bits)
                }
                None => write_command(&unit.table, h, &t),
            }
            .map_err(|e| err(e.to_string()))?;
            let out = model.determine(&inp).map_err(|e| err(format!("{e:?}")))?;
            let wrote = model.table().get(id as u32).ok().flatten();
            if wrote != Some(t) {
                return Err(err(format!(
                    "the determine command of hierarchy {id} wrote {wrote:?}, the world's table holds {t:?}"
                )));
            }
            dets.push((inp, out));
        }
        let cmd = merge_cmd(&world.store, &m.ids, m.out).map_err(|e| err(e.to_string()))?;
        let again = hierarchy_merge(&world.store, model.table(), &cmd, mode, k, sizes)
            .map_err(|e| err(e.to_string()))?;
        if again != tx {
            return Err(err(format!(
                "merge into {}: golden's hierarchy unit and its merger chain differ",
                m.out
            )));
        }
        let merge = cl.pack_merge(&cmd).map_err(|e| err(e.to_string()))?;
        cases.push(HierarchyCase { dets, merge, tx });
    }
    Ok(cases)
}

/// The stored hierarchies `ids`.
fn inputs_of<'w>(world: &'w World, ids: &[u8]) -> Result<Vec<&'w Hierarchy>, String> {
    ids.iter()
        .map(|&i| {
            world
                .store
                .get(i)
                .ok_or(format!("hierarchy merger RTL: no hierarchy {i}"))
        })
        .collect()
}

/// The report of the run `o` of golden's `txs` on the top `c` reaching
/// the store through `store`.
fn frame_of(
    o: &SimOutcome,
    txs: &[MergerTransaction],
    c: &MergerConfig,
    store: MergerStore,
    report: MergerRtlFrame,
    start: std::time::Instant,
) -> MergerRtlFrame {
    let t = &o.totals;
    let got = |name: &str| {
        t.received
            .iter()
            .filter(|r| r.0 == name)
            .map(|r| r.1)
            .sum::<u64>()
    };
    let golden_store_reads = txs.iter().map(golden_reads).sum();
    let store_reads = match &o.store {
        Some(st) => st.stats.reads,
        None => t
            .received
            .iter()
            .filter(|r| r.0.ends_with("_req"))
            .map(|r| r.1)
            .sum::<u64>(),
    };
    let records = got("nodes");
    let per_node = |x: u64| x as f64 / records.max(1) as f64;
    let first = |name: &str| t.first_high.iter().find(|p| p.0 == name).and_then(|p| p.1);
    let determine_cycles = first("translate_done").unwrap_or(0).min(t.cycles);
    let merge_cycles = t.cycles - determine_cycles;
    let store_failed = o.store.as_ref().is_some_and(|s| s.failure.is_some());
    let mismatches = t.mismatches
        + t.missing.iter().map(|m| m.1 as u64).sum::<u64>()
        + t.hang.is_some() as u64
        + t.status_failure().is_some() as u64
        + store_failed as u64;
    let cycles = merge_cycles.max(1) as f64;
    let shared = o.store.is_some();
    MergerRtlFrame {
        k: c.design.inputs,
        merges: txs.len(),
        cycles: t.cycles,
        determine_cycles,
        merge_cycles,
        records,
        refs: got("refs"),
        golden_records: txs.iter().map(|tx| tx.writer.nodes.len() as u64).sum(),
        golden_refs: txs.iter().map(|tx| tx.writer.refs.len() as u64).sum(),
        store_reads,
        golden_store_reads,
        cycles_per_node: per_node(merge_cycles),
        store_reads_per_node: per_node(store_reads),
        records_per_cycle: records as f64 / cycles,
        store_port: store.port_name(),
        store_latency: shared.then_some(store.latency),
        records_allowed_per_cycle: shared.then(|| records as f64 / store_reads.max(1) as f64),
        of_port: shared.then(|| store_reads as f64 / cycles),
        mismatches,
        seconds: start.elapsed().as_secs_f64(),
        ..report
    }
}

/// The store reads golden's units make in `tx`: every fetcher's node,
/// reference, child-reference and probe reads, and the writer's.
fn golden_reads(tx: &MergerTransaction) -> u64 {
    let fetch: usize = tx
        .fetch
        .iter()
        .map(|f| f.node_reqs.len() + f.ref_reqs.len() + f.cref_reqs.len() + f.probe_reqs.len())
        .sum();
    (fetch + tx.writer.ref_reqs.len()) as u64
}

/// The first failure of a merger run, decoded: the mismatching beat's
/// stream, index, cycle and differing fields; else a hang, missing beats,
/// the status outputs, or the shared port's reads.
fn failure(o: &SimOutcome) -> Option<String> {
    let t = &o.totals;
    if let Some(m) = &t.first_mismatch {
        let fields: Vec<String> = m
            .fields
            .iter()
            .filter(|f| f.1 != f.2)
            .map(|(name, e, g)| format!("{name}: expected {e}, got {g}"))
            .collect();
        return Some(format!(
            "`{}` beat {} at cycle {}: {}",
            m.stream,
            m.beat,
            m.cycle,
            fields.join(", ")
        ));
    }
    if let Some(h) = &t.hang {
        return Some(format!("hung: {h}"));
    }
    if let Some((s, n)) = t.missing.iter().find(|m| m.1 > 0) {
        return Some(format!("{n} `{s}` beats never came"));
    }
    t.status_failure().or_else(|| {
        let what = o.store.as_ref()?.failure.as_ref()?;
        Some(format!("`store_req`: {what}"))
    })
}

#[cfg(test)]
mod tests {
    use crate::run::{run, Options, Run, RunEngine};
    use golden::scene::Scene;

    /// The default scene (two merge groups: the terrain and walls, static,
    /// merged once; the ball, ring and satellite, merged again in frames 1
    /// and 2; nothing moves in frame 3) with coarse shapes, a few pixels
    /// and primary rays only: the IR engine takes about a millisecond a
    /// cycle of the merger top, and the test needs the merges, not the
    /// picture.
    fn scene() -> Scene {
        let mut text = include_str!("../../scenes/default.json").to_string();
        for (fine, coarse) in [
            (r#""cells": 128"#, r#""cells": 6"#),
            (
                r#""stacks": 24, "slices": 48"#,
                r#""stacks": 4, "slices": 6"#,
            ),
            (r#""rings": 48, "sides": 24"#, r#""rings": 6, "sides": 4"#),
        ] {
            assert!(text.contains(fine), "default.json has {fine}");
            text = text.replace(fine, coarse);
        }
        let mut s = Scene::parse(&text, "scenes/default.json", std::path::Path::new("."))
            .unwrap_or_else(|e| panic!("{e}"));
        (s.width, s.height) = (16, 12);
        (s.effects.shadow, s.effects.reflection_depth) = (false, 0);
        s
    }

    fn options(dir: &std::path::Path) -> Options {
        Options {
            rtl: true,
            engine: RunEngine::Ir,
            ..Options::golden_only(dir)
        }
    }

    /// Every frame's merges redone go through the hierarchy unit, their
    /// inputs placed by its determine commands, then the merger top back
    /// to back with one shared store port (the run's default), its reads answered
    /// from the store image of the merges' inputs: the records and
    /// references it writes are the frame's merged hierarchies (0
    /// mismatches, counts equal golden's), it reads what golden's units
    /// read, and the report's figures are consistent (the port's one read
    /// a clock bounds the records per cycle); a frame where nothing moved
    /// simulates no merger, and a scene with nothing to merge builds none.
    #[test]
    fn merger_top_writes_the_frames_merged_hierarchies() {
        let dir = tempfile::tempdir().unwrap();
        let s = scene();
        let r = run(&s, &options(dir.path())).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(r.mismatches, 0);
        assert!(r.rtl.merger.starts_with("built (IR): hierarchy_unit_"));
        let mut merges = 0;
        for f in &r.frames {
            let mut sum = (0, 0, 0, 0);
            for g in &f.groups {
                let Some(m) = &g.merger_rtl else {
                    assert!(!g.merged, "frame {}: a merge redone not simulated", f.frame);
                    continue;
                };
                assert_eq!(m.golden_records, g.merged_nodes, "frame {}", f.frame);
                assert!(m.golden_refs > 0 && m.golden_store_reads > 0, "{m:?}");
                assert_eq!(m.order, sum.3, "frame {}: group order", f.frame);
                sum = (
                    sum.0 + m.golden_records,
                    sum.1 + m.golden_refs,
                    sum.2 + m.golden_store_reads,
                    sum.3 + 1,
                );
                merges += 1;
            }
            let Some(t) = &f.merger else {
                assert_eq!(sum, (0, 0, 0, 0));
                continue;
            };
            assert_eq!(t.mismatches, 0, "frame {}: {:?}", f.frame, t.first_mismatch);
            assert_eq!(
                (t.records, t.refs, t.store_reads, t.merges),
                (sum.0, sum.1, sum.2, sum.3),
                "frame {}",
                f.frame
            );
            assert_eq!((t.golden_records, t.golden_refs), (sum.0, sum.1));
            assert!(f
                .groups
                .iter()
                .flat_map(|g| &g.merger_rtl)
                .all(|m| m.top == t.top));
            assert_shared_port_figures(t);
            // The frame's determine commands, one per input, wrote the
            // table before the first merge was taken.
            let inputs: usize = f
                .groups
                .iter()
                .filter(|g| g.merger_rtl.is_some())
                .map(|g| g.merger_rtl.as_ref().unwrap().n)
                .sum();
            assert_eq!(t.determines, inputs as u64, "frame {}", f.frame);
            assert!(t.determine_cycles > t.determines, "{t:?}");
            assert_eq!(t.determine_cycles + t.merge_cycles, t.cycles);
            assert_eq!(t.cycles_per_node, t.merge_cycles as f64 / sum.0 as f64);
            assert_eq!(t.store_reads_per_node, sum.2 as f64 / sum.0 as f64);
            assert_eq!(t.records_per_cycle, sum.0 as f64 / t.merge_cycles as f64);
        }
        // Both groups in frame 0, the dynamic one in frames 1 and 2.
        assert_eq!(merges, 4);
        assert_eq!(r.frames[0].merger.as_ref().map(|t| t.merges), Some(2));
        let still = r.frames.last().unwrap();
        assert!(still.merger.is_none());
        let said = |l: &String| l.contains("hierarchy merger RTL of group 1");
        assert!(still.skipped.iter().any(said), "{:?}", still.skipped);

        let mut alone = scene();
        alone.frames = 1;
        alone.groups = (0..alone.objects.len() as u8).map(|i| vec![i]).collect();
        let r = run(&alone, &options(dir.path())).unwrap_or_else(|e| panic!("{e}"));
        assert!(
            r.rtl.merger.starts_with("not used by the scene"),
            "{}",
            r.rtl.merger
        );
        assert!(r.frames.iter().all(|f| f.merger.is_none()));
    }

    /// Two merges back to back on one top take fewer cycles than each
    /// alone from reset: the second's `cfg` and count pass overlap the
    /// first's builder and writer (SPEC 8.15 step 8). The frame's run is
    /// compared with runs of one group each on the same top.
    #[test]
    fn a_frames_merges_overlap_on_one_top() {
        let dir = tempfile::tempdir().unwrap();
        let mut s = scene();
        s.frames = 1;
        let o = options(dir.path());
        let mut r = Run::new(&s, &o).unwrap();
        let both = r.frame(0).unwrap_or_else(|e| panic!("{e}")).clone();
        let run = both.merger.as_ref().unwrap();
        assert_eq!((run.merges, run.mismatches), (2, 0));
        let world = &r.frames.world;
        let merger = &mut r.merges.merger;
        let mut alone = 0;
        for g in &both.groups {
            let m = super::FrameMerge {
                ids: g_inputs(&s, g),
                out: g.root.unwrap(),
            };
            let one = merger
                .run_frame(world, &[m], s.effects.merge)
                .unwrap()
                .run
                .unwrap();
            assert_eq!((one.top.as_str(), one.mismatches), (run.top.as_str(), 0));
            alone += one.cycles;
        }
        assert!(
            run.cycles < alone,
            "{} back to back, {alone} alone",
            run.cycles
        );
    }

    /// The ids of group `g`'s objects (scene order is id order).
    fn g_inputs(s: &Scene, g: &crate::run::merges::GroupOut) -> Vec<u8> {
        g.objects
            .iter()
            .map(|name| s.objects.iter().position(|o| &o.name == name).unwrap() as u8)
            .collect()
    }

    /// A merger is the default unless a merge needs more, then each size
    /// grows to the power of two that holds it; a built one serves every
    /// merge its sizes hold.
    #[test]
    fn merger_sizes_grow_from_the_default_only_as_needed() {
        assert_eq!(
            [1, 2, 3, 4, 5, 1024, 1025].map(super::bits_for),
            [1, 1, 2, 2, 3, 10, 11]
        );
        let design = golden::merge::merge_module::MergeDesign::default();
        let default = rtl_gen::merge::MergerConfig::new(design);
        let small = super::Sizes {
            roots: 3,
            frontier: 100,
            capacity_bits: 4,
            leaf_bits: 2,
        };
        assert_eq!(small.config(design), default);
        assert!(small.held_by(&default));
        let big = super::Sizes {
            roots: 17,
            frontier: 300,
            capacity_bits: 12,
            leaf_bits: 5,
        };
        assert!(!big.held_by(&default));
        let c = big.config(design);
        assert_eq!((c.design.roots, c.sizes.fetch.roots), (32, 32));
        assert_eq!(c.sizes.fetch.frontier, 512);
        assert_eq!((c.sizes.capacity_bits, c.sizes.leaf_bits), (12, 5));
        assert!(big.held_by(&c) && small.held_by(&c));
        c.validate().unwrap();
    }

    /// A shared port's figures of a run: as many reads as golden's units,
    /// at most one a clock, and the records per cycle against what that
    /// allows.
    fn assert_shared_port_figures(m: &super::MergerRtlFrame) {
        assert_eq!(
            (m.store_port.as_str(), m.store_latency),
            ("shared:3", Some(1))
        );
        assert!(
            m.store_reads > 0 && m.store_reads == m.golden_store_reads,
            "{m:?}"
        );
        assert!(m.merge_cycles > m.store_reads, "one read a clock: {m:?}");
        let allowed = m.records as f64 / m.store_reads as f64;
        let share = m.store_reads as f64 / m.merge_cycles as f64;
        assert_eq!(
            (m.records_allowed_per_cycle, m.of_port),
            (Some(allowed), Some(share))
        );
        assert!(m.records_per_cycle < allowed, "{m:?}");
    }

    /// A flipped bit of the expected `header` beat is a mismatch of the
    /// frame, decoded by field, with its cycle (per-unit store ports: the
    /// answers precomputed by golden).
    #[test]
    fn merger_mismatch_is_counted_and_decoded() {
        let dir = tempfile::tempdir().unwrap();
        let mut s = scene();
        s.frames = 1;
        let o = Options {
            merger_store: super::MergerStore {
                port: golden::merge::merger::store_port::StorePort::PerUnit,
                latency: 1,
            },
            ..options(dir.path())
        };
        let mut r = Run::new(&s, &o).unwrap();
        r.merges.merger.flip_expected = true;
        let f = r.frame(0).unwrap_or_else(|e| panic!("{e}"));
        let m = f.merger.as_ref().unwrap();
        assert_eq!(m.mismatches, 1, "the first merge's header");
        assert!(f.mismatches >= 1);
        let first = m.first_mismatch.as_deref().unwrap();
        assert!(first.starts_with("`header` beat 0 at cycle "), "{first}");
        assert!(first.contains("out_id: expected"), "{first}");
        assert_eq!((m.store_port.as_str(), m.store_latency), ("per-unit", None));
        assert!(m.records_allowed_per_cycle.is_none() && m.of_port.is_none());
        assert!(m.store_reads > 0 && m.store_reads == m.golden_store_reads);
    }

    /// A bit flipped in the emitted merger top (bit 0, `leaf`, of every
    /// `nodes` beat), on a scene run with a shared store port: every merge
    /// of the frame fails, its first failure decoded by field with its
    /// cycle. Icarus, stepped from Rust as the store model needs: the IR
    /// engine reads no Verilog, and Verilator would build the patched top
    /// for half a minute.
    #[test]
    fn a_bit_flipped_in_the_emitted_top_is_caught_on_a_shared_port_run() {
        if !cosim::tools::tool_available("iverilog") {
            assert!(!cosim::tools::ci_mode(), "CI=true and iverilog missing");
            return;
        }
        let dir = tempfile::tempdir().unwrap();
        let mut s = scene();
        s.frames = 1;
        let o = options(dir.path());
        let mut r = Run::new(&s, &o).unwrap();
        let (line, rhs) = nodes_assign(&s);
        let width = golden::layout::NodeLayout::new(&s.params).width();
        let m = &mut r.merges.merger;
        m.sim_engine = cosim::units::merger::MergerEngine::Iverilog;
        m.patch = Some(cosim::units::merger::VerilogPatch {
            from: line,
            to: format!("assign nodes_data = {rhs} ^ {width}'d1;"),
        });
        let f = r.frame(0).unwrap_or_else(|e| panic!("{e}"));
        let m = f.merger.as_ref().unwrap();
        assert_eq!(m.merges, 2);
        assert_eq!(m.mismatches, m.golden_records, "every record: {m:?}");
        assert!(f.mismatches >= 2);
        let first = m.first_mismatch.as_deref().unwrap();
        assert!(first.starts_with("`nodes` beat 0 at cycle "), "{first}");
        let cycle: u64 = first["`nodes` beat 0 at cycle ".len()..]
            .split(':')
            .next()
            .and_then(|c| c.parse().ok())
            .unwrap_or_else(|| panic!("a cycle: {first}"));
        assert!(cycle > 0 && cycle < m.cycles, "{first}");
        // Only the flipped field differs.
        assert!(
            first.ends_with(": leaf: expected 0x1, got 0x0")
                || first.ends_with(": leaf: expected 0x0, got 0x1"),
            "{first}"
        );
        assert_eq!(m.store_reads, m.golden_store_reads, "{m:?}");
        assert!(
            f.simulated.iter().any(|l| l.contains("(Icarus)")),
            "{:?}",
            f.simulated
        );
    }

    /// The emitted merger top's line `assign nodes_data = <rhs>;` (the
    /// same in every size of the scene's shared-port top), and its rhs.
    fn nodes_assign(s: &Scene) -> (String, String) {
        let design = golden::merge::merge_module::MergeDesign {
            params: s.params,
            inputs: 3,
            mode: s.effects.merge,
            ..golden::merge::merge_module::MergeDesign::default()
        };
        let mut c = rtl_gen::merge::MergerConfig::new(design);
        c.sizes.store_port = golden::merge::merger::store_port::StorePort::SHARED;
        let module = rtl_gen::merge::hierarchy_merger_unit(&c).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let d = cosim::from_rtl::design_from_module(&module, dir.path()).unwrap();
        let head = "assign nodes_data = ";
        let line = d
            .verilog_files
            .iter()
            .flat_map(|f| {
                let text = std::fs::read_to_string(f).unwrap();
                text.lines()
                    .map(str::trim)
                    .map(String::from)
                    .collect::<Vec<_>>()
            })
            .find(|l| l.starts_with(head))
            .expect("the top drives nodes_data");
        let rhs = line[head.len()..].trim_end_matches(';').to_string();
        (line, rhs)
    }
}
