//! Translate-unit vectors (`hiermerge vectors --unit translate`, SPEC.md
//! sections 7.9 and 9): the seeded generator that reaches every hard case on
//! purpose, and the file form. The configuration ([`TranslateDesign`]) and
//! the transaction model ([`TranslateModel`]: determine and apply) are the
//! unit's own, in [`crate::translate::model`].

use std::path::Path;

use serde_json::{json, Value};

use super::{read_jsonl, write_jsonl, Fields, Header, ParamMap, UnitKind, VectorError};
use crate::grid::VoxelAddr;
use crate::layout::NodeLayout;
use crate::params::Params;
use crate::store::NodeRecord;
use crate::translate::float::Format;
use crate::translate::model::{
    ApplyCode, ApplyInputs, ApplyOutputs, ApplyRecord, TranslateDesign, TranslateModel,
    TranslateTxn, TxnInputs,
};
use crate::translate::stimulus::{hard_cases, random_inputs, SplitMix64};
use crate::translate::table::TranslationTable;
use crate::translate::translation::trans_bits;
use crate::translate::{
    TranslateError, TranslateInputs, TranslateOutputs, TranslateRecord, Translation,
};

impl TranslateDesign {
    /// Every parameter, as the vector header lists it.
    pub fn param_map(&self) -> ParamMap {
        let p = self.params();
        [
            ("max_lod", json!(p.max_lod)),
            ("quant_bits", json!(p.quant_bits)),
            ("index_bits", json!(p.index_bits)),
            ("hier_bits", json!(p.hier_bits)),
            ("table_depth", json!(self.unit.table_depth)),
            ("binary64", json!(self.binary64)),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v))
        .collect()
    }
}

// ---------------------------------------------------------------------------
// Generation

/// How the generator schedules kinds: blocks of this many transactions, the
/// first [`DETERMINE_PER_BLOCK`] of each determine, the rest apply.
pub const BLOCK: usize = 128;
/// Determine transactions at the start of each block.
pub const DETERMINE_PER_BLOCK: usize = 32;

/// The determine categories, each given the same share of the determine
/// slots (slot `i` takes category `i mod len`).
pub const DETERMINE_CATEGORIES: [&str; 15] = [
    "random",
    "random",
    "load_table",
    "bad_width",
    "tie",
    "subnormal",
    "negative_zero",
    "nan",
    "infinity",
    "huge_exponent",
    "extents_edge",
    "lod_extreme",
    "bad_lod",
    "bad_extents",
    "bad_ids",
];

/// The apply categories, each given the same share of the apply slots.
pub const APPLY_CATEGORIES: [&str; 12] = [
    "inside",
    "inside",
    "inside",
    "deepest_shift",
    "at_level",
    "above_level",
    "outside_x",
    "outside_y",
    "outside_z",
    "bad_id",
    "empty_entry",
    "bad_node",
];

/// Generates `count` transactions from `seed`, deterministically: blocks of
/// [`BLOCK`] transactions (determine first, then apply), every category in
/// [`DETERMINE_CATEGORIES`] / [`APPLY_CATEGORIES`] in turn, then the golden
/// hard cases ([`hard_cases`], those this design's ports carry; they write
/// every table entry, so they come last). With `count` below the number of
/// hard cases, the first `count` hard cases only. The generated writes use
/// only the lower half of the table, so that empty entries stay to be hit.
pub fn generate(
    design: &TranslateDesign,
    seed: u64,
    count: usize,
) -> Result<Vec<TranslateTxn>, VectorError> {
    let model_err = |e: TranslateError| VectorError::Model {
        what: format!("{} ({e:?})", design.tag()),
    };
    let mut model = TranslateModel::new(*design).map_err(model_err)?;
    let mut gen = Generator {
        design: *design,
        rng: SplitMix64(seed),
    };
    super::check_count("--count", count as u64, super::MAX_COUNT)
        .map_err(|what| VectorError::Model { what })?;
    let mut out = Vec::with_capacity(count);
    let hard: Vec<TranslateInputs> = hard_cases(&design.unit)
        .into_iter()
        .filter(|i| gen.carried(i))
        .collect();
    let (mut det, mut app) = (0usize, 0usize);
    for slot in 0..count.saturating_sub(hard.len()) {
        let inputs = if slot % BLOCK < DETERMINE_PER_BLOCK {
            det += 1;
            let cat = DETERMINE_CATEGORIES[(det - 1) % DETERMINE_CATEGORIES.len()];
            TxnInputs::Determine(gen.determine(cat))
        } else {
            app += 1;
            let cat = APPLY_CATEGORIES[(app - 1) % APPLY_CATEGORIES.len()];
            TxnInputs::Apply(gen.apply(cat, model.table()))
        };
        out.push(model.run(&inputs).map_err(model_err)?);
    }
    for i in hard.into_iter().take(count - out.len()) {
        out.push(model.run(&TxnInputs::Determine(i)).map_err(model_err)?);
    }
    Ok(out)
}

