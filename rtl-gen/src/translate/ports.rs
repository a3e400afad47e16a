//! The translation unit's stream payloads: which field sits where in each
//! `*_data` port (SPEC.md section 7.9), with every width taken from golden
//! (`Params`, `NodeLayout`, `trans_bits`), and packing of the golden
//! transactions into port values and back, for testbenches and tools.

use golden::layout::NodeLayout;
use golden::store::NodeRecord;
use golden::translate::model::{ApplyCode, ApplyInputs, ApplyOutputs, TranslateDesign};
use golden::translate::translation::trans_bits;
use golden::translate::{TranslateInputs, TranslateOutputs};

use crate::Bits;

/// One field of a payload: bits `[offset, offset + width)`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PortField {
    /// Field name (SPEC.md 7.9), axis fields suffixed `_x`, `_y`, `_z`.
    pub name: String,
    /// Bit of the field's lsb in the payload.
    pub offset: u32,
    /// Bits.
    pub width: u32,
}

/// A payload layout: fields packed from bit 0 upward in order.
#[derive(Clone, Debug, PartialEq, Eq, Default)]
pub struct PortLayout {
    /// Fields in bit order.
    pub fields: Vec<PortField>,
}

impl PortLayout {
    fn push(&mut self, name: &str, width: u32) {
        let offset = self.width();
        self.fields.push(PortField {
            name: name.to_string(),
            offset,
            width,
        });
    }

    fn push3(&mut self, name: &str, width: u32) {
        for axis in AXES {
            self.push(&format!("{name}_{axis}"), width);
        }
    }

    /// Total width in bits.
    pub fn width(&self) -> u32 {
        self.fields.last().map(|f| f.offset + f.width).unwrap_or(0)
    }

    /// The field called `name`.
    pub fn field(&self, name: &str) -> Option<&PortField> {
        self.fields.iter().find(|f| f.name == name)
    }

    /// Every field's value in `bits` (fields are at most 64 bits wide).
    pub fn decode(&self, bits: &Bits) -> Vec<(String, u64)> {
        self.fields
            .iter()
            .map(|f| {
                let v = if f.width == 0 {
                    0
                } else {
                    bits.extract(f.offset, f.width)
                        .ok()
                        .and_then(|b| b.to_u64())
                        .unwrap_or(u64::MAX)
                };
                (f.name.clone(), v)
            })
            .collect()
    }

    /// Packs `(name, value)` pairs; every field must be given exactly once
    /// and fit its width.
    pub fn encode(&self, values: &[(String, u64)]) -> Result<Bits, String> {
        let w = self.width();
        let mut words = vec![0u64; w.div_ceil(64).max(1) as usize];
        for f in &self.fields {
            let mut found = values.iter().filter(|(n, _)| *n == f.name);
            let v = match (found.next(), found.next()) {
                (Some((_, v)), None) => *v,
                _ => return Err(format!("field `{}` missing or given twice", f.name)),
            };
            if f.width < 64 && v >> f.width != 0 {
                return Err(format!(
                    "field `{}`: {v} does not fit in {} bits",
                    f.name, f.width
                ));
            }
            put(&mut words, f.offset, f.width, v);
        }
        if values.len() != self.fields.len() {
            return Err("a value names no field of the layout".into());
        }
        Bits::from_words(&words, w).map_err(|e| format!("{e:?}"))
    }
}

const AXES: [&str; 3] = ["x", "y", "z"];

fn put(words: &mut [u64], offset: u32, width: u32, v: u64) {
    for i in 0..width {
        if (v >> i) & 1 == 1 {
            let b = offset + i;
            words[(b / 64) as usize] |= 1 << (b % 64);
        }
    }
}

/// `det_in_data`: `format` (binary64 designs only), `placement_{x,y,z}`
/// (32 or 64 bits), `lod`, `extents_lo_{x,y,z}`, `extents_hi_{x,y,z}` (D),
/// `write_enable`, `write_id`, `read_id` (H).
pub fn det_in_layout(d: &TranslateDesign) -> PortLayout {
    let p = d.params();
    let mut l = PortLayout::default();
    if d.binary64 {
        l.push("format", 1);
    }
    l.push3("placement", d.placement_bits());
    l.push("lod", p.lod_bits());
    l.push3("extents_lo", p.coord_bits());
    l.push3("extents_hi", p.coord_bits());
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
pub fn det_out_layout(d: &TranslateDesign) -> PortLayout {
    let p = d.params();
    let tb = trans_bits(p);
    let mut l = PortLayout::default();
    l.push("ok", 1);
    l.push3("t", tb);
    l.push3("residual", d.placement_bits());
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
    l.push3("read_t", tb);
    l
}

/// `apply_in_data`: the node record (golden `NodeLayout`, `W` bits) then
/// `hier` (H).
pub fn apply_in_layout(d: &TranslateDesign) -> PortLayout {
    let p = d.params();
    let mut l = PortLayout::default();
    for f in NodeLayout::new(p).fields() {
        l.push(f.name, f.width);
    }
    l.push("hier", p.hier_bits as u32);
    l
}

/// `apply_out_data`: the node record, `hier`, then `code` (3 bits).
pub fn apply_out_layout(d: &TranslateDesign) -> PortLayout {
    let mut l = apply_in_layout(d);
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
    det_in_layout(d).encode(&v)
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
    det_out_layout(d).encode(&v)
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
    apply_in_layout(d).encode(&v)
}

/// The `apply_out_data` value of an apply transaction's expected outputs.
pub fn pack_apply_out(d: &TranslateDesign, o: &ApplyOutputs) -> Result<Bits, String> {
    let mut v = node_values(&o.node);
    v.push(("hier".into(), o.hier as u64));
    v.push(("code".into(), o.code as u64));
    apply_out_layout(d).encode(&v)
}
