//! The hierarchy merger as one top module (SPEC.md section 8.15): S610-S618
//! end to end. `k` fetchers walk the inputs in the store, the merging module
//! chooses the level and merges it, the upper builder builds every level
//! above, the record writer lays out the merged hierarchy. The glue, in this
//! module's files: a controller (the fetchers' `cfg` and commands, pass by
//! pass; `level_mode`, `per_node_mode`), the routing of the merging module's
//! `out` (nodes to the builder, references to the writer's `crefs`), and the
//! leaves above `m`: a k-way merge by (LOD, Morton, rank) (`leaf_merge`) into
//! one FIFO per LOD ([`crate::DropFifo`]): the builder takes `base{d}` at its pace.
//!
//! Golden: `golden::merge::merger::merger_transaction`, the chain of the
//! units' own transactions.

use golden::merge::fetcher::FetchSizes;
use golden::merge::merge_level::unit::BeatLayout;
use golden::merge::merge_module::TopLayout;
use golden::merge::merger::store_port::StorePort;
use golden::merge::merger::{MergerLayout, MergerSizes};
use golden::merge::MergeMode;
use golden::params::Params;

use super::{merge_module_name, merge_module_unit, upper_builder_unit, MergeConfig};
use crate::{Direction, Module, Signal, Stream};

mod leaf_merge;
mod level_mode;
mod per_node_mode;
mod store_port;
mod tail;

pub use store_port::{store_port_name, store_port_unit, StorePortConfig};

/// The merger's configuration: the merging module's design (grid
/// parameters, `k` inputs, mode, root-sorter capacity) and the sizes of the
/// fetchers' frontier FIFOs, the writer's buffers and the leaf FIFOs.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MergerConfig {
    /// The merging module's design; its `roots` is every fetcher's root
    /// sorter capacity.
    pub design: MergeConfig,
    /// Frontier FIFO (`fetch.frontier`; `fetch.roots` is not read), writer
    /// capacity and leaf FIFO sizes.
    pub sizes: MergerSizes,
}

impl MergerConfig {
    /// The merging module's default with `sizes` from
    /// [`MergerSizes::new`] (roots from the design).
    pub fn new(design: MergeConfig) -> MergerConfig {
        let mut sizes = MergerSizes::new(&design.params);
        sizes.fetch.roots = design.roots;
        MergerConfig { design, sizes }
    }

    /// The fetchers' sizes (the root sorter's capacity is the design's).
    pub fn fetch_sizes(&self) -> FetchSizes {
        FetchSizes {
            roots: self.design.roots,
            frontier: self.sizes.fetch.frontier,
        }
    }

    /// Refuses what the merger cannot build: what the merging module
    /// refuses, a writer capacity outside `1..I`,
    /// leaf FIFOs outside `1..=16` bits, a frontier outside `1..=2^16`.
    pub fn validate(&self) -> Result<(), String> {
        self.design.validate()?;
        let p = &self.design.params;
        MergerLayout::new(p, self.design.inputs, self.sizes.capacity_bits)
            .map_err(|e| e.to_string())?;
        if !(1..=16).contains(&self.sizes.leaf_bits) {
            return Err(format!(
                "leaf_bits = {}: expected 1..=16 (a leaf FIFO of 2^leaf_bits per LOD)",
                self.sizes.leaf_bits
            ));
        }
        if !(1..=1 << 16).contains(&self.sizes.fetch.frontier) {
            return Err(format!(
                "frontier = {}: expected 1..=65536",
                self.sizes.fetch.frontier
            ));
        }
        if let StorePort::Shared { tag_bits } = self.sizes.store_port {
            if !(1..=8).contains(&tag_bits) {
                return Err(format!(
                    "store port tag_bits = {tag_bits}: expected 1..=8 (a tag FIFO of 2^tag_bits reads)"
                ));
            }
        }
        Ok(())
    }
}

