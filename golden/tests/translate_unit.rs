//! The RTL-facing transaction: flags agree with determine, the table is
//! read before it is written, records survive JSON.

use golden::seed::seeded;
use golden::translate::float::Format;
use golden::translate::translation::{decode_component, encode_component};
use golden::translate::{
    determine, Axis, Placement, TranslateError, TranslateInputs, TranslateOutputs, TranslateRecord,
    TranslateUnit, TranslateUnitConfig, VoxelRange,
};
use golden::Params;
use proptest::prelude::*;

fn unit(p: Params, depth: u32) -> TranslateUnit {
    TranslateUnit::new(TranslateUnitConfig {
        params: p,
        table_depth: depth,
    })
    .unwrap()
}

fn inputs(
    format: Format,
    placement: [u64; 3],
    lod: u8,
    lo: [u32; 3],
    hi: [u32; 3],
) -> TranslateInputs {
    TranslateInputs {
        format: format.flag(),
        placement,
        lod,
        extents_lo: lo,
        extents_hi: hi,
        write_enable: 0,
        write_id: 0,
        read_id: 0,
    }
}

#[test]
fn a_write_is_seen_by_the_next_read_not_the_same_one() {
    let p = Params::new(8, 4, 16, 2).unwrap();
    let mut u = unit(p, 3);
    let mut i = inputs(
        Format::Binary64,
        [(-40.5f64).to_bits(), 0, 8f64.to_bits()],
        4,
        [3, 0, 0],
        [5, 2, 2],
    );
    i.write_enable = 1;
    i.write_id = 2;
    i.read_id = 2;
    let o = u.step(&i).unwrap();
    // k = 4: -40.5 / 16 = -2.53 -> -3 (residual 7.5); 8 / 16 = 0.5 -> 0 (even).
    assert_eq!(o.ok, 1);
    assert_eq!(o.t, [encode_component(-3, &p), 0, 0]);
    assert_eq!(f64::from_bits(o.residual[0]), 7.5);
    assert_eq!(f64::from_bits(o.residual[2]), 8.0);
    assert_eq!(
        (o.written, o.read_valid),
        (1, 0),
        "read-first: the old (empty) entry"
    );
    i.write_enable = 0;
    let o = u.step(&i).unwrap();
    assert_eq!((o.read_valid, o.read_lod), (1, 4));
    assert_eq!(decode_component(Axis::X, o.read_t[0], &p), Ok(-3));
    i.read_id = 3;
    i.write_enable = 1;
    i.write_id = 3;
    let o = u.step(&i).unwrap();
    assert_eq!(
        (o.err_read_id, o.read_valid, o.err_write_id, o.written),
        (1, 0, 1, 0)
    );
}

#[test]
fn every_failing_axis_raises_its_own_flag() {
    let p = Params::new(8, 4, 16, 2).unwrap();
    let mut u = unit(p, 4);
    let i = inputs(
        Format::Binary32,
        [
            f32::NAN.to_bits() as u64,
            f32::INFINITY.to_bits() as u64,
            1e30f32.to_bits() as u64,
        ],
        4,
        [0; 3],
        [0; 3],
    );
    let o = u.step(&i).unwrap();
    assert_eq!(
        (o.ok, o.err_nan, o.err_inf, o.err_range, o.err_outside),
        (0, 0b001, 0b010, 0b100, 0)
    );
    assert_eq!((o.t, o.residual), ([0; 3], [0; 3]));
    let i = inputs(Format::Binary32, [1 << 40, 0, 0], 4, [0; 3], [0; 3]);
    assert_eq!(u.step(&i).unwrap().err_width, 0b001);
    let i = inputs(Format::Binary32, [0; 3], 9, [0; 3], [0; 3]);
    let o = u.step(&i).unwrap();
    assert_eq!((o.err_lod, o.ok), (1, 0));
    // 2^4 = 16 voxels at LOD 4: extents hi = 16 is not a range.
    let i = inputs(Format::Binary32, [0; 3], 4, [0; 3], [0, 16, 0]);
    assert_eq!(u.step(&i).unwrap().err_extents, 1);
    // Values no port can carry are refused outright.
    let mut i = inputs(Format::Binary32, [0; 3], 4, [0; 3], [0; 3]);
    i.format = 2;
    assert!(matches!(
        u.step(&i),
        Err(TranslateError::PackedTooWide {
            what: "format flag",
            ..
        })
    ));
    i.format = 0;
    i.lod = 32;
    assert!(matches!(
        u.step(&i),
        Err(TranslateError::PackedTooWide { what: "lod", .. })
    ));
    i.lod = 4;
    i.read_id = 1 << 2;
    assert!(matches!(
        u.step(&i),
        Err(TranslateError::PackedTooWide {
            what: "read_id",
            ..
        })
    ));
}

