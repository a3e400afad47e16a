//! The hierarchy merger as one top module (SPEC.md section 8.15): S610-S618
//! end to end. `k` fetchers walk the inputs in the store, the merging module
//! chooses the level and merges it, the upper builder builds every level
//! above, the record writer lays out the merged hierarchy; the glue here is
//! a controller (the fetchers' `cfg` and commands, pass by pass), the routing
//! of the merging module's `out` (nodes to the builder's `base{m}`,
//! references to the writer's `crefs`), and the leaves above `m`: a k-way
//! merge by (LOD, Morton, rank) into one FIFO per LOD, because the builder
//! takes `base{d}` at its own pace while level `m` streams.
//!
//! Golden: `golden::merge::merger_unit::merger_transaction`, the chain of the
//! units' own transactions.

use golden::merge::fetch_unit::{FetchLayout, FetchSizes};
use golden::merge::merger_unit::{MergerLayout, MergerSizes};
use golden::merge::per_node_unit::PerNodeLayout;
use golden::merge::top::TopLayout;
use golden::merge::unit::{base_kind, level_kind, rank_bits, BeatLayout};
use golden::merge::MergeMode;

use super::fields::{coords, field, with_fields};
use super::network::morton_code;
use super::{
    fetcher_per_node_unit, fetcher_unit, merge_module_name, merge_module_unit, record_writer_unit,
    upper_builder_unit, MergeConfig,
};
use crate::{Direction, Module, Signal, Stream};

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
        Ok(())
    }
}

/// Module name of the merger for `c`.
pub fn hierarchy_merger_name(c: &MergerConfig) -> String {
    let inner = merge_module_name(&c.design);
    let rest = inner.strip_prefix("merge_module_").unwrap_or(&inner);
    format!(
        "hierarchy_merger_{rest}_r{}_f{}_c{}_l{}",
        c.design.roots, c.sizes.fetch.frontier, c.sizes.capacity_bits, c.sizes.leaf_bits
    )
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
}

/// Field `f` of `s`.
fn get<'m>(s: Signal<'m>, f: &golden::layout::Field) -> Signal<'m> {
    field(s, f).expect("a non-empty field")
}

/// The count pass runs in overlap mode on a good range (the merging
/// module's own test, 8.10).
fn counts_pass<'m>(m: &'m Module, c: &MergerConfig, lo: Signal<'m>, hi: Signal<'m>) -> Signal<'m> {
    let lb = c.design.params.lod_bits();
    let dmax = c.design.params.max_lod as u128;
    if c.design.threshold().is_none() {
        return m.lit(0, 1);
    }
    let beyond = if (1u128 << lb) - 1 > dmax {
        hi.gt(m.lit(dmax, lb))
    } else {
        m.lit(0, 1)
    };
    !(lo.gt(hi) | beyond)
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
fn pass_stream<'m>(
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

