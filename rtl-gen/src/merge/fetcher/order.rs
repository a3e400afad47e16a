//! The out ordering stage: a voxel's inner node, its leaf, then the inner
//! node's child references (`cref` reads, one a clock), as tokens for the
//! out stage; per-node, a pass's inner node first sends its probes.

use golden::merge::fetcher::fetch_err;
use golden::merge::merge_level::unit::level_kind;

use super::command::Command;
use super::parts::out_beat;
use super::visit::Head;
use super::{ok, Ctx, Ports};
use crate::{Signal, Stream};

/// The out ordering stage over the visit stage's items; returns the stream
/// of tokens (`ok` token kind, an `out` beat or a `cref` parent) and its
/// width.
pub(super) fn order_stage<'m>(
    cx: &Ctx<'_, 'm>,
    c: &Command<'m>,
    h: &Head<'m>,
    io: &Ports<'m>,
) -> (Stream<'m>, u32) {
    let (m, p, l, ib, lb) = (cx.m, cx.p, cx.l, cx.ib, cx.lb);
    let _scope = m.scope("order");
    let rl = &l.reference;
    let lit = |v: u64, w: u32| cx.lit(v, w);
    let (walk, start, c_pn, c_refs) = (c.walk, c.start, c.per_node, c.send_refs);
    let (items, oin_w, cref_req) = (h.items, h.oin_w, io.cref_req);
    let item = decode_item(cx, items, oin_w);
    let Item {
        refer: o_ref,
        is_node: o_is_node,
        leaf: o_leaf,
        voxel: o_voxel,
        first: o_first,
        end: o_end,
        ..
    } = item;
    let pend_valid = m.reg("pend_valid", 1);
    let pend_first = m.reg("pend_first", ib);
    let pend_end = m.reg("pend_end", ib + 1);
    let pend_voxel = m.reg("pend_voxel", 3 * p.coord_bits());
    let pend_node = m.reg("pend_node", ib);
    let cr_active = m.reg("cref_active", 1);
    let cr_idx = m.reg("cref_idx", ib);
    let cr_end = m.reg("cref_end", ib + 1);
    let cr_parent = m.reg("cref_parent", ib);
    let tok_w = ok::BITS + l.out.width();
    let tok_in = Stream::wires(m, "tokens_in", tok_w);
    let toks = tok_in.fifo("tokens", 4);
    let can = (walk & tok_in.ready & cref_req.ready).name("room");
    let same_leaf = (pend_valid & o_is_node & o_leaf & o_voxel.eq(pend_voxel)).name("leaf_of_held");
    let a_cref = (can & cr_active).name("cref_next");
    let b_leaf = (can & !cr_active & items.valid & same_leaf).name("held_leaf");
    let c_flush =
        (can & !cr_active & items.valid & pend_valid & !same_leaf).name("held_refs_first");
    let o_pn_inner = c_pn.map(|c| (o_is_node & !o_leaf & c).name("item_pass_inner"));
    let probe_run = o_pn_inner.map(|pi| {
        let active = m.reg("probe_active", 1);
        let sent = m.reg("probes_sent", 1);
        let begin_ok =
            (!cr_active & !active & items.valid & !pend_valid & pi & !sent).name("probe_first_ok");
        ProbeRun {
            active,
            sent,
            idx: m.reg("probe_idx", ib),
            end: m.reg("probe_end", ib + 1),
            parent: m.reg("probe_parent", ib),
            lod: m.reg("probe_lod", lb),
            begin_ok,
            begin: (can & begin_ok).name("probe_first"),
            next: (can & active).name("probe_next"),
        }
    });
    let d_item = match (&probe_run, o_pn_inner) {
        (Some(pr), Some(pi)) => {
            can & !cr_active & items.valid & !pend_valid & !pr.active & (!pi | pr.sent)
        }
        _ => can & !cr_active & items.valid & !pend_valid,
    }
    .name("item_out");
    items.ready.drive(b_leaf | d_item);
    match &probe_run {
        Some(pr) => {
            cref_req.valid.drive(
                walk & tok_in.ready
                    & (cr_active
                        | !cr_active & items.valid & pend_valid & !same_leaf
                        | pr.active
                        | pr.begin_ok),
            );
            cref_req.data.drive(pr.active.mux(
                pr.idx,
                pr.begin_ok.mux(o_first, cr_active.mux(cr_idx, pend_first)),
            ));
            probe_run_next(cx, c, pr, &item, d_item);
        }
        None => {
            cref_req.valid.drive(
                walk & tok_in.ready
                    & (cr_active | !cr_active & items.valid & pend_valid & !same_leaf),
            );
            cref_req.data.drive(cr_active.mux(cr_idx, pend_first));
        }
    }
    let cr_next = cr_idx.add(1, ib);
    let pf_next = pend_first.add(1, ib);
    cr_active.next(m.first_of(
        &[
            (start, lit(0, 1)),
            (a_cref, cr_next.zext(ib + 1).ne(cr_end)),
            (b_leaf, lit(1, 1)),
            (c_flush, pf_next.zext(ib + 1).ne(pend_end)),
        ],
        cr_active,
    ));
    cr_idx.next(m.first_of(
        &[(a_cref, cr_next), (b_leaf, pend_first), (c_flush, pf_next)],
        cr_idx,
    ));
    cr_end.next_when(b_leaf | c_flush, pend_end);
    cr_parent.next_when(b_leaf | c_flush, pend_node);
    let hold = match c_pn {
        Some(c) => d_item & o_is_node & !o_leaf & (c_refs | c),
        None => d_item & o_is_node & !o_leaf & c_refs,
    }
    .name("hold_refs");
    pend_valid.next(start.mux(
        lit(0, 1),
        (b_leaf | c_flush).mux(lit(0, 1), hold.mux(lit(1, 1), pend_valid)),
    ));
    pend_first.next_when(hold, o_first);
    pend_end.next_when(hold, o_end);
    pend_voxel.next_when(hold, o_voxel);
    pend_node.next_when(hold, o_ref.view(rl.node()));
    let moves = Moves {
        a_cref,
        b_leaf,
        c_flush,
        d_item,
    };
    let cref_parent = cr_active.mux(cr_parent, pend_node);
    drive_tokens(cx, &item, tok_in, &moves, cref_parent, probe_run.as_ref());
    (toks, tok_w)
}

