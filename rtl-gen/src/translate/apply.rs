//! The apply path (SPEC.md 7.6, 7.9): node records in, moved records out,
//! one per clock. Step 1 reads the table entry of the record's hierarchy
//! and checks id, entry, node and level; step 2 shifts each translation,
//! `t << (d - L)`; step 3 adds it, `x' = x + (t << (d - L))`, and checks
//! `0 <= x' < 2^d`; step 4 picks the code and the record. A record with a
//! nonzero code leaves unchanged, with the code: nothing is dropped. The
//! shift, the add and the select each have a step because any two of them
//! in one clock were the unit's critical path (docs/hardware.md 14.7).

use golden::layout::NodeLayout;
use golden::translate::model::{ApplyCode, TranslateDesign};

use super::bundle::Bundle;
use super::ports::{apply_in_layout, apply_out_layout};
use super::table::Table;
use crate::{Module, Signal, Stream};

/// Builds the path: ports `apply_in_*`, `apply_out_*`. Returns the valid
/// bits of its registers, the output handshake and whether the leaving
/// record carries an error.
pub(crate) fn apply_path<'m>(
    m: &'m Module,
    d: &TranslateDesign,
    table: &Table<'m>,
) -> (Vec<Signal<'m>>, Signal<'m>, Signal<'m>) {
    let p = d.params();
    let dmax = p.max_lod as u32;
    let lb = p.lod_bits();
    let nl = NodeLayout::new(p);
    let in_layout = apply_in_layout(d);
    let input = Stream::input(m, "apply_in", in_layout.width());
    let record = input.data.slice(nl.width() - 1, 0).name("apply_record");
    let hier = input.data.view_named(&in_layout, "hier");

    // Step 1: the entry and every check that does not need the sums.
    let entry = table.read(hier, "apply_read");
    let lod = record.view(nl.lod());
    let coords = [0, 1, 2].map(|a| record.view(nl.coord(a)));
    let mut bad_node =
        coords[0].srl(lod).ne(0) | coords[1].srl(lod).ne(0) | coords[2].srl(lod).ne(0);
    if (1u32 << lb) - 1 > dmax {
        bad_node = lod.gt(dmax as u128) | bad_node;
    }
    let above = lod.lt(entry.lod);
    let code = |c: ApplyCode| m.lit(c as u128, ApplyCode::BITS);
    let early = bad_node.mux(
        code(ApplyCode::BadNode),
        above.mux(code(ApplyCode::AboveLevel), code(ApplyCode::Ok)),
    );
    let early = (!entry.valid).mux(code(ApplyCode::EmptyEntry), early);
    let early = match table.id_out_of_range(hier) {
        Some(o) => o.mux(code(ApplyCode::BadId), early),
        None => early,
    };
    let mut s1 = Bundle::new();
    s1.put("record", record);
    s1.put("hier", hier);
    s1.put("code", early.name("apply_early_code"));
    s1.put("shift", lod.sub(entry.lod, lb).name("apply_shift"));
    for (a, t) in entry.t.iter().enumerate() {
        s1.put(&format!("t{a}"), *t);
    }
    let (st1, b1) = s1.pipeline_reg(input.valid, input.ready, "apply_s1");

    // Step 2: the shifted translations, and the bits of a sum at or above
    // the record's level (`x' >> d != 0` is a nonzero masked sum).
    let record = b1.get("record");
    let lod = record.view(nl.lod());
    let shift = b1.get("shift");
    let sum_bits = 2 * dmax + 2;
    let mut s2 = Bundle::new();
    s2.put("record", record);
    s2.put("hier", b1.get("hier"));
    s2.put("code", b1.get("code"));
    let ones = m.lit((1u128 << sum_bits) - 1, sum_bits);
    s2.put("high", (ones << lod).name("apply_high"));
    for a in 0..3 {
        let t = b1.get(&format!("t{a}")).as_signed();
        s2.put(&format!("offset{a}"), t.sext(sum_bits) << shift);
    }
    let (st2, b2) = s2.pipeline_reg(st1.valid, st1.ready, "apply_s2");

    // Step 3: add per axis, range check.
    let record = b2.get("record");
    let high = b2.get("high");
    let mut moved = Vec::new();
    let mut outside = Vec::new();
    for a in 0..3 {
        let x = record.view(nl.coord(a));
        let sum = x
            .add(b2.get(&format!("offset{a}")), sum_bits)
            .name(&format!("apply_sum_{}", ["x", "y", "z"][a]));
        outside.push(sum.as_signed().lt(0) | (sum & high).ne(0));
        moved.push(sum.slice(dmax - 1, 0));
    }
    let mut s3 = Bundle::new();
    s3.put("record", record);
    s3.put("hier", b2.get("hier"));
    s3.put("code", b2.get("code"));
    for a in 0..3 {
        s3.put(&format!("moved{a}"), moved[a]);
        s3.put(&format!("outside{a}"), outside[a]);
    }
    let (st3, b3) = s3.pipeline_reg(st2.valid, st2.ready, "apply_s3");

    // Step 4: the final code and the record that leaves.
    let record = b3.get("record");
    let axis = ["x", "y", "z"];
    let moved = [0, 1, 2].map(|a| b3.get(&format!("moved{a}")));
    let outside = [0, 1, 2].map(|a| {
        b3.get(&format!("outside{a}"))
            .name(&format!("apply_outside_{}", axis[a]))
    });
    let early = b3.get("code");
    let late = outside[0].mux(
        code(ApplyCode::OutsideX),
        outside[1].mux(
            code(ApplyCode::OutsideY),
            outside[2].mux(code(ApplyCode::OutsideZ), code(ApplyCode::Ok)),
        ),
    );
    let final_code = early.ne(0).mux(early, late).name("apply_code");
    let (x, z) = (nl.x(), nl.z());
    let mut parts = vec![];
    if z.end() < nl.width() {
        parts.push(record.slice(nl.width() - 1, z.end()));
    }
    parts.extend([moved[2], moved[1], moved[0]]);
    parts.push(record.slice(x.offset - 1, 0));
    let moved_record = m.concat(&parts);
    let out_record = final_code.eq(0).mux(moved_record, record);
    let mut out = Bundle::new();
    out.put("record", out_record);
    out.put("hier", b3.get("hier"));
    out.put("code", final_code);
    debug_assert_eq!(out.width(), apply_out_layout(d).width());
    let (st4, b4) = out.skid_buffer(st3.valid, st3.ready, "apply_out_q");
    let error = b4.get("code").ne(0);
    let valid = st4.valid;
    st4.output("apply_out");
    (
        vec![st1.valid, st2.valid, st3.valid, st4.valid],
        valid & st4.ready,
        error,
    )
}
