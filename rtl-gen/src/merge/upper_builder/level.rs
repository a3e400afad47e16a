//! S616, one level up (SPEC.md section 8, "Merging module RTL"): a level's
//! records in Morton order in, one inner record per parent voxel out (the
//! builder's `group_by_parent`), one beat per clock.
//!
//! Siblings are consecutive in Morton order, so a holding register `h`
//! accumulates the current parent: a beat whose parent voxel equals `h`'s
//! is absorbed (no output), any other beat (or `End`) completes `h`.
//! A child's cells in its parent, per axis with `o` the child's coordinate
//! bit: `floor((o 2^Q + lo) / 2)` and `ceil((o 2^Q + hi + 1) / 2) - 1 =
//! floor((o 2^Q + hi) / 2)`, i.e. the bits `{o, lo[Q-1:1]}` and
//! `{o, hi[Q-1:1]}`: no arithmetic. The parent's box is their per-axis
//! min/max. `first` is the level index of the group's first child and
//! `count` the group's size, with an error flag when either reaches `2^I`
//! or a child's box has `lo > hi` (the only use of the cells' bit 0).
//! The input beat carries only the record bits S616 reads (`lod` to `hi_z`).

use golden::merge::upper_builder::level_unit::UpperLayout;
use golden::params::Params;

use crate::{Module, Signal, Stream};

/// Module name of the upper-level unit for `p`.
pub fn upper_level_name(p: &Params) -> String {
    format!(
        "upper_level_d{}_q{}_i{}",
        p.max_lod, p.quant_bits, p.index_bits
    )
}

/// The cells of a child on one axis re-quantized into its parent.
fn cell_in_parent<'m>(m: &'m Module, cell: Signal<'m>, odd: Signal<'m>) -> Signal<'m> {
    let q = cell.width();
    if q == 1 {
        odd
    } else {
        m.concat(&[odd, cell.slice(q - 1, 1)])
    }
}

/// The upper-level unit for `p`: stream `in` of [`UpperLayout`] input beats
/// (`rec`, `end`), stream `out` of output beats (`rec`, `end`, `err`).
pub fn upper_level_unit(p: &Params) -> Module {
    let m = Module::new(&upper_level_name(p));
    let l = UpperLayout::new(p);
    let nl = &l.node;
    let i = p.index_bits as u32;
    let input = Stream::input(&m, "in", l.input.width());
    let out_ready = m.wire("h_out_ready", 1);
    let rec = input.data;
    let end = input.data.view(&l.in_end).name("in_end");
    let f = |x: &golden::layout::Field| l.in_child(x);

    // The parent of the incoming record: lod - 1, coordinates >> 1.
    let lod = rec.view(&f(nl.lod()));
    let parent_lod = lod.sub(1, lod.width()).name("parent_lod");
    let coords: Vec<Signal> = (0..3).map(|a| rec.view(&f(nl.coord(a)))).collect();
    let parent_xyz: Vec<Signal> = coords.iter().map(|c| c.srl(1u32)).collect();
    let parent_voxel = m
        .concat(&[parent_xyz[2], parent_xyz[1], parent_xyz[0], parent_lod])
        .name("parent_voxel");
    let mut in_lo = Vec::new();
    let mut in_hi = Vec::new();
    let mut bad_box = m.lit(0, 1);
    for (a, coord) in coords.iter().enumerate() {
        if let (Some(lo), Some(hi)) = (rec.view_opt(&f(nl.lo(a))), rec.view_opt(&f(nl.hi(a)))) {
            let odd = coord.bit(0);
            in_lo.push(cell_in_parent(&m, lo, odd));
            in_hi.push(cell_in_parent(&m, hi, odd));
            bad_box = bad_box | lo.gt(hi);
        }
    }
    let bad_box = bad_box.name("bad_box");

    let h_valid = m.reg("h_valid", 1);
    let h_end = m.reg("h_end", 1);
    let h_voxel = m.reg("h_voxel", parent_voxel.width());
    let h_lo: Vec<Signal> = in_lo
        .iter()
        .enumerate()
        .map(|(a, s)| m.reg(&format!("h_lo{a}"), s.width()))
        .collect();
    let h_hi: Vec<Signal> = in_hi
        .iter()
        .enumerate()
        .map(|(a, s)| m.reg(&format!("h_hi{a}"), s.width()))
        .collect();
    let h_first = m.reg("h_first", i);
    let h_count = m.reg("h_count", i);
    let h_err = m.reg("h_err", 1);
    // Index of the next record of the level, with a sticky overflow flag.
    let index = m.reg("index", i);
    let index_ovf = m.reg("index_ovf", 1);

    let absorb = (input.valid & !end & h_valid & !h_end & parent_voxel.eq(h_voxel)).name("absorb");
    let complete = (h_valid & input.valid & !absorb | h_valid & h_end).name("complete");
    let free = (!h_valid | (complete & out_ready)).name("free");
    // An `End` with no group held goes straight to the out skid buffer
    // instead of through `h`: an empty level (every level above the
    // merging level) then costs the builder's chain one clock, not two.
    let end_alone = (end & !h_valid).name("end_alone");
    let pass = (input.valid & end_alone).name("end_pass");
    let load = (input.valid & !absorb & free & !end_alone).name("load");
    input.ready.drive(absorb | end_alone.mux(out_ready, free));
    let taken = (absorb | load) & !end;

    let index_next = index.add(1, i + 1).name("index_inc");
    let level_done = (load & end | pass & out_ready).name("level_done");
    index.next(level_done.mux(m.lit(0, i), taken.mux(index_next.slice(i - 1, 0), index)));
    index_ovf.next(level_done.mux(m.lit(0, 1), index_ovf | (taken & index_next.bit(i))));

    let count_next = h_count.add(1, i + 1).name("count_inc");
    let lit0 = m.lit(0, 1);
    h_valid.next(load.mux(m.lit(1, 1), (complete & out_ready).mux(lit0, h_valid)));
    h_end.next_when(load, end);
    h_voxel.next_when(load, parent_voxel);
    for (a, (lo, hi)) in in_lo.iter().zip(&in_hi).enumerate() {
        let (hl, hh) = (h_lo[a], h_hi[a]);
        hl.next(load.mux(*lo, absorb.mux(hl.lt(*lo).mux(hl, *lo), hl)));
        hh.next(load.mux(*hi, absorb.mux(hh.gt(*hi).mux(hh, *hi), hh)));
    }
    h_first.next_when(load, index);
    h_count.next(load.mux(m.lit(1, i), absorb.mux(count_next.slice(i - 1, 0), h_count)));
    // `first` overflowed when the index did before this group; `count` when it wraps.
    h_err.next(load.mux(
        index_ovf | bad_box,
        h_err | (absorb & (count_next.bit(i) | bad_box)),
    ));

    // The parent record: leaf 0, voxel, box, first, count; fields low first.
    let mut low_first: Vec<Signal> = vec![lit0, h_voxel];
    low_first.extend(h_lo.iter().copied());
    low_first.extend(h_hi.iter().copied());
    low_first.push(h_first);
    low_first.push(h_count);
    low_first.reverse();
    let record = m.concat(&low_first);
    let node_beat = m.concat(&[h_err, lit0, record]);
    let end_beat = m.concat(&[m.lit(1, 2), m.lit(0, nl.width())]);
    let out = Stream {
        valid: complete | pass,
        ready: out_ready,
        data: (h_end | !h_valid).mux(end_beat, node_beat).name("h_beat"),
    };
    out.skid_buffer("out_skid").output("out");
    m
}
