//! The hierarchy unit (`rtl_gen::merge::hierarchy_unit`, docs/hardware.md
//! 8.16) against golden, bit for bit on every out stream, with seeded
//! stalls on every stream: the translation unit's determine commands write
//! the table, then the merge command's merger top reads it.
//!
//! A case is one random merger merge (golden's `random_merger_case_of`,
//! the merger bench's stimulus) whose translations are not packed by
//! software but written by determine commands, one per input, before its
//! merge command: a placement of exactly `t * 2^(D - L)` finest voxels, so
//! the determined translation is the case's. Golden runs the determine
//! commands on its translation unit model, whose table persists across
//! the merges of a run as the hardware's does, and the merge through
//! `golden::merge::hierarchy_unit::hierarchy_merge` on that table.

use std::path::Path;

use golden::bits::Bits;
use golden::merge::hierarchy_unit::{hierarchy_merge, merge_cmd, CmdLayout};
use golden::merge::merger::{MergerLayout, MergerTransaction};
use golden::store::{Hierarchy, HierarchyStore};
use golden::translate::extents::VoxelRange;
use golden::translate::model::{TranslateDesign, TranslateModel};
use golden::translate::stimulus::SplitMix64;
use golden::translate::{TranslateInputs, TranslateOutputs, Translation, TranslationTable};
use golden::vectors::hard_merges;
use golden::vectors::streams::{
    merger_beats, merger_layout, merger_ports, random_merger_case_of, MergeBeats, Merges, UnitPorts,
};
use rtl_gen::merge::HierarchyUnitConfig;
use rtl_gen::translate::ports::{det_in_layout, det_out_layout, pack_det_in, pack_det_out};

use crate::error::{CosimError, Result};
use crate::ledger::StimulusDigest;
use crate::tb::Transaction;

use super::chunked::{ChunkTotals, ChunkedSim, UnitStreams};
use super::merger::shared::{Front, SharedSim};
use super::merger::{chunk_sizes, SceneStore, SimOutcome};
use super::multi_stream::{beat_decoder, decoded_pair, ModuleEngine, RunConfig, VerilogPatch};
use golden::merge::merger::store_port::StorePort;

/// The stage name a run reports.
pub const STAGE: &str = "hierarchy_unit";

/// The status outputs a run counts the pulses of: `done` (one per merge),
/// `idle` (at the end), and `translate_done`, whose first pulse is the
/// clock the translation unit settled after the first determine
/// commands, the first merge command taken with it.
pub const PULSES: [&str; 3] = ["done", "idle", "translate_done"];

fn design_err(what: impl std::fmt::Display) -> CosimError {
    CosimError::Design {
        what: format!("hierarchy unit: {what}"),
    }
}

/// One merge through the hierarchy unit: the determine commands that write
/// its inputs' translations (with golden's outputs), then the merge.
#[derive(Clone, Debug)]
pub struct HierarchyCase {
    /// Determine commands, in order, and what each puts on `det_out`.
    pub dets: Vec<(TranslateInputs, TranslateOutputs)>,
    /// The merge command's beat.
    pub merge: Bits,
    /// Golden's merge.
    pub tx: MergerTransaction,
}

/// The determine command that writes translation `t` of `h` into entry
/// `h.id`: a placement of `t * 2^(D - L)` finest voxels per axis (exact in
/// the design's format) at `t`'s LOD `L`, `h`'s roots as extents.
pub fn write_command(
    d: &TranslateDesign,
    h: &Hierarchy,
    t: &Translation,
) -> Result<TranslateInputs> {
    offset_command(d, h, t, [0.0; 3])
}

/// [`write_command`] with each axis's placement moved by `off[a]` of a
/// voxel of `t`'s LOD, `|off[a]| < 1/2`: it still rounds to `t` (SPEC 7.3,
/// to nearest), leaving a residual, so the determine path's rounding sees
/// real fractions. An axis whose moved placement does not round back to
/// `t` in the design's format is placed exactly.
pub fn offset_command(
    d: &TranslateDesign,
    h: &Hierarchy,
    t: &Translation,
    off: [f64; 3],
) -> Result<TranslateInputs> {
    let p = d.params();
    let scale = f64::from(p.max_lod - t.lod.min(p.max_lod)).exp2();
    let encode = |grid: f64| match d.binary64 {
        true => grid.to_bits(),
        false => u64::from((grid as f32).to_bits()),
    };
    let decode = |bits: u64| match d.binary64 {
        true => f64::from_bits(bits),
        false => f64::from(f32::from_bits(bits as u32)),
    };
    let mut placement = [0u64; 3];
    for a in 0..3 {
        let exact = t.t[a] as f64 * scale;
        let moved = encode(exact + off[a].clamp(-0.375, 0.375) * scale);
        placement[a] = match (decode(moved) / scale - t.t[a] as f64).abs() < 0.5 {
            true => moved,
            false => encode(exact),
        };
    }
    placement_command(d, h, t.lod, placement)
}

