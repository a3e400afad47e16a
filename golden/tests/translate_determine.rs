//! determine checked against references that do not share its method:
//! (1) the standard library's binary64 arithmetic (division by 2^k,
//! `round_ties_even`, and an error-free TwoSum for the residual), and
//! (2) exact fixed-point integer arithmetic in i128.

use golden::translate::determine::{round_axis, AxisFault};
use golden::translate::float::{BINARY32, BINARY64};
use golden::translate::{
    determine, round_placement, Axis, Placement, TranslateError, Translation, VoxelRange,
};
use golden::Params;
use proptest::prelude::*;

/// What the reference says one axis rounds to.
#[derive(Debug, PartialEq)]
enum Expect {
    Ok { t: i64, residual: f64 },
    TooLarge,
    NaN,
    Inf,
}

/// Knuth's TwoSum: `s + e == a + b` exactly, with `s = fl(a + b)`.
fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    let bb = s - a;
    let e = (a - (s - bb)) + (b - bb);
    (s, e)
}

/// Reference from binary64 arithmetic. `v` is exact in f64 (binary32 values
/// widen exactly). Division by 2^k loses bits only when the quotient is
/// subnormal, and then it is far below 1/2, so `t = 0` either way.
fn reference(v: f64, k: u32, d: u8) -> Expect {
    if v.is_nan() {
        return Expect::NaN;
    }
    if v.is_infinite() {
        return Expect::Inf;
    }
    let scale = (k as f64).exp2();
    let t = (v / scale).round_ties_even();
    if t.abs() > ((1u64 << d) - 1) as f64 {
        return Expect::TooLarge;
    }
    let (s, e) = two_sum(v, -(t * scale));
    assert_eq!(e, 0.0, "p - t 2^k is not a binary64 value: v={v:e} k={k}");
    Expect::Ok {
        t: t as i64,
        residual: if s == 0.0 { 0.0 } else { s },
    }
}

fn ours64(bits: u64, k: u32, d: u8) -> Expect {
    match round_axis(BINARY64, bits, k, d as u32) {
        Ok(a) => Expect::Ok {
            t: a.t,
            residual: f64::from_bits(a.residual_bits),
        },
        Err(AxisFault::TooLarge) => Expect::TooLarge,
        Err(AxisFault::NotANumber) => Expect::NaN,
        Err(AxisFault::Infinite { .. }) => Expect::Inf,
    }
}

fn ours32(bits: u32, k: u32, d: u8) -> Expect {
    match round_axis(BINARY32, bits as u64, k, d as u32) {
        Ok(a) => {
            assert!(
                a.residual_bits >> 32 == 0,
                "binary32 residual wider than 32 bits"
            );
            Expect::Ok {
                t: a.t,
                residual: f32::from_bits(a.residual_bits as u32) as f64,
            }
        }
        Err(AxisFault::TooLarge) => Expect::TooLarge,
        Err(AxisFault::NotANumber) => Expect::NaN,
        Err(AxisFault::Infinite { .. }) => Expect::Inf,
    }
}

/// Checks one binary32 encoding: same t, same residual value, residual
/// exactly a binary32 value, and +0 for a zero residual (bit-exact).
fn check32(bits: u32, k: u32, d: u8) {
    let v = f32::from_bits(bits) as f64;
    let want = reference(v, k, d);
    if let Expect::Ok { residual, .. } = want {
        assert_eq!(
            residual as f32 as f64, residual,
            "residual not exact in binary32: {v:e} k={k}"
        );
    }
    let got = ours32(bits, k, d);
    assert_eq!(got, want, "binary32 {bits:#010x} ({v:e}) k={k} D={d}");
    if let Expect::Ok { residual, .. } = got {
        let a = round_axis(BINARY32, bits as u64, k, d as u32).unwrap();
        assert_eq!(a.residual_bits, (residual as f32).to_bits() as u64);
    }
}

