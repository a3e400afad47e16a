//! Classes of translation-unit transactions: the generator's hard-case
//! categories and the unit's error and status outcomes, counted from the
//! records (never from how they were generated).

use std::collections::BTreeMap;

use crate::translate::determine::shift_right_round_sticky;
use crate::translate::float::{unpack, Decoded, BINARY32, BINARY64};
use crate::translate::model::{ApplyCode, TranslateDesign, TranslateTxn};

/// The input and outcome classes of `txns` (the hard-case categories of the
/// generated vectors and every error and status the unit reports), counted
/// from the records themselves: what a regression's functional coverage
/// bins (SPEC 10.5) and the generator's own test count.
pub fn classes(d: &TranslateDesign, txns: &[TranslateTxn]) -> BTreeMap<&'static str, usize> {
    let p = d.params();
    let mut c: BTreeMap<&'static str, usize> = BTreeMap::new();
    let mut hit = |k: &'static str| *c.entry(k).or_default() += 1;
    for t in txns {
        match t {
            TranslateTxn::Determine(r) => {
                let (i, o) = (&r.inputs, &r.outputs);
                let fmt = if i.format == 1 { BINARY64 } else { BINARY32 };
                if i.lod <= p.max_lod {
                    let k = (p.max_lod - i.lod) as i32;
                    for &bits in &i.placement {
                        if !fmt.fits(bits) {
                            continue;
                        }
                        let sign = 1u64 << (fmt.total_bits() - 1);
                        if bits == sign {
                            hit("negative_zero");
                        }
                        let exp = (bits >> fmt.frac_bits) & fmt.exp_field_max();
                        if exp == 0 && bits & !sign != 0 {
                            hit("subnormal");
                        }
                        if let Decoded::Finite(u) = unpack(fmt, bits) {
                            let shift = u.lsb_exponent - k;
                            if u.significand != 0 && shift < 0 {
                                let s = shift_right_round_sticky(
                                    u.significand,
                                    (-shift) as u32,
                                    fmt.precision(),
                                );
                                if s.round && !s.sticky {
                                    hit("tie");
                                }
                            }
                        }
                    }
                }
                for (k, v) in [
                    ("ok", o.ok),
                    ("err_lod", o.err_lod),
                    ("err_extents", o.err_extents),
                    ("err_width", o.err_width),
                    ("err_nan", o.err_nan),
                    ("err_inf", o.err_inf),
                    ("err_range", o.err_range),
                    ("err_outside", o.err_outside),
                    ("err_write_id", o.err_write_id),
                    ("written", o.written),
                    ("err_read_id", o.err_read_id),
                    ("read_valid", o.read_valid),
                ] {
                    if v != 0 {
                        hit(k);
                    }
                }
                if o.ok == 1 && i.lod == 0 {
                    hit("ok_at_lod_0");
                }
                if o.ok == 1 && i.lod == p.max_lod {
                    hit("ok_at_lod_max");
                }
                let max_code = (1u64 << p.max_lod) - 1;
                let neg_max = (1u64 << (p.max_lod + 1)) - max_code;
                if o.written == 1 && o.t.iter().any(|&t| t == max_code || t == neg_max) {
                    hit("written_t_max");
                }
            }
            TranslateTxn::Apply(r) => {
                hit(match r.outputs.code {
                    ApplyCode::Ok => "apply_ok",
                    ApplyCode::BadId => "apply_bad_id",
                    ApplyCode::EmptyEntry => "apply_empty",
                    ApplyCode::BadNode => "apply_bad_node",
                    ApplyCode::AboveLevel => "apply_above_level",
                    ApplyCode::OutsideX => "apply_outside_x",
                    ApplyCode::OutsideY => "apply_outside_y",
                    ApplyCode::OutsideZ => "apply_outside_z",
                });
                let v = r.inputs.node.voxel;
                if r.outputs.code == ApplyCode::Ok && v.lod == p.max_lod {
                    hit("apply_ok_at_deepest");
                }
                let moved = r.outputs.node.voxel;
                let far = 1u64 << p.max_lod.saturating_sub(1);
                if r.outputs.code == ApplyCode::Ok
                    && v.lod == p.max_lod
                    && (moved.x as i64 - v.x as i64).unsigned_abs() >= far
                {
                    hit("apply_ok_half_scene_move");
                }
            }
        }
    }
    c
}

/// The classes of [`classes`] that [`super::translate::generate`] produces on purpose for
/// design `d` (those its parameters make reachable).
pub fn expected_classes(d: &TranslateDesign) -> Vec<&'static str> {
    let p = d.params();
    let mut want = vec![
        "negative_zero",
        "subnormal",
        "tie",
        "ok",
        "err_extents",
        "err_nan",
        "err_inf",
        "err_range",
        "err_outside",
        "written",
        "read_valid",
        "ok_at_lod_0",
        "ok_at_lod_max",
        "written_t_max",
        "apply_ok",
        "apply_bad_node",
        "apply_outside_x",
        "apply_outside_y",
        "apply_outside_z",
        "apply_ok_at_deepest",
        "apply_ok_half_scene_move",
    ];
    if (1u32 << p.lod_bits()) - 1 > p.max_lod as u32 {
        want.push("err_lod");
    }
    if d.unit.table_depth > 1 {
        want.push("apply_empty");
    }
    if d.unit.table_depth < p.hier_capacity() as u32 {
        want.extend(["err_write_id", "err_read_id", "apply_bad_id"]);
    }
    if d.binary64 {
        want.push("err_width");
    }
    if p.max_lod > 1 {
        want.push("apply_above_level");
    }
    want
}
