//! The out stage: beats in order, the child references checked as their
//! answers come; after the error beat only the later levels' `End`s, the
//! first of them dropped (the error stands for it). Per-node fetchers have
//! two out stages (answer, send) for the probes.

use golden::merge::fetcher::{fetch_err, FetchLayout};
use golden::merge::merge_level::unit::level_kind;
use golden::params::Params;

use super::command::{goto, Command};
use super::parts::{check_and_move, out_beat, reference, reference_code, Move, Next};
use super::{ok, ph, Ctx};
use crate::{Module, Signal, Stream};

/// The level modes' out stage over the ordering stage's tokens `toks` (of
/// `tok_w` bits).
pub(super) fn level_out_stage<'m>(
    cx: &Ctx<'_, 'm>,
    c: &mut Command<'m>,
    o_errored: Signal<'m>,
    (toks, tok_w): (Stream<'m>, u32),
    cref_resp: Stream<'m>,
    out: Stream<'m>,
) {
    let (m, l, ib) = (cx.m, cx.l, cx.ib);
    let _scope = m.scope("out");
    let (rl, bl) = (&l.reference, &l.beat);
    let lit = |v: u64, w: u32| cx.lit(v, w);
    let (walk, start, hier, nodes) = (c.walk, c.start, c.hier, c.nodes);
    let t_kind = toks.data.slice(tok_w - 1, tok_w - ok::BITS);
    let t_beat = toks.data.slice(l.out.width() - 1, 0);
    let t_parent = toks.data.slice(ib - 1, 0);
    let t_cref = t_kind.eq(lit(ok::TOK_CREF, ok::BITS)).name("token_cref");
    let cr_node = cref_resp.data.view(rl.node());
    let cr_hier = cref_resp.data.view(rl.hier());
    let cref_code = reference_code(m, cr_node, cr_hier, hier, nodes).name("cref_code");
    let answered = (!t_cref | cref_resp.valid).name("token_answered");
    let o_skip = m.reg("skip_end", 1);
    let t_end = (t_kind.eq(lit(ok::TOK_FINAL, ok::BITS))
        | t_kind.eq(lit(ok::TOK_BEAT, ok::BITS)) & t_beat.view(&bl.kind).eq(level_kind::END))
    .name("token_end");
    let t_send = (!o_errored | t_end & !o_skip).name("token_sent");
    let t_fire = (walk & toks.valid & answered & (!t_send | out.ready)).name("token_fire");
    toks.ready.drive(t_fire);
    cref_resp
        .ready
        .drive(walk & toks.valid & t_cref & (!t_send | out.ready));
    let child_beat = out_beat(
        m,
        l,
        None,
        Some(cref_resp.data),
        lit(level_kind::CHILD_REF, bl.kind.width),
        None,
    );
    let cref_err_beat = out_beat(
        m,
        l,
        None,
        Some(reference(m, hier, t_parent)),
        lit(level_kind::END, bl.kind.width),
        Some(cref_code),
    );
    out.valid.drive(walk & toks.valid & answered & t_send);
    out.data
        .drive(t_cref.mux(cref_code.eq(0).mux(child_beat, cref_err_beat), t_beat));
    let errs = t_kind.eq(lit(ok::TOK_ERR, ok::BITS)) | t_cref & cref_code.ne(0);
    let first_err = (t_fire & errs & !o_errored).name("first_error");
    o_errored.next(start.mux(lit(0, 1), first_err.mux(lit(1, 1), o_errored)));
    o_skip.next(start.mux(
        lit(0, 1),
        first_err.mux(
            lit(1, 1),
            (t_fire & t_end & o_errored).mux(lit(0, 1), o_skip),
        ),
    ));
    c.n_phase.when(
        t_fire & t_kind.eq(lit(ok::TOK_FINAL, ok::BITS)),
        goto(cx, ph::DONE),
    );
}