/// The hierarchy merger for `c`; an error when `c.validate()` refuses it.
///
/// Ports: `clk`, `rst`; streams `cfg` (in, [`MergerLayout::cfg_width`]),
/// `report` (out, the merging module's), `nodes`, `refs` (out, the
/// writer's), `header` (out, [`MergerLayout::header_width`]); every store
/// port stream (`*_req` out, `*_resp` in) of fetcher `i` as `f{i}_<name>`
/// (`f{i}_node_req`, `f{i}_ref_req`, ...) and of the writer as `w_<name>`,
/// not arbitrated; outputs `idle`, `done` (one clock after a header leaves),
/// `module_done` and the writer's status outputs as `w_<name>`.
pub fn hierarchy_merger_unit(c: &MergerConfig) -> Result<Module, String> {
    c.validate()?;
    if let MergeMode::PerNode { .. } = c.design.mode {
        return per_node_merger_unit(c);
    }
    let p = &c.design.params;
    let k = c.design.inputs;
    let ml = MergerLayout::new(p, k, c.sizes.capacity_bits).map_err(|e| e.to_string())?;
    let fl = &ml.fetch;
    let wl = &ml.writer;
    let tl = TopLayout::new(p);
    let inb = BeatLayout::input(p);
    let outb = BeatLayout::output(p);
    let lb = p.lod_bits();
    let dmax = p.max_lod as usize;
    let m = Module::new(&hierarchy_merger_name(c));
    let lit = |v: u64, w: u32| m.lit(v as u128, w);
    let zero = lit(0, 1);
    let one = lit(1, 1);

    let fetch_mod = fetcher_unit(p, &c.fetch_sizes());
    let writer_mod = record_writer_unit(p, c.sizes.capacity_bits).map_err(|e| e.to_string())?;
    let fetchers: Vec<_> = (0..k)
        .map(|i| m.instance(&format!("u_fetch{i}"), &fetch_mod))
        .collect();
    let module = m.instance("u_module", &merge_module_unit(&c.design));
    let builder = m.instance("u_builder", &upper_builder_unit(p));
    let writer = m.instance("u_writer", &writer_mod);

    // ---- cfg: taken when no merge is in progress and every unit is idle.
    let busy = m.reg("busy", 1);
    // Set while a command whose `out` beats are dropped (the closing
    // command) has not sent its End.
    let dropping: Vec<Signal> = (0..k).map(|i| m.reg(&format!("dropping{i}"), 1)).collect();
    let header_fire = m.wire("header_fire", 1);
    let mut quiet = !busy & module.output("idle");
    for (i, f) in fetchers.iter().enumerate() {
        quiet = quiet & f.output("idle") & !dropping[i];
    }
    let quiet = quiet.name("quiet");
    let cfg = Stream::input(&m, "cfg", ml.cfg_width);
    cfg.ready.drive(quiet);
    let cfg_fire = cfg.fire().name("cfg_fire");
    let cfg_q = m.reg("cfg_q", ml.cfg_width);
    cfg_q.next_when(cfg_fire, cfg.data);
    busy.next(cfg_fire.mux(one, header_fire.mux(zero, busy)));
    let count_in = get(cfg.data, &ml.count);
    let count_q = get(cfg_q, &ml.count);
    let lo = get(cfg_q, &ml.lo).name("lo");
    let hi = get(cfg_q, &ml.hi).name("hi");
    let out_id = get(cfg_q, &ml.out_id);
    let counting_in =
        counts_pass(&m, c, get(cfg.data, &ml.lo), get(cfg.data, &ml.hi)).name("count_pass");
    let cw = ml.count.width;
    let used_in: Vec<Signal> = (0..k).map(|i| count_in.gt(lit(i as u64, cw))).collect();
    let used: Vec<Signal> = (0..k)
        .map(|i| count_q.gt(lit(i as u64, cw)).name(&format!("used{i}")))
        .collect();

    // ---- the choice, read off the module's report on its way out.
    let report_ready = m.input("report_ready", 1);
    let report_valid = module.output("report_valid");
    let report_data = module.output("report_data");
    module.connect("report_ready", report_ready);
    m.output("report_valid", report_valid);
    m.output("report_data", report_data);
    let chosen_beat =
        (report_valid & report_ready & get(report_data, &tl.chosen).eq(1)).name("choice_seen");
    let known = m.reg("choice_known", 1);
    let ok = m.reg("choice_ok", 1);
    let level = m.reg("merge_lod", lb);
    known.next(chosen_beat.mux(one, header_fire.mux(zero, known)));
    ok.next(chosen_beat.mux(get(report_data, &tl.err).eq(0), header_fire.mux(zero, ok)));
    level.next_when(chosen_beat, get(report_data, &tl.lod));
    let merging = (known & ok).name("merging");

    // ---- cfg beats to the module, the fetchers and the writer.
    let mcfg_pend = m.reg("module_cfg_pending", 1);
    module.connect("cfg_valid", mcfg_pend);
    module.connect(
        "cfg_data",
        with_fields(&m, lit(0, tl.cfg_width), &[(tl.lo, lo), (tl.hi, hi)]),
    );
    let mcfg_fire = mcfg_pend & module.output("cfg_ready");
    mcfg_pend.next(cfg_fire.mux(one, mcfg_fire.mux(zero, mcfg_pend)));
    let wcfg_pend = m.reg("writer_cfg_pending", 1);
    writer.connect("cfg_valid", wcfg_pend);
    writer.connect(
        "cfg_data",
        with_fields(&m, lit(0, wl.cfg_width), &[(wl.cfg_out_id, out_id)]),
    );
    let wcfg_fire = wcfg_pend & writer.output("cfg_ready");
    wcfg_pend.next(cfg_fire.mux(one, wcfg_fire.mux(zero, wcfg_pend)));

    // ---- per input: its cfg, its commands, its stream into the module.
    let rb = rank_bits(k);
    let ferr = m.reg("fetch_err", fl.err.width);
    let ferr_rank = m.reg("fetch_rank", rb);
    let mut ferr_next = header_fire.mux(lit(0, fl.err.width), ferr);
    let mut ferr_rank_next = header_fire.mux(lit(0, rb), ferr_rank);
    let end_beat = with_fields(
        &m,
        lit(0, inb.width),
        &[(inb.kind, lit(level_kind::END, 2))],
    );
    let mut leaves_in = Vec::new();
    for (i, f) in fetchers.iter().enumerate() {
        let fcfg_pend = m.reg(&format!("fetch{i}_cfg_pending"), 1);
        f.connect("cfg_valid", fcfg_pend);
        let off = ml.input_offset(i);
        f.connect("cfg_data", cfg_q.slice(off + fl.cfg_width - 1, off));
        let fcfg_fire = fcfg_pend & f.output("cfg_ready");
        fcfg_pend.next(cfg_fire.mux(used_in[i], fcfg_fire.mux(zero, fcfg_pend)));

        let ph = m.reg(&format!("phase{i}"), phase::BITS);
        let in_ph = |v: u64| ph.eq(lit(v, phase::BITS));
        // The candidate level an unused input's next `End` stands for.
        let cmd_lod = m.reg(&format!("cmd_lod{i}"), lb);
        let count_ph = in_ph(phase::COUNT);
        let final_ph = in_ph(phase::FINAL);
        let lod = count_ph.mux(hi, merging.mux(level, lo));
        let cmd_data = with_fields(
            &m,
            lit(0, fl.cmd_width),
            &[
                (fl.lod, lod),
                (fl.send_refs, final_ph & merging),
                // The leaves above m come with level m (SPEC 8.15: no
                // deadlock, the fetcher ends `leaves` before level m).
                (fl.send_leaves, final_ph & merging),
                (fl.last, final_ph),
                // The count pass sends lo..=hi from one walk; the other
                // commands one level.
                (fl.from, count_ph.mux(lo, lod)),
            ],
        );
        let issuing = (count_ph | final_ph).name(&format!("issuing{i}"));
        f.connect("cmd_valid", used[i] & issuing);
        f.connect("cmd_data", cmd_data);
        let cmd_fire = used[i] & issuing & f.output("cmd_ready");

        // The module's in<i>: the fetcher's beats, or one End per pass for
        // an unused input; the closing command's beats are dropped.
        let in_ready = module.output(&format!("in{i}_ready"));
        let fo_valid = f.output("out_valid");
        let fo_data = f.output("out_data");
        let fo_err = get(fo_data, &fl.err);
        let fo_beat = fo_data.slice(fl.beat.width - 1, 0);
        let fo_end = get(fo_beat, &inb.kind).eq(level_kind::END);
        let virt = (!used[i] & (count_ph | (final_ph & merging))).name(&format!("virtual_end{i}"));
        let drop = dropping[i];
        module.connect(&format!("in{i}_valid"), used[i].mux(fo_valid & !drop, virt));
        module.connect(&format!("in{i}_data"), used[i].mux(fo_beat, end_beat));
        f.connect("out_ready", drop | (used[i] & in_ready));
        let fo_fire = fo_valid & (drop | (used[i] & in_ready));
        let virt_fire = virt & in_ready;
        let first_err = fo_fire & fo_err.ne(0) & ferr_next.eq(0);
        ferr_next = first_err.mux(fo_err, ferr_next);
        ferr_rank_next = first_err.mux(lit(i as u64, rb), ferr_rank_next);
        // An unused input has no closing command.
        let skip = !used[i] & final_ph & !merging;
        let step = (cmd_fire | virt_fire | skip).name(&format!("step{i}"));
        let last_count = cmd_lod.eq(hi);
        let after_step = count_ph.mux(
            (used[i] | last_count).mux(lit(phase::WAIT, phase::BITS), ph),
            lit(phase::DONE, phase::BITS),
        );
        let after_choice = lit(phase::FINAL, phase::BITS);
        let ph_next = cfg_fire.mux(
            counting_in.mux(
                lit(phase::COUNT, phase::BITS),
                lit(phase::WAIT, phase::BITS),
            ),
            header_fire.mux(
                lit(phase::NONE, phase::BITS),
                step.mux(
                    after_step,
                    (in_ph(phase::WAIT) & known).mux(after_choice, ph),
                ),
            ),
        );
        ph.next(ph_next);
        cmd_lod.next(cfg_fire.mux(
            get(cfg.data, &ml.lo),
            (step & count_ph).mux(cmd_lod.add(1, lb), cmd_lod),
        ));
        let drop_issued = cmd_fire & final_ph & !merging;
        dropping[i].next(drop_issued.mux(one, (fo_fire & fo_end).mux(zero, dropping[i])));

        // The store ports (every `*_req` / `*_resp` stream), straight through.
        for (port, dir, w) in store_streams(&fetch_mod) {
            pass_stream(&m, *f, &port, &format!("f{i}_{port}"), dir, w);
        }
        leaves_in.push((f.output("leaves_valid"), f.output("leaves_data"), i));
    }
    ferr.next(ferr_next);
    ferr_rank.next(ferr_rank_next);

    // ---- the leaves above m: k-way merge by (LOD, Morton, rank).
    let MergedLeaves {
        done: leaves_done,
        take: take_leaf,
        data: best_data,
        lod: best_lod,
    } = merge_leaves(
        &m,
        LeafInputs {
            fl,
            busy,
            header_fire,
            used: &used,
            leaves_in: &leaves_in,
            fetchers: &fetchers,
            rb,
        },
    );
    // A FIFO word: the leaves beat's `rec` and `ref` (from bit 0).
    let word_w = fl.leaf_ref.end().max(fl.leaf_rec.end());
    let word = best_data.slice(word_w - 1, 0);

    // ---- routing of the module's out.
    let mo_valid = module.output("out_valid");
    let mo_data = module.output("out_data");
    let mo_kind = get(mo_data, &outb.kind);
    let mo_ref = mo_kind.eq(base_kind::REF).name("out_is_ref");
    let mo_end = mo_kind.eq(base_kind::END).name("out_is_end");
    let mo_err = get(mo_data, outb.err.as_ref().expect("an output beat has err"));
    let mo_refer = get(mo_data, &outb.refer);
    let mo_beat = with_fields(
        &m,
        lit(0, inb.width),
        &[
            (inb.rec, get(mo_data, &outb.rec)),
            (inb.refer, mo_refer),
            (inb.kind, mo_kind),
        ],
    );

    // crefs: the reference beats, then End (a refused merge: End alone).
    let csent = m.reg("crefs_end_sent", 1);
    let cref_ready = writer.output("crefs_ready");
    let cref_valid = !csent & known & (!ok | (mo_valid & (mo_ref | mo_end)));
    let cref_is_end = !ok | mo_end;
    let cref_data = with_fields(
        &m,
        lit(0, wl.cref_width),
        &[
            (
                wl.cref,
                (ok & mo_ref).mux(mo_refer, lit(0, mo_refer.width())),
            ),
            (wl.cref_end, cref_is_end),
        ],
    );
    writer.connect("crefs_valid", cref_valid);
    writer.connect("crefs_data", cref_data);
    let cref_fire = cref_valid & cref_ready;
    csent.next((cref_fire & cref_is_end).mux(one, header_fire.mux(zero, csent)));

    // base{d}: the module's nodes at m, a leaf FIFO above m, End below m or
    // when refused.
    let cb = c.sizes.leaf_bits;
    let mut base_m_ready = zero;
    let mut base_m_sent = zero;
    let mut leaf_over = m.reg("leaf_overflow", 1);
    let mut over_next = header_fire.mux(zero, leaf_over);
    let reused_kind = lit(base_kind::REUSED, 2);
    for d in 0..=dmax {
        let dl = lit(d as u64, lb);
        let bsent = m.reg(&format!("base{d}_end_sent"), 1);
        let ready = builder.output(&format!("base{d}_ready"));
        let at_m = (merging & level.eq(dl)).name(&format!("base{d}_at_m"));
        let (valid, data, is_end) = if d < dmax {
            // The FIFO of LOD d.
            let q = DropFifo::new(&m, &format!("leaves{d}"), &format!("leaves{d}"), word_w, cb);
            let (empty, full) = (q.empty, q.full);
            let push = take_leaf & best_lod.eq(dl);
            q.write(word, push);
            over_next = (push & full).mux(one, over_next);
            let head = q.head();
            let above = (merging & dl.lt(level)).name(&format!("base{d}_above_m"));
            let leaf_beat = with_fields(
                &m,
                lit(0, inb.width),
                &[
                    (inb.rec, get(head, &fl.leaf_rec)),
                    (inb.refer, get(head, &fl.leaf_ref)),
                    (inb.kind, reused_kind),
                ],
            );
            let fifo_end = empty & leaves_done;
            let valid = !bsent
                & (at_m & mo_valid & !mo_ref
                    | above & (!empty | leaves_done)
                    | known & !at_m & !above);
            let data = at_m.mux(mo_beat, (above & !empty).mux(leaf_beat, end_beat));
            let is_end = at_m.mux(mo_end, above.mux(fifo_end, one));
            let pop = valid & ready & above & !empty;
            q.advance(push, pop, header_fire);
            (valid, data, is_end)
        } else {
            let valid = !bsent & (at_m & mo_valid & !mo_ref | known & !at_m);
            let data = at_m.mux(mo_beat, end_beat);
            let is_end = at_m.mux(mo_end, one);
            (valid, data, is_end)
        };
        builder.connect(&format!("base{d}_valid"), valid);
        builder.connect(&format!("base{d}_data"), data);
        let fire = valid & ready;
        bsent.next((fire & is_end).mux(one, header_fire.mux(zero, bsent)));
        base_m_ready = at_m.mux(ready & !bsent, base_m_ready);
        base_m_sent = at_m.mux(bsent, base_m_sent);
    }
    leaf_over.next(over_next);
    leaf_over = leaf_over.name("leaf_overflow_q");
    let mo_ready = merging
        & mo_ref.mux(
            cref_ready,
            mo_end.mux(
                (base_m_sent | base_m_ready) & (csent | cref_ready),
                base_m_ready,
            ),
        );
    module.connect("out_ready", mo_ready);
    let count_over = m.reg("count_overflow", 1);
    let created = mo_kind.eq(base_kind::CREATED);
    count_over
        .next((mo_valid & mo_ready & created & mo_err).mux(one, header_fire.mux(zero, count_over)));

    finish_merger(
        &m,
        Tail {
            dmax,
            module,
            builder,
            writer,
            writer_mod: &writer_mod,
            ml: &ml,
            header_fire,
            flags: [leaf_over, count_over, ferr, ferr_rank],
            busy,
            dropping: &dropping,
        },
    );
    Ok(m)
}

