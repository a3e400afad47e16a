//! The command stage: `cfg` (the input's header and translation entry,
//! kept until the last command) and `cmd` (one walk), the phase register,
//! and START's header checks.

use golden::merge::fetcher::fetch_err;

use super::parts::{Move, Next};
use super::{ph, Ctx};
use crate::{Signal, Stream};

/// What `cfg` and `cmd` set up, read by every later stage.
pub(super) struct Command<'m> {
    pub(super) phase: Signal<'m>,
    /// The phase's next value, set by the stages in priority order.
    pub(super) n_phase: Next<'m>,
    pub(super) cfg_have: Signal<'m>,
    pub(super) cfg_fire: Signal<'m>,
    pub(super) cmd_fire: Signal<'m>,
    /// PREFETCH only: the command to walk is taken.
    pub(super) in_hand: Option<Signal<'m>>,
    /// The first level of the command being taken (`first` loads it).
    pub(super) first_in: Signal<'m>,
    pub(super) idle: Signal<'m>,
    pub(super) start: Signal<'m>,
    pub(super) roots_ph: Signal<'m>,
    pub(super) walk: Signal<'m>,
    // From `cfg`.
    pub(super) hier: Signal<'m>,
    pub(super) roots: Signal<'m>,
    pub(super) top: Signal<'m>,
    pub(super) nodes: Signal<'m>,
    pub(super) refs: Signal<'m>,
    pub(super) entry_ok: Signal<'m>,
    pub(super) mv: Move<'m>,
    // From `cmd`.
    pub(super) lod: Signal<'m>,
    pub(super) send_refs: Signal<'m>,
    pub(super) send_leaves: Signal<'m>,
    pub(super) last: Signal<'m>,
    /// The first level sent.
    pub(super) first: Signal<'m>,
    /// The per-node command's bit (per-node fetchers only).
    pub(super) per_node: Option<Signal<'m>>,
}

impl<'m> Command<'m> {
    /// High in phase `s`.
    pub(super) fn is(&self, cx: &Ctx<'_, 'm>, s: u64) -> Signal<'m> {
        cx.m.states(ph::BITS, ph::STATES).is(self.phase, s)
    }

    /// The phase after the roots are ready (or START found the header
    /// bad): WALK with the command in hand, else ARMED to wait for it.
    pub(super) fn roots_ready(&self, cx: &Ctx<'_, 'm>) -> Signal<'m> {
        match self.in_hand {
            Some(h) => h.mux(goto(cx, ph::WALK), goto(cx, ph::ARMED)),
            None => goto(cx, ph::WALK),
        }
    }
}

/// Whether the fetcher reads a command's roots before its `cmd` beat, as
/// soon as the `cfg` beat, or the command before (not the `cfg`'s last),
/// allows (PREFETCH, docs/hardware.md 8.13): the level fetcher; the
/// per-node fetcher's commands start from `cmd` as before.
pub(super) fn prefetches(cx: &Ctx<'_, '_>) -> bool {
    cx.l.pn.is_none()
}

/// The phase code of `s`.
pub(super) fn goto<'m>(cx: &Ctx<'_, 'm>, s: u64) -> Signal<'m> {
    cx.m.states(ph::BITS, ph::STATES).code(s)
}