/// The out items FIFO's head, decoded.
#[derive(Clone, Copy)]
struct Item<'m> {
    rec: Signal<'m>,
    refer: Signal<'m>,
    code: Signal<'m>,
    kind: Signal<'m>,
    is_node: Signal<'m>,
    leaf: Signal<'m>,
    /// The node's voxel (z, y, x).
    voxel: Signal<'m>,
    /// Its child range: the first reference and one past the last.
    first: Signal<'m>,
    end: Signal<'m>,
}

fn decode_item<'m>(cx: &Ctx<'_, 'm>, items: Stream<'m>, oin_w: u32) -> Item<'m> {
    let (m, l, ib) = (cx.m, cx.l, cx.ib);
    let (nl, rl) = (&l.node, &l.reference);
    let lit = |v: u64, w: u32| cx.lit(v, w);
    let o_rec = items.data.slice(nl.width() - 1, 0);
    let o_ref = items.data.slice(nl.width() + rl.width() - 1, nl.width());
    let o_code = items.data.slice(
        nl.width() + rl.width() + fetch_err::BITS - 1,
        nl.width() + rl.width(),
    );
    let o_kind = items.data.slice(oin_w - 1, oin_w - ok::BITS);
    let o_is_node = o_kind.eq(lit(ok::NODE, ok::BITS));
    let o_leaf = o_rec.view(nl.leaf());
    let o_voxel = m.concat(&[o_rec.view(nl.z()), o_rec.view(nl.y()), o_rec.view(nl.x())]);
    let o_first = o_rec.view(nl.first());
    let o_end = o_first
        .zext(ib + 1)
        .add(o_rec.view(nl.count()).zext(ib + 1), ib + 1);
    Item {
        rec: o_rec,
        refer: o_ref,
        code: o_code,
        kind: o_kind,
        is_node: o_is_node,
        leaf: o_leaf,
        voxel: o_voxel,
        first: o_first,
        end: o_end,
    }
}

// Per-node: a pass's inner node first sends its probes, one `cref`
// read a clock (a probe token beside each), then goes out as the
// others (`probes_sent`).
struct ProbeRun<'m> {
    active: Signal<'m>,
    sent: Signal<'m>,
    idx: Signal<'m>,
    end: Signal<'m>,
    parent: Signal<'m>,
    lod: Signal<'m>,
    begin_ok: Signal<'m>,
    begin: Signal<'m>,
    next: Signal<'m>,
}