/// The signals the per-node out stages take from the fetcher.
pub(super) struct OutStageIo<'a, 'm> {
    pub(super) walk: Signal<'m>,
    pub(super) start: Signal<'m>,
    pub(super) hier: Signal<'m>,
    pub(super) nodes: Signal<'m>,
    pub(super) mv: &'a Move<'m>,
    pub(super) toks: Stream<'m>,
    pub(super) tok_w: u32,
    pub(super) cref_resp: Stream<'m>,
    pub(super) out: Stream<'m>,
    pub(super) o_errored: Signal<'m>,
}

/// What the per-node out stages give back: the `probe` request stream
/// (its skid buffer and port are added with the others) and the clock in
/// which an `End` token leaves (the join's "the pass's `End` has left").
pub(super) struct PerNodePorts<'m> {
    pub(super) probe_req: Stream<'m>,
    pub(super) end_fire: Signal<'m>,
}

/// The out stages of a fetcher built with the per-node command: the
/// **answer stage** takes each token with its `cref` answer, turning a
/// child-reference token into its beat (or the error naming the parent)
/// and a probe token into a `probe` read (its child's index and expected
/// LOD beside it in `out_probes`, 8 words), and the **send stage** sends
/// each beat in order, a probe's beat made from its `probe` answer (checked
/// at the parent's LOD + 1 and moved; an error names the child), with
/// [`fetcher_unit`]'s first-error rule.
pub(super) fn per_node_out_stages<'m>(
    m: &'m Module,
    p: &Params,
    l: &FetchLayout,
    f: &golden::merge::fetcher::PerNodeFetchLayout,
    io: OutStageIo<'_, 'm>,
    n_phase: &mut Next<'m>,
) -> PerNodePorts<'m> {
    const IN_FLIGHT: u32 = 8;
    let _scope = m.scope("out");
    let (nl, rl, bl) = (&l.node, &l.reference, &l.beat);
    let (ib, lb) = (p.index_bits as u32, p.lod_bits());
    let lit = |v: u64, w: u32| m.lit(v as u128, w);
    let code4 = |c: u64| lit(c, fetch_err::BITS);
    let kind = |k: u64| lit(k, ok::BITS);
    let OutStageIo {
        walk,
        start,
        hier,
        nodes,
        mv,
        toks,
        tok_w,
        cref_resp,
        out,
        o_errored,
    } = io;
    // ---- answer stage
    let t_kind = toks.data.slice(tok_w - 1, tok_w - ok::BITS);
    let t_parent = toks.data.slice(ib - 1, 0);
    let t_cref = t_kind.eq(kind(ok::TOK_CREF)).name("token_cref");
    let t_probe = (t_cref & toks.data.bit(ib)).name("token_probe");
    let t_plod = toks.data.slice(ib + lb, ib + 1);
    let cr_node = cref_resp.data.view(rl.node());
    let cr_hier = cref_resp.data.view(rl.hier());
    let cref_code = reference_code(m, cr_node, cr_hier, hier, nodes).name("cref_code");
    let cref_ok = cref_code.eq(0);
    let probe_req = Stream::wires(m, "probe_req_core", ib);
    let probe_resp = Stream::input(m, "probe_resp", nl.width());
    let tok2_in = Stream::wires(m, "probes_in", tok_w);
    let toks2 = tok2_in.fifo("probes", IN_FLIGHT);
    let answered = (!t_cref | cref_resp.valid).name("token_answered");
    let room = (tok2_in.ready & (!t_probe | probe_req.ready)).name("answer_room");
    let a_fire = (walk & toks.valid & answered & room).name("token_fire");
    toks.ready.drive(a_fire);
    cref_resp.ready.drive(walk & toks.valid & t_cref & room);
    probe_req
        .valid
        .drive(walk & toks.valid & t_probe & cref_resp.valid & cref_ok & tok2_in.ready);
    probe_req.data.drive(cr_node);
    // The probe's LOD is its parent's + 1, carry kept (a child of a node at
    // the deepest LOD is never at a valid one).
    let want = t_plod.zext(lb + 1).add(1, lb + 1);
    let wait_tok = m.concat(&[
        kind(ok::TOK_CREF),
        m.lit(0, l.out.width() - ib - lb - 1),
        want,
        cr_node,
    ]);
    let child_beat = out_beat(
        m,
        l,
        None,
        Some(cref_resp.data),
        lit(level_kind::CHILD_REF, bl.kind.width),
        None,
    );
    let cref_err_beat = out_beat(
        m,
        l,
        None,
        Some(reference(m, hier, t_parent)),
        lit(level_kind::END, bl.kind.width),
        Some(cref_code),
    );
    tok2_in.valid.drive(a_fire);
    tok2_in.data.drive(t_cref.mux(
        cref_ok.mux(
            t_probe.mux(wait_tok, m.concat(&[kind(ok::TOK_BEAT), child_beat])),
            m.concat(&[kind(ok::TOK_ERR), cref_err_beat]),
        ),
        toks.data,
    ));

    // ---- send stage: after the error beat only the later passes' `End`s,
    // the first of them dropped (the error stands for it)
    let k2 = toks2.data.slice(tok_w - 1, tok_w - ok::BITS);
    let b2 = toks2.data.slice(l.out.width() - 1, 0);
    let t_wait = k2.eq(kind(ok::TOK_CREF)).name("token_probe_wait");
    let p_idx = toks2.data.slice(ib - 1, 0);
    let p_want = toks2.data.slice(ib + lb, ib);
    let got = check_and_move(m, p, l, probe_resp.data, p_want.slice(lb - 1, 0), mv);
    let p_code = p_want
        .bit(lb)
        .mux(code4(fetch_err::LOD), got.code)
        .name("probe_code");
    let p_ref = reference(m, hier, p_idx);
    let probe_beat = m.lit(0, l.out.width()).with_fields(&[
        (bl.kind, lit(level_kind::INNER, bl.kind.width)),
        (bl.rec, got.moved),
        (bl.refer, p_ref),
        (f.probe, lit(1, 1)),
    ]);
    let probe_err = out_beat(
        m,
        l,
        None,
        Some(p_ref),
        lit(level_kind::END, bl.kind.width),
        Some(p_code),
    );
    let answered2 = (!t_wait | probe_resp.valid).name("probe_answered");
    let o_skip = m.reg("skip_end", 1);
    let t_end = (k2.eq(kind(ok::TOK_FINAL))
        | k2.eq(kind(ok::TOK_BEAT)) & b2.view(&bl.kind).eq(level_kind::END))
    .name("token_end");
    let t_send = (!o_errored | t_end & !o_skip).name("token_sent");
    let t_fire = (walk & toks2.valid & answered2 & (!t_send | out.ready)).name("send_fire");
    toks2.ready.drive(t_fire);
    probe_resp
        .ready
        .drive(walk & toks2.valid & t_wait & (!t_send | out.ready));
    out.valid.drive(walk & toks2.valid & answered2 & t_send);
    out.data
        .drive(t_wait.mux(p_code.eq(0).mux(probe_beat, probe_err), b2));
    let errs = k2.eq(kind(ok::TOK_ERR)) | t_wait & p_code.ne(0);
    let first_err = (t_fire & errs & !o_errored).name("first_error");
    o_errored.next(start.mux(lit(0, 1), first_err.mux(lit(1, 1), o_errored)));
    o_skip.next(start.mux(
        lit(0, 1),
        first_err.mux(
            lit(1, 1),
            (t_fire & t_end & o_errored).mux(lit(0, 1), o_skip),
        ),
    ));
    n_phase.when(
        t_fire & k2.eq(kind(ok::TOK_FINAL)),
        m.states(ph::BITS, ph::STATES).code(ph::DONE),
    );
    PerNodePorts {
        probe_req,
        end_fire: (t_fire & t_end).name("pass_end_left"),
    }
}