/// Module name of the merger for `c`.
pub fn hierarchy_merger_name(c: &MergerConfig) -> String {
    let inner = merge_module_name(&c.design);
    let rest = inner.strip_prefix("merge_module_").unwrap_or(&inner);
    let base = format!(
        "hierarchy_merger_{rest}_r{}_f{}_c{}_l{}",
        c.design.roots, c.sizes.fetch.frontier, c.sizes.capacity_bits, c.sizes.leaf_bits
    );
    // Per-unit ports (the default) keep the name they always had.
    match c.sizes.store_port {
        StorePort::PerUnit => base,
        StorePort::Shared { tag_bits } => format!("{base}_sp{tag_bits}"),
    }
}

/// Whether `c`'s units share one store port (their own streams are then
/// not passed out of the top).
fn shared_store(c: &MergerConfig) -> bool {
    c.sizes.store_port != StorePort::PerUnit
}

/// Phases of one input's command issuer.
mod phase {
    /// No merge.
    pub const NONE: u64 = 0;
    /// The count pass: one command walking to `hi` and sending `lo..=hi`
    /// (an unused input: one `End` per candidate LOD from the glue).
    pub const COUNT: u64 = 1;
    /// Waiting for the merging module's choice.
    pub const WAIT: u64 = 2;
    /// Issuing the merge-pass (or closing) command.
    pub const FINAL: u64 = 3;
    /// Every command issued.
    pub const DONE: u64 = 4;
    pub const BITS: u32 = 3;
    /// Every phase by name (the Verilog's `localparam`s).
    pub const STATES: &[(&str, u64)] = &[
        ("NONE", NONE),
        ("COUNT", COUNT),
        ("WAIT", WAIT),
        ("FINAL", FINAL),
        ("DONE", DONE),
    ];
}

/// Field `f` of `s`.
fn get<'m>(s: Signal<'m>, f: &golden::layout::Field) -> Signal<'m> {
    s.view(f)
}

/// The merging module's range check (8.10, 8.14): `lo <= hi` and `hi <= D`
/// when the field can hold more.
fn range_good<'m>(m: &'m Module, c: &MergerConfig, lo: Signal<'m>, hi: Signal<'m>) -> Signal<'m> {
    let lb = c.design.params.lod_bits();
    let dmax = c.design.params.max_lod as u128;
    let beyond = if (1u128 << lb) - 1 > dmax {
        hi.gt(m.lit(dmax, lb))
    } else {
        m.lit(0, 1)
    };
    !(lo.gt(hi) | beyond)
}

/// What both merger bodies start with: the instances (a fetcher per input,
/// the merging module, the upper builder, the writer) and the `cfg`
/// handshake. A merge is held in `cfg_q` from its `cfg` beat until its
/// header leaves (`header_fire`), or, when merges overlap, until the next
/// merge's `cfg` beat: a level-mode merger takes the next merge's `cfg`
/// and runs its count pass while this merge's builder and writer drain
/// (docs/hardware.md 8.15, "Consecutive merges").
struct Shell<'m> {
    zero: Signal<'m>,
    one: Signal<'m>,
    fetchers: Vec<crate::Instance<'m>>,
    module: crate::Instance<'m>,
    builder: crate::Instance<'m>,
    writer: crate::Instance<'m>,
    /// Consecutive merges overlap.
    overlap: bool,
    /// A merge was taken and its header has not left.
    busy: Signal<'m>,
    /// Two merges are taken: the older waits for its header, the newer
    /// may not pass its choice (always low when merges do not overlap).
    queued: Signal<'m>,
    /// Set while a command whose `out` beats are dropped (the closing
    /// command) has not sent its End.
    dropping: Vec<Signal<'m>>,
    header_fire: Signal<'m>,
    /// The header is offered and not taken: the flags beside the writer's
    /// beat hold still (section 8.15).
    header_hold: Signal<'m>,
    /// The merge settled (every command issued, every dropped command
    /// ended): its header may be offered. Driven by the tail.
    header_open: Signal<'m>,
    /// Every command of the merge was issued (driven by the mode).
    commands_sent: Signal<'m>,
    /// The `cfg` beats to the module and the writer are pending.
    module_cfg_pending: Signal<'m>,
    writer_cfg_pending: Signal<'m>,
    /// What starts a merge's header flags afresh (its `cfg` beat when
    /// merges overlap, else the last header leaving), and what holds them.
    flag_clear: Signal<'m>,
    flag_hold: Signal<'m>,
    cfg: Stream<'m>,
    cfg_fire: Signal<'m>,
    cfg_q: Signal<'m>,
    /// A shared store port: the slot (`store_req`'s `slot`: the merge's
    /// sequence number mod 2) of the fetchers' reads and of the writer's.
    slots: Option<Slots<'m>>,
    /// The input count of the `cfg` beat arriving, and of the merge held.
    count_in: Signal<'m>,
    count_q: Signal<'m>,
    lo: Signal<'m>,
    hi: Signal<'m>,
    out_id: Signal<'m>,
}

