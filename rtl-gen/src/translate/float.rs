//! One axis of determine (SPEC.md 7.2) as three pipeline steps, from the
//! IEEE-754 encoding's bits only, in the style of Berkeley SoftFloat:
//!
//! 1. [`unpack`]: sign, integer significand `m` (hidden bit explicit) and
//!    the alignment `a = e - k + P + 1` (clamped to `0..=P+1+D`), where
//!    `e` is the exponent of `m`'s lsb and `k = D - L`;
//! 2. [`round`]: `V = m << a` puts the binary point of `p / 2^k` at bit
//!    `P + 1`: the integer part is `V >> (P+1)`, the first dropped bit is
//!    the round bit and the rest the sticky bits; ties go to even. A
//!    clamped-low `a` is golden's saturated shift (`t = 0`), a clamped-high
//!    one always overflows the `D`-bit magnitude;
//! 3. [`pack_residual`]: the residual is `p` itself when `t = 0`; otherwise
//!    `R = frac` or `2^(P+1) - frac` (rounded up) in units of `2^(k-P-1)`,
//!    normalized by a leading-zero shifter, always a normal number
//!    (exponent field `k + bias - 1 - clz`).
//!
//! With binary64 enabled the datapath has `P = 53` and takes binary32 in
//! too: `m32 << 29` has the same alignment, and the normalized significand
//! gives the binary32 fraction in its top 23 bits below the hidden bit.

use golden::params::bits_to_hold;
use golden::translate::float::{FloatFormat, BINARY32, BINARY64};

use super::bundle::Bundle;
use crate::Signal;

/// The datapath's shape: its precision and whether binary64 is carried.
#[derive(Clone, Copy, Debug)]
pub(crate) struct FloatPath {
    pub binary64: bool,
    pub max_lod: u32,
}

impl FloatPath {
    /// The widest format carried.
    fn wide(&self) -> FloatFormat {
        if self.binary64 {
            BINARY64
        } else {
            BINARY32
        }
    }

    /// `P`: significand bits of the datapath.
    pub fn precision(&self) -> u32 {
        self.wide().precision()
    }

    /// Largest alignment `P + 1 + D`.
    fn a_max(&self) -> u32 {
        self.precision() + 1 + self.max_lod
    }

    fn a_bits(&self) -> u32 {
        bits_to_hold(self.a_max() as u64)
    }
}

/// Sign, significand and alignment of one encoding of format `f` read
/// from the low `f.total_bits()` of `enc`. `a_raw` is signed.
struct Fields<'m> {
    sign: Signal<'m>,
    exp_max: Signal<'m>,
    frac_nz: Signal<'m>,
    m: Signal<'m>,
    a_raw: Signal<'m>,
}

/// Width of the signed `a_raw` arithmetic.
const A_RAW_BITS: u32 = 13;

fn fields<'m>(f: FloatFormat, enc: Signal<'m>, k: Signal<'m>) -> Fields<'m> {
    let fb = f.frac_bits;
    let eb = f.exp_bits;
    let sign = enc.bit(fb + eb);
    let exp = enc.slice(fb + eb - 1, fb);
    let frac = enc.slice(fb - 1, 0);
    let exp_zero = exp.eq(0);
    let hidden = !exp_zero;
    // A subnormal has the exponent of field 1.
    let exp_eff = exp_zero.mux(exp.module().lit(1, eb), exp);
    // a = e - k + P + 1 with e = exp_eff - bias - f: exp_eff + 2 - bias - k.
    let a_raw = exp_eff
        .zext(A_RAW_BITS)
        .sub(f.bias() as u128 - 2, A_RAW_BITS)
        .sub(k.zext(A_RAW_BITS), A_RAW_BITS)
        .as_signed();
    Fields {
        sign,
        exp_max: exp.reduce_and(),
        frac_nz: frac.reduce_or(),
        m: hidden.concat(frac),
        a_raw,
    }
}

