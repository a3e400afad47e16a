//! The generated translation unit against the golden model, bit for bit,
//! with random back-pressure, in each reference configuration (the
//! default, D = 31 with binary64, Q = 0, binary64 at the default grid, the
//! smallest grid): 100,000 transactions at full volume (SPEC 10.3) in
//! Verilator (through `cosim::units::translate::run`) and 10,000 in Icarus
//! Verilog (batch mode,
//! `cosim::icarus::IcarusBatch`, 4-state: any X on an output after reset
//! fails), plus a short Icarus pipe-engine run of the library testbench. A
//! missing tool fails under CI=true and is a printed skip otherwise.

use cosim::from_rtl::design_from_module;
use cosim::icarus::{BatchSpec, IcarusBatch, LaneVector};
use cosim::tb::{BenchConfig, FieldDecoder, StreamNames, Vector};
use cosim::units::translate::{run, RunConfig};
use cosim::volume::volume;
use cosim::{open_engine, EngineKind};
use golden::seed::seeded;
use golden::translate::model::{ApplyCode, TranslateDesign, TranslateTxn};
use golden::vectors::translate::generate;
use rtl_gen::translate::ports::{
    apply_out_layout, det_out_layout, pack_apply_in, pack_apply_out, pack_det_in, pack_det_out,
};
use rtl_gen::translate::{reference_designs, translate_unit};

fn tools_present(kind: EngineKind) -> bool {
    match kind.check_tools() {
        Ok(()) => true,
        Err(e) if std::env::var("CI").is_ok_and(|v| v == "true") => {
            panic!("{} is required under CI=true: {e}", kind.name())
        }
        Err(e) => {
            eprintln!("SKIPPED: {e}");
            false
        }
    }
}

fn check(kind: EngineKind, d: &TranslateDesign, count: usize, seed: u64, stall: f64) {
    let seed = seeded(seed);
    let txns = generate(d, seed, count).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let design = design_from_module(&translate_unit(d), dir.path()).unwrap();
    let mut engine = open_engine(kind, &design, false).unwrap_or_else(|e| panic!("{e}"));
    let start = std::time::Instant::now();
    let config = RunConfig {
        seed,
        stall: cosim::tb::Stalls::Coin(stall),
        flip_expected: None,
        ..Default::default()
    };
    let o = run(engine.as_mut(), d, &txns, &config, None, &mut |_, _| {})
        .unwrap_or_else(|f| panic!("{f}"));
    println!(
        "{} {}: {} transactions ({} determine, {} apply) in {} cycles at stall {stall}, {:?}",
        kind.name(),
        d.tag(),
        o.transactions,
        o.determine,
        o.apply,
        o.cycles,
        start.elapsed()
    );
}

#[test]
fn verilator_in_every_configuration() {
    if !tools_present(EngineKind::Verilator) {
        return;
    }
    let designs = reference_designs();
    for (n, d) in designs.iter().enumerate() {
        let stall = [0.4, 0.3, 0.5, 0.2, 0.35][n % 5];
        check(
            EngineKind::Verilator,
            d,
            volume(100_000),
            21 + n as u64,
            stall,
        );
    }
}

/// The two streams of the unit as batch lanes: 0 = determine, 1 = apply.
fn lanes() -> Vec<StreamNames> {
    ["det", "apply"]
        .iter()
        .map(|p| StreamNames {
            in_valid: format!("{p}_in_valid"),
            in_ready: format!("{p}_in_ready"),
            in_payload: vec![format!("{p}_in_data")],
            out_valid: format!("{p}_out_valid"),
            out_ready: format!("{p}_out_ready"),
            out_payload: vec![format!("{p}_out_data")],
        })
        .collect()
}

/// A scoreboard decoder printing each field of a lane's payload.
fn decoder(layout: golden::layout::Layout) -> Box<FieldDecoder> {
    Box::new(
        move |txn: &cosim::tb::Transaction| match layout.unpack(&txn[0]) {
            Ok(fields) => fields
                .into_iter()
                .map(|(n, v)| (n.to_string(), format!("{v:#x}")))
                .collect(),
            Err(e) => vec![("undecodable".to_string(), e.to_string())],
        },
    )
}

/// The batch vectors of `txns`: each on its path's lane, the first of a run
/// of one kind waiting for every earlier output (then nothing of the
/// earlier run is in flight, so its table writes are seen, as in
/// `units::translate::run`). Also the sticky error bits golden implies.
fn lane_vectors(d: &TranslateDesign, txns: &[TranslateTxn]) -> (Vec<LaneVector>, (bool, bool)) {
    let mut errs = (false, false);
    let mut out = Vec::with_capacity(txns.len());
    let mut previous_lane = None;
    for t in txns {
        let (lane, input, expected) = match t {
            TranslateTxn::Determine(r) => {
                errs.0 |= r.outputs.ok == 0;
                let i = pack_det_in(d, &r.inputs).unwrap();
                (0, i, pack_det_out(d, &r.outputs).unwrap())
            }
            TranslateTxn::Apply(r) => {
                errs.1 |= r.outputs.code != ApplyCode::Ok;
                let i = pack_apply_in(d, &r.inputs).unwrap();
                (1, i, pack_apply_out(d, &r.outputs).unwrap())
            }
        };
        out.push(LaneVector {
            lane,
            wait_for_earlier_outputs: previous_lane != Some(lane),
            vector: Vector {
                input: vec![input.clone()],
                outputs: vec![vec![expected.clone()]],
            },
        });
        previous_lane = Some(lane);
    }
    (out, errs)
}