/// Whose merge a shared port's reads are for: the fetchers serve the
/// newest merge taken, the writer the oldest whose header has not left
/// (with two merges taken, the older).
#[derive(Clone, Copy)]
struct Slots<'m> {
    fetchers: Signal<'m>,
    writer: Signal<'m>,
}

impl<'m> Shell<'m> {
    /// A header flag as the header shows it, given the register `front`
    /// the merge's events set: with two merges taken, the older merge's
    /// value, kept from the newer's `cfg` beat in `<name>_header`.
    fn shown_flag(&self, m: &'m Module, front: Signal<'m>, name: &str) -> Signal<'m> {
        if !self.overlap {
            return front;
        }
        let kept = m.reg(&format!("{name}_header"), front.width());
        kept.next_when(self.cfg_fire, front);
        self.queued.mux(kept, front)
    }
}

/// The [`Shell`] of a merger `m` of `c`, its fetchers instances of
/// `fetch_mod` (level-mode or per-node) and its writer of `writer_mod`;
/// with `overlap`, consecutive merges overlap.
fn shell<'m>(
    m: &'m Module,
    c: &MergerConfig,
    ml: &MergerLayout,
    fetch_mod: &Module,
    writer_mod: &Module,
    overlap: bool,
) -> Shell<'m> {
    let p = &c.design.params;
    let k = c.design.inputs;
    let zero = m.lit(0, 1);
    let one = m.lit(1, 1);
    let fetchers: Vec<_> = (0..k)
        .map(|i| m.instance(&format!("u_fetch{i}"), fetch_mod))
        .collect();
    let module = m.instance("u_module", &merge_module_unit(&c.design));
    let builder = m.instance("u_builder", &upper_builder_unit(p));
    let writer = m.instance("u_writer", writer_mod);

    let dropping: Vec<Signal> = (0..k).map(|i| m.reg(&format!("dropping{i}"), 1)).collect();
    let header_fire = m.wire("header_fire", 1);
    let header_hold = m.wire("header_hold", 1);
    let header_open = m.reg("header_open", 1);
    let commands_sent = m.wire("commands_sent", 1);
    let module_cfg_pending = m.reg("module_cfg_pending", 1);
    let writer_cfg_pending = m.reg("writer_cfg_pending", 1);
    let cfg = Stream::input(m, "cfg", ml.cfg.width());
    let cfg_fire = cfg.fire().name("cfg_fire");
    let (busy, queued, front_free) = if overlap {
        // One merge taken (`busy`) or two (`queued` too). `queued` rises
        // only with a `cfg` beat, which the choice gate below relies on.
        let busy = m.reg("busy", 1);
        let queued = m.reg("queued", 1);
        busy.next(cfg_fire.mux(one, (header_fire & !queued).mux(zero, busy)));
        queued.next((cfg_fire & busy & !header_fire).mux(one, header_fire.mux(zero, queued)));
        // The next merge may start once this one settled: its fetchers
        // are then done with it (`quiet` below), and the `cfg` beats it
        // sent were taken.
        // Nor while the module offers a choice: it is this merge's, which
        // passed already when the merge settled, and the newer merge's
        // `choice_waits` must never withdraw a beat offered (so that the
        // handshake proof needs no more than this).
        let tl = TopLayout::new(p);
        let choice_offered =
            module.output("report_valid") & get(module.output("report_data"), &tl.chosen);
        let settled_alone = busy
            & header_open
            & !queued
            & !module_cfg_pending
            & !writer_cfg_pending
            & !choice_offered;
        // (`header_open` and `queued` without `busy` never happen; the
        // proof's induction would meet them, and there a `cfg` beat would
        // clear the flags of a header offered.)
        let none_taken = !busy & !queued & !header_open;
        (busy, queued, none_taken | settled_alone)
    } else {
        let busy = m.reg("busy", 1);
        busy.next(cfg_fire.mux(one, header_fire.mux(zero, busy)));
        (busy, zero, !busy)
    };
    // Overlapping merges need the fetchers done, not the module: its own
    // `cfg` waits in `module_cfg_pending`, and its network holds the newer
    // merge's beats until it is idle (8.10). A fetcher's `idle` is its walk
    // alone; its `out` and `leaves` skid buffers may still hold beats, and
    // the next `cfg` re-routes them, so they must be empty too.
    let mut quiet = if overlap {
        front_free
    } else {
        front_free & module.output("idle")
    };
    for (i, f) in fetchers.iter().enumerate() {
        quiet = quiet & f.output("idle") & !dropping[i];
        if overlap {
            quiet = quiet & !f.output("out_valid") & !f.output("leaves_valid");
        }
    }
    let quiet = quiet.name("quiet");
    cfg.ready.drive(quiet);
    let cfg_q = m.reg("cfg_q", ml.cfg.width());
    cfg_q.next_when(cfg_fire, cfg.data);
    let slots = shared_store(c).then(|| {
        // The slot of the next merge taken: merges are numbered from 0 at
        // reset, and at most two are taken, so a bit tells them apart.
        let slot_next = m.reg("slot_next", 1);
        slot_next.next(cfg_fire.mux(!slot_next, slot_next));
        let newest = (!slot_next).name("fetch_slot");
        Slots {
            fetchers: newest,
            writer: queued.mux(slot_next, newest).name("writer_slot"),
        }
    });
    let (flag_clear, flag_hold) = if overlap {
        (
            cfg_fire,
            (header_hold & !queued & !cfg_fire).name("flags_hold"),
        )
    } else {
        (header_fire, header_hold)
    };
    Shell {
        zero,
        one,
        fetchers,
        module,
        builder,
        writer,
        overlap,
        busy,
        queued,
        dropping,
        header_fire,
        header_hold,
        header_open,
        commands_sent,
        module_cfg_pending,
        writer_cfg_pending,
        flag_clear,
        flag_hold,
        cfg,
        cfg_fire,
        cfg_q,
        slots,
        count_in: get(cfg.data, &ml.count),
        count_q: get(cfg_q, &ml.count),
        lo: get(cfg_q, &ml.lo).name("lo"),
        hi: get(cfg_q, &ml.hi).name("hi"),
        out_id: get(cfg_q, &ml.out_id),
    }
}