struct Generator {
    design: TranslateDesign,
    rng: SplitMix64,
}

impl Generator {
    fn p(&self) -> Params {
        self.design.unit.params
    }

    /// True when this design's ports carry the transaction.
    fn carried(&self, i: &TranslateInputs) -> bool {
        self.design.binary64 || (i.format == 0 && i.placement.iter().all(|b| b >> 32 == 0))
    }

    fn format(&mut self) -> Format {
        if self.design.binary64 && self.rng.below(2) == 1 {
            Format::Binary64
        } else {
            Format::Binary32
        }
    }

    /// A table id for generated writes: the lower half of the table.
    fn write_id(&mut self) -> u32 {
        self.rng
            .below((self.design.unit.table_depth as u64 / 2).max(1)) as u32
    }

    /// A random transaction of golden's stimulus this design carries
    /// (writes inside the table folded into its lower half).
    fn random(&mut self) -> TranslateInputs {
        loop {
            let mut i = random_inputs(&mut self.rng, &self.design.unit);
            if i.write_id < self.design.unit.table_depth {
                i.write_id %= (self.design.unit.table_depth / 2).max(1);
            }
            if self.carried(&i) {
                return i;
            }
        }
    }

    fn encode(format: Format, v: f64) -> u64 {
        match format {
            Format::Binary32 => (v as f32).to_bits() as u64,
            Format::Binary64 => v.to_bits(),
        }
    }

    /// A placement inside the scene for every axis, with a valid range of
    /// extents, at level `lod`, in `format`: the starting point of most
    /// categories, which then spoil one axis on purpose.
    fn placed(&mut self, format: Format, lod: u8) -> TranslateInputs {
        let p = self.p();
        let d = p.max_lod;
        let n = 1i64 << lod;
        let k = (d - lod) as i32;
        let mut i = TranslateInputs {
            format: format.flag(),
            placement: [0; 3],
            lod,
            extents_lo: [0; 3],
            extents_hi: [0; 3],
            write_enable: 0,
            write_id: 0,
            read_id: self.rng.below(p.hier_capacity()) as u32,
        };
        for a in 0..3 {
            let lo = self.rng.below(n as u64) as i64;
            let hi = (lo + self.rng.below(3) as i64).min(n - 1);
            i.extents_lo[a] = lo as u32;
            i.extents_hi[a] = hi as u32;
            let t = self.rng.range_i64(-lo, n - 1 - hi);
            // A fraction below half a voxel with at most 16 bits, so that
            // binary32 keeps it whenever |t| < 2^7.
            let frac = self.rng.range_i64(-(1 << 15) + 1, (1 << 15) - 1) as f64 / 65536.0;
            i.placement[a] = Self::encode(format, (t as f64 + frac) * 2f64.powi(k));
        }
        i
    }

    fn any_lod(&mut self) -> u8 {
        self.rng.below(self.p().max_lod as u64 + 1) as u8
    }

