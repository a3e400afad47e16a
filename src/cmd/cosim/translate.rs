//! `--unit translate`: the translation unit's transactions, generated or
//! from a vectors file, through one engine.

use std::path::Path;

use cosim::from_rtl::design_from_module;
use cosim::units::translate::{self, Failure, RunConfig};
use golden::translate::model::TranslateDesign;
use golden::vectors::translate::{generate, read_translate_vectors};

use super::report::{finish_report, Counts, FieldReport, MismatchReport, Report};
use super::{bar, count, factory, vcd_path, Args, VCD_RADIUS};

/// Runs the translation unit's transactions.
pub(super) fn run(
    a: &Args,
    design: &TranslateDesign,
    flip: Option<usize>,
    dir: &Path,
) -> Result<Report, String> {
    let txns = match &a.vectors {
        Some(p) => {
            read_translate_vectors(p, design)
                .map_err(|e| e.to_string())?
                .1
        }
        None => {
            let count = count(a)?;
            generate(design, a.seed, count).map_err(|e| e.to_string())?
        }
    };
    let module = rtl_gen::translate::translate_unit(design);
    cosim::waves::check_scope(&module, a.wave_scope.as_deref()).map_err(|e| e.to_string())?;
    let cdesign = design_from_module(&module, dir).map_err(|e| e.to_string())?;
    let mut make = factory(a, &module, &cdesign)?;
    super::no_stream_stalls(&a.stall_stream, "--unit translate")?;
    let config = RunConfig {
        seed: a.seed,
        stall: super::stalls(a)?,
        wave_scope: a.wave_scope.clone(),
        wave_window: a.wave_window,
        flip_expected: flip,
    };
    let pb = bar(txns.len() as u64, a.json);
    let result = translate::run_with_vcd_on_mismatch(
        &mut make,
        design,
        &txns,
        &config,
        Some(vcd_path(a, "translate")),
        VCD_RADIUS,
        &mut |done, cycle| {
            pb.set_position(done);
            pb.set_message(format!("cycle {cycle}"));
        },
    );
    pb.finish_and_clear();
    let n = txns.len() as u64;
    let (counts, first, vcd) = match result {
        Ok(o) => {
            super::bins::translate(design, &txns);
            let counts = Counts {
                transactions: n,
                records: n,
                nodes: n,
                mismatches: 0,
                cycles: o.cycles,
                wall_seconds: o.wall.as_secs_f64(),
            };
            (counts, None, None)
        }
        Err(Failure::Engine(e)) => return Err(e.to_string()),
        Err(Failure::Mismatch(m)) => {
            let counts = Counts {
                transactions: n,
                records: n,
                nodes: n,
                mismatches: 1,
                cycles: m.cycle,
                wall_seconds: 0.0,
            };
            let first = MismatchReport {
                transaction: m.transaction as u64,
                stream: None,
                beat: None,
                kind: m.kind.to_string(),
                cycle: m.cycle,
                seed: m.seed,
                what: m.what.clone(),
                fields: m
                    .fields
                    .iter()
                    .map(|f| FieldReport {
                        name: f.name.clone(),
                        expected: format!("{:#x}", f.expected),
                        got: format!("{:#x}", f.got),
                        differs: f.differs(),
                    })
                    .collect(),
            };
            (counts, Some(first), m.vcd.clone())
        }
    };
    // A window asked of a passing run is written too.
    let vcd = vcd.or_else(|| {
        let p = vcd_path(a, "translate");
        (a.wave_window.is_some() && p.exists()).then_some(p)
    });
    finish_report(a, "translate_unit", flip, counts, first, vcd.as_ref())
}
