//! The merger of a `per-node:N/D` configuration (SPEC 8.15, per-node mode).

use golden::merge::fetcher::FetchLayout;
use golden::merge::level_choice::unit::rank_bits;
use golden::merge::merge_level::unit::{base_kind, level_kind, BeatLayout};
use golden::merge::merger::MergerLayout;
use golden::merge::per_node::unit::PerNodeLayout;
use golden::params::Params;

use super::leaf_merge::{merge_leaves, LeafInputs, MergedLeaves};
use super::tail::{finish_merger, Store, Tail};
use super::{
    cfg_beats, field_of, get, hierarchy_merger_name, pass_stream, range_good, shared_store, shell,
    store_streams, MergerConfig, Shell,
};
use crate::merge::{fetcher_per_node_unit, record_writer_unit};
use crate::DropFifo;
use crate::{Module, Signal};

/// The merger of a `per-node:N/D` configuration (SPEC 8.15, per-node mode):
/// every used fetcher gets one per-node command at `lo` (references, the
/// leaves above `lo`, last) and the module's `report` (the narrow beat of
/// [`golden::merge::fetcher::PerNodeFetchLayout`]); the module's `out`
/// nodes of every pass go into the FIFO of their LOD (the leaves above `lo`
/// into theirs), its reference beats to the writer's `crefs`. The builder
/// sees the base only once the module is done: a shallower pass's nodes
/// cannot pass the builder's stage before every deeper level is known.
pub(super) fn per_node_merger_unit(c: &MergerConfig) -> Result<Module, String> {
    let p = &c.design.params;
    let k = c.design.inputs;
    let ml = MergerLayout::new(p, k, c.sizes.capacity_bits).map_err(|e| e.to_string())?;
    let fl = FetchLayout::per_node(p);
    let m = Module::new(&hierarchy_merger_name(c));
    let lit = |v: u64, w: u32| m.lit(v as u128, w);
    let fetch_mod = fetcher_per_node_unit(p, &c.fetch_sizes());
    let writer_mod = record_writer_unit(p, c.sizes.capacity_bits).map_err(|e| e.to_string())?;
    let s = shell(&m, c, &ml, &fetch_mod, &writer_mod, false);
    let good_in =
        range_good(&m, c, get(s.cfg.data, &ml.lo), get(s.cfg.data, &ml.hi)).name("good_in");
    let good = range_good(&m, c, s.lo, s.hi).name("range_good");
    let cw = ml.count.width;
    let used_in: Vec<Signal> = (0..k).map(|i| s.count_in.gt(lit(i as u64, cw))).collect();
    let used: Vec<Signal> = (0..k)
        .map(|i| s.count_q.gt(lit(i as u64, cw)).name(&format!("used{i}")))
        .collect();

    // ---- the module's end: its `done` pulse (after the last pass's End
    // left `out`, or after a refusal's report beat).
    let finished = m.reg("module_finished", 1);
    finished
        .next((s.busy & s.module.output("done")).mux(s.one, s.header_fire.mux(s.zero, finished)));
    cfg_beats(&m, p, &ml, &s);
    let g = Merge {
        used_in: &used_in,
        used: &used,
        good_in,
        good,
        finished,
    };
    let (next_pass, report_drained) = report_fork(&m, p, &fl, &s, &g);
    let (ferr, ferr_rank, leaves_in) = inputs(&m, c, &ml, &fl, &s, &g, next_pass, &fetch_mod);

    // ---- the leaves above lo: k-way merge by (LOD, Morton, rank).
    let merged = merge_leaves(
        &m,
        LeafInputs {
            fl: &fl,
            busy: s.busy,
            header_fire: s.header_fire,
            used: &used,
            leaves_in: &leaves_in,
            fetchers: &s.fetchers,
            rb: rank_bits(k),
        },
    );
    let (leaf_over, count_over) = route_out(&m, c, &ml, &fl, &s, &g, &merged);
    finish_merger(
        &m,
        Tail {
            dmax: p.max_lod as usize,
            module: s.module,
            builder: s.builder,
            writer: s.writer,
            writer_mod: &writer_mod,
            store: Store {
                config: c,
                cfg_q: s.cfg_q,
                slots: s.slots,
                fetchers: &s.fetchers,
                fetch_mod: &fetch_mod,
            },
            ml: &ml,
            header_fire: s.header_fire,
            header_hold: s.header_hold,
            header_open: s.header_open,
            commands_sent: s.commands_sent,
            report_drained: Some(report_drained),
            module_idle: None,
            flags: [leaf_over, count_over, ferr, ferr_rank],
            busy: s.busy,
            dropping: &s.dropping,
        },
    );
    Ok(m)
}

