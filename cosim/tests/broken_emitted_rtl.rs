//! Issue 6's acceptance: a deliberately broken RTL, one bit of the EMITTED
//! translation unit flipped, is caught by the harness with the report a
//! person can act on: the failing transaction, every field by name with
//! the differing one marked, expected against got, the cycle, the seed, and
//! a VCD of the cycles around it. The unbroken design passes the same run.

use std::path::Path;

use cosim::from_rtl::design_from_module;
use cosim::units::translate::{run_with_vcd_on_mismatch, Failure, RunConfig};
use cosim::{open_engine, Design, Engine, EngineKind};
use golden::translate::model::TranslateDesign;
use golden::vectors::translate::generate;

/// The apply path's code for "outside the scene on x" is 5 (SPEC 7.9); the
/// broken design says 1 (bit 2 of the constant flipped).
const GOOD: &str = "apply_outside_x ? 3'd5";
const BROKEN: &str = "apply_outside_x ? 3'd1";

fn verilator_present() -> bool {
    match EngineKind::Verilator.check_tools() {
        Ok(()) => true,
        Err(e) if std::env::var("CI").as_deref() == Ok("true") => panic!("CI=true: {e}"),
        Err(e) => {
            eprintln!("skipping: {e}; install with apt-get install verilator");
            false
        }
    }
}

fn run_on(
    design: &Design,
    d: &TranslateDesign,
    vcd: &Path,
) -> Result<cosim::units::translate::Outcome, Failure> {
    let txns = generate(d, 17, 3000).unwrap();
    let config = RunConfig {
        seed: 17,
        stall: cosim::tb::Stalls::Coin(0.3),
        flip_expected: None,
        ..Default::default()
    };
    let mut make = |trace: bool| -> cosim::Result<Box<dyn Engine>> {
        open_engine(EngineKind::Verilator, design, trace)
    };
    run_with_vcd_on_mismatch(
        &mut make,
        d,
        &txns,
        &config,
        Some(vcd.to_path_buf()),
        20,
        &mut |_, _| {},
    )
}

#[test]
fn one_flipped_bit_of_the_emitted_translation_unit_is_caught_with_a_report() {
    if !verilator_present() {
        return;
    }
    let d = TranslateDesign::default();
    let module = rtl_gen::translate::translate_unit(&d);

    let good_dir = tempfile::tempdir().unwrap();
    let good = design_from_module(&module, good_dir.path()).unwrap();
    let outcome = run_on(&good, &d, &good_dir.path().join("good.vcd"))
        .unwrap_or_else(|f| panic!("the unbroken design fails: {f:?}"));
    assert_eq!(outcome.transactions, 3000);

    let bad_dir = tempfile::tempdir().unwrap();
    let bad = design_from_module(&module, bad_dir.path()).unwrap();
    assert_eq!(bad.verilog_files.len(), 1);
    let file = &bad.verilog_files[0];
    let text = std::fs::read_to_string(file).unwrap();
    assert_eq!(
        text.matches(GOOD).count(),
        1,
        "the emitted design no longer has `{GOOD}`"
    );
    std::fs::write(file, text.replace(GOOD, BROKEN)).unwrap();

    let vcd = bad_dir.path().join("broken.vcd");
    let m = match run_on(&bad, &d, &vcd) {
        Err(Failure::Mismatch(m)) => m,
        other => panic!("the broken design was not caught: {other:?}"),
    };
    let report = m.to_string();
    println!("{report}");
    assert_eq!(m.kind, "apply");
    assert_eq!(m.seed, 17);
    assert!(m.cycle > 0);
    let differing: Vec<_> = m.fields.iter().filter(|f| f.differs()).collect();
    assert_eq!(differing.len(), 1, "{report}");
    assert_eq!(
        (differing[0].expected, differing[0].got),
        (5, 1),
        "{report}"
    );
    assert!(
        report.contains(&format!("*{}", differing[0].name)),
        "{report}"
    );
    let vcd_path = m.vcd.as_ref().expect("a VCD was written");
    let vcd_text = std::fs::read_to_string(vcd_path).unwrap();
    assert!(
        vcd_text.contains("$enddefinitions") && vcd_text.contains('#'),
        "VCD {}",
        vcd_path.display()
    );
}