/// The `cfg` beats to the module (its candidate range) and the writer (the
/// output id); the fetchers' go with their commands.
fn cfg_beats<'m>(m: &'m Module, p: &Params, ml: &MergerLayout, s: &Shell<'m>) {
    let tl = TopLayout::new(p);
    let wl = &ml.writer;
    let lit = |v: u64, w: u32| m.lit(v as u128, w);
    let (zero, one, module, writer) = (s.zero, s.one, s.module, s.writer);
    let (cfg_fire, lo, hi, out_id) = (s.cfg_fire, s.lo, s.hi, s.out_id);
    let mcfg_pend = s.module_cfg_pending;
    module.connect("cfg_valid", mcfg_pend);
    module.connect(
        "cfg_data",
        lit(0, tl.cfg.width()).with_fields(&[(tl.lo, lo), (tl.hi, hi)]),
    );
    let mcfg_fire = mcfg_pend & module.output("cfg_ready");
    mcfg_pend.next(cfg_fire.mux(one, mcfg_fire.mux(zero, mcfg_pend)));
    let wcfg_pend = s.writer_cfg_pending;
    writer.connect("cfg_valid", wcfg_pend);
    writer.connect(
        "cfg_data",
        lit(0, wl.cfg.width()).with_fields(&[(wl.cfg_out_id, out_id)]),
    );
    let wcfg_fire = wcfg_pend & writer.output("cfg_ready");
    wcfg_pend.next(cfg_fire.mux(one, wcfg_fire.mux(zero, wcfg_pend)));
}