fn check64(bits: u64, k: u32, d: u8) {
    let v = f64::from_bits(bits);
    let want = reference(v, k, d);
    let got = ours64(bits, k, d);
    assert_eq!(got, want, "binary64 {bits:#018x} ({v:e}) k={k} D={d}");
    if let Expect::Ok { residual, .. } = got {
        let a = round_axis(BINARY64, bits, k, d as u32).unwrap();
        assert_eq!(
            a.residual_bits,
            residual.to_bits(),
            "zero residual must be +0"
        );
    }
}

/// Fractions that exercise the rounding: edges, halves, alternating bits.
fn interesting_fractions(frac_bits: u32) -> Vec<u64> {
    let top = 1u64 << (frac_bits - 1);
    let all = (1u64 << frac_bits) - 1;
    let mut v = vec![
        0,
        1,
        2,
        3,
        top,
        top - 1,
        top + 1,
        all,
        all - 1,
        all >> 1,
        all & 0x5555_5555_5555_5555,
    ];
    for s in 0..frac_bits {
        v.push(1 << s);
        v.push(all >> s);
    }
    v
}

#[test]
fn binary32_every_exponent_with_edge_fractions() {
    for d in [31u8, 16, 3] {
        for k in [0u32, 1, 2, 7, 16, 30, 31] {
            if k > d as u32 {
                continue;
            }
            for e in 0..=255u32 {
                for f in interesting_fractions(23) {
                    for s in [0u32, 1] {
                        check32((s << 31) | (e << 23) | f as u32, k, d);
                    }
                }
            }
        }
    }
}

#[test]
fn binary32_exhaustive_high_half_with_sampled_low_half() {
    // Every sign/exponent/high-fraction pattern, with low halves that put the
    // rounding point on and around the dropped bits.
    for hi in 0..=0xffffu32 {
        for lo in [0u32, 1, 0x7fff, 0x8000, 0x8001, 0xffff, 0x4000] {
            check32((hi << 16) | lo, 3, 31);
        }
    }
}

#[test]
fn binary64_every_exponent_with_edge_fractions() {
    for d in [31u8, 20, 1] {
        for k in [0u32, 1, 5, 19, 31] {
            if k > d as u32 {
                continue;
            }
            for e in 0..=2047u64 {
                for f in interesting_fractions(52) {
                    for s in [0u64, 1] {
                        check64((s << 63) | (e << 52) | f, k, d);
                    }
                }
            }
        }
    }
}

#[test]
fn exact_ties_go_to_even_at_every_scale() {
    for k in 0..=31u32 {
        let e = (k as f64).exp2();
        for n in -200i64..200 {
            // (n + 1/2) voxels exactly.
            let v = (n as f64 + 0.5) * e;
            let even = if n.rem_euclid(2) == 0 { n } else { n + 1 };
            match ours64(v.to_bits(), k, 31) {
                Expect::Ok { t, residual } => {
                    assert_eq!(t, even, "{v} / 2^{k}");
                    assert_eq!(residual.abs(), e / 2.0);
                }
                other => panic!("{v}: {other:?}"),
            }
            if let Expect::Ok { t, .. } = ours32((v as f32).to_bits(), k, 31) {
                assert_eq!(t, even, "binary32 {v} / 2^{k}");
            }
        }
    }
}

#[test]
fn values_near_two_to_the_d() {
    let d = 31u8;
    let top = (1u64 << 31) as f64;
    let cases: [(f64, Option<i64>); 8] = [
        (top - 1.0, Some((1 << 31) - 1)),
        (top - 1.5, Some((1 << 31) - 2)),
        (top - 0.75, Some((1 << 31) - 1)),
        (top - 0.5, None), // tie to the even 2^31: outside the field
        (top, None),
        (-(top - 1.0), Some(-(1 << 31) + 1)),
        (-(top - 0.5), None),
        (-top, None),
    ];
    for (v, want) in cases {
        let got = ours64(v.to_bits(), 0, d);
        match want {
            Some(t) => assert!(
                matches!(got, Expect::Ok { t: g, .. } if g == t),
                "{v}: {got:?}"
            ),
            None => assert_eq!(got, Expect::TooLarge, "{v}"),
        }
    }
    // Coarser levels: at k = 31 (L = 0) |t| <= 2^31 - 1 allows huge placements.
    assert!(matches!(
        ours64((1e18f64).to_bits(), 31, 31),
        Expect::Ok { t: 465661287, .. }
    ));
    assert_eq!(ours64(f64::MAX.to_bits(), 31, 31), Expect::TooLarge);
    assert_eq!(ours32(f32::MAX.to_bits(), 31, 31), Expect::TooLarge);
}

