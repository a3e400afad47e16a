//! S614, the merged nodes at the merging level (unit 506; SPEC.md section 8,
//! "Merging module RTL"): one voxel group at a time, one beat per clock.
//!
//! A holding register `h` carries the beat to emit next. An inner node opens
//! an accumulator in `h`; every further inner node of the same voxel is
//! absorbed into it (box cells: per-axis min of `lo`, max of `hi`; `count`:
//! the sum, with a sticky overflow flag), consuming its beat without an
//! output. The first beat that is not absorbed closes the accumulator: one
//! inner node alone leaves as *reused* (its record and `ref` as they came),
//! two or more as *created* (`first` 0, `ref` 0). Leaves leave as reused,
//! child references pass only while the voxel's inner nodes were merged
//! (`grp_created`), `End` passes. Every output and `in_ready` come from
//! registers through the output skid buffer.
//!
//! The union of boxes of one voxel re-quantized outward into that voxel is
//! the per-axis min/max of their cells: all of them are relative to the same
//! voxel with the same cell size, so golden's `requantize_outward` of the
//! fine-unit union returns exactly those cells.

use golden::layout::NodeLayout;
use golden::merge::merge_level::unit::{base_kind, level_kind, BeatLayout};
use golden::params::Params;

use crate::{Module, Stream};

/// Module name of the S614 unit for `p`.
pub fn merge_level_name(p: &Params) -> String {
    format!("merge_level_{}", p.tag())
}

/// The S614 unit for `p`: stream `in` of [`BeatLayout::input`] beats,
/// stream `out` of [`BeatLayout::output`] beats.
pub fn merge_level_unit(p: &Params) -> Module {
    let m = Module::new(&merge_level_name(p));
    let li = BeatLayout::input(p);
    let lo_ = BeatLayout::output(p);
    let nl: &NodeLayout = &li.node;
    let input = Stream::input(&m, "in", li.width());
    let out_ready = m.wire("h_out_ready", 1);

    let in_rec = input.data.view(&li.rec);
    let in_ref = input.data.view(&li.refer);
    let in_kind = input.data.view(&li.kind).name("in_kind");

    let h_valid = m.reg("h_valid", 1);
    let h_open = m.reg("h_open", 1);
    let h_multi = m.reg("h_multi", 1);
    let h_ovf = m.reg("h_ovf", 1);
    let h_kind = m.reg("h_kind", 2);
    let h_rec = m.reg("h_rec", li.rec.width);
    let h_ref = m.reg("h_ref", li.refer.width);
    let grp_created = m.reg("grp_created", 1);

    let is_inner = in_kind.eq(level_kind::INNER).name("in_is_inner");
    let is_ref = in_kind.eq(level_kind::CHILD_REF).name("in_is_ref");
    let same_voxel = in_rec
        .view_span(nl.lod(), nl.z())
        .eq(h_rec.view_span(nl.lod(), nl.z()))
        .name("same_voxel");
    let absorb = (input.valid & is_inner & h_valid & h_open & same_voxel).name("absorb");
    let complete = (h_valid & (!h_open | (input.valid & !absorb))).name("complete");
    let free = (!h_valid | (complete & out_ready)).name("free");
    let load = (input.valid & !absorb & free).name("load");
    let created_now = (h_valid & h_open)
        .mux(h_multi, grp_created)
        .name("created_now");
    let keep = !(is_ref & !created_now);
    input.ready.drive(absorb | free);

    // The accumulator absorbing one more inner node of its voxel.
    let i = p.index_bits as u32;
    let count_sum = h_rec
        .view(nl.count())
        .add(in_rec.view(nl.count()), i + 1)
        .name("count_sum");
    let mut merged = vec![(*nl.count(), count_sum.slice(i - 1, 0))];
    for a in 0..3 {
        if let (Some(hl), Some(il)) = (h_rec.view_opt(nl.lo(a)), in_rec.view_opt(nl.lo(a))) {
            merged.push((*nl.lo(a), hl.lt(il).mux(hl, il)));
        }
        if let (Some(hh), Some(ih)) = (h_rec.view_opt(nl.hi(a)), in_rec.view_opt(nl.hi(a))) {
            merged.push((*nl.hi(a), hh.gt(ih).mux(hh, ih)));
        }
    }
    let merged_rec = h_rec.with_fields(&merged).name("merged_rec");

    let lit = |v: u64, w: u32| m.lit(v as u128, w);
    let drained = complete & out_ready;
    h_valid.next(load.mux(keep, drained.mux(lit(0, 1), h_valid)));
    h_open.next_when(load, is_inner);
    h_multi.next(load.mux(lit(0, 1), absorb | h_multi));
    h_ovf.next(load.mux(lit(0, 1), (absorb & count_sum.bit(i)) | h_ovf));
    // Inner and leaf beats leave as REUSED unless merged; REF and END keep their code.
    h_kind.next_when(load, in_kind.bit(1).mux(in_kind, lit(base_kind::REUSED, 2)));
    h_rec.next(load.mux(in_rec, absorb.mux(merged_rec, h_rec)));
    h_ref.next_when(load, in_ref);
    grp_created.next_when(load & h_valid & h_open, h_multi);

    // The beat `h` stands for.
    let created = (h_open & h_multi).name("h_created");
    let out_kind = h_open.mux(
        h_multi.mux(lit(base_kind::CREATED, 2), lit(base_kind::REUSED, 2)),
        h_kind,
    );
    let created_rec = h_rec.with_fields(&[(*nl.first(), lit(0, i))]);
    let out_rec = created.mux(created_rec, h_rec);
    let out_ref = created.mux(lit(0, li.refer.width), h_ref);
    let err = created & h_ovf;
    debug_assert_eq!(lo_.width(), li.width() + 1);
    let out = Stream {
        valid: complete,
        ready: out_ready,
        data: m.concat(&[err, out_kind, out_ref, out_rec]).name("h_beat"),
    };
    out.skid_buffer("out_skid").output("out");
    m
}