/// What the merge held is: the inputs it uses (of the `cfg` beat arriving,
/// and of the merge held), whether its candidate range is good, and whether
/// the module is done.
struct Merge<'a, 'm> {
    used_in: &'a [Signal<'m>],
    used: &'a [Signal<'m>],
    good_in: Signal<'m>,
    good: Signal<'m>,
    finished: Signal<'m>,
}

/// The module's `report`: an eager fork to the top's `report` and, as the
/// narrow beat, to every fetcher running the per-node command. Each side
/// takes the beat once (`taken`); the module's beat leaves when all have.
/// Returns the clock a `pass_end` beat with `more` leaves, and whether the
/// merge's last report beat (the `pass_end` without `more` that ends every
/// merge, a refusal's included) has left: the fetchers are fed only while
/// the merge is busy, so its header waits for that.
fn report_fork<'m>(
    m: &'m Module,
    p: &Params,
    fl: &FetchLayout,
    s: &Shell<'m>,
    g: &Merge<'_, 'm>,
) -> (Signal<'m>, Signal<'m>) {
    let fpn = fl.pn.as_ref().expect("a per-node fetch layout");
    let pl = PerNodeLayout::new(p);
    let lit = |v: u64, w: u32| m.lit(v as u128, w);
    let (zero, one, module, busy, fetchers) = (s.zero, s.one, s.module, s.busy, &s.fetchers);
    let (used, good) = (g.used, g.good);
    let rep_v = module.output("report_valid");
    let rep_d = module.output("report_data");
    let narrow = lit(0, fpn.report.width())
        .with_fields(
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
    let pass_end = get(rep_d, &pl.pass_end);
    let more = get(rep_d, &pl.more);
    let next_pass = (rep_fire & pass_end & more).name("next_pass");
    let drained = m.reg("report_drained", 1);
    drained.next(
        s.cfg_fire
            .mux(zero, (rep_fire & pass_end & !more).mux(one, drained)),
    );
    (next_pass, drained)
}

/// Per input: its cfg, its one command, its stream into the module and its
/// store ports; returns the first fetch error, its input's rank, and each
/// fetcher's `leaves` stream.
#[allow(clippy::too_many_arguments, clippy::type_complexity)]
fn inputs<'m>(
    m: &'m Module,
    c: &MergerConfig,
    ml: &MergerLayout,
    fl: &FetchLayout,
    s: &Shell<'m>,
    g: &Merge<'_, 'm>,
    next_pass: Signal<'m>,
    fetch_mod: &Module,
) -> (Signal<'m>, Signal<'m>, Vec<(Signal<'m>, Signal<'m>, usize)>) {
    let p = &c.design.params;
    let k = c.design.inputs;
    let shared = shared_store(c);
    let fpn = fl.pn.as_ref().expect("a per-node fetch layout");
    let pl = PerNodeLayout::new(p);
    let inb = BeatLayout::input(p);
    let lit = |v: u64, w: u32| m.lit(v as u128, w);
    let (zero, one, module, header_fire) = (s.zero, s.one, s.module, s.header_fire);
    let (cfg_fire, cfg_q, lo) = (s.cfg_fire, s.cfg_q, s.lo);
    let (fetchers, dropping) = (&s.fetchers, &s.dropping);
    let (used_in, used, good_in, good) = (g.used_in, g.used, g.good_in, g.good);
    let rb = rank_bits(k);
    let ferr = m.reg("fetch_err", fl.err.width);
    let ferr_rank = m.reg("fetch_rank", rb);
    let mut ferr_next = header_fire.mux(lit(0, fl.err.width), ferr);
    let mut ferr_rank_next = header_fire.mux(lit(0, rb), ferr_rank);
    let end_beat = lit(0, inb.width()).with_fields(&[(inb.kind, lit(level_kind::END, 2))]);
    let end_in = lit(0, pl.input.width()).with_fields(&[(field_of(&inb), end_beat)]);
    let mut leaves_in = Vec::new();
    let mut sent = one;
    for (i, f) in fetchers.iter().enumerate() {
        let fcfg_pend = m.reg(&format!("fetch{i}_cfg_pending"), 1);
        f.connect("cfg_valid", fcfg_pend);
        let off = ml.input_offset(i);
        f.connect("cfg_data", cfg_q.slice(off + fl.cfg.width() - 1, off));
        let fcfg_fire = fcfg_pend & f.output("cfg_ready");
        fcfg_pend.next(cfg_fire.mux(used_in[i], fcfg_fire.mux(zero, fcfg_pend)));

        // One command per merge: per-node at lo on a good range, else the
        // closing command (its beats dropped).
        let cmd_pend = m.reg(&format!("cmd{i}_pending"), 1);
        let cmd_data = lit(0, fl.cmd.width()).with_fields(&[
            (fl.lod, lo),
            (fl.send_refs, good),
            (fl.send_leaves, good),
            (fl.last, one),
            (fl.from, lo),
            (fpn.per_node, good),
        ]);
        f.connect("cmd_valid", cmd_pend);
        f.connect("cmd_data", cmd_data);
        let cmd_fire = cmd_pend & f.output("cmd_ready");
        cmd_pend.next(cfg_fire.mux(used_in[i], cmd_fire.mux(zero, cmd_pend)));
        sent = sent & !cmd_pend;

        // The module's in<i>: the fetcher's beats (err dropped, probe
        // kept), or for an unused input one End per pass: owed from the
        // start and after every `pass_end` beat with `more`.
        let in_ready = module.output(&format!("in{i}_ready"));
        let fo_valid = f.output("out_valid");
        let fo_data = f.output("out_data");
        let fo_err = get(fo_data, &fl.err);
        let fo_beat = fo_data.slice(fl.beat.width() - 1, 0);
        let fo_end = get(fo_beat, &inb.kind).eq(level_kind::END);
        let fo_in = lit(0, pl.input.width()).with_fields(&[
            (field_of(&inb), fo_beat),
            (pl.probe, get(fo_data, &fpn.probe)),
        ]);
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
        // (A shared port connects them in `finish_merger`.)
        for (port, dir, w) in store_streams(fetch_mod).into_iter().filter(|_| !shared) {
            pass_stream(m, *f, &port, &format!("f{i}_{port}"), dir, w);
        }
        leaves_in.push((f.output("leaves_valid"), f.output("leaves_data"), i));
    }
    s.commands_sent.drive(sent);
    ferr.next(s.header_hold.mux(ferr, ferr_next));
    ferr_rank.next(s.header_hold.mux(ferr_rank, ferr_rank_next));

    (ferr, ferr_rank, leaves_in)
}

