//! The determine path (SPEC.md 7.2-7.5, 7.9): a stream of placement
//! transactions in, a stream of results out, the table written on the way.
//!
//! Five steps, one pipeline register after each, the last a skid buffer:
//! 1. unpack the encodings; level, `k = D - L`, extents validity;
//! 2. align (`m << a`);
//! 3. round half to even, field range;
//! 4. residual normalization, extents rule, flags, `ok` and `written`;
//! 5. read entry `read_id` and, on the edge the result leaves, write entry
//!    `write_id`. Reading in the same step as the write, before it, is
//!    golden's read-first order, and transactions reach this step in
//!    order. The alignment, the rounding, the extents rule and the table's
//!    write enable each have a step: any two in one clock were the unit's
//!    critical path (docs/hardware.md 14.7).

use golden::translate::model::TranslateDesign;

use super::bundle::Bundle;
use super::float::{align, pack_residual, round, unpack, FloatPath};
use super::ports::{det_in_layout, det_out_layout};
use super::table::Table;
use crate::{Module, Signal, Stream};

const AXES: [&str; 3] = ["x", "y", "z"];

/// Builds the path: ports `det_in_*`, `det_out_*`. Returns the valid bits
/// of its pipeline registers (for `idle`) and the output handshake (for
/// the error status).
pub(crate) fn determine_path<'m>(
    m: &'m Module,
    d: &TranslateDesign,
    table: &Table<'m>,
) -> (Vec<Signal<'m>>, Signal<'m>, Signal<'m>) {
    let p = d.params();
    let dmax = p.max_lod as u32;
    let fp = FloatPath {
        binary64: d.binary64,
        max_lod: dmax,
    };
    let input = Stream::input(m, "det_in", det_in_layout(d).width());
    let (s1, err_lod, format) = unpack_step(m, d, &fp, input.data);
    let (st1, b1) = s1.pipeline_reg(input.valid, input.ready, "det_s1");

    // Step 2.
    let mut sa = Bundle::new();
    for a in AXES {
        align(&fp, &b1, &format!("{a}_"), &mut sa);
    }
    for n in b1.names() {
        if !AXES.iter().any(|a| n.starts_with(&format!("{a}_"))) {
            sa.put(&n, b1.get(&n));
        }
    }
    let (sta, ba) = sa.pipeline_reg(st1.valid, st1.ready, "det_align");

    // Step 3.
    let mut s2 = Bundle::new();
    for a in AXES {
        round(&fp, &ba, &format!("{a}_"), &mut s2);
    }
    let mut common = vec![
        "err_extents",
        "lod",
        "write_enable",
        "write_id",
        "read_id",
        "k",
    ];
    for a in [
        "t_min_x", "t_min_y", "t_min_z", "t_max_x", "t_max_y", "t_max_z",
    ] {
        common.push(a);
    }
    if err_lod.is_some() {
        common.push("err_lod");
    }
    if format.is_some() {
        common.push("format");
    }
    for n in common {
        s2.put(n, ba.get(n));
    }
    let (st2, b2) = s2.pipeline_reg(sta.valid, sta.ready, "det_s2");

    // Step 4.
    let k = b2.get("k");
    let format = format.map(|_| b2.get("format"));
    let err_lod = err_lod.map(|_| b2.get("err_lod"));
    let err_extents = b2.get("err_extents");
    let zero = m.lit(0, 1);
    let live = err_lod.map(|e| !e);
    let gate = |s: Signal<'m>| match live {
        Some(l) => l & s,
        None => s,
    };
    let mut axes = Vec::new();
    let (mut nan, mut inf, mut range, mut wide, mut outside) =
        (vec![], vec![], vec![], vec![], vec![]);
    for a in AXES {
        let r = pack_residual(&fp, &b2, format, k, &format!("{a}_"));
        let t = r.t.sext(dmax + 2);
        let low = t.lt(b2.get(&format!("t_min_{a}")).as_signed());
        let high = t.ge(b2.get(&format!("t_max_{a}")).as_signed());
        let fault = match r.wide {
            Some(w) => w | r.nan | r.inf | r.range,
            None => r.nan | r.inf | r.range,
        };
        outside.push(gate(!err_extents & !fault & (low | high)));
        nan.push(gate(r.nan));
        inf.push(gate(r.inf));
        range.push(gate(r.range));
        if let Some(w) = r.wide {
            wide.push(gate(w));
        }
        axes.push(r);
    }
    let mask = |v: &[Signal<'m>]| m.concat(&[v[2], v[1], v[0]]);
    let (nan, inf, range, outside) = (mask(&nan), mask(&inf), mask(&range), mask(&outside));
    let wide = (!wide.is_empty()).then(|| mask(&wide));
    let err_extents = gate(err_extents);
    let mut any =
        err_extents | nan.reduce_or() | inf.reduce_or() | range.reduce_or() | outside.reduce_or();
    if let Some(w) = wide {
        any = any | w.reduce_or();
    }
    if let Some(e) = err_lod {
        any = any | e;
    }
    let ok = (!any).name("det_ok");

    let write_id = b2.get("write_id");
    let read_id = b2.get("read_id");
    let we = b2.get("write_enable");
    let err_write_id = match table.id_out_of_range(write_id) {
        Some(o) => we & o,
        None => zero,
    };
    let written = (we & ok & !err_write_id).name("det_written");
    let err_read_id = table.id_out_of_range(read_id).unwrap_or(zero);

    // Step 4's register holds the output payload but the entry read in
    // step 5 (with `t` and the residual not yet zeroed when not `ok`), then
    // what step 5 writes.
    let mut s3 = Bundle::new();
    s3.put("ok", ok);
    for (a, r) in AXES.iter().zip(&axes) {
        s3.put(&format!("t_{a}"), r.t.as_unsigned());
    }
    for (a, r) in AXES.iter().zip(&axes) {
        s3.put(&format!("residual_{a}"), r.residual);
    }
    s3.put("err_lod", err_lod.unwrap_or(zero));
    s3.put("err_extents", err_extents);
    if let Some(w) = wide {
        s3.put("err_width", w);
    }
    s3.put("err_nan", nan);
    s3.put("err_inf", inf);
    s3.put("err_range", range);
    s3.put("err_outside", outside);
    s3.put("err_write_id", err_write_id);
    s3.put("written", written);
    s3.put("err_read_id", err_read_id);
    let payload = s3.names();
    for n in ["lod", "write_id", "read_id"] {
        s3.put(n, b2.get(n));
    }
    let (st3, b3) = s3.pipeline_reg(st2.valid, st2.ready, "det_s3");

    read_write_step(m, d, table, (st3, b3), &payload, &[st1, sta, st2])
}