    fn determine(&mut self, category: &str) -> TranslateInputs {
        let p = self.p();
        let d = p.max_lod;
        let format = self.format();
        let lod = self.any_lod();
        let axis = self.rng.below(3) as usize;
        let mut i = self.placed(format, lod);
        let k = (d - lod) as i32;
        let sign = if self.rng.below(2) == 0 { 1.0 } else { -1.0 };
        match category {
            "load_table" => {
                i.write_enable = 1;
                i.write_id = self.write_id();
                // The largest moves now and then: the whole scene edge,
                // half of them at the deepest level (`|t| = 2^D - 1`).
                if self.rng.below(2) == 0 {
                    if self.rng.below(2) == 0 {
                        let id = i.write_id;
                        i = self.placed(format, d);
                        i.write_enable = 1;
                        i.write_id = id;
                    }
                    let (lod, k) = (i.lod, (d - i.lod) as i32);
                    let edge = (1u32 << lod) - 1;
                    let to_top = self.rng.below(2) == 0;
                    i.extents_lo[axis] = if to_top { 0 } else { edge };
                    i.extents_hi[axis] = i.extents_lo[axis];
                    let t = if to_top { edge as f64 } else { -(edge as f64) };
                    i.placement[axis] = Self::encode(format, t * 2f64.powi(k));
                }
            }
            "tie" => {
                let n = 1i64 << lod.min(20);
                let j = self.rng.range_i64(-n, n - 1);
                i.placement[axis] = Self::encode(format, (2 * j + 1) as f64 * 2f64.powi(k - 1));
                i.extents_lo[axis] = 0;
                i.extents_hi[axis] = 0;
            }
            "subnormal" => {
                let bits = match format {
                    Format::Binary32 => {
                        (self.rng.below((1 << 23) - 1) + 1) | ((sign < 0.0) as u64) << 31
                    }
                    Format::Binary64 => {
                        (self.rng.below((1 << 52) - 1) + 1) | ((sign < 0.0) as u64) << 63
                    }
                };
                i.placement[axis] = bits;
            }
            "negative_zero" => i.placement[axis] = Self::encode(format, -0.0),
            // A binary32 encoding with bits above bit 31 (64-bit ports only).
            "bad_width" if self.design.binary64 => {
                i.format = 0;
                i.placement = i.placement.map(|b| b & 0xffff_ffff);
                i.placement[axis] |= (self.rng.below(u32::MAX as u64) + 1) << 32;
            }
            "nan" => {
                i.placement[axis] = match format {
                    Format::Binary32 => {
                        0x7f80_0000
                            | (self.rng.below((1 << 23) - 1) + 1)
                            | (self.rng.below(2) << 31)
                    }
                    Format::Binary64 => {
                        0x7ff0_0000_0000_0000
                            | (self.rng.below((1 << 52) - 1) + 1)
                            | (self.rng.below(2) << 63)
                    }
                }
            }
            "infinity" => i.placement[axis] = Self::encode(format, sign * f64::INFINITY),
            "huge_exponent" => {
                // At or beyond 2^D voxels: always out of the field.
                let e = d as i32 + k + self.rng.below(60) as i32;
                i.placement[axis] = Self::encode(format, sign * 1.25 * 2f64.powi(e.min(127)));
            }
            "extents_edge" => {
                // Exactly at the scene's edge, or one voxel past it.
                let edge = (1u32 << lod) - 1;
                let past = self.rng.below(2) as i64;
                let (lo, hi, t) = if self.rng.below(2) == 0 {
                    let lo = self.rng.below(edge as u64 + 1) as u32;
                    (lo, edge, -(lo as i64) - past)
                } else {
                    let hi = self.rng.below(edge as u64 + 1) as u32;
                    (0, hi, (edge - hi) as i64 + past)
                };
                i.extents_lo[axis] = lo;
                i.extents_hi[axis] = hi;
                i.placement[axis] = Self::encode(format, t as f64 * 2f64.powi(k));
            }
            "lod_extreme" => {
                let lod = if self.rng.below(2) == 0 { 0 } else { d };
                i = self.placed(format, lod);
                i.write_enable = 1;
                i.write_id = self.write_id();
            }
            "bad_lod" => {
                let top = (1u32 << p.lod_bits()) - 1;
                if top > d as u32 {
                    i.lod = d + 1 + self.rng.below((top - d as u32) as u64) as u8;
                }
                i.write_enable = 1;
            }
            "bad_extents" => {
                if self.rng.below(2) == 0 && lod > 0 {
                    i.extents_lo[axis] = i.extents_hi[axis] + 1;
                    i.extents_lo[axis] &= (1u32 << lod) - 1;
                    if i.extents_lo[axis] <= i.extents_hi[axis] {
                        i.extents_hi[axis] = 0;
                        i.extents_lo[axis] = 1;
                    }
                } else if lod < d {
                    i.extents_hi[axis] = (1u32 << lod) + self.rng.below(1 << lod) as u32;
                } else {
                    i.extents_lo[axis] = 1;
                    i.extents_hi[axis] = 0;
                }
            }
            "bad_ids" => {
                i.write_enable = 1;
                let cap = p.hier_capacity();
                let depth = self.design.unit.table_depth as u64;
                let past = |rng: &mut SplitMix64| {
                    if depth < cap {
                        (depth + rng.below(cap - depth)) as u32
                    } else {
                        rng.below(cap) as u32
                    }
                };
                i.write_id = past(&mut self.rng);
                i.read_id = past(&mut self.rng);
            }
            _ => i = self.random(),
        }
        i
    }

