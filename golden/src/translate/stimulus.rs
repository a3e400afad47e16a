//! Stimulus for the unit's test vectors (`hiermerge vectors --unit
//! translate`): a fixed list of hard cases, and a seeded random generator
//! that reaches every outcome on purpose (ties, subnormals, the field limit,
//! the scene edges, NaN and infinities, bad ids), not by luck.

use super::float::Format;
use super::translation::trans_max;
use super::unit::{TranslateInputs, TranslateUnitConfig};
use crate::params::Params;

/// SplitMix64: a small, well-known, seedable generator (no dependency).
#[derive(Clone, Debug)]
pub struct SplitMix64(pub u64);

impl SplitMix64 {
    /// The next 64 bits of the stream ([`crate::scenes::splitmix64_next`]).
    pub fn next_u64(&mut self) -> u64 {
        crate::scenes::splitmix64_next(&mut self.0)
    }

    /// Uniform in `0..n` (`n >= 1`); the modulo bias is irrelevant here.
    pub fn below(&mut self, n: u64) -> u64 {
        self.next_u64() % n
    }

    /// Uniform in `lo..=hi`.
    pub fn range_i64(&mut self, lo: i64, hi: i64) -> i64 {
        lo + self.below((hi - lo) as u64 + 1) as i64
    }
}

/// Encodes a value exactly representable in binary64 in the given format
/// (binary32 rounds to nearest: the unit sees whatever the encoding holds).
fn encode(format: Format, v: f64) -> u64 {
    match format {
        Format::Binary32 => (v as f32).to_bits() as u64,
        Format::Binary64 => v.to_bits(),
    }
}

fn base(format: Format, lod: u8) -> TranslateInputs {
    TranslateInputs {
        format: format.flag(),
        placement: [0; 3],
        lod,
        extents_lo: [0; 3],
        extents_hi: [0; 3],
        write_enable: 0,
        write_id: 0,
        read_id: 0,
    }
}

/// The hard cases, in a fixed order: ties at several scales, zeros and
/// subnormals, the field limit, the scene edges, every special encoding,
/// bad levels and extents, and table ids at and beyond the depth.
pub fn hard_cases(c: &TranslateUnitConfig) -> Vec<TranslateInputs> {
    let p = &c.params;
    let d = p.max_lod;
    let mut out = Vec::new();
    for format in [Format::Binary32, Format::Binary64] {
        for lod in [0, d / 2, d] {
            let k = (d - lod) as i32;
            let e = 2f64.powi(k);
            let edge = (1u32 << lod) - 1;
            let values = [
                0.0,
                -0.0,
                0.5 * e,
                1.5 * e,
                2.5 * e,
                -2.5 * e,
                -3.5 * e,
                f64::from_bits(1),
                f32::from_bits(1) as f64,
                f32::MIN_POSITIVE as f64,
                f64::MIN_POSITIVE,
                e - 2f64.powi(k - 30),
            ];
            // Axis x carries the case; extents are the whole cell 0 so
            // small non-negative translations pass the rule.
            for v in values {
                let mut i = base(format, lod);
                i.placement[0] = encode(format, v);
                i.extents_hi = [0; 3];
                out.push(i);
            }
            // Scene edges: exactly fitting, one voxel past, one before 0.
            let mut fit = base(format, lod);
            fit.extents_lo = [0, 0, edge];
            fit.extents_hi = [0, 0, edge];
            fit.placement = [encode(format, edge as f64 * e), 0, 0];
            out.push(fit);
            let mut past = fit;
            past.placement[2] = encode(format, e);
            out.push(past);
            let mut before = fit;
            before.placement[1] = encode(format, -e);
            out.push(before);
            // The field limit: 2^D - 1/2 voxels ties to the even 2^D.
            let mut limit = base(format, lod);
            limit.placement[0] = encode(format, (trans_max(p) as f64 + 0.5) * e);
            out.push(limit);
            let mut most = base(format, lod);
            most.placement[0] = encode(format, -(trans_max(p) as f64) * e);
            out.push(most);
        }
        // Every special encoding on every axis.
        let specials: [u64; 6] = match format {
            Format::Binary32 => [
                f32::NAN.to_bits() as u64,
                0x7f80_0001,
                0xffc0_0000,
                f32::INFINITY.to_bits() as u64,
                f32::NEG_INFINITY.to_bits() as u64,
                f32::MAX.to_bits() as u64,
            ],
            Format::Binary64 => [
                f64::NAN.to_bits(),
                0x7ff0_0000_0000_0001,
                0xfff8_0000_0000_0000,
                f64::INFINITY.to_bits(),
                f64::NEG_INFINITY.to_bits(),
                f64::MAX.to_bits(),
            ],
        };
        for (n, s) in specials.iter().enumerate() {
            let mut i = base(format, d);
            i.placement[n % 3] = *s;
            out.push(i);
        }
    }
    let mut wide = base(Format::Binary32, d);
    wide.placement[1] = 1 << 32;
    out.push(wide);
    if d < (1u8 << p.lod_bits()) - 1 {
        out.push(base(Format::Binary64, d + 1));
    }
    let mut bad_ext = base(Format::Binary64, d);
    bad_ext.extents_lo[2] = 1;
    out.push(bad_ext);
    // Table: write then read every id, then ids at the depth and above.
    for id in 0..c.table_depth {
        let mut w = base(Format::Binary64, d);
        w.placement = [encode(Format::Binary64, id as f64), 0, 0];
        w.write_enable = 1;
        w.write_id = id;
        w.read_id = id;
        out.push(w);
        let mut r = base(Format::Binary64, d);
        r.read_id = id;
        out.push(r);
    }
    let top_id = (p.hier_capacity() - 1) as u32;
    if c.table_depth <= top_id {
        let mut w = base(Format::Binary64, d);
        w.write_enable = 1;
        w.write_id = c.table_depth;
        w.read_id = top_id;
        out.push(w);
    }
    out
}