#[test]
fn records_round_trip_through_json() {
    let p = Params::default();
    let mut u = unit(p, 16);
    let i = inputs(
        Format::Binary64,
        [12345.678f64.to_bits(), 0, u64::MAX >> 1],
        3,
        [0; 3],
        [1; 3],
    );
    let o = u.step(&i).unwrap();
    let r = TranslateRecord {
        inputs: i,
        outputs: o,
    };
    let s = serde_json::to_string(&r).unwrap();
    assert!(s.contains("\"err_nan\":4"));
    let back: TranslateRecord = serde_json::from_str(&s).unwrap();
    assert_eq!(back, r);
}

/// Placement encodings that hit every class: small values, ties, huge,
/// NaN, infinities, raw bits.
fn placement_bits(format: Format) -> BoxedStrategy<u64> {
    match format {
        Format::Binary64 => prop_oneof![
            6 => (-20.0f64..400.0).prop_map(f64::to_bits),
            1 => (-3000.0f64..3000.0).prop_map(f64::to_bits),
            1 => (-200i64..200).prop_map(|n| (n as f64 * 8.0 + 4.0).to_bits()),
            1 => Just(f64::NAN.to_bits()),
            1 => Just(f64::NEG_INFINITY.to_bits()),
            1 => Just(1e300f64.to_bits()),
            1 => any::<u64>(),
        ]
        .boxed(),
        Format::Binary32 => prop_oneof![
            8 => (-20.0f32..400.0).prop_map(|v| v.to_bits() as u64),
            1 => (-3000.0f32..3000.0).prop_map(|v| v.to_bits() as u64),
            1 => Just(f32::NAN.to_bits() as u64),
            1 => Just(f32::INFINITY.to_bits() as u64),
            1 => any::<u32>().prop_map(u64::from),
            1 => Just(1u64 << 33),
        ]
        .boxed(),
    }
}

/// An extents range at `lod`: mostly a valid range (small, so placements
/// near the origin pass the rule), sometimes anything the ports carry.
fn extents(lod: u8) -> BoxedStrategy<([u32; 3], [u32; 3])> {
    let n = 1u32 << lod.min(10);
    let axis = (0..n.div_ceil(2), 0u32..4).prop_map(move |(lo, w)| (lo, (lo + w).min(n - 1)));
    prop_oneof![
        4 => [axis.clone(), axis.clone(), axis].prop_map(|r| (r.map(|a| a.0), r.map(|a| a.1))),
        1 => ([0u32..1024, 0u32..1024, 0u32..1024], [0u32..1024, 0u32..1024, 0u32..1024]),
    ]
    .boxed()
}

fn random_inputs() -> impl Strategy<Value = TranslateInputs> {
    (
        prop_oneof![Just(Format::Binary32), Just(Format::Binary64)],
        0u8..=13,
    )
        .prop_flat_map(|(f, lod)| {
            let b = placement_bits(f);
            ([b.clone(), b.clone(), b], extents(lod))
                .prop_map(move |(placement, (lo, hi))| inputs(f, placement, lod, lo, hi))
        })
}