    /// A record with a random box, leaf flag and range around `voxel`.
    fn node(&mut self, voxel: VoxelAddr) -> NodeRecord {
        let p = self.p();
        let q = p.quant_bits as u32;
        let cells = 1u64 << q;
        let mut lo = [0u16; 3];
        let mut hi = [0u16; 3];
        for a in 0..3 {
            let l = self.rng.below(cells);
            lo[a] = l as u16;
            hi[a] = (l + self.rng.below(cells - l)) as u16;
        }
        let imax = p.index_capacity();
        NodeRecord {
            leaf: self.rng.below(2) == 1,
            voxel,
            lo,
            hi,
            first: self.rng.below(imax) as u32,
            count: (1 + self.rng.below(imax - 1).min(imax - 2)) as u32,
        }
    }

    /// Valid table entries (id, translation).
    fn entries(table: &TranslationTable) -> Vec<(u32, Translation)> {
        (0..table.depth() as u32)
            .filter_map(|id| table.get(id).ok().flatten().map(|t| (id, t)))
            .collect()
    }

    /// A coordinate at LOD `d` whose move by `off` lands inside `[0, 2^d)`,
    /// or any coordinate when none does.
    fn coord_inside(&mut self, d: u8, off: i64) -> u32 {
        let n = 1i64 << d;
        let (lo, hi) = (0i64.max(-off), (n - 1).min(n - 1 - off));
        if lo <= hi {
            self.rng.range_i64(lo, hi) as u32
        } else {
            self.rng.below(n as u64) as u32
        }
    }

    /// A coordinate at LOD `d` whose move by `off` leaves `[0, 2^d)`, if any.
    fn coord_outside(&mut self, d: u8, off: i64) -> Option<u32> {
        let n = 1i64 << d;
        if off > 0 {
            // x + off >= n  <=>  x >= n - off
            Some(self.rng.range_i64((n - off).max(0), n - 1) as u32)
        } else if off < 0 {
            Some(self.rng.range_i64(0, (-off - 1).min(n - 1)) as u32)
        } else {
            None
        }
    }

    fn apply(&mut self, category: &str, table: &TranslationTable) -> ApplyInputs {
        let p = self.p();
        let d_max = p.max_lod;
        let entries = Self::entries(table);
        let depth = table.depth() as u64;
        let cap = p.hier_capacity();
        let pick = match entries.len() {
            0 => None,
            n => Some(entries[self.rng.below(n as u64) as usize]),
        };
        let Some((id, t)) = pick else {
            // Nothing written yet: an empty entry or an id past the table.
            let voxel = VoxelAddr::new(0, 0, 0, 0);
            return ApplyInputs {
                hier: self.rng.below(cap) as u32,
                node: self.node(voxel),
            };
        };
        let shifted = |d: u8, a: usize| t.t[a] << (d - t.lod);
        let moved_inside = |g: &mut Generator, d: u8| {
            let c = [0, 1, 2].map(|a| g.coord_inside(d, shifted(d, a)));
            VoxelAddr::new(d, c[0], c[1], c[2])
        };
        let voxel = match category {
            "deepest_shift" => moved_inside(self, d_max),
            "at_level" => moved_inside(self, t.lod),
            "above_level" if t.lod > 0 => {
                let d = self.rng.below(t.lod as u64) as u8;
                let c = [0; 3].map(|_| self.rng.below(1 << d) as u32);
                VoxelAddr::new(d, c[0], c[1], c[2])
            }
            "outside_x" | "outside_y" | "outside_z" => {
                let a = match category {
                    "outside_x" => 0,
                    "outside_y" => 1,
                    _ => 2,
                };
                let d = t.lod + self.rng.below((d_max - t.lod) as u64 + 1) as u8;
                let mut v = moved_inside(self, d);
                if let Some(x) = self.coord_outside(d, shifted(d, a)) {
                    match a {
                        0 => v.x = x,
                        1 => v.y = x,
                        _ => v.z = x,
                    }
                }
                v
            }
            "bad_node" => {
                let top = (1u32 << p.lod_bits()) - 1;
                let d = t.lod + self.rng.below((d_max - t.lod) as u64 + 1) as u8;
                if top > d_max as u32 && self.rng.below(2) == 0 {
                    let lod = d_max + 1 + self.rng.below((top - d_max as u32) as u64) as u8;
                    VoxelAddr::new(lod, 0, 0, 0)
                } else if d < d_max {
                    let mut v = moved_inside(self, d);
                    v.y = (1u32 << d) + self.rng.below((1u64 << d_max) - (1u64 << d)) as u32;
                    v
                } else {
                    moved_inside(self, d)
                }
            }
            _ => {
                let d = t.lod + self.rng.below((d_max - t.lod) as u64 + 1) as u8;
                moved_inside(self, d)
            }
        };
        let hier = match category {
            "bad_id" if depth < cap => (depth + self.rng.below(cap - depth)) as u32,
            "empty_entry" => {
                let empty: Vec<u32> = (0..depth as u32)
                    .filter(|i| table.get(*i).ok().flatten().is_none())
                    .collect();
                match empty.len() {
                    0 => id,
                    n => empty[self.rng.below(n as u64) as usize],
                }
            }
            _ => id,
        };
        ApplyInputs {
            hier,
            node: self.node(voxel),
        }
    }
}