/// Step 1 on the `det_in` beat `data`: the encodings unpacked, `k = D -
/// L`, the extents' validity and bounds on `t` (the bundle before
/// `det_s1`); with `err_lod` where `L` can exceed `D` and `format` where
/// binary64 is built.
fn unpack_step<'m>(
    m: &'m Module,
    d: &TranslateDesign,
    fp: &FloatPath,
    data: Signal<'m>,
) -> (Bundle<'m>, Option<Signal<'m>>, Option<Signal<'m>>) {
    let p = d.params();
    let (dmax, lb) = (p.max_lod as u32, p.lod_bits());
    let in_layout = det_in_layout(d);
    let get = |n: &str| data.view_named(&in_layout, n);
    let mut s1 = Bundle::new();
    let lod = get("lod");
    let format = d.binary64.then(|| get("format"));
    let err_lod = ((1u32 << lb) - 1 > dmax).then(|| lod.gt(dmax as u128).name("err_lod"));
    let k = m.lit(dmax as u128, lb).sub(lod, lb).name("k");
    for a in AXES {
        unpack(
            fp,
            get(&format!("placement_{a}")),
            format,
            k,
            &format!("{a}_"),
            &mut s1,
        );
    }
    let mut bad_extents = Vec::new();
    for a in AXES {
        let (lo, hi) = (
            get(&format!("extents_lo_{a}")),
            get(&format!("extents_hi_{a}")),
        );
        bad_extents.push(lo.gt(hi) | hi.srl(lod).ne(0));
        // The extents rule's bounds on t, so that step 4 compares without
        // adding: `lo + t < 0` is `t < -lo`, `hi + t >= 2^L` is
        // `t >= 2^L - hi` (signed D + 2 bits hold every operand; past D,
        // `err_lod` masks the rule).
        let wide = dmax + 2;
        let limit = m.lit(1, wide) << lod;
        s1.put(&format!("t_min_{a}"), m.lit(0, wide).sub(lo, wide));
        s1.put(&format!("t_max_{a}"), limit.sub(hi, wide));
    }
    let err_extents = bad_extents[0] | bad_extents[1] | bad_extents[2];
    s1.put("err_extents", err_extents);
    if let Some(e) = err_lod {
        s1.put("err_lod", e);
    }
    if let Some(f) = format {
        s1.put("format", f);
    }
    for n in ["lod", "write_enable", "write_id", "read_id"] {
        s1.put(n, get(n));
    }
    s1.put("k", k);
    (s1, err_lod, format)
}

/// Step 5 after `det_s3` (`b3`, its stream `st3`): entry `read_id` read
/// into the output payload (`t` and the residual zeroed when not `ok`),
/// entry `write_id` written on the edge the result leaves, the skid buffer
/// `det_out_q` onto `det_out`. Returns what [`determine_path`] returns,
/// `earlier` being the streams of the registers before `det_s3`.
fn read_write_step<'m>(
    m: &'m Module,
    d: &TranslateDesign,
    table: &Table<'m>,
    (st3, b3): (Stream<'m>, Bundle<'m>),
    payload: &[String],
    earlier: &[Stream<'m>],
) -> (Vec<Signal<'m>>, Signal<'m>, Signal<'m>) {
    let read_id = b3.get("read_id");
    let entry = table.read(read_id, "det_read");
    let ok = b3.get("ok");
    let mut out = Bundle::new();
    for n in payload {
        let v = b3.get(n);
        if n.starts_with("t_") || n.starts_with("residual_") {
            out.put(n, ok.mux(v, m.lit(0, v.width())));
        } else {
            out.put(n, v);
        }
    }
    out.put("read_valid", entry.valid);
    out.put("read_lod", entry.lod);
    for (a, t) in AXES.iter().zip(entry.t) {
        out.put(&format!("read_t_{a}"), t.as_unsigned());
    }
    // The bundle is built in the payload's field order (ports.rs).
    debug_assert_eq!(out.width(), det_out_layout(d).width());
    let (st4, _) = out.skid_buffer(st3.valid, st3.ready, "det_out_q");
    // The entry is written on the edge the result leaves step 5.
    let t = AXES.map(|a| b3.get(&format!("t_{a}")).as_signed());
    let written = b3.get("written");
    table.write(b3.get("write_id"), b3.get("lod"), t, st3.fire() & written);
    let out_fire_valid = st4.valid;
    let ok_out = st4.data.bit(0);
    st4.output("det_out");
    let out_fire = out_fire_valid & st4.ready;
    let mut valids: Vec<Signal<'m>> = earlier.iter().map(|s| s.valid).collect();
    valids.extend([st3.valid, out_fire_valid]);
    (valids, out_fire, !ok_out)
}
