//! The merger of a level-choice configuration (`overlap`, `fixed`,
//! `below-top`, `proportion`; SPEC 8.15): in overlap mode a count pass over
//! `lo..=hi` first, then the module's choice and one merge pass at that level.

use golden::merge::level_choice::unit::rank_bits;
use golden::merge::merge_level::unit::{base_kind, level_kind, BeatLayout};
use golden::merge::merge_module::TopLayout;
use golden::merge::merger::MergerLayout;
use golden::params::Params;

use super::leaf_merge::{merge_leaves, LeafInputs, MergedLeaves};
use super::tail::{finish_merger, Store, Tail};
use super::{
    cfg_beats, get, hierarchy_merger_name, pass_stream, phase, range_good, shared_store, shell,
    store_streams, MergerConfig, Shell,
};
use crate::merge::{fetcher_unit, record_writer_unit};
use crate::DropFifo;
use crate::{Module, Signal};

/// The count pass runs in overlap mode on a good range (the merging
/// module's own test, 8.10).
fn counts_pass<'m>(m: &'m Module, c: &MergerConfig, lo: Signal<'m>, hi: Signal<'m>) -> Signal<'m> {
    match c.design.threshold() {
        None => m.lit(0, 1),
        Some(_) => range_good(m, c, lo, hi),
    }
}

/// The merger of a level-choice configuration: [`super::hierarchy_merger_unit`]
/// once `c` is validated and its mode is not per-node.
pub(super) fn level_merger_unit(c: &MergerConfig) -> Result<Module, String> {
    let p = &c.design.params;
    let k = c.design.inputs;
    let ml = MergerLayout::new(p, k, c.sizes.capacity_bits).map_err(|e| e.to_string())?;
    let m = Module::new(&hierarchy_merger_name(c));
    let lit = |v: u64, w: u32| m.lit(v as u128, w);
    let fetch_mod = fetcher_unit(p, &c.fetch_sizes());
    let writer_mod = record_writer_unit(p, c.sizes.capacity_bits).map_err(|e| e.to_string())?;
    // Consecutive merges overlap; behind a shared port the older merge's
    // writer and the newer's fetchers then read through one `store_req`,
    // whose `slot` says whose read each is.
    let s = shell(&m, c, &ml, &fetch_mod, &writer_mod, true);
    let counting_in =
        counts_pass(&m, c, get(s.cfg.data, &ml.lo), get(s.cfg.data, &ml.hi)).name("count_pass");
    let cw = ml.count.width;
    let used_in: Vec<Signal> = (0..k).map(|i| s.count_in.gt(lit(i as u64, cw))).collect();
    let used: Vec<Signal> = (0..k)
        .map(|i| s.count_q.gt(lit(i as u64, cw)).name(&format!("used{i}")))
        .collect();
    let ch = choice(&m, p, &s);
    cfg_beats(&m, p, &ml, &s);
    let u = Used {
        used_in: &used_in,
        used: &used,
        counting_in,
    };
    let (ferr, ferr_rank, leaves_in) = inputs(&m, c, &ml, &s, &ch, &u, &fetch_mod);

    // ---- the leaves above m: k-way merge by (LOD, Morton, rank).
    let merged = merge_leaves(
        &m,
        LeafInputs {
            fl: &ml.fetch,
            busy: s.busy,
            header_fire: s.header_fire,
            used: &used,
            leaves_in: &leaves_in,
            fetchers: &s.fetchers,
            rb: rank_bits(k),
        },
    );
    let (leaf_over, count_over) = route_out(&m, c, &ml, &s, &ch, &merged);
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
            report_drained: None,
            module_idle: Some(s.module.output("idle")),
            flags: [leaf_over, count_over, ferr, ferr_rank],
            busy: s.busy,
            dropping: &s.dropping,
        },
    );
    Ok(m)
}

/// The merging level the module chose, read off its report on its way out.
/// The choice, the `base{d}` and `crefs` ends and the leaves belong to the
/// older merge until its header leaves: the newer merge's choice waits.
struct Choice<'m> {
    /// The report's choice beat has passed.
    known: Signal<'m>,
    /// The choice beat passes now.
    seen: Signal<'m>,
    /// What the choice beat passing now says: not an error, and its level.
    seen_ok: Signal<'m>,
    seen_level: Signal<'m>,
    /// The choice is not an error.
    ok: Signal<'m>,
    /// The merging level `m`.
    level: Signal<'m>,
    /// `known & ok`: the merge goes on at `level`.
    merging: Signal<'m>,
}

