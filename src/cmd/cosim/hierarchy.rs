//! `--unit hierarchy`: seeded random merges through the hierarchy unit
//! (docs/hardware.md 8.16), each merge's translations written by determine
//! commands before its merge command.

use std::path::Path;

use cosim::units::hierarchy_unit;
use golden::merge::merge_module::MergeDesign;
use rtl_gen::merge::HierarchyUnitConfig;

use super::merger::merger_config;
use super::report::{chunked_failure, finish_report, Counts, HierarchyReport, Report};
use super::{bar, bench_config, count, module_engine, Args};

/// The hierarchy unit `a` asks for: the merger of `design` with the sizes
/// flags, and a translation unit of `--table-depth` entries (default one
/// per hierarchy id) taking binary64 placements.
pub(super) fn config_of(a: &Args, design: &MergeDesign) -> Result<HierarchyUnitConfig, String> {
    let merger = merger_config(design, a.capacity_bits, a.leaf_bits)?;
    hierarchy_config(merger, a.design.table_depth)
}

/// The hierarchy unit around `merger` with a table of `table_depth`
/// entries (default one per hierarchy id), validated (also `export-tb`'s).
pub(crate) fn hierarchy_config(
    merger: rtl_gen::merge::MergerConfig,
    table_depth: Option<u32>,
) -> Result<HierarchyUnitConfig, String> {
    let mut c = HierarchyUnitConfig::new(merger);
    if let Some(depth) = table_depth {
        c.table.unit.table_depth = depth;
    }
    c.validate()
        .map_err(|e| format!("hierarchy unit configuration: {e}"))?;
    Ok(c)
}

/// `--unit hierarchy`: `--count` random merges, every stream with its own
/// stall pattern, 10,000 merges at a time.
pub(super) fn run(
    a: &Args,
    design: &MergeDesign,
    flip: Option<usize>,
    dir: &Path,
) -> Result<Report, String> {
    let engine = module_engine(a.engine)?;
    let c = config_of(a, design)?;
    let count = count(a)?;
    let stage = hierarchy_unit::STAGE;
    let bench = bench_config(a, stage)?;
    if !a.json {
        eprintln!(
            "running {count} merges through {} on {}",
            rtl_gen::merge::hierarchy_unit_name(&c),
            a.engine.name()
        );
    }
    let pb = bar(count as u64, a.json);
    let o = hierarchy_unit::run(
        &c,
        engine,
        &bench,
        hierarchy_unit::Cases {
            count,
            merges: super::merger::merges_of(a),
            flip,
        },
        dir,
        &mut |merges, cycle| {
            pb.set_position(merges);
            pb.set_message(format!("cycle {cycle}"));
        },
    );
    pb.finish_and_clear();
    let o = o.map_err(|e| e.to_string())?;
    let (t, stats) = (&o.totals, &o.stats);
    if t.passed() {
        super::bins::hierarchy(c.merger.design.inputs, stats);
    }
    let received = |name: &str| t.received.iter().find(|r| r.0 == name).map_or(0, |r| r.1);
    let counts = Counts {
        transactions: t.merges as u64,
        records: received("det_out"),
        nodes: received("nodes"),
        mismatches: t.mismatches,
        cycles: t.cycles,
        wall_seconds: t.wall.as_secs_f64(),
    };
    let first = chunked_failure(stage, a.seed, t);
    let mut report = finish_report(a, stage, flip, counts, first, t.vcd.as_ref())?;
    report.hierarchy = Some(HierarchyReport {
        determines: stats.determines,
        rewrites: stats.rewrites,
        residuals: stats.residuals,
        hard_cases: stats.named,
        refused: stats.merges.refused as u64,
        fetch_errors: stats.merges.fetch_errors as u64,
        golden_seconds: t.golden_wall.as_secs_f64(),
        top: rtl_gen::merge::hierarchy_unit_name(&c),
        netlist_sha256: o.netlist_sha256.clone(),
        stimulus_sha256: o.stimulus_sha256.clone(),
    });
    Ok(report)
}