/// The range check of the per-node module (8.14): `lo <= hi` and `hi <= D`
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

/// The merger of a `per-node:N/D` configuration (SPEC 8.15, per-node mode):
/// every used fetcher gets one per-node command at `lo` (references, the
/// leaves above `lo`, last) and the module's `report` (the narrow beat of
/// [`golden::merge::fetch_unit::PerNodeFetchLayout`]); the module's `out`
/// nodes of every pass go into the FIFO of their LOD (the leaves above `lo`
/// into theirs), its reference beats to the writer's `crefs`. The builder
/// sees the base only once the module is done: a shallower pass's nodes
/// cannot pass the builder's stage before every deeper level is known.
fn per_node_merger_unit(c: &MergerConfig) -> Result<Module, String> {
    let p = &c.design.params;
    let k = c.design.inputs;
    let ml = MergerLayout::new(p, k, c.sizes.capacity_bits).map_err(|e| e.to_string())?;
    let fl = FetchLayout::per_node(p);
    let fpn = fl.pn.as_ref().expect("a per-node fetch layout");
    let wl = &ml.writer;
    let tl = TopLayout::new(p);
    let pl = PerNodeLayout::new(p);
    let inb = BeatLayout::input(p);
    let outb = BeatLayout::output(p);
    let lb = p.lod_bits();
    let dmax = p.max_lod as usize;
    let m = Module::new(&hierarchy_merger_name(c));
    let lit = |v: u64, w: u32| m.lit(v as u128, w);
    let zero = lit(0, 1);
    let one = lit(1, 1);

    let fetch_mod = fetcher_per_node_unit(p, &c.fetch_sizes());
    let writer_mod = record_writer_unit(p, c.sizes.capacity_bits).map_err(|e| e.to_string())?;
    let fetchers: Vec<_> = (0..k)
        .map(|i| m.instance(&format!("u_fetch{i}"), &fetch_mod))
        .collect();
    let module = m.instance("u_module", &merge_module_unit(&c.design));
    let builder = m.instance("u_builder", &upper_builder_unit(p));
    let writer = m.instance("u_writer", &writer_mod);

    // ---- cfg: taken when no merge is in progress and every unit is idle.
    let busy = m.reg("busy", 1);
    let dropping: Vec<Signal> = (0..k).map(|i| m.reg(&format!("dropping{i}"), 1)).collect();
    let header_fire = m.wire("header_fire", 1);
    let mut quiet = !busy & module.output("idle");
    for (i, f) in fetchers.iter().enumerate() {
        quiet = quiet & f.output("idle") & !dropping[i];
    }
    let quiet = quiet.name("quiet");
    let cfg = Stream::input(&m, "cfg", ml.cfg_width);
    cfg.ready.drive(quiet);
    let cfg_fire = cfg.fire().name("cfg_fire");
    let cfg_q = m.reg("cfg_q", ml.cfg_width);
    cfg_q.next_when(cfg_fire, cfg.data);
    busy.next(cfg_fire.mux(one, header_fire.mux(zero, busy)));
    let count_in = get(cfg.data, &ml.count);
    let count_q = get(cfg_q, &ml.count);
    let lo = get(cfg_q, &ml.lo).name("lo");
    let hi = get(cfg_q, &ml.hi).name("hi");
    let out_id = get(cfg_q, &ml.out_id);
    let good_in = range_good(&m, c, get(cfg.data, &ml.lo), get(cfg.data, &ml.hi)).name("good_in");
    let good = range_good(&m, c, lo, hi).name("range_good");
    let cw = ml.count.width;
    let used_in: Vec<Signal> = (0..k).map(|i| count_in.gt(lit(i as u64, cw))).collect();
    let used: Vec<Signal> = (0..k)
        .map(|i| count_q.gt(lit(i as u64, cw)).name(&format!("used{i}")))
        .collect();

    // ---- the module's end: its `done` pulse (after the last pass's End
    // left `out`, or after a refusal's report beat).
    let finished = m.reg("module_finished", 1);
    finished.next((busy & module.output("done")).mux(one, header_fire.mux(zero, finished)));

    // ---- cfg beats to the module and the writer.
    let mcfg_pend = m.reg("module_cfg_pending", 1);
    module.connect("cfg_valid", mcfg_pend);
    module.connect(
        "cfg_data",
        with_fields(&m, lit(0, tl.cfg_width), &[(tl.lo, lo), (tl.hi, hi)]),
    );
    let mcfg_fire = mcfg_pend & module.output("cfg_ready");
    mcfg_pend.next(cfg_fire.mux(one, mcfg_fire.mux(zero, mcfg_pend)));
    let wcfg_pend = m.reg("writer_cfg_pending", 1);
    writer.connect("cfg_valid", wcfg_pend);
    writer.connect(
        "cfg_data",
        with_fields(&m, lit(0, wl.cfg_width), &[(wl.cfg_out_id, out_id)]),
    );
    let wcfg_fire = wcfg_pend & writer.output("cfg_ready");
    wcfg_pend.next(cfg_fire.mux(one, wcfg_fire.mux(zero, wcfg_pend)));

    // ---- report: an eager fork to the top's `report` and, as the narrow
    // beat, to every fetcher running the per-node command. Each side takes
    // the beat once (`taken`); the module's beat leaves when all have.
    let rep_v = module.output("report_valid");
    let rep_d = module.output("report_data");
    let narrow = with_fields(
        &m,
        lit(0, fpn.report_width),
        &fpn.report_sources(&pl)
            .map(|(to, from)| (to, get(rep_d, &from))),
    )
    .name("report_narrow");
    let top_taken = m.reg("report_top_taken", 1);
    let report_ready = m.input("report_ready", 1);
    m.output("report_valid", rep_v & !top_taken);
    m.output("report_data", rep_d);
    let mut all_took = top_taken | report_ready;
    let mut fork = vec![(top_taken, rep_v & !top_taken & report_ready)];
    for (i, f) in fetchers.iter().enumerate() {
        let taken = m.reg(&format!("report{i}_taken"), 1);
        let feeds = (busy & used[i] & good).name(&format!("report{i}_feeds"));
        let v = rep_v & feeds & !taken;
        f.connect("report_valid", v);
        f.connect("report_data", narrow);
        let r = f.output("report_ready");
        all_took = all_took & (!feeds | taken | r);
        fork.push((taken, v & r));
    }
    let all_took = all_took.name("report_all_took");
    module.connect("report_ready", all_took);
    let rep_fire = (rep_v & all_took).name("report_fire");
    for (taken, fire) in fork {
        taken.next(rep_fire.mux(zero, fire.mux(one, taken)));
    }
    let next_pass = (rep_fire & get(rep_d, &pl.pass_end) & get(rep_d, &pl.more)).name("next_pass");

    // ---- per input: its cfg, its command, its stream into the module.
    let rb = rank_bits(k);
    let ferr = m.reg("fetch_err", fl.err.width);
    let ferr_rank = m.reg("fetch_rank", rb);
    let mut ferr_next = header_fire.mux(lit(0, fl.err.width), ferr);
    let mut ferr_rank_next = header_fire.mux(lit(0, rb), ferr_rank);
    let end_beat = with_fields(
        &m,
        lit(0, inb.width),
        &[(inb.kind, lit(level_kind::END, 2))],
    );
    let end_in = with_fields(&m, lit(0, pl.in_width), &[(field_of(&inb), end_beat)]);
    let mut leaves_in = Vec::new();
    for (i, f) in fetchers.iter().enumerate() {
        let fcfg_pend = m.reg(&format!("fetch{i}_cfg_pending"), 1);
        f.connect("cfg_valid", fcfg_pend);
        let off = ml.input_offset(i);
        f.connect("cfg_data", cfg_q.slice(off + fl.cfg_width - 1, off));
        let fcfg_fire = fcfg_pend & f.output("cfg_ready");
        fcfg_pend.next(cfg_fire.mux(used_in[i], fcfg_fire.mux(zero, fcfg_pend)));

        // One command per merge: per-node at lo on a good range, else the
        // closing command (its beats dropped).
        let cmd_pend = m.reg(&format!("cmd{i}_pending"), 1);
        let cmd_data = with_fields(
            &m,
            lit(0, fl.cmd_width),
            &[
                (fl.lod, lo),
                (fl.send_refs, good),
                (fl.send_leaves, good),
                (fl.last, one),
                (fl.from, lo),
                (fpn.per_node, good),
            ],
        );
        f.connect("cmd_valid", cmd_pend);
        f.connect("cmd_data", cmd_data);
        let cmd_fire = cmd_pend & f.output("cmd_ready");
        cmd_pend.next(cfg_fire.mux(used_in[i], cmd_fire.mux(zero, cmd_pend)));

        // The module's in<i>: the fetcher's beats (err dropped, probe
        // kept), or for an unused input one End per pass: owed from the
        // start and after every `pass_end` beat with `more`.
        let in_ready = module.output(&format!("in{i}_ready"));
        let fo_valid = f.output("out_valid");
        let fo_data = f.output("out_data");
        let fo_err = get(fo_data, &fl.err);
        let fo_beat = fo_data.slice(fl.beat.width - 1, 0);
        let fo_end = get(fo_beat, &inb.kind).eq(level_kind::END);
        let fo_in = with_fields(
            &m,
            lit(0, pl.in_width),
            &[
                (field_of(&inb), fo_beat),
                (pl.probe, get(fo_data, &fpn.probe)),
            ],
        );
        let owed = m.reg(&format!("end_owed{i}"), 1);
        let virt = (!used[i] & owed).name(&format!("virtual_end{i}"));
        let drop = dropping[i];
        module.connect(&format!("in{i}_valid"), used[i].mux(fo_valid & !drop, virt));
        module.connect(&format!("in{i}_data"), used[i].mux(fo_in, end_in));
        f.connect("out_ready", drop | (used[i] & in_ready));
        let fo_fire = fo_valid & (drop | (used[i] & in_ready));
        let virt_fire = virt & in_ready;
        owed.next(cfg_fire.mux(
            !used_in[i] & good_in,
            header_fire.mux(
                zero,
                (next_pass & !used[i]).mux(one, virt_fire.mux(zero, owed)),
            ),
        ));
        let first_err = fo_fire & fo_err.ne(0) & ferr_next.eq(0);
        ferr_next = first_err.mux(fo_err, ferr_next);
        ferr_rank_next = first_err.mux(lit(i as u64, rb), ferr_rank_next);
        let drop_issued = cmd_fire & !good;
        dropping[i].next(drop_issued.mux(one, (fo_fire & fo_end).mux(zero, dropping[i])));

        // The store ports (every `*_req` / `*_resp` stream, the probe port
        // included), straight through.
        for (port, dir, w) in store_streams(&fetch_mod) {
            pass_stream(&m, *f, &port, &format!("f{i}_{port}"), dir, w);
        }
        leaves_in.push((f.output("leaves_valid"), f.output("leaves_data"), i));
    }
    ferr.next(ferr_next);
    ferr_rank.next(ferr_rank_next);

    // ---- the leaves above lo: k-way merge by (LOD, Morton, rank).
    let MergedLeaves {
        done: leaves_done,
        take: take_leaf,
        data: best_data,
        lod: best_lod,
    } = merge_leaves(
        &m,
        LeafInputs {
            fl: &fl,
            busy,
            header_fire,
            used: &used,
            leaves_in: &leaves_in,
            fetchers: &fetchers,
            rb,
        },
    );
    let nl = &fl.node;
    let leaf_beat = with_fields(
        &m,
        lit(0, inb.width),
        &[
            (inb.rec, get(best_data, &fl.leaf_rec)),
            (inb.refer, get(best_data, &fl.leaf_ref)),
            (inb.kind, lit(base_kind::REUSED, 2)),
        ],
    );

    // ---- the module's out: reference beats to crefs, nodes into the FIFO
    // of their LOD, each pass's End dropped (the builder's End comes from
    // the FIFOs once the module is done).
    let mo_valid = module.output("out_valid");
    let mo_data = module.output("out_data");
    let mo_kind = get(mo_data, &outb.kind);
    let mo_ref = mo_kind.eq(base_kind::REF).name("out_is_ref");
    let mo_end = mo_kind.eq(base_kind::END).name("out_is_end");
    let mo_err = get(mo_data, outb.err.as_ref().expect("an output beat has err"));
    let mo_refer = get(mo_data, &outb.refer);
    let mo_rec = get(mo_data, &outb.rec);
    let mo_lod = field(mo_rec, nl.lod()).expect("a record's lod");
    let mo_beat = with_fields(
        &m,
        lit(0, inb.width),
        &[
            (inb.rec, mo_rec),
            (inb.refer, mo_refer),
            (inb.kind, mo_kind),
        ],
    );
    let mo_node = (mo_valid & !mo_ref & !mo_end).name("out_is_node");

    // crefs: the reference beats of every pass, then End once the module
    // is done (a refused merge: End alone).
    let csent = m.reg("crefs_end_sent", 1);
    let cref_ready = writer.output("crefs_ready");
    let cref_ref = (mo_valid & mo_ref).name("cref_is_ref");
    let cref_valid = !csent & busy & (cref_ref | finished);
    let cref_data = with_fields(
        &m,
        lit(0, wl.cref_width),
        &[
            (wl.cref, cref_ref.mux(mo_refer, lit(0, mo_refer.width()))),
            (wl.cref_end, !cref_ref),
        ],
    );
    writer.connect("crefs_valid", cref_valid);
    writer.connect("crefs_data", cref_data);
    let cref_fire = cref_valid & cref_ready;
    csent.next((cref_fire & !cref_ref).mux(one, header_fire.mux(zero, csent)));
    let mo_ready = mo_ref.mux(cref_ready & !csent, one);
    module.connect("out_ready", mo_ready);
    let count_over = m.reg("count_overflow", 1);
    let created = mo_kind.eq(base_kind::CREATED);
    count_over
        .next((mo_valid & mo_ready & created & mo_err).mux(one, header_fire.mux(zero, count_over)));

    // base{d}: the FIFO of LOD d (leaves for d < lo, the passes' nodes for
    // d >= lo), shown once the module is done and the leaves complete,
    // then End; End alone on a bad range.
    let cb = c.sizes.leaf_bits;
    let leaf_over = m.reg("leaf_overflow", 1);
    let mut over_next = header_fire.mux(zero, leaf_over);
    let base_open = (busy & finished & (!good | leaves_done)).name("base_open");
    for d in 0..=dmax {
        let dl = lit(d as u64, lb);
        let bsent = m.reg(&format!("base{d}_end_sent"), 1);
        let ready = builder.output(&format!("base{d}_ready"));
        let q = DropFifo::new(
            &m,
            &format!("base{d}_fifo"),
            &format!("base{d}"),
            inb.width,
            cb,
        );
        let (empty, full) = (q.empty, q.full);
        let above_lo = dl.lt(lo);
        let push_leaf = take_leaf & best_lod.eq(dl) & above_lo;
        let push_node = mo_node & mo_lod.eq(dl) & !above_lo;
        let push = (push_leaf | push_node).name(&format!("base{d}_push"));
        q.write(push_node.mux(mo_beat, leaf_beat), push);
        over_next = (push & full).mux(one, over_next);
        let head = q.head();
        let shows = good & !empty;
        let valid = base_open & !bsent;
        let data = shows.mux(head, end_beat);
        builder.connect(&format!("base{d}_valid"), valid);
        builder.connect(&format!("base{d}_data"), data);
        let fire = valid & ready;
        let pop = fire & shows;
        bsent.next((fire & !shows).mux(one, header_fire.mux(zero, bsent)));
        q.advance(push, pop, header_fire);
    }
    leaf_over.next(over_next);
    let leaf_over = leaf_over.name("leaf_overflow_q");

    finish_merger(
        &m,
        Tail {
            dmax,
            module,
            builder,
            writer,
            writer_mod: &writer_mod,
            ml: &ml,
            header_fire,
            flags: [leaf_over, count_over, ferr, ferr_rank],
            busy,
            dropping: &dropping,
        },
    );
    Ok(m)
}

