//! The generated translation unit against the golden model, bit for bit,
//! in Verilator (100,000 transactions in each reference configuration:
//! the default, D = 31 with binary64, Q = 0, binary64 at the default grid,
//! the smallest grid) and Icarus Verilog (100,000 default, 5,000 per other
//! configuration, 4-state: any X on an output after reset fails), through
//! cosim's engines, with random back-pressure. A missing tool fails under
//! CI=true and is a printed skip otherwise.

use cosim::from_rtl::design_from_module;
use cosim::units::translate::{run, RunConfig};
use cosim::{open_engine, EngineKind};
use golden::vectors::translate::{generate, TranslateDesign};
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
    let txns = generate(d, seed, count).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let design = design_from_module(&translate_unit(d), dir.path()).unwrap();
    let mut engine = open_engine(kind, &design, false).unwrap_or_else(|e| panic!("{e}"));
    let start = std::time::Instant::now();
    let config = RunConfig {
        seed,
        stall,
        flip_expected: None,
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
fn verilator_100k_in_every_configuration() {
    if !tools_present(EngineKind::Verilator) {
        return;
    }
    let designs = reference_designs();
    for (n, d) in designs.iter().enumerate() {
        let stall = [0.4, 0.3, 0.5, 0.2, 0.35][n % 5];
        check(EngineKind::Verilator, d, 100_000, 21 + n as u64, stall);
    }
}

#[test]
fn icarus_default_100k_and_other_configurations() {
    if !tools_present(EngineKind::Icarus) {
        return;
    }
    let designs = reference_designs();
    check(EngineKind::Icarus, &designs[0], 100_000, 31, 0.3);
    for (n, d) in designs.iter().enumerate().skip(1) {
        check(EngineKind::Icarus, d, 5_000, 31 + n as u64, 0.5);
    }
}