#[test]
fn nan_and_infinity_are_errors_on_the_named_axis() {
    let p = Params::new(16, 8, 24, 4).unwrap();
    for nan in [
        0x7ff8_0000_0000_0000u64,
        0x7ff0_0000_0000_0001,
        0xfff8_0000_0000_0001,
        0x7fff_ffff_ffff_ffff,
    ] {
        let e = round_placement(&Placement::from_bits64([0, nan, 0]), 8, &p).unwrap_err();
        assert_eq!(
            e,
            TranslateError::NotANumber {
                axis: Axis::Y,
                bits: nan
            }
        );
        assert!(e.to_string().contains("placement y is NaN"));
    }
    let e =
        round_placement(&Placement::binary32([1.0, 2.0, f32::NEG_INFINITY]), 8, &p).unwrap_err();
    assert_eq!(
        e,
        TranslateError::Infinite {
            axis: Axis::Z,
            negative: true
        }
    );
    // The first failing axis wins, x before y.
    let e =
        round_placement(&Placement::binary64([f64::INFINITY, f64::NAN, 0.0]), 8, &p).unwrap_err();
    assert_eq!(
        e,
        TranslateError::Infinite {
            axis: Axis::X,
            negative: false
        }
    );
    let wide = Placement {
        format: golden::translate::Format::Binary32,
        bits: [1 << 32, 0, 0],
    };
    assert!(matches!(
        round_placement(&wide, 8, &p),
        Err(TranslateError::PlacementTooWide { axis: Axis::X, .. })
    ));
    assert!(matches!(
        round_placement(&Placement::binary64([0.0, 0.0, 1e300]), 8, &p),
        Err(TranslateError::TranslationTooLarge {
            axis: Axis::Z,
            field_bits: 17,
            ..
        })
    ));
    assert_eq!(
        round_placement(&Placement::binary64([0.0; 3]), 17, &p),
        Err(TranslateError::LodAboveMax {
            lod: 17,
            max_lod: 16
        })
    );
}

#[test]
fn negative_zero_and_subnormals_round_to_zero_with_themselves_as_residual() {
    for bits in [0x8000_0000u32, 1, 0x8000_0001, 0x007f_ffff, 0x0080_0000] {
        for k in [0u32, 5, 31] {
            let got = ours32(bits, k, 31);
            let v = f32::from_bits(bits) as f64;
            assert_eq!(
                got,
                Expect::Ok {
                    t: 0,
                    residual: if v == 0.0 { 0.0 } else { v }
                }
            );
        }
    }
    let a = round_axis(BINARY32, 0x8000_0000, 0, 31).unwrap();
    assert_eq!(a.residual_bits, 0, "-0 gives a +0 residual");
}