/// A child's store-port streams: `(name, direction, data width)` of every
/// stream whose name ends in `_req` (out) or `_resp` (in).
fn store_streams(child: &Module) -> Vec<(String, Direction, u32)> {
    let ports = child.ports();
    ports
        .iter()
        .filter_map(|q| {
            let name = q.name.strip_suffix("_valid")?;
            (name.ends_with("_req") || name.ends_with("_resp")).then(|| {
                let w = ports
                    .iter()
                    .find(|x| x.name == format!("{name}_data"))
                    .map_or(0, |x| x.width);
                (name.to_string(), q.direction, w)
            })
        })
        .collect()
}

/// Stream `port` of instance `inst` as this module's stream `outer`: an
/// output stream (`dir` Output) leaves, an input stream (`width` bits)
/// comes in.
pub(crate) fn pass_stream<'m>(
    m: &'m Module,
    inst: crate::Instance<'m>,
    port: &str,
    outer: &str,
    dir: Direction,
    width: u32,
) {
    match dir {
        Direction::Output => {
            let s = Stream {
                valid: inst.output(&format!("{port}_valid")),
                data: inst.output(&format!("{port}_data")),
                ready: m.wire(&format!("{outer}_ready_w"), 1),
            };
            inst.connect(&format!("{port}_ready"), s.ready);
            s.output(outer);
        }
        Direction::Input => {
            let s = Stream::input(m, outer, width);
            inst.connect(&format!("{port}_valid"), s.valid);
            inst.connect(&format!("{port}_data"), s.data);
            s.ready.drive(inst.output(&format!("{port}_ready")));
        }
    }
}

/// The whole of a beat layout as one field from bit 0.
fn field_of(b: &BeatLayout) -> golden::layout::Field {
    golden::layout::Field {
        name: "beat",
        offset: 0,
        width: b.width(),
    }
}

/// The hierarchy merger for `c`; an error when `c.validate()` refuses it.
///
/// Ports: `clk`, `rst`; streams `cfg` (in, [`MergerLayout::cfg`]),
/// `report` (out, the merging module's), `nodes`, `refs` (out, the
/// writer's), `header` (out, [`MergerLayout::header`]); every store
/// port stream (`*_req` out, `*_resp` in) of fetcher `i` as `f{i}_<name>`
/// (`f{i}_node_req`, `f{i}_ref_req`, ...) and of the writer as `w_<name>`,
/// not arbitrated (`StorePort::PerUnit`), or, with `StorePort::Shared`,
/// the one port `store_req` (out) / `store_resp` (in) of the store front
/// end ([`store_port_unit`]) instead; outputs `idle`, `done` (one clock after a header leaves),
/// `module_done` and the writer's status outputs as `w_<name>`.
pub fn hierarchy_merger_unit(c: &MergerConfig) -> Result<Module, String> {
    c.validate()?;
    match c.design.mode {
        MergeMode::PerNode { .. } => per_node_mode::per_node_merger_unit(c),
        _ => level_mode::level_merger_unit(c),
    }
}