/// A FIFO of `2^cb` words on a memory, whose pushes while full are
/// dropped (the caller flags them): `{name}_wr` / `{name}_rd` pointers of
/// `cb + 1` bits (the top bit tells full from empty), cleared at the end of
/// a merge.
struct DropFifo<'m> {
    m: &'m Module,
    mem: crate::Memory<'m>,
    wr: Signal<'m>,
    rd: Signal<'m>,
    cb: u32,
    empty: Signal<'m>,
    full: Signal<'m>,
}

impl<'m> DropFifo<'m> {
    fn new(m: &'m Module, mem_name: &str, name: &str, width: u32, cb: u32) -> Self {
        let mem = m.memory(mem_name, width, 1 << cb);
        let wr = m.reg(&format!("{name}_wr"), cb + 1);
        let rd = m.reg(&format!("{name}_rd"), cb + 1);
        let empty = wr.eq(rd);
        let full = wr.slice(cb - 1, 0).eq(rd.slice(cb - 1, 0)) & !wr.bit(cb).eq(rd.bit(cb));
        DropFifo {
            m,
            mem,
            wr,
            rd,
            cb,
            empty,
            full,
        }
    }

    /// Writes `data` when `push` and not full.
    fn write(&self, data: Signal<'m>, push: Signal<'m>) {
        let cb = self.cb;
        self.mem
            .write(self.wr.slice(cb - 1, 0), data, push & !self.full);
    }