/// Step 1. Puts into `out` (names prefixed `pre`): `s`, `m`, `a`, `nan`,
/// `inf`, `wide` (binary64 designs), `enc`.
pub(crate) fn unpack<'m>(
    fp: &FloatPath,
    enc: Signal<'m>,
    format: Option<Signal<'m>>,
    k: Signal<'m>,
    pre: &str,
    out: &mut Bundle<'m>,
) {
    let m = enc.module();
    let p = fp.precision();
    let f32 = fields(BINARY32, enc.slice(31, 0), k);
    let (s, exp_max, frac_nz, sig, a_raw) = match format {
        None => (f32.sign, f32.exp_max, f32.frac_nz, f32.m, f32.a_raw),
        Some(is64) => {
            let f64 = fields(BINARY64, enc, k);
            let pick = |a: Signal<'m>, b: Signal<'m>| is64.mux(a, b);
            let m32 = f32.m.concat(m.lit(0, p - BINARY32.precision()));
            let wide = !is64 & enc.slice(63, 32).reduce_or();
            out.put(&format!("{pre}wide"), wide.name(&format!("{pre}wide")));
            (
                pick(f64.sign, f32.sign),
                pick(f64.exp_max, f32.exp_max),
                pick(f64.frac_nz, f32.frac_nz),
                pick(f64.m, m32),
                pick(f64.a_raw, f32.a_raw).as_signed(),
            )
        }
    };
    let a_max = fp.a_max();
    let ab = fp.a_bits();
    let a = a_raw.lt(0).mux(
        m.lit(0, ab),
        a_raw
            .gt(a_max as u128)
            .mux(m.lit(a_max as u128, ab), a_raw.slice(ab - 1, 0)),
    );
    out.put(&format!("{pre}s"), s);
    out.put(&format!("{pre}m"), sig.name(&format!("{pre}m")));
    out.put(&format!("{pre}a"), a.name(&format!("{pre}a")));
    out.put(&format!("{pre}nan"), exp_max & frac_nz);
    out.put(&format!("{pre}inf"), exp_max & !frac_nz);
    out.put(&format!("{pre}enc"), enc);
}

/// Step 2. Reads `s, m, a` of `inp`, puts `aligned` (`m << a`), `m_nz`,
/// and passes `s`, `enc`, `nan`, `inf`, `wide` on.
pub(crate) fn align<'m>(fp: &FloatPath, inp: &Bundle<'m>, pre: &str, out: &mut Bundle<'m>) {
    let get = |n: &str| inp.get(&format!("{pre}{n}"));
    let (sig, a) = (get("m"), get("a"));
    let p = fp.precision();
    let d = fp.max_lod;
    let v = (sig.zext(2 * p + 1 + d) << a.as_unsigned()).name(&format!("{pre}aligned"));
    let put = |out: &mut Bundle<'m>, n: &str, v: Signal<'m>| out.put(&format!("{pre}{n}"), v);
    put(out, "aligned", v);
    put(out, "m_nz", sig.ne(0));
    for n in ["s", "enc", "nan", "inf"] {
        put(out, n, get(n));
    }
    if fp.binary64 {
        put(out, "wide", get("wide"));
    }
}

/// Step 3. Reads `s, aligned` of `inp`, puts `t` (signed `D+1`),
/// `too_large`, `r` (`P+1` bits), `r_sign`, `t_zero`, and passes `m_nz`,
/// `enc`, `nan`, `inf`, `wide` on.
pub(crate) fn round<'m>(fp: &FloatPath, inp: &Bundle<'m>, pre: &str, out: &mut Bundle<'m>) {
    let get = |n: &str| inp.get(&format!("{pre}{n}"));
    let (s, v) = (get("s"), get("aligned"));
    let m = s.module();
    let p = fp.precision();
    let d = fp.max_lod;
    let int = v.slice(2 * p + d, p + 1);
    let frac = v.slice(p, 0);
    let round_bit = frac.bit(p);
    let sticky = frac.slice(p - 1, 0).reduce_or();
    let inc = (round_bit & (sticky | int.bit(0))).name(&format!("{pre}inc"));
    let mag = int.add(inc, p + d + 1).name(&format!("{pre}mag"));
    let too_large = mag.slice(p + d, d).reduce_or();
    let t_mag = mag.slice(d - 1, 0).zext(d + 1);
    let t = s.mux(m.lit(0, d + 1).sub(t_mag, d + 1), t_mag);
    // Rounded up: the residual is negative, 2^(P+1) - frac units.
    let r = inc.mux(m.lit(0, p + 1).sub(frac, p + 1), frac);
    let put = |out: &mut Bundle<'m>, n: &str, v: Signal<'m>| out.put(&format!("{pre}{n}"), v);
    put(out, "t", t.name(&format!("{pre}t")).as_signed());
    put(out, "too_large", too_large);
    put(out, "r", r.name(&format!("{pre}r")));
    put(out, "r_sign", s ^ inc);
    put(out, "t_zero", mag.eq(0));
    for n in ["m_nz", "enc", "nan", "inf"] {
        put(out, n, get(n));
    }
    if fp.binary64 {
        put(out, "wide", get("wide"));
    }
}