/// The flag that determine's first error corresponds to.
fn flag_of(e: &TranslateError, o: &TranslateOutputs) -> bool {
    let bit = |a: &Axis| 1u8 << a.index();
    match e {
        TranslateError::LodAboveMax { .. } => o.err_lod == 1,
        TranslateError::BadExtents { .. } => o.err_extents == 1,
        TranslateError::PlacementTooWide { axis, .. } => o.err_width & bit(axis) != 0,
        TranslateError::NotANumber { axis, .. } => o.err_nan & bit(axis) != 0,
        TranslateError::Infinite { axis, .. } => o.err_inf & bit(axis) != 0,
        TranslateError::TranslationTooLarge { axis, .. } => o.err_range & bit(axis) != 0,
        TranslateError::OutsideScene { axis, .. } => o.err_outside & bit(axis) != 0,
        _ => false,
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 5000, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn step_agrees_with_determine(i in random_inputs()) {
        // D = 10 (lod_bits 4, so LODs 11..=13 reach the err_lod flag).
        let p = Params::new(10, 4, 16, 2).unwrap();
        let mut u = unit(p, 4);
        let o = u.step(&i).unwrap();
        let format = if i.format == 0 { Format::Binary32 } else { Format::Binary64 };
        let ext = VoxelRange { lod: i.lod, lo: i.extents_lo, hi: i.extents_hi };
        let placement = Placement { format, bits: i.placement };
        match determine(&placement, i.lod, &ext, &p) {
            Ok(d) => {
                prop_assert_eq!(o.ok, 1);
                prop_assert_eq!(o.t, d.translation.t.map(|v| encode_component(v, &p)));
                prop_assert_eq!(o.residual, d.residual.bits);
            }
            Err(e) => {
                prop_assert_eq!(o.ok, 0);
                prop_assert!(flag_of(&e, &o), "{e} but flags {o:?}");
                prop_assert_eq!((o.t, o.residual), ([0; 3], [0; 3]));
            }
        }
    }
}

#[test]
fn random_transactions_succeed_often_enough_to_mean_something() {
    // Runs the generator alone and counts successes, so a generator that
    // only ever produced errors would fail here.
    use proptest::strategy::ValueTree;
    use proptest::test_runner::TestRunner;
    let p = Params::new(10, 4, 16, 2).unwrap();
    let mut runner = TestRunner::deterministic();
    let (mut ok, n) = (0, 2000);
    for _ in 0..n {
        let i = random_inputs().new_tree(&mut runner).unwrap().current();
        ok += unit(p, 4).step(&i).unwrap().ok as u32;
    }
    println!("{ok} of {n} random transactions succeed");
    assert!(ok > n / 10, "only {ok} of {n} random transactions succeed");
}

/// Which outputs a run of transactions raised at least once.
#[derive(Default, Debug)]
struct Seen {
    ok: bool,
    lod: bool,
    extents: bool,
    width: bool,
    nan: bool,
    inf: bool,
    range: bool,
    outside: bool,
    write_id: bool,
    written: bool,
    read_id: bool,
    read_valid: bool,
    nonzero_residual: bool,
}

impl Seen {
    fn add(&mut self, o: &TranslateOutputs) {
        self.ok |= o.ok == 1;
        self.lod |= o.err_lod == 1;
        self.extents |= o.err_extents == 1;
        self.width |= o.err_width != 0;
        self.nan |= o.err_nan != 0;
        self.inf |= o.err_inf != 0;
        self.range |= o.err_range != 0;
        self.outside |= o.err_outside != 0;
        self.write_id |= o.err_write_id == 1;
        self.written |= o.written == 1;
        self.read_id |= o.err_read_id == 1;
        self.read_valid |= o.read_valid == 1;
        self.nonzero_residual |= o.residual.iter().any(|r| *r != 0);
    }

    /// Everything was seen; `err_lod` only where some port value exceeds D.
    fn all(&self, p: &Params) -> bool {
        let lod_reachable = (p.max_lod as u32) < (1 << p.lod_bits()) - 1;
        self.ok
            && (self.lod || !lod_reachable)
            && self.extents
            && self.width
            && self.nan
            && self.inf
            && self.range
            && self.outside
            && self.write_id
            && self.written
            && self.read_id
            && self.read_valid
            && self.nonzero_residual
    }
}

fn configs() -> [TranslateUnitConfig; 3] {
    [
        TranslateUnitConfig {
            params: Params::new(31, 16, 32, 8).unwrap(),
            table_depth: 200,
        },
        TranslateUnitConfig {
            params: Params::new(4, 2, 8, 2).unwrap(),
            table_depth: 3,
        },
        TranslateUnitConfig {
            params: Params::default(),
            table_depth: 10,
        },
    ]
}

#[test]
fn hard_cases_raise_every_output_and_fit_the_ports() {
    use golden::translate::stimulus::hard_cases;
    for c in configs() {
        let mut u = TranslateUnit::new(c).unwrap();
        let mut seen = Seen::default();
        let cases = hard_cases(&c);
        for i in &cases {
            seen.add(&u.step(i).unwrap());
        }
        assert!(seen.all(&c.params), "{c:?}: {seen:?}");
        println!("{} hard cases at D = {}", cases.len(), c.params.max_lod);
    }
}

#[test]
fn random_stimulus_is_seeded_and_reaches_every_output() {
    use golden::translate::stimulus::{random_inputs, SplitMix64};
    for c in configs() {
        let mut u = TranslateUnit::new(c).unwrap();
        let mut rng = SplitMix64(seeded(7));
        let mut seen = Seen::default();
        let n = 5000;
        let mut ok = 0;
        let mut first = Vec::new();
        for _ in 0..n {
            let i = random_inputs(&mut rng, &c);
            let o = u.step(&i).unwrap();
            ok += o.ok as u32;
            seen.add(&o);
            if first.len() < 10 {
                first.push(i);
            }
        }
        assert!(seen.all(&c.params), "{c:?}: {seen:?}");
        assert!(ok > n / 4, "{ok} of {n} ok");
        let mut again = SplitMix64(seeded(7));
        let replay: Vec<_> = (0..10).map(|_| random_inputs(&mut again, &c)).collect();
        assert_eq!(replay, first, "same seed, same transactions");
    }
}