    /// The oldest word (meaningful when not empty).
    fn head(&self) -> Signal<'m> {
        self.mem.read(self.rd.slice(self.cb - 1, 0))
    }

    /// Moves the pointers: a kept push, a pop; `clear` empties it.
    fn advance(&self, push: Signal<'m>, pop: Signal<'m>, clear: Signal<'m>) {
        let (wr, rd, w) = (self.wr, self.rd, self.cb + 1);
        let zero = self.m.lit(0, w);
        wr.next(clear.mux(zero, (push & !self.full).mux(wr.add(1, w), wr)));
        rd.next(clear.mux(zero, pop.mux(rd.add(1, w), rd)));
    }
}

/// What the leaves merge needs: the fetchers' `leaves` streams
/// (`(valid, data, input)`), which inputs the merge uses, the controller's
/// `busy` and the header's handshake that ends the merge.
struct LeafInputs<'a, 'm> {
    fl: &'a FetchLayout,
    busy: Signal<'m>,
    header_fire: Signal<'m>,
    used: &'a [Signal<'m>],
    leaves_in: &'a [(Signal<'m>, Signal<'m>, usize)],
    fetchers: &'a [crate::Instance<'m>],
    rb: u32,
}

/// The leaves above the merging level (or `lo`), merged over the used
/// fetchers by (LOD, Morton, rank): `take` while a leaf is chosen, `data`
/// its beat (rec, ref, lod), `lod` its LOD, `done` once every used fetcher
/// sent its leaves `end` (held to the end of the merge).
struct MergedLeaves<'m> {
    done: Signal<'m>,
    take: Signal<'m>,
    data: Signal<'m>,
    lod: Signal<'m>,
}