/// The determine command that places `h` by `placement` (the encodings of
/// the design's format, grid units) at LOD `lod` and writes entry `h.id`,
/// `h`'s roots as extents at `lod`.
pub fn placement_command(
    d: &TranslateDesign,
    h: &Hierarchy,
    lod: u8,
    placement: [u64; 3],
) -> Result<TranslateInputs> {
    let tops: Vec<_> = h.roots().iter().map(|n| n.voxel).collect();
    let ext = VoxelRange::of_nodes(&tops, lod, d.params()).map_err(|e| {
        design_err(format!(
            "input {}: its roots' extents at LOD {lod}: {e}",
            h.id
        ))
    })?;
    Ok(TranslateInputs {
        format: d.binary64 as u8,
        placement,
        lod,
        extents_lo: ext.lo,
        extents_hi: ext.hi,
        write_enable: 1,
        write_id: h.id as u32,
        read_id: h.id as u32,
    })
}

/// A random case for `c` from `rng` (`kind`: the merger bench's random or
/// hard-kind draws), its determine commands run on `model` (the table as
/// the run's commands so far left it).
pub fn random_case(
    rng: &mut SplitMix64,
    c: &HierarchyUnitConfig,
    model: &mut TranslateModel,
    kind: Merges,
) -> Result<HierarchyCase> {
    let case =
        random_merger_case_of(rng, &c.merger.design, c.merger.sizes, kind).map_err(design_err)?;
    case_of(
        rng,
        c,
        model,
        (&case.store, &case.table, &case.ids),
        case.out_id,
    )
}

/// The case merging `ids` of `store` into `out_id`: per input a determine
/// command that writes its translation of `table` into the unit's table
/// (run on `model`), a random fraction of a voxel off the grid, then the
/// merge command and golden's merge on that table.
pub fn case_of(
    rng: &mut SplitMix64,
    c: &HierarchyUnitConfig,
    model: &mut TranslateModel,
    case: (&HierarchyStore, &TranslationTable, &[u8]),
    out_id: u8,
) -> Result<HierarchyCase> {
    repeated_case_of(rng, c, model, case, (out_id, 1))
}

/// Determine commands per input of a hard run's first named case
/// ([`Draw`]), back to back: more than the determine pipeline holds (its
/// four stages and the two entries of `det_out`'s skid buffer), so that
/// every stage holds its beat while `det_out` is held (the coverage run's
/// `det_out` stalls; 4 per input, 8 at k = 2, left the first two stages
/// unheld there: measured).
pub const DETERMINE_BURST: usize = 8;

/// [`case_of`] with `repeat` determine commands per input, back to back
/// (each a different fraction off the grid, the last one's entry the
/// same).
fn repeated_case_of(
    rng: &mut SplitMix64,
    c: &HierarchyUnitConfig,
    model: &mut TranslateModel,
    (store, table, ids): (&HierarchyStore, &TranslationTable, &[u8]),
    (out_id, repeat): (u8, usize),
) -> Result<HierarchyCase> {
    let repeated: Vec<u8> = ids
        .iter()
        .flat_map(|&id| std::iter::repeat_n(id, repeat))
        .collect();
    let dets = determines(rng, c, model, (store, table), &repeated)?;
    let cmd = merge_cmd(store, ids, out_id).map_err(design_err)?;
    let (k, sizes) = (c.merger.design.inputs, c.merger.sizes);
    let tx = hierarchy_merge(store, model.table(), &cmd, c.merger.design.mode, k, sizes)
        .map_err(design_err)?;
    let merge = c.cmd_layout().pack_merge(&cmd).map_err(design_err)?;
    Ok(HierarchyCase { dets, merge, tx })
}

