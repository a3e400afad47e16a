//! S608's overlap counter (merging level determining unit 508; SPEC.md
//! section 8, "Merging module RTL"): one level's `(voxel, rank)` beats in
//! (Morton, rank) order, then `End`; out, one beat per level: `shared`,
//! `union`, `above = shared * den > num * union` (the threshold `num / den`
//! is a generator parameter, so both products are shift-and-add by
//! constants) and `overflow`.
//!
//! Consecutive beats of one voxel form a group; the group counts once in
//! `union`, and in `shared` when some beat's rank differs from the group's
//! first (ranks are sorted, so that is "two or more distinct inputs").
//! A count that would reach `2^I` sets the sticky overflow flag; the output
//! then carries zeros besides it (as the golden transaction says).

use golden::merge::level_choice::unit::OverlapLayout;
use golden::params::Params;

use crate::{Module, Signal, Stream};

/// Module name of the overlap counter.
pub fn overlap_counter_name(p: &Params, inputs: usize, num: u32, den: u32) -> String {
    format!(
        "overlap_counter_d{}_i{}_k{}_t{}_{}",
        p.max_lod, p.index_bits, inputs, num, den
    )
}

/// `value * c` for a constant `c`, as a sum of shifted copies, `width` bits
/// (wide enough for the exact product).
pub(super) fn times_constant<'m>(
    m: &'m Module,
    value: Signal<'m>,
    c: u32,
    width: u32,
) -> Signal<'m> {
    let v = value.zext(width);
    let mut acc = m.lit(0, width);
    for b in 0..32 {
        if c >> b & 1 == 1 {
            acc = acc.add(v << b, width);
        }
    }
    acc
}

/// The overlap counter for `p`, `inputs` inputs (rank width) and threshold
/// `num / den` (`0 <= num <= den`, `den >= 1`; checked by the caller with
/// `golden::merge::level_choice::check_ratio`).
pub fn overlap_counter_unit(p: &Params, inputs: usize, num: u32, den: u32) -> Module {
    let m = Module::new(&overlap_counter_name(p, inputs, num, den));
    let l = OverlapLayout::new(p, inputs);
    let input = Stream::input(&m, "in", l.input.width());
    let i = p.index_bits as u32;

    let voxel = input
        .data
        .slice(l.coord[2].end() - 1, l.coord[0].offset)
        .name("in_voxel");
    let rank = input.data.view(&l.rank).name("in_rank");
    let end = input.data.view(&l.end).name("in_end");

    let g_valid = m.reg("g_valid", 1);
    let g_voxel = m.reg("g_voxel", voxel.width());
    let g_rank = m.reg("g_rank", rank.width());
    let g_shared = m.reg("g_shared", 1);
    let shared = m.reg("shared_count", i);
    let union = m.reg("union_count", i);
    let overflow = m.reg("overflow", 1);
    let out_valid = m.reg("out_valid", 1);
    let out_ready = m.input("out_ready", 1);

    // A level's result waits in the output register; the next level's
    // beats wait until it is taken.
    let accept = (!out_valid | out_ready).name("accept");
    input.ready.drive(accept);
    let fire = (input.valid & accept).name("fire");
    let same = (g_valid & voxel.eq(g_voxel)).name("same_voxel");
    // The current group closes on a new voxel or the end of the level.
    let close = (fire & g_valid & (end | !same)).name("close");
    let union_next = union.add(1, i + 1).name("union_inc");
    // shared <= union, so only the union count can overflow.
    let shared_next = shared.add(1, i).name("shared_inc");
    let counts_shared = close & g_shared;
    let lit0 = m.lit(0, 1);

    let ovf_now = overflow | (close & union_next.bit(i));
    let union_after = close.mux(union_next.slice(i - 1, 0), union);
    let shared_after = counts_shared.mux(shared_next, shared);
    let level_done = fire & end;
    // The end of a level resets the counters for the next one; the result
    // is kept in `r_*` until taken.
    overflow.next(level_done.mux(lit0, ovf_now));
    union.next(level_done.mux(m.lit(0, i), union_after));
    shared.next(level_done.mux(m.lit(0, i), shared_after));
    g_valid.next(fire.mux(!end, g_valid));
    g_voxel.next_when(fire, voxel);
    g_rank.next_when(fire & !same, rank);
    g_shared.next(fire.mux(same.mux(g_shared | rank.ne(g_rank), lit0), g_shared));

    let r_shared = m.reg("r_shared", i);
    let r_union = m.reg("r_union", i);
    let r_overflow = m.reg("r_overflow", 1);
    r_shared.next_when(level_done, ovf_now.mux(m.lit(0, i), shared_after));
    r_union.next_when(level_done, ovf_now.mux(m.lit(0, i), union_after));
    r_overflow.next_when(level_done, ovf_now);
    out_valid.next(level_done.mux(m.lit(1, 1), (out_valid & !out_ready).name("out_held")));

    let pw = i + 33;
    let lhs = times_constant(&m, r_shared, den, pw).name("shared_x_den");
    let rhs = times_constant(&m, r_union, num, pw).name("num_x_union");
    let above = lhs.gt(rhs).name("above");
    m.output("out_valid", out_valid);
    m.output(
        "out_data",
        m.concat(&[r_overflow, above, r_union, r_shared]),
    );
    m
}