fn merge_leaves<'m>(m: &'m Module, t: LeafInputs<'_, 'm>) -> MergedLeaves<'m> {
    let LeafInputs {
        fl,
        busy,
        header_fire,
        used,
        leaves_in,
        fetchers,
        rb,
    } = t;
    let lit = |v: u64, w: u32| m.lit(v as u128, w);
    let (one, zero) = (lit(1, 1), lit(0, 1));
    let leaves_done = m.reg("leaves_done", 1);
    let active = (busy & !leaves_done).name("leaves_active");
    let nl = &fl.node;
    let mut all_valid = active;
    let mut all_end = one;
    let mut heads = Vec::new();
    for &(v, d, i) in leaves_in {
        let end = get(d, &fl.leaf_end);
        let rec = get(d, &fl.leaf_rec);
        let xyz = coords(rec, nl);
        let key = m
            .concat(&[!used[i] | end, get(d, &fl.leaf_lod), morton_code(m, xyz)])
            .name(&format!("leaf_key{i}"));
        all_valid = all_valid & (!used[i] | v);
        all_end = all_end & (!used[i] | end);
        // What a winner carries on: rec, ref, lod (not the end flag).
        heads.push((key, d.slice(fl.leaf_lod.end() - 1, 0)));
    }
    let all_valid = all_valid.name("leaves_all_valid");
    let all_end = all_end.name("leaves_all_end");
    // The lowest key wins, the lower rank on a tie (strictly lower keys
    // replace).
    let (mut best_key, mut best_data) = heads[0];
    let mut best = lit(0, rb);
    for (j, &(key, d)) in heads.iter().enumerate().skip(1) {
        let better = key.lt(best_key);
        if j + 1 < heads.len() {
            best_key = better.mux(key, best_key);
        }
        best_data = better.mux(d, best_data);
        best = better.mux(lit(j as u64, rb), best);
    }
    let best = best.name("leaf_best");
    let best_data = best_data.name("leaf_best_data");
    let take_leaf = (all_valid & !all_end).name("leaf_take");
    for (f, &(_, _, i)) in fetchers.iter().zip(leaves_in) {
        f.connect(
            "leaves_ready",
            used[i] & all_valid & (all_end | best.eq(lit(i as u64, rb))),
        );
    }
    leaves_done.next((all_valid & all_end).mux(one, header_fire.mux(zero, leaves_done)));
    let best_lod = get(best_data, &fl.leaf_lod);
    MergedLeaves {
        done: leaves_done,
        take: take_leaf,
        data: best_data,
        lod: best_lod,
    }
}