/// The module's out: reference beats to crefs, nodes into the FIFO of their
/// LOD, each pass's End dropped (the builder's End comes from the FIFOs
/// once the module is done); the leaves above `lo` into theirs. Returns the
/// leaf FIFOs' and the module's count overflow flags.
fn route_out<'m>(
    m: &'m Module,
    c: &MergerConfig,
    ml: &MergerLayout,
    fl: &FetchLayout,
    s: &Shell<'m>,
    g: &Merge<'_, 'm>,
    merged: &MergedLeaves<'m>,
) -> (Signal<'m>, Signal<'m>) {
    let p = &c.design.params;
    let wl = &ml.writer;
    let inb = BeatLayout::input(p);
    let outb = BeatLayout::output(p);
    let lb = p.lod_bits();
    let dmax = p.max_lod as usize;
    let lit = |v: u64, w: u32| m.lit(v as u128, w);
    let (zero, one, module, builder, writer, header_fire, busy, lo) = (
        s.zero,
        s.one,
        s.module,
        s.builder,
        s.writer,
        s.header_fire,
        s.busy,
        s.lo,
    );
    let (good, finished) = (g.good, g.finished);
    let MergedLeaves {
        done: leaves_done,
        take: take_leaf,
        data: best_data,
        lod: best_lod,
    } = *merged;
    let end_beat = lit(0, inb.width()).with_fields(&[(inb.kind, lit(level_kind::END, 2))]);
    let nl = &fl.node;
    let leaf_beat = lit(0, inb.width()).with_fields(&[
        (inb.rec, get(best_data, &fl.leaf_rec)),
        (inb.refer, get(best_data, &fl.leaf_ref)),
        (inb.kind, lit(base_kind::REUSED, 2)),
    ]);

    let mo_valid = module.output("out_valid");
    let mo_data = module.output("out_data");
    let mo_kind = get(mo_data, &outb.kind);
    let mo_ref = mo_kind.eq(base_kind::REF).name("out_is_ref");
    let mo_end = mo_kind.eq(base_kind::END).name("out_is_end");
    let mo_err = get(mo_data, outb.err.as_ref().expect("an output beat has err"));
    let mo_refer = get(mo_data, &outb.refer);
    let mo_rec = get(mo_data, &outb.rec);
    let mo_lod = mo_rec.view(nl.lod());
    let mo_beat = lit(0, inb.width()).with_fields(&[
        (inb.rec, mo_rec),
        (inb.refer, mo_refer),
        (inb.kind, mo_kind),
    ]);
    let mo_node = (mo_valid & !mo_ref & !mo_end).name("out_is_node");

    // crefs: the reference beats of every pass, then End once the module
    // is done (a refused merge: End alone).
    let csent = m.reg("crefs_end_sent", 1);
    let cref_ready = writer.output("crefs_ready");
    let cref_ref = (mo_valid & mo_ref).name("cref_is_ref");
    let cref_valid = !csent & busy & (cref_ref | finished);
    let cref_data = lit(0, wl.crefs.width()).with_fields(&[
        (wl.cref, cref_ref.mux(mo_refer, lit(0, mo_refer.width()))),
        (wl.cref_end, !cref_ref),
    ]);
    writer.connect("crefs_valid", cref_valid);
    writer.connect("crefs_data", cref_data);
    let cref_fire = cref_valid & cref_ready;
    csent.next((cref_fire & !cref_ref).mux(one, header_fire.mux(zero, csent)));
    let mo_ready = mo_ref.mux(cref_ready & !csent, one);
    module.connect("out_ready", mo_ready);
    let count_over = m.reg("count_overflow", 1);
    let created = mo_kind.eq(base_kind::CREATED);
    let count_next =
        (mo_valid & mo_ready & created & mo_err).mux(one, header_fire.mux(zero, count_over));
    count_over.next(s.header_hold.mux(count_over, count_next));

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
            m,
            &format!("base{d}_fifo"),
            &format!("base{d}"),
            inb.width(),
            cb,
        );
        let (empty, full) = (q.empty(), q.full());
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
    leaf_over.next(s.header_hold.mux(leaf_over, over_next));
    let leaf_over = leaf_over.name("leaf_overflow_q");

    (leaf_over, count_over)
}
