//! The translation unit's stream payloads: which field sits where in each
//! `*_data` port (SPEC.md section 7.9), with every width taken from golden
//! (`Params`, `NodeLayout`, `trans_bits`), and packing of the golden
//! transactions into port values and back, for testbenches and tools.

use golden::layout::{Layout, NodeLayout};
use golden::store::NodeRecord;
use golden::translate::model::{ApplyCode, ApplyInputs, ApplyOutputs, TranslateDesign};
use golden::translate::translation::trans_bits;
use golden::translate::{TranslateInputs, TranslateOutputs};

use crate::Bits;

const AXES: [&str; 3] = ["x", "y", "z"];

/// Appends `{name}_x`, `{name}_y`, `{name}_z`, each `width` bits.
fn push3(l: &mut Layout, name: &str, width: u32) {
    for axis in AXES {
        l.push(&format!("{name}_{axis}"), width);
    }
}

/// `values` packed into `l`: every field given exactly once, each fitting
/// its width.
fn encode(l: &Layout, values: &[(String, u64)]) -> Result<Bits, String> {
    l.pack(values).map_err(|e| e.to_string())
}

/// `det_in_data`: `format` (binary64 designs only), `placement_{x,y,z}`
/// (32 or 64 bits), `lod`, `extents_lo_{x,y,z}`, `extents_hi_{x,y,z}` (D),
/// `write_enable`, `write_id`, `read_id` (H).
pub fn det_in_layout(d: &TranslateDesign) -> Layout {
    let p = d.params();
    let mut l = Layout::new("det_in_data");
    if d.binary64 {
        l.push("format", 1);
    }
    push3(&mut l, "placement", d.placement_bits());
    l.push("lod", p.lod_bits());
    push3(&mut l, "extents_lo", p.coord_bits());
    push3(&mut l, "extents_hi", p.coord_bits());
    l.push("write_enable", 1);
    l.push("write_id", p.hier_bits as u32);
    l.push("read_id", p.hier_bits as u32);
    l
}

/// `det_out_data`: `ok`, `t_{x,y,z}` (D+1), `residual_{x,y,z}` (32 or 64),
/// `err_lod`, `err_extents`, `err_width` (binary64 designs only), `err_nan`,
/// `err_inf`, `err_range`, `err_outside` (3 each, bit per axis),
/// `err_write_id`, `written`, `err_read_id`, `read_valid`, `read_lod`,
/// `read_t_{x,y,z}`.
pub fn det_out_layout(d: &TranslateDesign) -> Layout {
    let p = d.params();
    let tb = trans_bits(p);
    let mut l = Layout::new("det_out_data");
    l.push("ok", 1);
    push3(&mut l, "t", tb);
    push3(&mut l, "residual", d.placement_bits());
    l.push("err_lod", 1);
    l.push("err_extents", 1);
    if d.binary64 {
        l.push("err_width", 3);
    }
    for f in ["err_nan", "err_inf", "err_range", "err_outside"] {
        l.push(f, 3);
    }
    for f in ["err_write_id", "written", "err_read_id", "read_valid"] {
        l.push(f, 1);
    }
    l.push("read_lod", p.lod_bits());
    push3(&mut l, "read_t", tb);
    l
}

/// `apply_in_data`: the node record (golden `NodeLayout`, `W` bits) then
/// `hier` (H).
pub fn apply_in_layout(d: &TranslateDesign) -> Layout {
    apply_layout(d, "apply_in_data")
}

fn apply_layout(d: &TranslateDesign, name: &str) -> Layout {
    let p = d.params();
    let mut l = Layout::new(name);
    for f in NodeLayout::new(p).fields() {
        l.push(f.name, f.width);
    }
    l.push("hier", p.hier_bits as u32);
    l
}

/// `apply_out_data`: the node record, `hier`, then `code` (3 bits).
pub fn apply_out_layout(d: &TranslateDesign) -> Layout {
    let mut l = apply_layout(d, "apply_out_data");
    l.push("code", ApplyCode::BITS);
    l
}

fn named3(name: &str, v: [u64; 3]) -> impl Iterator<Item = (String, u64)> + '_ {
    AXES.iter()
        .zip(v)
        .map(move |(a, v)| (format!("{name}_{a}"), v))
}

/// The `det_in_data` value of a transaction's inputs.
pub fn pack_det_in(d: &TranslateDesign, i: &TranslateInputs) -> Result<Bits, String> {
    let mut v: Vec<(String, u64)> = Vec::new();
    if d.binary64 {
        v.push(("format".into(), i.format as u64));
    } else if i.format != 0 {
        return Err("format 1 (binary64) in a binary32-only design".into());
    }
    v.extend(named3("placement", i.placement));
    v.push(("lod".into(), i.lod as u64));
    v.extend(named3("extents_lo", i.extents_lo.map(u64::from)));
    v.extend(named3("extents_hi", i.extents_hi.map(u64::from)));
    v.push(("write_enable".into(), i.write_enable as u64));
    v.push(("write_id".into(), i.write_id as u64));
    v.push(("read_id".into(), i.read_id as u64));
    encode(&det_in_layout(d), &v)
}

/// The `det_out_data` value of a transaction's expected outputs.
pub fn pack_det_out(d: &TranslateDesign, o: &TranslateOutputs) -> Result<Bits, String> {
    let mut v: Vec<(String, u64)> = vec![("ok".into(), o.ok as u64)];
    v.extend(named3("t", o.t));
    v.extend(named3("residual", o.residual));
    v.push(("err_lod".into(), o.err_lod as u64));
    v.push(("err_extents".into(), o.err_extents as u64));
    if d.binary64 {
        v.push(("err_width".into(), o.err_width as u64));
    } else if o.err_width != 0 {
        return Err("err_width set in a binary32-only design".into());
    }
    for (n, x) in [
        ("err_nan", o.err_nan),
        ("err_inf", o.err_inf),
        ("err_range", o.err_range),
        ("err_outside", o.err_outside),
        ("err_write_id", o.err_write_id),
        ("written", o.written),
        ("err_read_id", o.err_read_id),
        ("read_valid", o.read_valid),
        ("read_lod", o.read_lod),
    ] {
        v.push((n.into(), x as u64));
    }
    v.extend(named3("read_t", o.read_t));
    encode(&det_out_layout(d), &v)
}

fn node_values(n: &NodeRecord) -> Vec<(String, u64)> {
    let v = n.voxel;
    let mut out: Vec<(String, u64)> =
        vec![("leaf".into(), n.leaf as u64), ("lod".into(), v.lod as u64)];
    out.extend(named3("", [v.x, v.y, v.z].map(u64::from)).map(|(k, x)| (k[1..].to_string(), x)));
    out.extend(named3("lo", n.lo.map(u64::from)));
    out.extend(named3("hi", n.hi.map(u64::from)));
    out.push(("first".into(), n.first as u64));
    out.push(("count".into(), n.count as u64));
    out
}

/// The `apply_in_data` value of an apply transaction's inputs.
pub fn pack_apply_in(d: &TranslateDesign, i: &ApplyInputs) -> Result<Bits, String> {
    let mut v = node_values(&i.node);
    v.push(("hier".into(), i.hier as u64));
    encode(&apply_in_layout(d), &v)
}

/// The `apply_out_data` value of an apply transaction's expected outputs.
pub fn pack_apply_out(d: &TranslateDesign, o: &ApplyOutputs) -> Result<Bits, String> {
    let mut v = node_values(&o.node);
    v.push(("hier".into(), o.hier as u64));
    v.push(("code".into(), o.code as u64));
    encode(&apply_out_layout(d), &v)
}