/// Leading-zero normalization of `r` (`P+1` bits): returns `(norm, clz)`
/// with `norm = (r << clz)[P:1]` (bit `P-1` the hidden bit, 0 only when
/// `r = 0`; bit 0 of `r << clz` is always 0 for a residual, SPEC 7.2).
fn normalize<'m>(r: Signal<'m>) -> (Signal<'m>, Signal<'m>) {
    let w = r.width();
    let mut x = r;
    let mut clz_bits = Vec::new();
    let mut s = 1u32 << (31 - (w - 1).leading_zeros());
    while s > 1 {
        let top_zero = x
            .slice(w - 1, w - s)
            .eq(0)
            .named_after(r, &format!("zero{s}"));
        x = top_zero
            .mux(x << s, x)
            .named_after(r, &format!("shifted{s}"));
        clz_bits.push(top_zero);
        s /= 2;
    }
    let top_zero = x.bit(w - 1).eq(0);
    clz_bits.push(top_zero);
    let norm = top_zero.mux(x.slice(w - 2, 0), x.slice(w - 1, 1));
    let m = r.module();
    (norm, m.concat(&clz_bits))
}

/// Step 4's result for one axis: the signed translation, the fault bits
/// (exclusive: a wide encoding is not decoded, a special is not rounded)
/// and the residual encoding (`placement_bits` wide).
pub(crate) struct AxisResult<'m> {
    pub t: Signal<'m>,
    pub wide: Option<Signal<'m>>,
    pub nan: Signal<'m>,
    pub inf: Signal<'m>,
    pub range: Signal<'m>,
    pub residual: Signal<'m>,
}

/// Step 4. Reads step 3's outputs (prefix `pre`) and `k`.
pub(crate) fn pack_residual<'m>(
    fp: &FloatPath,
    inp: &Bundle<'m>,
    format: Option<Signal<'m>>,
    k: Signal<'m>,
    pre: &str,
) -> AxisResult<'m> {
    let get = |n: &str| inp.get(&format!("{pre}{n}"));
    let p = fp.precision();
    let (norm, clz) = normalize(get("r"));
    let nonzero = norm.bit(p - 1);
    let sign = get("r_sign");
    let exponent = |f: FloatFormat| {
        let eb = f.exp_bits;
        k.zext(eb)
            .add(f.bias() as u128 - 1, eb)
            .sub(clz.zext(eb), eb)
    };
    let frac32 = norm.slice(p - 2, p - 1 - BINARY32.frac_bits);
    let packed32 = sign.concat(exponent(BINARY32)).concat(frac32);
    let packed = match format {
        None => packed32,
        Some(is64) => {
            let packed64 = sign.concat(exponent(BINARY64)).concat(norm.slice(p - 2, 0));
            is64.mux(packed64, packed32.zext(64))
        }
    };
    let m = sign.module();
    let pb = packed.width();
    let zero = m.lit(0, pb);
    // t = 0: the residual is the placement itself (+0 for either zero).
    let residual = get("t_zero").mux(get("m_nz").mux(get("enc"), zero), nonzero.mux(packed, zero));
    let (nan, inf) = (get("nan"), get("inf"));
    let range = !(nan | inf) & get("too_large");
    // A binary32 encoding with high bits set is not decoded at all.
    let (wide, nan, inf, range) = if fp.binary64 {
        let w = get("wide");
        (Some(w), !w & nan, !w & inf, !w & range)
    } else {
        (None, nan, inf, range)
    };
    AxisResult {
        t: get("t").as_signed(),
        wide,
        nan,
        inf,
        range,
        residual: residual.name(&format!("{pre}residual")),
    }
}