/// The case merging `ids` (two or more) of `store` when no determine
/// command wrote the entry of the input of rank `rank`: determine commands
/// for the others only, on a `model` whose entry of `ids[rank]` is still
/// invalid (a chunk's table from reset), then the merge command. That
/// input's fetcher refuses its `cfg` (`ENTRY`, `fetch_rank` = `rank`) and
/// the merge is golden's of the others (`hard_merges::entry_error_merge`).
/// `None` when the entry is valid or golden does not model the merge bit
/// for bit.
pub fn entry_error_case(
    rng: &mut SplitMix64,
    c: &HierarchyUnitConfig,
    model: &mut TranslateModel,
    (store, table, ids): (&HierarchyStore, &TranslationTable, &[u8]),
    (out_id, rank): (u8, usize),
) -> Result<Option<HierarchyCase>> {
    let broken = ids.get(rank).copied();
    let unwritten = broken.is_some_and(|id| model.table().get(id as u32).ok().flatten().is_none());
    if ids.len() < 2 || !unwritten || out_id != hard_merges::out_id(&c.merger.design.params) {
        return Ok(None);
    }
    let others: Vec<u8> = ids
        .iter()
        .copied()
        .filter(|&id| Some(id) != broken)
        .collect();
    let dets = determines(rng, c, model, (store, table), &others)?;
    let (design, sizes) = (&c.merger.design, c.merger.sizes);
    let tx = hard_merges::entry_error_merge(design, sizes, store, model.table(), ids, rank)
        .map_err(design_err)?;
    let Some(tx) = tx else {
        return Ok(None);
    };
    let cmd = merge_cmd(store, ids, out_id).map_err(design_err)?;
    let merge = c.cmd_layout().pack_merge(&cmd).map_err(design_err)?;
    Ok(Some(HierarchyCase { dets, merge, tx }))
}

/// Per input of `ids` a determine command that writes its translation of
/// `table` into the unit's table, a random fraction of a voxel off the
/// grid, run on `model`; with what each puts on `det_out`.
fn determines(
    rng: &mut SplitMix64,
    c: &HierarchyUnitConfig,
    model: &mut TranslateModel,
    (store, table): (&HierarchyStore, &TranslationTable),
    ids: &[u8],
) -> Result<Vec<(TranslateInputs, TranslateOutputs)>> {
    let mut dets = Vec::new();
    for &id in ids {
        let h = store
            .get(id)
            .ok_or_else(|| design_err("an input left the store"))?;
        let t = table
            .get(id as u32)
            .ok()
            .flatten()
            .ok_or_else(|| design_err(format!("input {id} has no translation in the case")))?;
        // A fraction of a voxel off the grid, below half of one: the
        // determine path rounds it away and keeps it as the residual.
        let off = [(); 3].map(|_| (rng.below(751) as f64 - 375.0) / 1000.0);
        let inp = offset_command(&c.table, h, &t, off)?;
        let out = model.determine(&inp).map_err(design_err)?;
        if model.table().get(id as u32).ok().flatten() != Some(t) {
            return Err(design_err(format!(
                "input {id}: the determine command did not write translation {t:?} (outputs {out:?})"
            )));
        }
        dets.push((inp, out));
    }
    Ok(dets)
}

/// The translation unit's hard determine commands (golden's
/// `translate::stimulus::hard_cases`: placements of -0, subnormals, NaN,
/// infinities, the largest finite values, ties at the field's limit, the
/// scene's edges, bad extents) that the unit's `cmd` beat carries, run on
/// `model`, with what each puts on `det_out`. They write entries of the
/// table, some invalid; a case's own determine commands write its inputs'
/// entries after them.
fn hard_determines(
    c: &HierarchyUnitConfig,
    model: &mut TranslateModel,
) -> Result<Vec<(TranslateInputs, TranslateOutputs)>> {
    let cl = c.cmd_layout();
    let mut dets = Vec::new();
    for inp in golden::translate::stimulus::hard_cases(&c.table.unit) {
        let carried = pack_det_in(&c.table, &inp)
            .ok()
            .is_some_and(|det| cl.pack_determine(&det).is_ok());
        if carried {
            dets.push((inp, model.determine(&inp).map_err(design_err)?));
        }
    }
    Ok(dets)
}

/// The cases of a run in order: with [`Merges::Hard`], first the first
/// hard case of two inputs or more with its first input's entry never
/// written ([`entry_error_case`]: the merge software asks of an input it
/// did not place), then the same with its inputs in reverse order (the
/// unwritten entry at the last rank), then golden's named hard cases of
/// valid inputs (`hard_merges::hard_cases`: real merges, several and
/// sixteen roots, the leaf ladder, the deep tops) and the leaf floods
/// (`hard_merges::leaf_floods`), the first of them after the translation
/// unit's hard determine commands (`hard_determines`) and
/// [`DETERMINE_BURST`] determine commands per input, those golden does not
/// model bit for bit left out (`MergerTransaction::exact`: per-node mode's
/// FIFOs dropping nodes), then random merges of `kind`.
pub struct Draw {
    rng: SplitMix64,
    kind: Merges,
    /// The entry-error cases with the rank of the unwritten entry, drawn
    /// first (the table is then from reset).
    entry_errors: std::collections::VecDeque<(golden::merge::stimulus::RealCase, usize)>,
    named: std::collections::VecDeque<golden::merge::stimulus::RealCase>,
    /// Named cases drawn so far (those left out not counted).
    pub named_drawn: u64,
    /// Whether the next named case of valid inputs comes after a burst of
    /// [`DETERMINE_BURST`] determine commands per input (the first one).
    burst: bool,
}