// ---------------------------------------------------------------------------
// File form

fn node_to_json(n: &NodeRecord) -> Value {
    json!({
        "leaf": n.leaf as u8,
        "lod": n.voxel.lod,
        "x": n.voxel.x, "y": n.voxel.y, "z": n.voxel.z,
        "lo_x": n.lo[0], "lo_y": n.lo[1], "lo_z": n.lo[2],
        "hi_x": n.hi[0], "hi_y": n.hi[1], "hi_z": n.hi[2],
        "first": n.first,
        "count": n.count,
    })
}

fn node_from_json(f: &Fields, p: &Params) -> Result<NodeRecord, VectorError> {
    let l = NodeLayout::new(p);
    let get = |field: &crate::layout::Field| f.uint(field.name, field.width);
    Ok(NodeRecord {
        leaf: get(l.leaf())? == 1,
        voxel: VoxelAddr::new(
            get(l.lod())? as u8,
            get(l.x())? as u32,
            get(l.y())? as u32,
            get(l.z())? as u32,
        ),
        lo: [
            get(l.lo(0))? as u16,
            get(l.lo(1))? as u16,
            get(l.lo(2))? as u16,
        ],
        hi: [
            get(l.hi(0))? as u16,
            get(l.hi(1))? as u16,
            get(l.hi(2))? as u16,
        ],
        first: get(l.first())? as u32,
        count: get(l.count())? as u32,
    })
}

/// A transaction as its JSON line.
pub fn txn_to_json(t: &TranslateTxn) -> Value {
    match t {
        TranslateTxn::Determine(r) => {
            let (i, o) = (&r.inputs, &r.outputs);
            json!({
                "op": "determine",
                "in": {
                    "format": i.format, "placement": i.placement, "lod": i.lod,
                    "extents_lo": i.extents_lo, "extents_hi": i.extents_hi,
                    "write_enable": i.write_enable, "write_id": i.write_id, "read_id": i.read_id,
                },
                "out": {
                    "ok": o.ok, "t": o.t, "residual": o.residual,
                    "err_lod": o.err_lod, "err_extents": o.err_extents, "err_width": o.err_width,
                    "err_nan": o.err_nan, "err_inf": o.err_inf, "err_range": o.err_range,
                    "err_outside": o.err_outside, "err_write_id": o.err_write_id,
                    "written": o.written, "err_read_id": o.err_read_id,
                    "read_valid": o.read_valid, "read_lod": o.read_lod, "read_t": o.read_t,
                },
            })
        }
        TranslateTxn::Apply(r) => json!({
            "op": "apply",
            "in": { "hier": r.inputs.hier, "node": node_to_json(&r.inputs.node) },
            "out": {
                "code": r.outputs.code as u8,
                "hier": r.outputs.hier,
                "node": node_to_json(&r.outputs.node),
            },
        }),
    }
}