/// `count` golden transactions through the batch simulator with stall
/// `stall` on every stream; checks the outputs in order per path, and from
/// the watched status outputs: every cycle `done == idle && !idle one
/// cycle earlier` (idle before the first cycle: reset leaves the unit
/// empty), and at the end (after the drain) `idle` and the sticky error
/// bits golden implies.
fn check_batch(batch: &IcarusBatch, d: &TranslateDesign, count: usize, seed: u64, stall: f64) {
    let seed = seeded(seed);
    let txns = generate(d, seed, count).unwrap();
    let (vs, (det_err, app_err)) = lane_vectors(d, &txns);
    let config = BenchConfig {
        seed,
        in_stall: cosim::tb::Stalls::Coin(stall),
        out_stall: cosim::tb::Stalls::Coin(stall),
        reproduce: Some("cargo test -p cosim --release --test translate_engines".into()),
        ..BenchConfig::default()
    };
    let layouts = [det_out_layout(d), apply_out_layout(d)];
    let r = batch
        .run(
            &vs,
            &mut |lane| Some(decoder(layouts[lane].clone())),
            &config,
        )
        .unwrap_or_else(|e| panic!("{}: {e}", d.tag()));
    let b = &r.bench;
    println!(
        "{} {}: {} transactions, {} beats, {} cycles at stall {stall}, {:.2} s wall ({:.0} cycles/s of vvp)",
        b.engine,
        d.tag(),
        txns.len(),
        b.inputs_sent,
        b.cycles,
        b.wall.as_secs_f64(),
        r.cycles_per_second()
    );
    assert!(b.passed(), "{}:\n{b}", d.tag());
    assert_eq!(b.matched, txns.len() as u64);
    let mut idle_before = true;
    let mut last = Vec::new();
    r.watch.for_each_cycle(b.cycles, |cycle, v| {
        let (idle, done) = (v[0].bit(0), v[1].bit(0));
        assert_eq!(
            done,
            idle && !idle_before,
            "{} cycle {cycle}: done = {done}, idle = {idle}, idle one cycle earlier = {idle_before}",
            d.tag()
        );
        idle_before = idle;
        last = v.to_vec();
    });
    assert_eq!(
        r.watch.ports,
        ["idle", "done", "det_error_seen", "apply_error_seen"]
    );
    assert!(last[0].bit(0), "{}: idle at the end", d.tag());
    assert_eq!(
        (last[2].bit(0), last[3].bit(0)),
        (det_err, app_err),
        "{}: sticky error bits (det, apply) at the end",
        d.tag()
    );
}

/// The Icarus batch runs of the reference configurations `which` (100,000
/// transactions each, stall 0.05..=0.5 per configuration).
fn icarus_batch_configurations(which: &[usize]) {
    if !tools_present(EngineKind::Icarus) {
        return;
    }
    let spec = BatchSpec {
        lanes: lanes(),
        watch: ["idle", "done", "det_error_seen", "apply_error_seen"]
            .map(String::from)
            .to_vec(),
        constants: Vec::new(),
    };
    let designs = reference_designs();
    for &n in which {
        let d = &designs[n];
        let dir = tempfile::tempdir().unwrap();
        let design = design_from_module(&translate_unit(d), dir.path()).unwrap();
        let batch = IcarusBatch::new(&design, &spec).unwrap_or_else(|e| panic!("{e}"));
        let stall = [0.3, 0.5, 0.2, 0.45, 0.05][n % 5];
        // Icarus, the 4-state engine, at depth (SPEC 10.3).
        check_batch(&batch, d, 10_000, 31 + n as u64, stall);
    }
}

// Two tests of about equal time, so the test harness runs them side by side.
#[test]
fn icarus_default_d31_and_smallest_grid() {
    icarus_batch_configurations(&[0, 1, 4]);
}

#[test]
fn icarus_q0_and_binary64() {
    icarus_batch_configurations(&[2, 3]);
    assert_eq!(reference_designs().len(), 5, "every configuration is run");
}

/// The library testbench (`units::translate::run`) on the Icarus pipe
/// engine, which the CLI's `hiermerge cosim --engine iverilog` uses.
#[test]
fn icarus_pipe_engine_runs_the_library_testbench() {
    if !tools_present(EngineKind::Icarus) {
        return;
    }
    let designs = reference_designs();
    check(EngineKind::Icarus, &designs[0], 2_000, 41, 0.3);
    check(EngineKind::Icarus, &designs[1], 1_000, 42, 0.5);
}