fn choice<'m>(m: &'m Module, p: &Params, s: &Shell<'m>) -> Choice<'m> {
    let tl = TopLayout::new(p);
    let lb = p.lod_bits();
    let (zero, one, module, header_fire) = (s.zero, s.one, s.module, s.header_fire);
    let report_ready = m.input("report_ready", 1);
    let report_data = module.output("report_data");
    // The newer of two merges passes its choice once the older's header
    // has left: its count pass runs while the older's builder and writer
    // drain, and the routing below is the older's until then.
    let choice_waits = (s.queued & get(report_data, &tl.chosen).eq(1)).name("choice_waits");
    let report_valid = module.output("report_valid") & !choice_waits;
    module.connect("report_ready", report_ready & !choice_waits);
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

    Choice {
        known,
        seen: chosen_beat,
        seen_ok: get(report_data, &tl.err).eq(0),
        seen_level: get(report_data, &tl.lod),
        ok,
        level,
        merging,
    }
}

/// Which inputs the merge uses (of the `cfg` beat arriving, and of the
/// merge held), and whether it starts with a count pass.
struct Used<'a, 'm> {
    used_in: &'a [Signal<'m>],
    used: &'a [Signal<'m>],
    counting_in: Signal<'m>,
}

/// Per input: its cfg, its commands, its stream into the module and its
/// store ports; returns the first fetch error, its input's rank, and each
/// fetcher's `leaves` stream.
#[allow(clippy::type_complexity)]
fn inputs<'m>(
    m: &'m Module,
    c: &MergerConfig,
    ml: &MergerLayout,
    s: &Shell<'m>,
    ch: &Choice<'m>,
    u: &Used<'_, 'm>,
    fetch_mod: &Module,
) -> (Signal<'m>, Signal<'m>, Vec<(Signal<'m>, Signal<'m>, usize)>) {
    let p = &c.design.params;
    let k = c.design.inputs;
    let shared = shared_store(c);
    let fl = &ml.fetch;
    let inb = BeatLayout::input(p);
    let lb = p.lod_bits();
    let lit = |v: u64, w: u32| m.lit(v as u128, w);
    let (zero, one, module) = (s.zero, s.one, s.module);
    let (cfg, cfg_fire, cfg_q, lo, hi) = (s.cfg, s.cfg_fire, s.cfg_q, s.lo, s.hi);
    let (fetchers, dropping) = (&s.fetchers, &s.dropping);
    let (known, merging, level) = (ch.known, ch.merging, ch.level);
    let (used_in, used, counting_in) = (u.used_in, u.used, u.counting_in);
    let rb = rank_bits(k);
    let ferr = m.reg("fetch_err", fl.err.width);
    let ferr_rank = m.reg("fetch_rank", rb);
    let mut ferr_next = s.flag_clear.mux(lit(0, fl.err.width), ferr);
    let mut ferr_rank_next = s.flag_clear.mux(lit(0, rb), ferr_rank);
    let end_beat = lit(0, inb.width()).with_fields(&[(inb.kind, lit(level_kind::END, 2))]);
    let mut leaves_in = Vec::new();
    let mut sent = one;
    for (i, f) in fetchers.iter().enumerate() {
        // The fetcher's `cfg` beat goes out in the clock the merge's is
        // taken, its data then straight from the `cfg` beat (from `cfg_q`
        // while it waits): the count pass's root reads start a clock sooner.
        let fcfg_pend = m.reg(&format!("fetch{i}_cfg_pending"), 1);
        let fcfg_now = (cfg_fire & used_in[i]).name(&format!("fetch{i}_cfg_now"));
        let fcfg_valid = fcfg_pend | fcfg_now;
        f.connect("cfg_valid", fcfg_valid);
        let off = ml.input_offset(i);
        let slice = |d: Signal<'m>| d.slice(off + fl.cfg.width() - 1, off);
        f.connect("cfg_data", fcfg_pend.mux(slice(cfg_q), slice(cfg.data)));
        let fcfg_fire = fcfg_valid & f.output("cfg_ready");
        fcfg_pend.next(fcfg_fire.mux(zero, fcfg_now.mux(one, fcfg_pend)));

        let ph = m.reg(&format!("phase{i}"), phase::BITS);
        let phases = m.states(phase::BITS, phase::STATES);
        let in_ph = |v: u64| phases.is(ph, v);
        sent = sent & in_ph(phase::DONE);
        // The candidate level an unused input's next `End` stands for.
        let cmd_lod = m.reg(&format!("cmd_lod{i}"), lb);
        let count_ph = in_ph(phase::COUNT);
        let final_ph = in_ph(phase::FINAL);
        // The merge-pass (or closing) command goes out in the clock the
        // choice passes (`final_now`, from the report beat), and from FINAL
        // while it waits: the walk to `m` starts a clock sooner.
        let final_now = (in_ph(phase::WAIT) & ch.seen).name(&format!("final_now{i}"));
        let final_cmd = final_ph | final_now;
        let merging_cmd = final_now.mux(ch.seen_ok, merging);
        let level_cmd = final_now.mux(ch.seen_level, level);
        let lod = count_ph.mux(hi, merging_cmd.mux(level_cmd, lo));
        let cmd_data = lit(0, fl.cmd.width()).with_fields(&[
            (fl.lod, lod),
            (fl.send_refs, final_cmd & merging_cmd),
            // The leaves above m come with level m (SPEC 8.15: no
            // deadlock, the fetcher ends `leaves` before level m).
            (fl.send_leaves, final_cmd & merging_cmd),
            (fl.last, final_cmd),
            // The count pass sends lo..=hi from one walk; the other
            // commands one level.
            (fl.from, count_ph.mux(lo, lod)),
        ]);
        let issuing = (count_ph | final_cmd).name(&format!("issuing{i}"));
        f.connect("cmd_valid", used[i] & issuing);
        f.connect("cmd_data", cmd_data);
        let cmd_fire = used[i] & issuing & f.output("cmd_ready");

        // The module's in<i>: the fetcher's beats, or one End per pass for
        // an unused input; the closing command's beats are dropped.
        let in_ready = module.output(&format!("in{i}_ready"));
        let fo_valid = f.output("out_valid");
        let fo_data = f.output("out_data");
        let fo_err = get(fo_data, &fl.err);
        let fo_beat = fo_data.slice(fl.beat.width() - 1, 0);
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
            (used[i] | last_count).mux(phases.code(phase::WAIT), ph),
            phases.code(phase::DONE),
        );
        let after_choice = phases.code(phase::FINAL);
        // A merge's phases stay DONE until the next `cfg`: with merges
        // overlapping, the older's header leaves during the newer's passes.
        // Leave WAIT in the clock the choice passes, not the next: the
        // merge pass's commands go out a clock sooner. While two merges
        // are taken, `known` is the older's.
        let own_choice = (known & !s.queued) | ch.seen;
        let ph_next = cfg_fire.mux(
            counting_in.mux(phases.code(phase::COUNT), phases.code(phase::WAIT)),
            step.mux(
                after_step,
                (in_ph(phase::WAIT) & own_choice).mux(after_choice, ph),
            ),
        );
        ph.next(ph_next);
        cmd_lod.next(cfg_fire.mux(
            get(cfg.data, &ml.lo),
            (step & count_ph).mux(cmd_lod.add(1, lb), cmd_lod),
        ));
        let drop_issued = cmd_fire & final_cmd & !merging_cmd;
        dropping[i].next(drop_issued.mux(one, (fo_fire & fo_end).mux(zero, dropping[i])));

        // The store ports (every `*_req` / `*_resp` stream), straight through.
        // (A shared port connects them in `finish_merger`.)
        for (port, dir, w) in store_streams(fetch_mod).into_iter().filter(|_| !shared) {
            pass_stream(m, *f, &port, &format!("f{i}_{port}"), dir, w);
        }
        leaves_in.push((f.output("leaves_valid"), f.output("leaves_data"), i));
    }
    s.commands_sent.drive(sent);
    ferr.next(s.flag_hold.mux(ferr, ferr_next));
    ferr_rank.next(s.flag_hold.mux(ferr_rank, ferr_rank_next));
    let ferr = s.shown_flag(m, ferr, "fetch_err");
    let ferr_rank = s.shown_flag(m, ferr_rank, "fetch_rank");

    (ferr, ferr_rank, leaves_in)
}