/// A probe run's registers after `pr.begin` (an item's first probe) or
/// `pr.next`.
fn probe_run_next<'m>(
    cx: &Ctx<'_, 'm>,
    c: &Command<'m>,
    pr: &ProbeRun<'m>,
    item: &Item<'m>,
    d_item: Signal<'m>,
) {
    let (l, ib) = (cx.l, cx.ib);
    let (nl, rl) = (&l.node, &l.reference);
    let lit = |v: u64, w: u32| cx.lit(v, w);
    let start = c.start;
    let (o_rec, o_ref, o_first, o_end) = (item.rec, item.refer, item.first, item.end);
    let o_count = o_rec.view(nl.count());
    let idx_next = pr.idx.add(1, ib);
    let last = idx_next.zext(ib + 1).eq(pr.end);
    pr.active.next(start.mux(
        lit(0, 1),
        pr.next.mux(!last, pr.begin.mux(o_count.ne(1), pr.active)),
    ));
    pr.sent.next(start.mux(
        lit(0, 1),
        (pr.next & last | pr.begin & o_count.eq(1)).mux(lit(1, 1), d_item.mux(lit(0, 1), pr.sent)),
    ));
    pr.idx.next(
        pr.begin
            .mux(o_first.add(1, ib), pr.next.mux(idx_next, pr.idx)),
    );
    pr.end.next_when(pr.begin, o_end);
    pr.parent.next_when(pr.begin, o_ref.view(rl.node()));
    pr.lod.next_when(pr.begin, o_rec.view(nl.lod()));
}

/// Which of the ordering stage's moves happen this clock: the next `cref`
/// read of a running range, the held inner node's leaf, the held node's
/// references first, the item out.
struct Moves<'m> {
    a_cref: Signal<'m>,
    b_leaf: Signal<'m>,
    c_flush: Signal<'m>,
    d_item: Signal<'m>,
}

/// The tokens the ordering stage pushes: a `cref` read's parent, an item's
/// beat (node, error, `End`), or per-node a probe.
fn drive_tokens<'m>(
    cx: &Ctx<'_, 'm>,
    item: &Item<'m>,
    tok_in: Stream<'m>,
    mv: &Moves<'m>,
    cref_parent: Signal<'m>,
    probe_run: Option<&ProbeRun<'m>>,
) {
    let (m, l, ib, lb) = (cx.m, cx.l, cx.ib, cx.lb);
    let (nl, rl, bl) = (&l.node, &l.reference, &l.beat);
    let lit = |v: u64, w: u32| cx.lit(v, w);
    let (o_rec, o_ref, o_code, o_kind, o_leaf) =
        (item.rec, item.refer, item.code, item.kind, item.leaf);
    let Moves {
        a_cref,
        b_leaf,
        c_flush,
        d_item,
    } = *mv;
    let node_beat = out_beat(
        m,
        l,
        Some(o_rec),
        Some(o_ref),
        o_leaf.mux(
            lit(level_kind::LEAF, bl.kind.width),
            lit(level_kind::INNER, bl.kind.width),
        ),
        None,
    );
    let err_beat = out_beat(
        m,
        l,
        None,
        Some(o_ref),
        lit(level_kind::END, bl.kind.width),
        Some(o_code),
    );
    let end_out = out_beat(m, l, None, None, lit(level_kind::END, bl.kind.width), None);
    let cref_tok = m.concat(&[
        lit(ok::TOK_CREF, ok::BITS),
        m.lit(0, l.out.width() - ib),
        cref_parent,
    ]);
    let item_tok = m.first_of(
        &[
            (
                o_kind.eq(lit(ok::NODE, ok::BITS)),
                m.concat(&[lit(ok::TOK_BEAT, ok::BITS), node_beat]),
            ),
            (
                o_kind.eq(lit(ok::ERR, ok::BITS)),
                m.concat(&[lit(ok::TOK_ERR, ok::BITS), err_beat]),
            ),
            (
                o_kind.eq(lit(ok::FINAL, ok::BITS)),
                m.concat(&[lit(ok::TOK_FINAL, ok::BITS), end_out]),
            ),
        ],
        m.concat(&[lit(ok::TOK_BEAT, ok::BITS), end_out]),
    );
    match probe_run {
        Some(pr) => {
            // A probe token: a `cref` token with bit I set and the parent's
            // LOD above it.
            let probe_tok = m.concat(&[
                lit(ok::TOK_CREF, ok::BITS),
                m.lit(0, l.out.width() - ib - 1 - lb),
                pr.begin.mux(o_rec.view(nl.lod()), pr.lod),
                lit(1, 1),
                pr.begin.mux(o_ref.view(rl.node()), pr.parent),
            ]);
            tok_in
                .valid
                .drive(a_cref | b_leaf | c_flush | d_item | pr.begin | pr.next);
            tok_in.data.drive(
                (pr.begin | pr.next).mux(probe_tok, (a_cref | c_flush).mux(cref_tok, item_tok)),
            );
        }
        None => {
            tok_in.valid.drive(a_cref | b_leaf | c_flush | d_item);
            tok_in
                .data
                .drive((a_cref | c_flush).mux(cref_tok, item_tok));
        }
    }
}