/// One random transaction. About half place a hierarchy inside the scene
/// (so `ok` is common); the rest draw ties, random encodings, specials and
/// bad extents, levels and ids.
pub fn random_inputs(rng: &mut SplitMix64, c: &TranslateUnitConfig) -> TranslateInputs {
    let p: &Params = &c.params;
    let d = p.max_lod;
    let format = if rng.below(2) == 0 {
        Format::Binary32
    } else {
        Format::Binary64
    };
    let lod_max = ((1u32 << p.lod_bits()) - 1).min(d as u32 + 1) as u8;
    let lod = if rng.below(32) == 0 {
        rng.below(lod_max as u64 + 1) as u8
    } else {
        rng.below(d as u64 + 1) as u8
    };
    let mut i = base(format, lod);
    let l = lod.min(d);
    let n = 1i64 << l;
    let k = (d - l) as i32;
    for a in 0..3 {
        let lo = rng.below(n as u64) as i64;
        let hi = (lo + rng.below(4) as i64).min(n - 1);
        i.extents_lo[a] = lo as u32;
        i.extents_hi[a] = hi as u32;
        let bits = match rng.below(16) {
            // Inside the scene: a translation that fits, plus a fraction of
            // a voxel with up to 20 bits (exact in binary64).
            0..=8 => {
                let t = rng.range_i64(-lo, n - 1 - hi);
                let frac = rng.range_i64(-(1 << 20), 1 << 20) as f64 / (1u64 << 21) as f64;
                encode(format, (t as f64 + frac) * 2f64.powi(k))
            }
            // A tie: an odd number of half voxels.
            9 | 10 => encode(
                format,
                (2 * rng.range_i64(-n, n) + 1) as f64 * 2f64.powi(k - 1),
            ),
            // Any encoding at all.
            11 | 12 => match format {
                // Now and then with bits above bit 31 (the width flag).
                Format::Binary32 if rng.below(8) == 0 => rng.next_u64() | 1 << 40,
                Format::Binary32 => rng.next_u64() & 0xffff_ffff,
                Format::Binary64 => rng.next_u64(),
            },
            // Near the field limit.
            13 => encode(
                format,
                (trans_max(p) as f64 + rng.below(2) as f64 * 0.5) * 2f64.powi(k),
            ),
            // Specials and zeros.
            _ => [
                encode(format, f64::NAN),
                encode(format, f64::INFINITY),
                encode(format, f64::NEG_INFINITY),
                encode(format, -0.0),
            ][rng.below(4) as usize],
        };
        i.placement[a] = bits;
    }
    if rng.below(32) == 0 {
        i.extents_lo[0] = i.extents_hi[0] + 1;
        i.extents_lo[0] &= (1u32 << d) - 1;
    }
    let ids = p.hier_capacity();
    i.write_enable = (rng.below(2) == 0) as u8;
    i.write_id = rng.below(ids) as u32;
    i.read_id = rng.below(ids) as u32;
    i
}
