//! RTL cycles (SPEC 13.4) from the co-simulation library, on Verilator:
//! cycles per merge of the hierarchy merger top (`cosim::units::merger`,
//! seeded random merges, no stalls) and cycles per record of the
//! translation unit (`cosim::units::translate`), both checked bit for bit
//! against golden while they run.

use std::path::Path;

use cosim::units::merge_module::{ModuleEngine, RunConfig as BenchConfig};
use cosim::units::{merger, translate};
use cosim::{open_engine, EngineKind};
use golden::merge::merge_module::MergeDesign;
use golden::translate::model::TranslateDesign;
use golden::translate::TranslateUnitConfig;
use golden::vectors::translate::generate;
use golden::Params;
use serde::Serialize;

/// What the RTL took at one configuration.
#[derive(Serialize, Clone, Debug)]
pub struct RtlFigures {
    pub engine: String,
    pub seed: u64,
    pub stall: f64,
    pub merges: u64,
    pub merge_cycles: u64,
    pub cycles_per_merge: f64,
    pub translate_records: u64,
    pub translate_cycles: u64,
    pub cycles_per_translated_record: f64,
}

/// Stall probability of the study's runs: none, the unit's own pace.
pub const STALL: f64 = 0.0;

/// The merger the study measures at `params`: the defaults of
/// `hiermerge cosim --unit merger` (inputs, mode, sizes).
pub fn merger_config(params: Params) -> Result<rtl_gen::merge::MergerConfig, String> {
    let c = rtl_gen::merge::MergerConfig::new(MergeDesign {
        params,
        ..Default::default()
    });
    c.validate()
        .map_err(|e| format!("hierarchy merger at {}: {e}", params.tag()))?;
    Ok(c)
}

/// Runs `merges` merges and `records` translation records at `params`.
pub fn measure(
    params: Params,
    seed: u64,
    merges: usize,
    records: usize,
    dir: &Path,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<RtlFigures, String> {
    EngineKind::Verilator
        .check_tools()
        .map_err(|e| e.to_string())?;
    let c = merger_config(params)?;
    let config = merger::RunConfig {
        bench: BenchConfig {
            seed,
            stall: cosim::tb::Stalls::Coin(STALL),
            vcd_path: None,
            vcd_radius: 0,
            verilog_patch: None,
            ..BenchConfig::default()
        },
        count: merges,
        merges: cosim::units::merger::Merges::Random,
        store_latency: 1,
        flip_expected: None,
    };
    let o = merger::run(&c, ModuleEngine::Verilator, &config, dir, progress)
        .map_err(|e| e.to_string())?;
    if !o.passed() {
        return Err(format!(
            "hierarchy merger at {}: the RTL disagrees with golden (reproduce: hiermerge cosim --unit merger --seed {seed} --count {merges} --stall 0 --max-lod {} --quant-bits {})",
            params.tag(),
            params.max_lod,
            params.quant_bits
        ));
    }
    let (tcycles, trecords) = translate_cycles(params, seed, records, dir)?;
    let merges = o.totals.merges as u64;
    Ok(RtlFigures {
        engine: "verilator".into(),
        seed,
        stall: STALL,
        merges,
        merge_cycles: o.totals.cycles,
        cycles_per_merge: o.totals.cycles as f64 / merges.max(1) as f64,
        translate_records: trecords,
        translate_cycles: tcycles,
        cycles_per_translated_record: tcycles as f64 / trecords.max(1) as f64,
    })
}

/// Cycles and records of `records` seeded translation-unit transactions.
fn translate_cycles(
    params: Params,
    seed: u64,
    records: usize,
    dir: &Path,
) -> Result<(u64, u64), String> {
    let design = TranslateDesign {
        unit: TranslateUnitConfig {
            params,
            table_depth: params.hier_capacity() as u32,
        },
        binary64: false,
    };
    let txns = generate(&design, seed, records).map_err(|e| e.to_string())?;
    let module = rtl_gen::translate::translate_unit(&design);
    let cdesign = cosim::from_rtl::design_from_module(&module, dir).map_err(|e| e.to_string())?;
    let mut engine =
        open_engine(EngineKind::Verilator, &cdesign, false).map_err(|e| e.to_string())?;
    let config = translate::RunConfig {
        seed,
        stall: cosim::tb::Stalls::Coin(STALL),
        flip_expected: None,
        ..Default::default()
    };
    let o = translate::run(
        engine.as_mut(),
        &design,
        &txns,
        &config,
        None,
        &mut |_, _| {},
    )
    .map_err(|e| match e {
        translate::Failure::Engine(e) => e.to_string(),
        translate::Failure::Mismatch(m) => format!(
            "translation unit at {}: the RTL disagrees with golden: {}",
            params.tag(),
            m.what
        ),
    })?;
    Ok((o.cycles, o.transactions))
}
