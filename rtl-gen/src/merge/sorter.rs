//! The root sorter (SPEC.md section 8, "Merging module RTL"; patent
//! paragraph 107's Morton code sorter, bounded): the roots of one input,
//! translated, in stored order, then `End`; out, the same beats in
//! (translated Morton code, inner before leaf) order, stable, then `End`.
//! Sorting the roots is enough (`golden::merge::unit::root_sort_transaction`
//! says why): below the top a translation keeps every child's octant.
//!
//! An insertion array of `capacity` entries takes one beat per clock: every
//! entry compares its key with the new one in parallel, entries with a
//! greater key shift up by one, the new beat lands in the gap (equal keys
//! stay in arrival order). `End` copies the array in one clock into the
//! output bank, or into a second, waiting bank while the output bank still
//! drains; the output bank drains one beat per clock (then `End`, with `err`
//! set if a root beyond the capacity was dropped) while the next input fills
//! the array. Skid buffers register both streams' handshakes.

use golden::merge::unit::{level_kind, BeatLayout};
use golden::params::Params;

use super::fields::field;
use crate::{Module, Signal, Stream};

/// Module name of the root sorter.
pub fn root_sorter_name(p: &Params, capacity: usize) -> String {
    format!(
        "root_sorter_d{}_q{}_i{}_h{}_n{}",
        p.max_lod, p.quant_bits, p.index_bits, p.hier_bits, capacity
    )
}

/// The sort key of a beat: the Morton code of its voxel (bit `i` of x, y, z
/// at `3i`, `3i + 1`, `3i + 2`), then the leaf bit (inner first).
fn sort_key<'m>(m: &'m Module, beat: Signal<'m>, l: &BeatLayout) -> Signal<'m> {
    let rec = field(beat, &l.rec).expect("record bits");
    let nl = &l.node;
    let c: Vec<Signal> = (0..3)
        .map(|a| field(rec, nl.coord(a)).expect("coordinate"))
        .collect();
    let mut high_first = Vec::new();
    for i in (0..nl.x().width).rev() {
        high_first.extend([c[2].bit(i), c[1].bit(i), c[0].bit(i)]);
    }
    high_first.push(field(rec, nl.leaf()).expect("leaf bit"));
    m.concat(&high_first)
}

/// The root sorter for `p` with room for `capacity >= 1` roots: stream `in`
/// of [`BeatLayout::input`] beats (kinds INNER, LEAF, END), stream `out` of
/// [`BeatLayout::output`] beats (same kinds; `err` on END).
pub fn root_sorter_unit(p: &Params, capacity: usize) -> Module {
    let m = Module::new(&root_sorter_name(p, capacity));
    let li = BeatLayout::input(p);
    let w = li.width;
    let n = capacity.max(1);
    let input = Stream::input(&m, "in", w).skid_buffer("in_skid");
    let out_ready = m.wire("core_out_ready", 1);
    let kind = field(input.data, &li.kind).expect("kind").name("in_kind");
    let is_end = kind.eq(level_kind::END).name("in_is_end");
    let new_key = sort_key(&m, input.data, &li).name("new_key");

    let e: Vec<Signal> = (0..n).map(|i| m.reg(&format!("e{i}"), w)).collect();
    let v: Vec<Signal> = (0..n).map(|i| m.reg(&format!("v{i}"), 1)).collect();
    let ovf = m.reg("ovf", 1);
    let o: Vec<Signal> = (0..n).map(|i| m.reg(&format!("o{i}"), w)).collect();
    let ov: Vec<Signal> = (0..n).map(|i| m.reg(&format!("ov{i}"), 1)).collect();
    let o_end = m.reg("o_end", 1);
    let o_err = m.reg("o_err", 1);
    // A second, waiting bank: a sorted set whose turn comes after `o`'s.
    let q: Vec<Signal> = (0..n).map(|i| m.reg(&format!("q{i}"), w)).collect();
    let qv: Vec<Signal> = (0..n).map(|i| m.reg(&format!("qv{i}"), 1)).collect();
    let q_full = m.reg("q_full", 1);
    let q_err = m.reg("q_err", 1);

    // The output bank drains from entry 0, then gives its END.
    let out_valid = ov[0] | o_end;
    let out_fire = (out_valid & out_ready).name("out_fire");
    // `o` is free after this edge when empty or when its END is taken now.
    let o_free = (!out_valid | (out_fire & !ov[0])).name("o_free");
    let bank_free = (!q_full | o_free).name("bank_free");
    input.ready.drive(!is_end | bank_free);
    let fire = (input.valid & (!is_end | bank_free)).name("in_fire");
    let insert = (fire & !is_end).name("insert");
    let flush = (fire & is_end).name("flush");
    let full = v[n - 1];

    // Position mask: entry i moves up when it is empty or its key is greater.
    let gt: Vec<Signal> = (0..n)
        .map(|i| (!v[i] | sort_key(&m, e[i], &li).gt(new_key)).name(&format!("gt{i}")))
        .collect();
    let lit0 = m.lit(0, 1);
    for i in 0..n {
        let shifted = if i == 0 {
            input.data
        } else {
            gt[i - 1].mux(e[i - 1], input.data)
        };
        let placed = gt[i].mux(shifted, e[i]);
        e[i].next_when(insert & !full, placed);
        let grown = if i == 0 { m.lit(1, 1) } else { v[i - 1] | v[i] };
        v[i].next(flush.mux(lit0, (insert & !full).mux(grown, v[i])));
    }
    ovf.next(flush.mux(lit0, ovf | (insert & full)));

    // Bank moves at the edge: `o` takes `q` (or the flushed array when `q`
    // is empty) once free; otherwise it shifts as it drains and `q` takes
    // the flushed array.
    let o_from_q = (o_free & q_full).name("o_from_q");
    let o_from_e = (o_free & !q_full & flush).name("o_from_e");
    let q_from_e = (flush & !o_from_e).name("q_from_e");
    let shift = (out_fire & ov[0]).name("o_shift");
    for i in 0..n {
        let next_o = if i + 1 < n { o[i + 1] } else { m.lit(0, w) };
        let next_ov = if i + 1 < n { ov[i + 1] } else { lit0 };
        o[i].next(o_from_q.mux(q[i], o_from_e.mux(e[i], shift.mux(next_o, o[i]))));
        ov[i].next(o_from_q.mux(qv[i], o_from_e.mux(v[i], shift.mux(next_ov, ov[i]))));
        q[i].next_when(q_from_e, e[i]);
        qv[i].next_when(q_from_e, v[i]);
    }
    let loaded = o_from_q | o_from_e;
    o_end.next(loaded.mux(m.lit(1, 1), (out_fire & !ov[0]).mux(lit0, o_end)));
    o_err.next(o_from_q.mux(q_err, o_from_e.mux(ovf, o_err)));
    q_full.next(q_from_e.mux(m.lit(1, 1), o_from_q.mux(lit0, q_full)));
    q_err.next_when(q_from_e, ovf);

    let end_beat = m.concat(&[o_err, m.lit(level_kind::END as u128, 2), m.lit(0, w - 2)]);
    let data = ov[0]
        .mux(m.concat(&[lit0, o[0]]), end_beat)
        .name("core_out_data");
    let out = Stream {
        valid: out_valid.name("core_out_valid"),
        ready: out_ready,
        data,
    };
    out.skid_buffer("out_skid").output("out");
    m
}