impl Draw {
    /// The draws of a run of `kind` from `seed` for `c`.
    pub fn new(c: &HierarchyUnitConfig, seed: u64, kind: Merges) -> Result<Draw> {
        let (entry_errors, named) = match kind {
            Merges::Hard => {
                let mut cases = hard_merges::hard_cases(&c.merger.design).map_err(design_err)?;
                let p = &c.merger.design.params;
                let floods = hard_merges::leaf_floods(p, c.merger.sizes.leaf_bits);
                cases.extend(floods.map_err(design_err)?);
                let mut errors = std::collections::VecDeque::new();
                if let Some(pair) = cases.iter().find(|c| c.2.len() >= 2) {
                    let (store, table, ids) = pair.clone();
                    let last = ids.len() - 1;
                    let reversed = ids.iter().rev().copied().collect();
                    errors.push_back((pair.clone(), 0));
                    errors.push_back(((store, table, reversed), last));
                }
                (errors, cases.into())
            }
            Merges::Random => Default::default(),
        };
        Ok(Draw {
            rng: SplitMix64(seed),
            kind,
            entry_errors,
            named,
            named_drawn: 0,
            burst: true,
        })
    }

    /// The next case, its determine commands run on `model`.
    pub fn next(
        &mut self,
        c: &HierarchyUnitConfig,
        model: &mut TranslateModel,
    ) -> Result<HierarchyCase> {
        let out_id = hard_merges::out_id(&c.merger.design.params);
        while let Some(((store, table, ids), rank)) = self.entry_errors.pop_front() {
            let before = model.clone();
            let case = (&store, &table, ids.as_slice());
            let case = entry_error_case(&mut self.rng, c, model, case, (out_id, rank))?;
            match case {
                Some(case) if case.tx.exact => {
                    self.named_drawn += 1;
                    return Ok(case);
                }
                _ => *model = before,
            }
        }
        while let Some((store, table, ids)) = self.named.pop_front() {
            // A case left out sends nothing, so its determine commands
            // must not stay in the model's table either.
            let before = model.clone();
            let (hard, repeat) = match self.burst {
                true => (hard_determines(c, model)?, DETERMINE_BURST),
                false => (Vec::new(), 1),
            };
            let case = (&store, &table, ids.as_slice());
            let mut case = repeated_case_of(&mut self.rng, c, model, case, (out_id, repeat))?;
            if case.tx.exact {
                self.named_drawn += 1;
                self.burst = false;
                case.dets.splice(0..0, hard);
                return Ok(case);
            }
            *model = before;
        }
        random_case(&mut self.rng, c, model, self.kind)
    }
}

/// The hierarchy unit's streams: `cmd` and the merger's inputs but its
/// `cfg`; `det_out` and the merger's outputs (`header` last).
pub fn unit_ports(c: &HierarchyUnitConfig) -> Result<UnitPorts> {
    let merger = merger_ports(&c.merger.design, &c.merger.sizes).map_err(design_err)?;
    // Shown as a determine command: a merge command's fields overlap it.
    let det_in = det_in_layout(&c.table);
    let cmd = (c.cmd_layout().determine).flattened("cmd", |f| (f.name == "det").then_some(&det_in));
    let det_out = det_out_layout(&c.table).renamed("det_out");
    let mut inputs = vec![cmd];
    inputs.extend(merger.inputs.into_iter().skip(1));
    let mut outputs = vec![det_out];
    outputs.extend(merger.outputs);
    Ok(UnitPorts { inputs, outputs })
}

/// Case `case`'s beats on every stream of [`unit_ports`].
pub fn case_beats(
    c: &HierarchyUnitConfig,
    ml: &MergerLayout,
    case: &HierarchyCase,
) -> Result<MergeBeats> {
    let cl: CmdLayout = c.cmd_layout();
    let merger = merger_beats(&c.merger.design, ml, &case.tx).map_err(design_err)?;
    let mut cmds = Vec::new();
    let mut det_outs = Vec::new();
    for (inp, out) in &case.dets {
        let det = pack_det_in(&c.table, inp).map_err(design_err)?;
        cmds.push(cl.pack_determine(&det).map_err(design_err)?);
        det_outs.push(pack_det_out(&c.table, out).map_err(design_err)?);
    }
    cmds.push(case.merge.clone());
    let mut inputs = vec![cmds];
    inputs.extend(merger.inputs.into_iter().skip(1));
    let mut outputs = vec![det_outs];
    outputs.extend(merger.outputs);
    Ok(MergeBeats { inputs, outputs })
}