/// The `cfg` and `cmd` streams and the registers they set.
pub(super) fn command<'m>(cx: &Ctx<'_, 'm>) -> Command<'m> {
    let (m, l, lb) = (cx.m, cx.l, cx.lb);
    let phase = m.reg("phase", ph::BITS);
    let phases = m.states(ph::BITS, ph::STATES);
    let is = |s: u64| phases.is(phase, s);
    let mut n_phase = Next::new(phase);

    let cfg = Stream::input(m, "cfg", l.cfg.width());
    let cmd = Stream::input(m, "cmd", l.cmd.width());
    let cfg_have = m.reg("cfg_have", 1);
    let idle = is(ph::IDLE).name("is_idle");
    cfg.ready.drive(idle & !cfg_have);
    // A level fetcher reads a command's roots before the command comes
    // (PREFETCH) and takes it from START to ARMED.
    let armed = prefetches(cx).then(|| is(ph::ARMED).name("is_armed"));
    let cmd_have = armed.map(|_| m.reg("cmd_have", 1));
    let cmd_wait = match (cmd_have, armed) {
        (Some(h), Some(a)) => (is(ph::START) | is(ph::ROOTS) | a) & !h,
        _ => idle,
    };
    cmd.ready.drive(cmd_wait & cfg_have);
    let cfg_fire = cfg.fire().name("cfg_fire");
    let cmd_fire = cmd.fire().name("cmd_fire");
    let in_hand = cmd_have.map(|h| {
        let walking = is(ph::WALK);
        h.next(walking.mux(cx.lit(0, 1), cmd_fire.mux(cx.lit(1, 1), h)));
        (h | cmd_fire).name("cmd_in_hand")
    });
    let cfg_data = cfg.data;
    let keep = |name: &str, f: &golden::layout::Field| {
        let r = m.reg(name, f.width);
        r.next_when(cfg_fire, cfg_data.view(f));
        r
    };
    let hier = keep("cfg_hier", &l.hier);
    let roots = keep("cfg_roots", &l.roots);
    let top = keep("cfg_top", &l.top);
    let nodes = keep("cfg_nodes", &l.nodes);
    let refs = keep("cfg_refs", &l.refs);
    let entry_valid = keep("cfg_entry_valid", &l.entry_valid);
    let mv = Move {
        lod: keep("cfg_entry_lod", &l.entry_lod),
        t: [0, 1, 2].map(|a| keep(&format!("cfg_entry_t{a}"), &l.entry_t[a])),
    };
    let dmax = cx.p.max_lod as u64;
    let mut entry_ok = entry_valid;
    if (1u64 << lb) - 1 > dmax {
        entry_ok = entry_ok & mv.lod.le(cx.lit(dmax, lb));
    }
    for t in &mv.t {
        // The code -2^D is never produced and is refused when read (7.3).
        entry_ok = entry_ok & t.ne(m.lit(1u128 << dmax, t.width()));
    }
    let entry_ok = entry_ok.name("entry_ok");

    let c_lod = m.reg("cmd_lod", lb);
    let c_refs = m.reg("cmd_send_refs", 1);
    let c_leaves = m.reg("cmd_send_leaves", 1);
    let c_last = m.reg("cmd_last", 1);
    c_lod.next_when(cmd_fire, cmd.data.view(&l.lod));
    c_refs.next_when(cmd_fire, cmd.data.view(&l.send_refs));
    c_leaves.next_when(cmd_fire, cmd.data.view(&l.send_leaves));
    c_last.next_when(cmd_fire, cmd.data.view(&l.last));
    // The first level sent: `min(from, lod)` (`from >= lod`: one level).
    let c_first = m.reg("cmd_first", lb);
    let cmd_from = cmd.data.view(&l.from);
    let cmd_lod = cmd.data.view(&l.lod);
    let first = cmd_from.gt(cmd_lod).mux(cmd_lod, cmd_from);
    // The per-node command's passes start at `lod` (`from` not read).
    let c_pn = l.pn.as_ref().map(|f| {
        let r = m.reg("cmd_per_node", 1);
        r.next_when(cmd_fire, cmd.data.view(&f.per_node));
        r
    });
    let first = match &l.pn {
        Some(f) => cmd.data.view(&f.per_node).mux(cmd_lod, first),
        None => first,
    };
    c_first.next_when(cmd_fire, first);
    match armed {
        Some(a) => {
            n_phase.when(cfg_fire, goto(cx, ph::START));
            n_phase.when(cmd_fire & a, goto(cx, ph::WALK));
        }
        None => n_phase.when(cmd_fire, goto(cx, ph::START)),
    }

    let walk = is(ph::WALK).name("walking");
    let start = is(ph::START);
    let roots_ph = is(ph::ROOTS);
    Command {
        phase,
        n_phase,
        cfg_have,
        cfg_fire,
        cmd_fire,
        in_hand,
        first_in: first,
        idle,
        start,
        roots_ph,
        walk,
        hier,
        roots,
        top,
        nodes,
        refs,
        entry_ok,
        mv,
        lod: c_lod,
        send_refs: c_refs,
        send_leaves: c_leaves,
        last: c_last,
        first: c_first,
        per_node: c_pn,
    }
}

/// The first error before the walk (header or root), reported by the visit
/// stage ahead of the top level; its next values are set by START and the
/// roots stage, then cleared by the visit stage.
pub(super) struct FirstErr<'m> {
    pub(super) valid: Signal<'m>,
    pub(super) code: Signal<'m>,
    pub(super) node: Signal<'m>,
    /// START found the header bad: the walk reports it and ends.
    pub(super) header: Signal<'m>,
    pub(super) n_valid: Next<'m>,
    pub(super) n_code: Next<'m>,
    pub(super) n_node: Next<'m>,
}

/// START: the header checks. A failure is reported as the command's first
/// error, before a walk with no roots.
pub(super) fn header_checks<'m>(cx: &Ctx<'_, 'm>, c: &mut Command<'m>) -> FirstErr<'m> {
    let (m, ib) = (cx.m, cx.ib);
    let (roots, nodes, start) = (c.roots, c.nodes, c.start);
    let roots_bad = (roots.eq(0) | roots.gt(nodes)).name("roots_bad");
    let roots_over = if (cx.sizes.roots as u64) >> ib != 0 {
        cx.lit(0, 1)
    } else {
        roots.gt(cx.lit(cx.sizes.roots as u64, ib))
    }
    .name("roots_over");
    let hdr_code = m
        .first_of(
            &[
                (!c.entry_ok, cx.code4(fetch_err::ENTRY)),
                (roots_bad, cx.code4(fetch_err::ROOT_COUNT)),
                (roots_over, cx.code4(fetch_err::ROOT_CAPACITY)),
            ],
            cx.code4(0),
        )
        .name("header_code");
    let hdr_bad = hdr_code.ne(0);
    let ready = c.roots_ready(cx);
    c.n_phase
        .when(start, hdr_bad.mux(ready, goto(cx, ph::ROOTS)));
    let valid = m.reg("first_err_valid", 1);
    let code = m.reg("first_err_code", fetch_err::BITS);
    let node = m.reg("first_err_node", ib);
    let header = m.reg("header_err", 1);
    let mut e = FirstErr {
        valid,
        code,
        node,
        header,
        n_valid: Next::new(valid),
        n_code: Next::new(code),
        n_node: Next::new(node),
    };
    e.n_valid.when(start, hdr_bad);
    e.n_code.when(start, hdr_code);
    e.n_node.when(start, cx.lit(0, ib));
    header.next_when(start, hdr_bad);
    e
}