/// What both merger bodies hand to [`finish_merger`]: the instances, the
/// header's flags (`leaf_overflow`, `count_overflow`, `fetch_err`,
/// `fetch_rank`) and the controller state `idle` is made of.
struct Tail<'a, 'm> {
    dmax: usize,
    module: crate::Instance<'m>,
    builder: crate::Instance<'m>,
    writer: crate::Instance<'m>,
    writer_mod: &'a Module,
    ml: &'a MergerLayout,
    header_fire: Signal<'m>,
    flags: [Signal<'m>; 4],
    busy: Signal<'m>,
    dropping: &'a [Signal<'m>],
}

/// The end of every merger (level modes and per-node alike): the builder's
/// levels into the writer; the writer's store ports, `nodes` and `refs`
/// straight through; its header with the merger's flags; `done`, `idle`.
fn finish_merger<'m>(m: &'m Module, t: Tail<'_, 'm>) {
    let Tail {
        dmax,
        module,
        builder,
        writer,
        writer_mod,
        ml,
        header_fire,
        flags: [leaf_over, count_over, ferr, ferr_rank],
        busy,
        dropping,
    } = t;
    let wl = &ml.writer;
    let lit = |v: u64, w: u32| m.lit(v as u128, w);
    let one = lit(1, 1);
    // ---- builder -> writer.
    for d in 0..=dmax {
        let s = format!("level{d}");
        writer.connect(&format!("{s}_valid"), builder.output(&format!("{s}_valid")));
        writer.connect(&format!("{s}_data"), builder.output(&format!("{s}_data")));
        builder.connect(&format!("{s}_ready"), writer.output(&format!("{s}_ready")));
    }
    writer.connect("done_valid", builder.output("done_valid"));
    writer.connect("done_data", builder.output("done_data"));
    builder.connect("done_ready", writer.output("done_ready"));

    // ---- the writer's ports: nodes, refs, store ports straight through;
    // header with the merger's flags.
    for (port, dir, w) in store_streams(writer_mod) {
        pass_stream(m, writer, &port, &format!("w_{port}"), dir, w);
    }
    for port in ["nodes", "refs"] {
        pass_stream(m, writer, port, port, Direction::Output, 0);
    }
    for q in writer_mod.ports() {
        let is_stream = ["_valid", "_data", "_ready"]
            .iter()
            .any(|s| q.name.ends_with(s));
        if q.direction == Direction::Output && !is_stream {
            m.output(&format!("w_{}", q.name), writer.output(&q.name));
        }
    }
    let h_valid = writer.output("header_valid");
    let h_data = writer.output("header_data");
    let header_ready = m.input("header_ready", 1);
    writer.connect("header_ready", header_ready);
    header_fire.drive(h_valid & header_ready);
    let writer_header = golden::layout::Field {
        name: "writer_header",
        offset: 0,
        width: wl.header_width,
    };
    let header = with_fields(
        m,
        lit(0, ml.header_width),
        &[
            (writer_header, h_data),
            (ml.leaf_overflow, leaf_over),
            (ml.count_overflow, count_over),
            (ml.fetch_err, ferr),
            (ml.fetch_rank, ferr_rank),
        ],
    );
    m.output("header_valid", h_valid);
    m.output("header_data", header);

    let done = m.reg("done_pulse", 1);
    done.next(header_fire);
    m.output("done", done);
    let idle = (!busy & dropping.iter().fold(one, |a, c| a & !*c)).name("merger_idle");
    m.output("idle", idle);
    m.output("module_done", module.output("done"));
}

/// The whole of a beat layout as one field from bit 0.
fn field_of(b: &BeatLayout) -> golden::layout::Field {
    golden::layout::Field {
        name: "beat",
        offset: 0,
        width: b.width,
    }
}