/// What a run's cases reached, for its functional coverage: the merger's
/// outcomes ([`super::merger::merge_stats`] of golden's merges) and the
/// determine commands, with how many rewrote an entry an earlier merge of
/// the chunk had read (the table persists across merges).
#[derive(Clone, Debug, Default)]
pub struct HierarchyStats {
    /// The merges' outcomes.
    pub merges: super::merger::MergeStats,
    /// Determine commands.
    pub determines: u64,
    /// Determine commands that wrote an entry already written in the chunk.
    pub rewrites: u64,
    /// Determine commands whose placement was off the grid (a residual).
    pub residuals: u64,
    /// Merges of golden's named hard cases ([`Draw`]).
    pub named: u64,
}

/// The next `n` cases of `draw`, on a translation unit from reset (each
/// chunk of a run starts from reset), as the unit's streams; what they
/// reach is added to `stats`.
fn next_streams(
    c: &HierarchyUnitConfig,
    draw: &mut Draw,
    n: usize,
    stats: &mut HierarchyStats,
) -> Result<UnitStreams> {
    let ml = merger_layout(&c.merger.design, &c.merger.sizes).map_err(design_err)?;
    let mut model = TranslateModel::new(c.table).map_err(design_err)?;
    let mut written = std::collections::BTreeSet::new();
    let mut merges = Vec::with_capacity(n);
    let mut txs = Vec::with_capacity(n);
    let named_before = draw.named_drawn;
    for _ in 0..n {
        let case = draw.next(c, &mut model)?;
        for (inp, out) in &case.dets {
            stats.determines += 1;
            stats.rewrites += !written.insert(inp.write_id) as u64;
            stats.residuals += out.residual.iter().any(|&r| r != 0) as u64;
        }
        merges.push(case_beats(c, &ml, &case)?);
        txs.push(case.tx);
    }
    stats.named += draw.named_drawn - named_before;
    let s = super::merger::merge_stats(&txs);
    stats.merges.add(&s);
    UnitStreams::from_merges(&unit_ports(c)?, &merges)
}

/// `count` cases of `merges` from `seed`, on a translation unit from
/// reset, as the unit's streams.
pub fn case_streams(
    c: &HierarchyUnitConfig,
    seed: u64,
    count: usize,
    merges: Merges,
) -> Result<UnitStreams> {
    next_streams(
        c,
        &mut Draw::new(c, seed, merges)?,
        count,
        &mut HierarchyStats::default(),
    )
}

/// The unit's per-unit-port simulator (`module`, its Verilog in `design`)
/// on `engine`, its streams `ports`, watching [`PULSES`].
fn per_unit_sim(
    module: rtl_gen::Module,
    design: crate::design::Design,
    engine: ModuleEngine,
    ports: &UnitPorts,
    patched: bool,
) -> Result<ChunkedSim> {
    fn names(s: &[golden::layout::Layout]) -> Vec<&str> {
        s.iter().map(|s| s.name()).collect()
    }
    let (i, o) = (names(&ports.inputs), names(&ports.outputs));
    ChunkedSim::watching(module, design, engine, (&i, &o), patched, &PULSES)
}

/// The layout of output stream `name` of `ports` (an empty one, showing
/// no field, for a name that is no output).
fn output_layout(ports: &UnitPorts, name: &str) -> golden::layout::Layout {
    let layout = ports.outputs.iter().find(|s| s.name() == name);
    layout.map_or_else(|| golden::layout::Layout::new(name), Clone::clone)
}

/// An (expected, got) pair of output stream `stream` of `ports`, decoded
/// by its fields.
fn decode(
    ports: &UnitPorts,
    stream: &str,
    e: &Transaction,
    g: &Transaction,
) -> Vec<(String, String, String)> {
    decoded_pair(&*beat_decoder(output_layout(ports, stream)), e, g)
}

/// What a [`run`] did: its totals, what its cases reached, and the
/// digests its long-run ledger entry records (SPEC 10.2).
#[derive(Clone, Debug, Default)]
pub struct Outcome {
    /// Beats, mismatches, cycles and pulses of every chunk run.
    pub totals: ChunkTotals,
    /// What the cases reached.
    pub stats: HierarchyStats,
    /// [`netlist_digest`] of the unit as generated (a patched run is a
    /// test of the bench, never recorded in a ledger).
    pub netlist_sha256: String,
    /// The stimulus digest of the chunks that ran: a run stopped after a
    /// failing chunk says so by a digest of what ran.
    pub stimulus_sha256: String,
}

/// The hierarchy unit `c`'s netlist digest (10.2): structural, so a rename
/// that keeps behaviour keeps a ledger entry current.
pub fn netlist_digest(c: &HierarchyUnitConfig) -> Result<String> {
    crate::ledger::netlist_digest(&rtl_gen::merge::hierarchy_unit(c).map_err(design_err)?)
}