/// The routing of the module's `out`: reference beats to the writer's
/// `crefs`, nodes at `m` to the builder's base of that LOD, the leaves
/// above `m` through a FIFO per LOD, `End` below `m` or when refused;
/// returns the leaf FIFOs' and the module's count overflow flags.
fn route_out<'m>(
    m: &'m Module,
    c: &MergerConfig,
    ml: &MergerLayout,
    s: &Shell<'m>,
    ch: &Choice<'m>,
    merged: &MergedLeaves<'m>,
) -> (Signal<'m>, Signal<'m>) {
    let p = &c.design.params;
    let (fl, wl) = (&ml.fetch, &ml.writer);
    let inb = BeatLayout::input(p);
    let outb = BeatLayout::output(p);
    let lb = p.lod_bits();
    let dmax = p.max_lod as usize;
    let lit = |v: u64, w: u32| m.lit(v as u128, w);
    let (zero, one, module, builder, writer, header_fire) =
        (s.zero, s.one, s.module, s.builder, s.writer, s.header_fire);
    let (known, ok, level, merging) = (ch.known, ch.ok, ch.level, ch.merging);
    let MergedLeaves {
        done: leaves_done,
        take: take_leaf,
        data: best_data,
        lod: best_lod,
    } = *merged;
    // A FIFO word: the leaves beat's `rec` and `ref` (from bit 0).
    let word_w = fl.leaf_ref.end().max(fl.leaf_rec.end());
    let word = best_data.slice(word_w - 1, 0);
    let end_beat = lit(0, inb.width()).with_fields(&[(inb.kind, lit(level_kind::END, 2))]);
    let mo_valid = module.output("out_valid");
    let mo_data = module.output("out_data");
    let mo_kind = get(mo_data, &outb.kind);
    let mo_ref = mo_kind.eq(base_kind::REF).name("out_is_ref");
    let mo_end = mo_kind.eq(base_kind::END).name("out_is_end");
    let mo_err = get(mo_data, outb.err.as_ref().expect("an output beat has err"));
    let mo_refer = get(mo_data, &outb.refer);
    let mo_beat = lit(0, inb.width()).with_fields(&[
        (inb.rec, get(mo_data, &outb.rec)),
        (inb.refer, mo_refer),
        (inb.kind, mo_kind),
    ]);

    // crefs: the reference beats, then End (a refused merge: End alone).
    let csent = m.reg("crefs_end_sent", 1);
    let cref_ready = writer.output("crefs_ready");
    let cref_valid = !csent & known & (!ok | (mo_valid & (mo_ref | mo_end)));
    let cref_is_end = !ok | mo_end;
    let cref_data = lit(0, wl.crefs.width()).with_fields(&[
        (
            wl.cref,
            (ok & mo_ref).mux(mo_refer, lit(0, mo_refer.width())),
        ),
        (wl.cref_end, cref_is_end),
    ]);
    writer.connect("crefs_valid", cref_valid);
    writer.connect("crefs_data", cref_data);
    let cref_fire = cref_valid & cref_ready;
    csent.next((cref_fire & cref_is_end).mux(one, header_fire.mux(zero, csent)));

    // base{d}: the module's nodes at m, a leaf FIFO above m, End below m or
    // when refused.
    let cb = c.sizes.leaf_bits;
    let mut base_m_ready = zero;
    let mut base_m_sent = zero;
    // Leaf and count overflow come from merge passes alone, and those never
    // overlap (the newer merge's choice waits for the older's header): so
    // these flags start afresh as the header leaves and need no copy.
    let leaf_over = m.reg("leaf_overflow", 1);
    let mut over_next = header_fire.mux(zero, leaf_over);
    let reused_kind = lit(base_kind::REUSED, 2);
    for d in 0..=dmax {
        let dl = lit(d as u64, lb);
        let bsent = m.reg(&format!("base{d}_end_sent"), 1);
        let ready = builder.output(&format!("base{d}_ready"));
        let at_m = (merging & level.eq(dl)).name(&format!("base{d}_at_m"));
        let (valid, data, is_end) = if d < dmax {
            // The FIFO of LOD d, read once the leaves are complete (8.15 step 4).
            let q = DropFifo::new(m, &format!("leaves{d}"), &format!("leaves{d}"), word_w, cb);
            let (empty, full) = (q.empty(), q.full());
            let push = (take_leaf & best_lod.eq(dl)).name(&format!("leaves{d}_push"));
            q.write(word, push);
            over_next = (push & full).mux(one, over_next);
            let head = q.head();
            let above = (merging & dl.lt(level)).name(&format!("base{d}_above_m"));
            let leaf_beat = lit(0, inb.width()).with_fields(&[
                (inb.rec, get(head, &fl.leaf_rec)),
                (inb.refer, get(head, &fl.leaf_ref)),
                (inb.kind, reused_kind),
            ]);
            let fifo_end = (empty & leaves_done).name(&format!("leaves{d}_end"));
            let from_fifo = (above & !empty).name(&format!("leaves{d}_head_out"));
            let valid =
                !bsent & (at_m & mo_valid & !mo_ref | above & leaves_done | known & !at_m & !above);
            let data = at_m.mux(mo_beat, from_fifo.mux(leaf_beat, end_beat));
            let is_end = at_m.mux(mo_end, above.mux(fifo_end, one));
            let pop = (valid & ready & above & !empty).name(&format!("leaves{d}_pop"));
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
    leaf_over.next(s.header_hold.mux(leaf_over, over_next));
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
    let count_next =
        (mo_valid & mo_ready & created & mo_err).mux(one, header_fire.mux(zero, count_over));
    count_over.next(s.header_hold.mux(count_over, count_next));

    (leaf_over, count_over)
}
