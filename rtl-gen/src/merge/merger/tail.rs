//! What every merger ends with, whichever mode chose its levels.

use golden::merge::merger::MergerLayout;

use super::{pass_stream, store_port, store_streams, MergerConfig};
use crate::{Direction, Module, Signal};

/// What both merger bodies hand to [`finish_merger`]: the instances, the
/// header's flags (`leaf_overflow`, `count_overflow`, `fetch_err`,
/// `fetch_rank`) and the controller state `idle` is made of.
pub(super) struct Tail<'a, 'm> {
    pub(super) dmax: usize,
    pub(super) module: crate::Instance<'m>,
    pub(super) builder: crate::Instance<'m>,
    pub(super) writer: crate::Instance<'m>,
    pub(super) writer_mod: &'a Module,
    pub(super) store: Store<'a, 'm>,
    pub(super) ml: &'a MergerLayout,
    pub(super) header_fire: Signal<'m>,
    pub(super) header_hold: Signal<'m>,
    pub(super) header_open: Signal<'m>,
    pub(super) commands_sent: Signal<'m>,
    /// Per-node: the merge's report has reached every side it feeds (the
    /// fetchers wait for its decisions). Level modes feed no fetcher.
    pub(super) report_drained: Option<Signal<'m>>,
    /// Level modes: the top is idle only once the merging module is too.
    /// (Per-node, the next `cfg` waits for it already.)
    pub(super) module_idle: Option<Signal<'m>>,
    pub(super) flags: [Signal<'m>; 4],
    pub(super) busy: Signal<'m>,
    pub(super) dropping: &'a [Signal<'m>],
}

/// What a shared store port connects: the configuration and every
/// fetcher (instances of `fetch_mod`); the writer is the [`Tail`]'s.
pub(super) struct Store<'a, 'm> {
    pub(super) config: &'a MergerConfig,
    /// The merge's `cfg` beat, held: each fetcher's hierarchy.
    pub(super) cfg_q: Signal<'m>,
    /// The slots of the fetchers' and the writer's reads (a shared port).
    pub(super) slots: Option<super::Slots<'m>>,
    pub(super) fetchers: &'a [crate::Instance<'m>],
    pub(super) fetch_mod: &'a Module,
}

/// The end of every merger (level modes and per-node alike): the builder's
/// levels into the writer; the writer's store ports, `nodes` and `refs`
/// straight through; its header with the merger's flags; `done`, `idle`.
pub(super) fn finish_merger<'m>(m: &'m Module, t: Tail<'_, 'm>) {
    let Tail {
        dmax,
        module,
        builder,
        writer,
        writer_mod,
        store,
        ml,
        header_fire,
        header_hold,
        header_open,
        commands_sent,
        report_drained,
        module_idle,
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
    if let Some(slots) = store.slots {
        let hier = &ml.fetch.hier;
        let mut clients: Vec<_> = store
            .fetchers
            .iter()
            .enumerate()
            .map(|(i, f)| {
                let at = ml.input_offset(i) + hier.offset;
                let h = store.cfg_q.slice(at + hier.width - 1, at);
                let h = h.name(&format!("f{i}_hier"));
                let above = m
                    .concat(&[slots.fetchers, h])
                    .name(&format!("f{i}_slot_hier"));
                (*f, store.fetch_mod, above)
            })
            .collect();
        clients.push((writer, writer_mod, slots.writer));
        store_port::connect_shared(m, store.config, &clients);
    } else {
        for (port, dir, w) in store_streams(writer_mod) {
            pass_stream(m, writer, &port, &format!("w_{port}"), dir, w);
        }
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
    // The header waits until every command of the merge was issued and
    // every dropped (closing) command has sent its End: only then are the
    // flags final, and the next merge's cannot mix in. Per-node, it waits
    // for the merge's report too: its header ends the merge (`busy`), after
    // which no report beat reaches a fetcher. `header_open` is a register so
    // that the beat, once offered, stays offered.
    let no_drop = dropping.iter().fold(one, |a, c| a & !*c);
    let settled = match report_drained {
        Some(drained) => busy & commands_sent & no_drop & drained,
        None => busy & commands_sent & no_drop,
    }
    .name("merge_settled");
    header_open.next(header_fire.mux(lit(0, 1), header_open | settled));
    let h_valid = (writer.output("header_valid") & header_open).name("header_offered");
    let h_data = writer.output("header_data");
    let header_ready = m.input("header_ready", 1);
    writer.connect("header_ready", header_ready & header_open);
    header_fire.drive(h_valid & header_ready);
    header_hold.drive(h_valid & !header_ready);
    let writer_header = golden::layout::Field {
        name: "writer_header",
        offset: 0,
        width: wl.header.width(),
    };
    let header = lit(0, ml.header.width()).with_fields(&[
        (writer_header, h_data),
        (ml.leaf_overflow, leaf_over),
        (ml.count_overflow, count_over),
        (ml.fetch_err, ferr),
        (ml.fetch_rank, ferr_rank),
    ]);
    m.output("header_valid", h_valid);
    m.output("header_data", header);

    let done = m.reg("done_pulse", 1);
    done.next(header_fire);
    m.output("done", done);
    let idle = match module_idle {
        Some(mi) => !busy & no_drop & mi,
        None => !busy & no_drop,
    }
    .name("merger_idle");
    m.output("idle", idle);
    m.output("module_done", module.output("done"));
}