/// The cases of a [`run`]: how many, which kind, and the flip hook.
#[derive(Clone, Copy, Debug)]
pub struct Cases {
    /// Merges to run.
    pub count: usize,
    /// Random merges, or the hard cases first ([`Draw`]).
    pub merges: Merges,
    /// The test hook: flips bit 0 of this merge's expected `header` beat
    /// (its `out_id`).
    pub flip: Option<usize>,
}

impl Cases {
    /// `count` random merges, nothing flipped.
    pub fn random(count: usize) -> Cases {
        Cases {
            count,
            merges: Merges::Random,
            flip: None,
        }
    }
}

/// The stimulus digest (10.2) of the run [`run`] makes of `cases` from
/// `seed` with the stall pattern `stall` and the named streams' own
/// `streams`, without simulating it.
pub fn stimulus_digest(
    c: &HierarchyUnitConfig,
    seed: u64,
    cases: Cases,
    (stall, streams): (crate::tb::Stalls, &crate::tb::StreamStalls),
) -> Result<String> {
    let mut draw = Draw::new(c, seed, cases.merges)?;
    let mut digest = StimulusDigest::new(seed, cases.count as u64, stall, streams);
    let mut stats = HierarchyStats::default();
    for n in chunk_sizes(cases.count) {
        let s = next_streams(c, &mut draw, n, &mut stats)?;
        digest.add_chunk(&s.inputs, &s.outputs);
    }
    Ok(digest.finish())
}

