//! The generated translation unit against the golden model, bit for bit,
//! in rtl-gen's IR simulator (an engine at depth, SPEC 10.3): 10,000
//! transactions (golden hard cases, every category of the vector generator)
//! in the default configuration, 5,000 in each other reference
//! configuration, with random
//! back-pressure; and the cycle count with none (one record per clock).

use cosim::from_rtl::design_from_module;
use cosim::ir_engine::IrEngine;
use cosim::units::translate::{run, Outcome, RunConfig};
use golden::seed::seeded;
use golden::translate::model::{TranslateDesign, TranslateTxn};
use golden::vectors::translate::generate;
use rtl_gen::translate::{reference_designs, translate_unit};

/// Runs `txns` on the IR simulator through the library testbench; panics
/// with the decoded report at the first mismatch.
fn run_ir(d: &TranslateDesign, txns: &[TranslateTxn], stall: f64, seed: u64) -> Outcome {
    let m = translate_unit(d);
    let dir = tempfile::tempdir().unwrap();
    let design = design_from_module(&m, dir.path()).unwrap();
    let mut engine = IrEngine::new(&m, &design).unwrap();
    let config = RunConfig {
        seed,
        stall: cosim::tb::Stalls::Coin(stall),
        flip_expected: None,
        ..Default::default()
    };
    run(&mut engine, d, txns, &config, None, &mut |_, _| {}).unwrap_or_else(|f| panic!("{f}"))
}

fn check(d: &TranslateDesign, count: usize, seed: u64, stall: f64) {
    let seed = seeded(seed);
    let txns = generate(d, seed, count).unwrap();
    let o = run_ir(d, &txns, stall, seed);
    println!(
        "{}: {} transactions ({} determine, {} apply) in {} cycles at stall {stall}",
        d.tag(),
        o.transactions,
        o.determine,
        o.apply,
        o.cycles
    );
}

#[test]
fn default_configuration() {
    let d = TranslateDesign::default();
    check(&d, 6_000, 1, 0.3);
    check(&d, 4_000, 2, 0.5);
}

#[test]
fn other_configurations() {
    for (n, d) in reference_designs().iter().enumerate().skip(1) {
        check(d, 5_000, 10 + n as u64, 0.25);
    }
}

/// With no back-pressure each path takes one record per clock: a run of
/// `n` records costs `n` cycles plus the path's pipeline depth (3
/// registers for determine, 2 for apply), so the cycle count is exact.
#[test]
fn one_record_per_clock_without_back_pressure() {
    for d in reference_designs() {
        let all = generate(&d, 7, 3_000).unwrap();
        // One table write, then a long run of each kind.
        let load = all
            .iter()
            .find(|t| matches!(t, TranslateTxn::Determine(r) if r.outputs.written == 1))
            .copied()
            .expect("the generator writes the table");
        let dets: Vec<TranslateTxn> = all
            .iter()
            .filter(|t| matches!(t, TranslateTxn::Determine(_)))
            .copied()
            .collect();
        let apps: Vec<TranslateTxn> = all
            .iter()
            .filter(|t| matches!(t, TranslateTxn::Apply(_)))
            .copied()
            .collect();
        // Re-run through golden so the expected outputs follow this order.
        let mut model = golden::translate::model::TranslateModel::new(d).unwrap();
        let mut txns = Vec::new();
        for t in std::iter::once(&load).chain(&dets).chain(&apps) {
            let inputs = match t {
                TranslateTxn::Determine(r) => {
                    golden::translate::model::TxnInputs::Determine(r.inputs)
                }
                TranslateTxn::Apply(r) => golden::translate::model::TxnInputs::Apply(r.inputs),
            };
            txns.push(model.run(&inputs).unwrap());
        }
        let o = run_ir(&d, &txns, 0.0, 3);
        let (nd, na) = (1 + dets.len() as u64, apps.len() as u64);
        println!(
            "{}: determine {nd} + apply {na} records in {} cycles: {:.4} records/cycle",
            d.tag(),
            o.cycles,
            (nd + na) as f64 / o.cycles as f64
        );
        assert_eq!(o.cycles, (nd + 5) + (na + 4), "{}", d.tag());
    }
}