/// Decodes one record line, checking every field against its port width.
pub fn txn_from_json(f: &Fields, design: &TranslateDesign) -> Result<TranslateTxn, VectorError> {
    let p = design.params();
    let (lod, d, h, tb) = (
        p.lod_bits(),
        p.coord_bits(),
        p.hier_bits as u32,
        trans_bits(p),
    );
    let pb = design.placement_bits();
    match f.string("op")? {
        "determine" => {
            let i = f.object("in")?;
            let o = f.object("out")?;
            let u3 = |v: [u64; 3]| v.map(|x| x as u32);
            let format = i.uint("format", 1)? as u8;
            if format == 1 && !design.binary64 {
                return Err(i.bad("format", "0 (this design has no binary64)"));
            }
            let inputs = TranslateInputs {
                format,
                placement: i.uints("placement", pb)?,
                lod: i.uint("lod", lod)? as u8,
                extents_lo: u3(i.uints("extents_lo", d)?),
                extents_hi: u3(i.uints("extents_hi", d)?),
                write_enable: i.uint("write_enable", 1)? as u8,
                write_id: i.uint("write_id", h)? as u32,
                read_id: i.uint("read_id", h)? as u32,
            };
            if !design.binary64 && o.uint("err_width", 3)? != 0 {
                return Err(o.bad("err_width", "0 (this design has no binary64)"));
            }
            let outputs = TranslateOutputs {
                ok: o.uint("ok", 1)? as u8,
                t: o.uints("t", tb)?,
                residual: o.uints("residual", pb)?,
                err_lod: o.uint("err_lod", 1)? as u8,
                err_extents: o.uint("err_extents", 1)? as u8,
                err_width: o.uint("err_width", 3)? as u8,
                err_nan: o.uint("err_nan", 3)? as u8,
                err_inf: o.uint("err_inf", 3)? as u8,
                err_range: o.uint("err_range", 3)? as u8,
                err_outside: o.uint("err_outside", 3)? as u8,
                err_write_id: o.uint("err_write_id", 1)? as u8,
                written: o.uint("written", 1)? as u8,
                err_read_id: o.uint("err_read_id", 1)? as u8,
                read_valid: o.uint("read_valid", 1)? as u8,
                read_lod: o.uint("read_lod", lod)? as u8,
                read_t: o.uints("read_t", tb)?,
            };
            Ok(TranslateTxn::Determine(TranslateRecord { inputs, outputs }))
        }
        "apply" => {
            let i = f.object("in")?;
            let o = f.object("out")?;
            let code = o.uint("code", ApplyCode::BITS)?;
            Ok(TranslateTxn::Apply(ApplyRecord {
                inputs: ApplyInputs {
                    hier: i.uint("hier", h)? as u32,
                    node: node_from_json(&i.object("node")?, p)?,
                },
                outputs: ApplyOutputs {
                    code: ApplyCode::from_bits(code).ok_or_else(|| o.bad("code", "0..=7"))?,
                    hier: o.uint("hier", h)? as u32,
                    node: node_from_json(&o.object("node")?, p)?,
                },
            }))
        }
        _ => Err(f.bad("op", "\"determine\" or \"apply\"")),
    }
}

/// Generates and writes `count` transactions for `design` from `seed` to
/// `path` (atomically; see [`super::write_jsonl`]).
pub fn write_translate_vectors(
    path: &Path,
    design: &TranslateDesign,
    seed: u64,
    count: usize,
) -> Result<(), VectorError> {
    let txns = generate(design, seed, count)?;
    write_translate_txns(path, design, seed, &txns)
}

/// Writes given transactions (already run through [`TranslateModel`]).
pub fn write_translate_txns(
    path: &Path,
    design: &TranslateDesign,
    seed: u64,
    txns: &[TranslateTxn],
) -> Result<(), VectorError> {
    let header = Header {
        unit: UnitKind::Translate,
        params: design.param_map(),
        seed,
        count: txns.len() as u64,
    };
    write_jsonl(path, &header, txns.iter().map(|t| Ok(txn_to_json(t))))
}

/// Reads a translate vector file for the design under test: the header's
/// parameters must equal `design`'s (else [`VectorError::ParamsDiffer`]
/// naming each), and every record must decode with its port widths.
pub fn read_translate_vectors(
    path: &Path,
    design: &TranslateDesign,
) -> Result<(Header, Vec<TranslateTxn>), VectorError> {
    let raw = read_jsonl(path, UnitKind::Translate, &design.param_map())?;
    let mut txns = Vec::with_capacity(raw.records.len());
    for (line, v) in &raw.records {
        let f = Fields::root(&raw.path, *line, v)?;
        let txn = txn_from_json(&f, design)?;
        super::refuse_unknown(&raw.path, *line, v, &txn_to_json(&txn))?;
        txns.push(txn);
    }
    Ok((raw.header, txns))
}