/// Runs `cases` from `config.seed` through the hierarchy unit `c` on
/// `engine`, its Verilog written to `dir`, [`super::chunked::CHUNK`]
/// merges at a time, each chunk from reset (the table too); stops after
/// the first chunk that fails. Every output beat compared (a mismatch
/// decoded field by field), one `done` per merge, `idle` at the end of
/// every chunk; `config`'s Verilog patch (the test hook) applied. Per-unit
/// store ports only: the streams carry the store's answers. `progress`
/// gets (merges whose outputs arrived so far, cycle).
pub fn run(
    c: &HierarchyUnitConfig,
    engine: ModuleEngine,
    config: &RunConfig,
    cases: Cases,
    dir: &Path,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<Outcome> {
    if c.merger.sizes.store_port != golden::merge::merger::store_port::StorePort::PerUnit {
        return Err(CosimError::Unsupported {
            what:
                "a hierarchy unit with a shared store port (its store answers reads as they come)"
                    .into(),
        });
    }
    let module = rtl_gen::merge::hierarchy_unit(c).map_err(design_err)?;
    crate::waves::check_scope(&module, config.wave_scope.as_deref())?;
    let mut out = Outcome {
        netlist_sha256: crate::ledger::netlist_digest(&module)?,
        ..Outcome::default()
    };
    let design = crate::from_rtl::design_from_module(&module, dir)?;
    if let Some(patch) = &config.verilog_patch {
        super::multi_stream::apply_patch(&design, patch, engine)?;
    }
    let ports = unit_ports(c)?;
    let sim = per_unit_sim(
        module,
        design,
        engine,
        &ports,
        config.verilog_patch.is_some(),
    )?;
    let decode = |stream: &str, e: &Transaction, g: &Transaction| decode(&ports, stream, e, g);
    let mut draw = Draw::new(c, config.seed, cases.merges)?;
    let mut digest = StimulusDigest::new(
        config.seed,
        cases.count as u64,
        config.stall,
        &config.stream_stalls,
    );
    let mut first = 0;
    for n in chunk_sizes(cases.count) {
        let t = std::time::Instant::now();
        let mut streams = next_streams(c, &mut draw, n, &mut out.stats)?;
        digest.add_chunk(&streams.inputs, &streams.outputs);
        out.totals.golden_wall += t.elapsed();
        if let Some(f) = cases.flip.filter(|f| (first..first + n).contains(f)) {
            // `header` is the last output stream; every merge has its one beat.
            streams.flip_first(streams.outputs.len() - 1, f - first)?;
        }
        if sim.run_chunk(&mut out.totals, n, &streams, config, &decode, progress)? {
            break;
        }
        first += n;
    }
    out.stimulus_sha256 = digest.finish();
    Ok(out)
}

/// The exported testbench of `c` (`hiermerge export-tb --unit hierarchy`):
/// `count` cases of `merges` from `seed` as [`run`] draws them (one run
/// from reset), the Verilog written to `rtl`. Per-unit store ports: the
/// store's answers are input streams.
pub fn export_spec(
    c: &HierarchyUnitConfig,
    seed: u64,
    (count, merges): (usize, Merges),
    stalls: crate::tb::Stalls,
    rtl: &Path,
) -> Result<crate::export_tb::ExportSpec> {
    if c.merger.sizes.store_port != golden::merge::merger::store_port::StorePort::PerUnit {
        return Err(CosimError::Unsupported {
            what: "an exported testbench of a hierarchy unit with a shared store port".into(),
        });
    }
    let streams = case_streams(c, seed, count, merges)?;
    let module = rtl_gen::merge::hierarchy_unit(c).map_err(design_err)?;
    let design = crate::from_rtl::design_from_module(&module, rtl)?;
    let ports = unit_ports(c)?;
    let (inputs, outputs) =
        super::multi_stream::export_streams(&streams, |name| output_layout(&ports, name));
    Ok(crate::export_tb::ExportSpec {
        design,
        transaction: "merge".into(),
        transactions: count as u64,
        inputs,
        outputs,
        checks: super::multi_stream::export_checks(count),
        seed,
        stalls,
        stream_stalls: crate::tb::StreamStalls::default(),
        command: String::new(),
        store: None,
    })
}

/// A hierarchy unit built once and run on cases from elsewhere, each run
/// one chunk from reset (the table too): a scene's frame, its determine
/// commands then its merges (`hiermerge run`). With a shared store port its
/// reads are answered by a store model, as the merger's are
/// ([`super::merger::MergerSim`]).
pub struct HierarchySim {
    config: HierarchyUnitConfig,
    ports: UnitPorts,
    sim: Sim,
}

enum Sim {
    PerUnit(ChunkedSim),
    Shared(Box<SharedSim>),
}

impl HierarchySim {
    /// The hierarchy unit `c` on `engine`, its Verilog written to `dir`
    /// (which must outlive the simulator) and broken by `patch` when given
    /// (the test hook; not on the IR engine); Verilator builds it here.
    pub fn new(
        c: &HierarchyUnitConfig,
        engine: ModuleEngine,
        dir: &Path,
        patch: Option<&VerilogPatch>,
    ) -> Result<HierarchySim> {
        let module = rtl_gen::merge::hierarchy_unit(c).map_err(design_err)?;
        let design = crate::from_rtl::design_from_module(&module, dir)?;
        if let Some(patch) = patch {
            super::multi_stream::apply_patch(&design, patch, engine)?;
        }
        let shared = c.merger.sizes.store_port != StorePort::PerUnit;
        super::merger::prebuild(&design, engine, patch.is_some() && !shared)?;
        let ports = unit_ports(c)?;
        let sim = match shared {
            true => Sim::Shared(Box::new(SharedSim::with_front(
                &c.merger,
                (module, design),
                engine,
                Front::Hierarchy(Box::new(c.cmd_layout())),
                &PULSES,
            ))),
            false => Sim::PerUnit(per_unit_sim(
                module,
                design,
                engine,
                &ports,
                patch.is_some(),
            )?),
        };
        Ok(HierarchySim {
            config: c.clone(),
            ports,
            sim,
        })
    }

    /// Runs `cases` as one chunk from reset: every output beat compared (a
    /// mismatch decoded field by field), one `done` per merge, `idle` at the
    /// end; `flip_expected` (the test hook) flips bit 0 of that merge's
    /// expected `header` beat. A shared store port's reads are answered from
    /// `store` (None: from the words golden's units read) and checked
    /// against golden's units' reads.
    pub fn run(
        &self,
        cases: &[HierarchyCase],
        bench: &RunConfig,
        flip_expected: Option<usize>,
        store: Option<SceneStore>,
    ) -> Result<SimOutcome> {
        let c = &self.config;
        let ml = merger_layout(&c.merger.design, &c.merger.sizes).map_err(design_err)?;
        let merges = cases
            .iter()
            .map(|case| case_beats(c, &ml, case))
            .collect::<Result<Vec<_>>>()?;
        let mut streams = UnitStreams::from_merges(&self.ports, &merges)?;
        if let Some(n) = flip_expected {
            streams.flip_first(streams.outputs.len() - 1, n)?;
        }
        let txs: Vec<MergerTransaction> = cases.iter().map(|c| c.tx.clone()).collect();
        let stats = super::merger::merge_stats(&txs);
        let decode =
            |stream: &str, e: &Transaction, g: &Transaction| decode(&self.ports, stream, e, g);
        let mut totals = ChunkTotals::default();
        let n = cases.len();
        let store = match &self.sim {
            Sim::PerUnit(sim) => {
                sim.run_chunk(&mut totals, n, &streams, bench, &decode, &mut |_, _| {})?;
                None
            }
            Sim::Shared(sim) => {
                let (t, outcome) = sim.run_once(streams, n, bench, store, &decode)?;
                totals = t;
                Some(outcome)
            }
        };
        Ok(SimOutcome {
            totals,
            stats,
            store,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use golden::merge::fetcher::fetch_err;
    use rtl_gen::merge::{MergeConfig, MergerConfig};

    /// A hard run's first case is a merge whose first input no determine
    /// command wrote: determine commands for the others only, a merge
    /// command naming all, and golden's header saying `ENTRY` at rank 0,
    /// with the other inputs' merge; the model's table keeps the first
    /// input's entry invalid. The second is the same inputs in reverse
    /// order, `ENTRY` at the last rank. A random run has no such case.
    #[test]
    fn a_hard_run_starts_with_a_merge_of_an_unwritten_entry() {
        let c = HierarchyUnitConfig::new(MergerConfig::new(MergeConfig::default()));
        let mut model = TranslateModel::new(c.table).unwrap();
        let mut draw = Draw::new(&c, 1, Merges::Hard).unwrap();
        let case = draw.next(&c, &mut model).unwrap();
        let inputs = case.tx.fetch.len();
        assert!(inputs >= 2);
        assert_eq!(case.dets.len(), inputs - 1);
        let h = &case.tx.header;
        assert_eq!((h.fetch_err, h.fetch_rank), (fetch_err::ENTRY, 0));
        let f0 = &case.tx.fetch[0];
        assert!(f0.node_reqs.is_empty() && f0.ref_reqs.is_empty());
        assert!(case.tx.fetch[1..].iter().all(|f| !f.node_reqs.is_empty()));
        let p = &c.merger.design.params;
        let invalid = golden::translate::table::pack_entry(None, p);
        assert_eq!(case.tx.cfg.inputs[0].entry, invalid);
        assert_eq!(draw.named_drawn, 1);
        let last = draw.next(&c, &mut model).unwrap();
        let rank = last.tx.fetch.len() - 1;
        assert_eq!(
            (last.tx.header.fetch_err, last.tx.header.fetch_rank),
            (fetch_err::ENTRY, rank as u16)
        );
        assert_eq!(last.tx.cfg.inputs[rank].entry, invalid);
        assert_eq!(last.dets.len(), rank);
        let next = draw.next(&c, &mut model).unwrap();
        assert_eq!(next.tx.header.fetch_err, 0);
        let inputs = next.tx.fetch.len();
        // The translation unit's hard determine commands, then the burst:
        // some fail (`ok` 0), and the merge still reads its inputs' entries
        // as its own determine commands wrote them.
        let hard = golden::translate::stimulus::hard_cases(&c.table.unit).len();
        let extra = next.dets.len() - inputs * DETERMINE_BURST;
        assert!(extra > hard / 2 && extra <= hard, "{extra} of {hard}");
        assert!(next.dets[..extra].iter().any(|(_, o)| o.ok == 0));
        assert!(next.dets[extra..].iter().all(|(_, o)| o.ok == 1));
        let after = draw.next(&c, &mut model).unwrap();
        assert_eq!(after.dets.len(), after.tx.fetch.len());
        let mut random = Draw::new(&c, 1, Merges::Random).unwrap();
        let mut model = TranslateModel::new(c.table).unwrap();
        for _ in 0..5 {
            let case = random.next(&c, &mut model).unwrap();
            assert_eq!(case.tx.header.fetch_err, 0);
        }
    }

    /// What the draws record on `det_out` is what a fresh table gives the
    /// commands sent, in order: a named case left out (per-node mode, FIFOs
    /// of 2 entries, which drop the module's nodes) leaves no table write
    /// behind in the model.
    #[test]
    fn the_draws_record_what_the_sent_commands_determine() {
        let design = MergeConfig {
            mode: golden::merge::MergeMode::PerNode { num: 1, den: 2 },
            ..Default::default()
        };
        let mut merger = MergerConfig::new(design);
        merger.sizes.leaf_bits = 1;
        let c = HierarchyUnitConfig::new(merger);
        let named = golden::vectors::hard_merges::hard_cases(&c.merger.design).unwrap();
        let mut model = TranslateModel::new(c.table).unwrap();
        let mut replay = TranslateModel::new(c.table).unwrap();
        let mut draw = Draw::new(&c, 1, Merges::Hard).unwrap();
        for n in 0..named.len() + 3 {
            let case = draw.next(&c, &mut model).unwrap();
            for (inp, out) in &case.dets {
                assert_eq!(&replay.determine(inp).unwrap(), out, "case {n}: {inp:?}");
            }
        }
        assert!(
            draw.named_drawn < named.len() as u64,
            "a named case is left out, so this checks its writes are undone"
        );
    }
}