#[test]
fn determine_applies_the_scene_extents_rule() {
    let p = Params::new(10, 4, 16, 2).unwrap();
    // A hierarchy occupying LOD-4 voxels x 0..=2, y 5..=5, z 14..=15; L = 4,
    // voxel edge 2^6 = 64 grid units.
    let ext = VoxelRange {
        lod: 4,
        lo: [0, 5, 14],
        hi: [2, 5, 15],
    };
    let ok = determine(
        &Placement::binary64([13.0 * 64.0, -5.0 * 64.0 - 31.0, 0.0]),
        4,
        &ext,
        &p,
    )
    .unwrap();
    assert_eq!(
        ok.translation,
        Translation {
            lod: 4,
            t: [13, -5, 0]
        }
    );
    assert_eq!(ok.residual.value_f64(Axis::Y), -31.0);
    // x: 0..=2 moved by 14 reaches 16 = 2^4.
    assert_eq!(
        determine(&Placement::binary64([14.0 * 64.0, 0.0, 0.0]), 4, &ext, &p),
        Err(TranslateError::OutsideScene {
            axis: Axis::X,
            lo: 14,
            hi: 16,
            lod: 4
        })
    );
    // y: 5 moved by -6 is -1; the residual rounding decides (-5.5 voxels -> -6, even).
    assert_eq!(
        determine(&Placement::binary64([0.0, -5.5 * 64.0, 0.0]), 4, &ext, &p),
        Err(TranslateError::OutsideScene {
            axis: Axis::Y,
            lo: -1,
            hi: -1,
            lod: 4
        })
    );
    assert!(determine(&Placement::binary64([0.0, -4.5 * 64.0, 0.0]), 4, &ext, &p).is_ok());
    let bad = VoxelRange {
        lod: 4,
        lo: [3, 0, 0],
        hi: [2, 0, 0],
    };
    assert!(matches!(
        determine(&Placement::binary64([0.0; 3]), 4, &bad, &p),
        Err(TranslateError::BadExtents { axis: Axis::X, .. })
    ));
    assert!(matches!(
        determine(&Placement::binary64([0.0; 3]), 5, &ext, &p),
        Err(TranslateError::ExtentsLodMismatch {
            extents_lod: 4,
            lod: 5
        })
    ));
}

/// Exact reference in integers: the value times 2^60 as an i128, divided by
/// 2^(k+60) with round-half-even done on the remainder.
fn fixed_reference(v: f64, k: u32) -> (i64, i128) {
    let scaled = v * 2f64.powi(60); // exact: a power-of-two scale in range
    let fixed = scaled as i128;
    assert_eq!(fixed as f64, scaled, "value not on the 2^-60 grid");
    let div = 1i128 << (k + 60);
    let q = fixed.div_euclid(div);
    let r = fixed.rem_euclid(div);
    let t = match (2 * r).cmp(&div) {
        std::cmp::Ordering::Less => q,
        std::cmp::Ordering::Greater => q + 1,
        std::cmp::Ordering::Equal => q + (q & 1),
    };
    (t as i64, fixed - t * div)
}

/// `(D, k)` with `0 <= k <= D`.
fn level_pair() -> impl Strategy<Value = (u8, u32)> {
    (1u8..=31).prop_flat_map(|d| (Just(d), 0u32..=d as u32))
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 20000, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn binary64_any_bits_match_the_float_reference(bits in any::<u64>(), (d, k) in level_pair()) {
        check64(bits, k, d);
    }

    #[test]
    fn binary32_any_bits_match_the_float_reference(bits in any::<u32>(), (d, k) in level_pair()) {
        check32(bits, k, d);
    }

    #[test]
    fn binary64_moderate_values_match_the_integer_reference(
        m in -(1i64 << 53)..(1i64 << 53), e in -60i32..=-23, k in 0u32..=31,
    ) {
        // m 2^e: |v| < 2^30, on the 2^-60 grid.
        let v = m as f64 * 2f64.powi(e);
        let (t, r_fixed) = fixed_reference(v, k);
        let a = round_axis(BINARY64, v.to_bits(), k, 31).unwrap();
        prop_assert_eq!(a.t, t);
        let r = f64::from_bits(a.residual_bits);
        prop_assert_eq!((r * 2f64.powi(60)) as i128, r_fixed);
        prop_assert!(r_fixed.abs() <= 1i128 << (k + 59));
    }

    #[test]
    fn binary32_moderate_values_match_the_integer_reference(
        m in -(1i32 << 24)..(1i32 << 24), e in -40i32..=6, k in 0u32..=31,
    ) {
        let v32 = m as f32 * 2f32.powi(e);
        prop_assume!(v32 as f64 == m as f64 * 2f64.powi(e));
        let (t, r_fixed) = fixed_reference(v32 as f64, k);
        let a = round_axis(BINARY32, v32.to_bits() as u64, k, 31).unwrap();
        prop_assert_eq!(a.t, t);
        let r = f32::from_bits(a.residual_bits as u32) as f64;
        prop_assert_eq!((r * 2f64.powi(60)) as i128, r_fixed);
    }
}
