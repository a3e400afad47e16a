//! Where a cycle of the Icarus batch modes goes: the generated testbench's
//! own statements against the design's evaluation. Printed, never asserted.
//!
//! `cargo bench -p cosim --bench icarus_batch_speed`
//!
//! Each bench runs twice: on the real unit, and on a stand-in with the
//! same ports that accepts every input beat at once (`*_ready` tied high,
//! every other output 0) and is given no expected outputs, so vvp runs the
//! same testbench over a design that costs nearly nothing. vvp's CPU time
//! per cycle on the stand-in is the testbench's share (per cycle: a long
//! run's CPU minus a short one's, over the difference in cycles; each the
//! cheapest of three runs).
//! Every unit is also run as emitted with `RegisterStyle::NextWires` (every
//! register loaded every cycle from a continuous `r_next` mux, the emission
//! before the enable idiom; SPEC 11), on the same beats: the report must
//! equal the default emission's, and the two CPU figures side by side are
//! the idiom's gain. Hierarchy merger top (`IcarusMultiBatch`,
//! `cosim::units::merger`): default design, 16 random merges against 3,
//! stall 0.3. Merging module (`IcarusMultiBatch`): default design, 300
//! merges, stall 0.3; merge-level stage (`IcarusBatch`): default design,
//! 1,500 levels, stall 0.3.

use cosim::icarus::{BatchSpec, IcarusBatch, IcarusMultiBatch, LaneVector};
use cosim::tb::{BenchConfig, StreamBeats, StreamNames, Vector};
use cosim::units::{merge_level, merge_module, merger};
use cosim::{Design, PortDir};
use golden::merge::merge_module::MergeDesign;
use golden::translate::stimulus::SplitMix64;
use rtl_gen::verilog::{write_design_with_style, RegisterStyle};
use std::path::Path;
use std::time::Duration;

const RUNS: usize = 3;

type Res<T> = Result<T, Box<dyn std::error::Error>>;

fn config() -> BenchConfig {
    BenchConfig {
        seed: 5,
        in_stall: cosim::tb::Stalls::Coin(0.3),
        out_stall: cosim::tb::Stalls::Coin(0.3),
        stop_on_mismatch: false,
        watchdog_cycles: 100_000,
        ..BenchConfig::default()
    }
}

/// A design with `real`'s ports whose outputs named in `ready_high` are 1
/// and every other output 0, written to `dir`.
fn stand_in(real: &Design, ready_high: &[String], dir: &Path) -> Res<Design> {
    let mut text = format!("module {}(\n", real.top);
    let decls: Vec<String> = real
        .ports
        .iter()
        .map(|p| {
            let dir = if p.dir == PortDir::Input {
                "input wire"
            } else {
                "output wire"
            };
            format!("    {dir} [{}:0] {}", p.width - 1, p.name)
        })
        .collect();
    text += &decls.join(",\n");
    text += "\n);\n";
    for p in real.ports.iter().filter(|p| p.dir == PortDir::Output) {
        let value = u8::from(ready_high.contains(&p.name));
        text += &format!("    assign {} = {}'d{value};\n", p.name, p.width);
    }
    text += "endmodule\n";
    let file = dir.join("stand_in.v");
    std::fs::write(&file, text)?;
    Ok(Design {
        verilog_files: vec![file],
        ..real.clone()
    })
}

/// `design` (of `module`) as emitted with every register loaded every cycle
/// (`RegisterStyle::NextWires`), written to `dir`.
fn next_wires(module: &rtl_gen::Module, design: &Design, dir: &Path) -> Res<Design> {
    let files = write_design_with_style(module, dir, RegisterStyle::NextWires)?;
    Ok(Design {
        verilog_files: files,
        ..design.clone()
    })
}

/// The line comparing a unit's default emission with `NextWires`.
fn print_styles(what: &str, enables: (u64, f64), next_wires: (u64, f64)) {
    println!(
        "{what}: enable idiom {:.2} us/cycle of vvp CPU ({:.0} cycles/s); NextWires {:.2} \
         us/cycle ({:.0} cycles/s): {:.2}x faster",
        enables.1,
        1e6 / enables.1,
        next_wires.1,
        1e6 / next_wires.1,
        next_wires.1 / enables.1
    );
}

/// CPU time of the waited-for children of this process so far (user +
/// system, `cutime + cstime` of `/proc/self/stat`): vvp's own CPU, which a
/// loaded machine does not inflate as it does wall time.
fn children_cpu() -> Duration {
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let after_name = stat.rsplit_once(')').map_or("", |s| s.1);
    let fields: Vec<u64> = after_name
        .split_whitespace()
        .map(|f| f.parse().unwrap_or(0))
        .collect();
    // Fields 16 and 17 of the file (cutime, cstime) are 13 and 14 after the name.
    let ticks = fields.get(13).copied().unwrap_or(0) + fields.get(14).copied().unwrap_or(0);
    Duration::from_millis(ticks * 10)
}

/// The cheapest of `RUNS` runs: (cycles, CPU of vvp and the mask pipe's
/// `mkfifo`).
fn best(mut run: impl FnMut() -> cosim::Result<u64>) -> cosim::Result<(u64, Duration)> {
    let mut best: Option<(u64, Duration)> = None;
    for _ in 0..RUNS {
        let before = children_cpu();
        let cycles = run()?;
        let cpu = children_cpu().saturating_sub(before);
        if best.is_none_or(|b| cpu < b.1) {
            best = Some((cycles, cpu));
        }
    }
    Ok(best.expect("at least one run"))
}

/// vvp's CPU time per cycle, without its fixed costs (start, file
/// loads): the difference between a long run and a short one of the same
/// bench, over the difference of their cycles. `run(true)`: the long one.
fn per_cycle(mut run: impl FnMut(bool) -> cosim::Result<u64>) -> cosim::Result<(u64, f64)> {
    let long = best(|| run(true))?;
    let short = best(|| run(false))?;
    let us = (long.1.as_secs_f64() - short.1.as_secs_f64()) * 1e6
        / long.0.saturating_sub(short.0).max(1) as f64;
    Ok((long.0, us))
}

fn print(what: &str, real: (u64, f64), stand: (u64, f64)) {
    println!(
        "{what}: real {} cycles, {:.2} us/cycle of vvp CPU ({:.0} cycles/s); stand-in {} cycles, \
         {:.2} us/cycle: the testbench is {:.0}% of a cycle",
        real.0,
        real.1,
        1e6 / real.1,
        stand.0,
        stand.1,
        100.0 * stand.1 / real.1
    );
}

fn merge_module(dir: &Path) -> Res<()> {
    let d = MergeDesign::default();
    let module = merge_module::merge_module(&d);
    let design = cosim::from_rtl::design_from_module(&module, dir)?;
    let most = merge_module::DEFAULT_MOST_VOXELS;
    let long = merge_module::generate_streams(&d, 5, 300, most, None)?;
    let short = merge_module::generate_streams(&d, 5, 10, most, None)?;
    let names = merge_module::input_names(&d);
    let names: Vec<&str> = names.iter().map(String::as_str).collect();
    let c = config();
    let run_on = |design: &Design| -> Res<(u64, f64)> {
        let batch = IcarusMultiBatch::new(design, &names, &merge_module::OUTPUT_NAMES)?;
        Ok(per_cycle(|is_long| {
            let s = if is_long { &long } else { &short };
            let r = batch.run(&s.inputs, &s.outputs, &c)?;
            assert!(r.report.passed(), "{}", r.report);
            Ok(r.report.cycles)
        })?)
    };
    let real = run_on(&design)?;
    let old_dir = tempfile::tempdir()?;
    let old = run_on(&next_wires(&module, &design, old_dir.path())?)?;
    assert_eq!(old.0, real.0, "both emissions take the same cycles");
    let readies: Vec<String> = names.iter().map(|n| format!("{n}_ready")).collect();
    let stand_dir = tempfile::tempdir()?;
    let standin = stand_in(&design, &readies, stand_dir.path())?;
    let none: Vec<StreamBeats> = merge_module::OUTPUT_NAMES
        .iter()
        .map(|o| StreamBeats {
            name: o.to_string(),
            beats: Vec::new(),
        })
        .collect();
    let sbatch = IcarusMultiBatch::new(&standin, &names, &merge_module::OUTPUT_NAMES)?;
    let stand = per_cycle(|is_long| {
        let s = if is_long { &long } else { &short };
        let r = sbatch.run(&s.inputs, &none, &c)?;
        assert!(r.report.passed(), "{}", r.report);
        Ok(r.report.cycles)
    })?;
    print("merging module, IcarusMultiBatch", real, stand);
    print_styles("merging module", real, old);
    Ok(())
}

/// Merges of the hierarchy merger bench's long and short runs.
const MERGER_LONG: usize = 16;
const MERGER_SHORT: usize = 3;

fn hierarchy_merger(dir: &Path) -> Res<()> {
    let c = rtl_gen::merge::MergerConfig::new(MergeDesign::default());
    let module = rtl_gen::merge::hierarchy_merger_unit(&c)?;
    let design = cosim::from_rtl::design_from_module(&module, dir)?;
    let mut rng = SplitMix64(5);
    let txs = (0..MERGER_LONG)
        .map(|_| merger::random_merge(&mut rng, &c))
        .collect::<cosim::Result<Vec<_>>>()?;
    let long = merger::merger_streams(&c, &txs)?.streams;
    let short = merger::merger_streams(&c, &txs[..MERGER_SHORT])?.streams;
    let ins: Vec<&str> = long.inputs.iter().map(|s| s.name.as_str()).collect();
    let outs: Vec<&str> = long.outputs.iter().map(|s| s.name.as_str()).collect();
    let c = config();
    let run_on = |design: &Design| -> Res<((u64, f64), f64, cosim::tb::MultiReport)> {
        let batch = IcarusMultiBatch::new_watching(design, &ins, &outs, &merger::PULSES)?;
        let mut wall_rate = 0.0;
        let mut report = None;
        let r = per_cycle(|is_long| {
            let s = if is_long { &long } else { &short };
            let r = batch.run(&s.inputs, &s.outputs, &c)?;
            assert!(r.report.passed(), "{}", r.report);
            if is_long {
                wall_rate = r.cycles_per_second();
                report = Some(r.report.clone());
            }
            Ok(r.report.cycles)
        })?;
        Ok((r, wall_rate, report.expect("a long run")))
    };
    let (real, real_wall, real_report) = run_on(&design)?;
    let old_dir = tempfile::tempdir()?;
    let (old, old_wall, old_report) = run_on(&next_wires(&module, &design, old_dir.path())?)?;
    assert_eq!(
        (old_report.cycles, &old_report.received, old_report.matched),
        (
            real_report.cycles,
            &real_report.received,
            real_report.matched
        ),
        "both emissions must behave alike"
    );
    let readies: Vec<String> = ins.iter().map(|n| format!("{n}_ready")).collect();
    let stand_dir = tempfile::tempdir()?;
    let standin = stand_in(&design, &readies, stand_dir.path())?;
    let none: Vec<StreamBeats> = outs
        .iter()
        .map(|o| StreamBeats {
            name: o.to_string(),
            beats: Vec::new(),
        })
        .collect();
    let sbatch = IcarusMultiBatch::new_watching(&standin, &ins, &outs, &merger::PULSES)?;
    let stand = per_cycle(|is_long| {
        let s = if is_long { &long } else { &short };
        let r = sbatch.run(&s.inputs, &none, &c)?;
        assert!(r.report.passed(), "{}", r.report);
        Ok(r.report.cycles)
    })?;
    print("hierarchy merger top, IcarusMultiBatch", real, stand);
    print_styles("hierarchy merger top", real, old);
    println!(
        "hierarchy merger top: a long run's wall (files, vvp, compare): enable idiom \
         {real_wall:.0} cycles/s, NextWires {old_wall:.0} cycles/s"
    );
    Ok(())
}

fn merge_level(dir: &Path) -> Res<()> {
    let d = MergeDesign::default();
    let module = merge_level::merge_level_module(&d.params);
    let design = cosim::from_rtl::design_from_module(&module, dir)?;
    let levels = merge_level::generate_levels(&d, 5, 1500)?;
    let vectors = merge_level::bench_vectors(&levels, None)?;
    let names = StreamNames::single("data");
    let c = config();
    let batch = IcarusBatch::new(&design, &BatchSpec::single(&names))?;
    let lanes: Vec<LaneVector> = vectors
        .iter()
        .map(|v| LaneVector::new(0, v.clone()))
        .collect();
    // A short run: whole levels (a level's beats belong together).
    let short = merge_level::bench_vectors(&levels[..levels.len() / 50], None)?.len();
    let run_on = |batch: &IcarusBatch| {
        per_cycle(|is_long| {
            let n = if is_long { lanes.len() } else { short };
            let r = batch.run(&lanes[..n], &mut |_| None, &c)?;
            assert!(r.bench.passed(), "{}", r.bench);
            Ok(r.bench.cycles)
        })
    };
    let real = run_on(&batch)?;
    let old_dir = tempfile::tempdir()?;
    let old_design = next_wires(&module, &design, old_dir.path())?;
    let old = run_on(&IcarusBatch::new(&old_design, &BatchSpec::single(&names))?)?;
    assert_eq!(old.0, real.0, "both emissions take the same cycles");
    let stand_dir = tempfile::tempdir()?;
    let standin = stand_in(
        &design,
        std::slice::from_ref(&names.in_ready),
        stand_dir.path(),
    )?;
    let sbatch = IcarusBatch::new(&standin, &BatchSpec::single(&names))?;
    let no_outputs: Vec<LaneVector> = vectors
        .iter()
        .map(|v| {
            LaneVector::new(
                0,
                Vector {
                    input: v.input.clone(),
                    outputs: Vec::new(),
                },
            )
        })
        .collect();
    let stand = per_cycle(|is_long| {
        let n = if is_long { no_outputs.len() } else { short };
        let r = sbatch.run(&no_outputs[..n], &mut |_| None, &c)?;
        assert!(r.bench.passed(), "{}", r.bench);
        Ok(r.bench.cycles)
    })?;
    print("merge-level stage, IcarusBatch", real, stand);
    print_styles("merge-level stage", real, old);
    Ok(())
}

fn main() -> Res<()> {
    if !cosim::tools::tool_available("iverilog") {
        eprintln!("iverilog missing: {}", cosim::tools::INSTALL_HINT);
        return Ok(());
    }
    let dir = tempfile::tempdir()?;
    hierarchy_merger(dir.path())?;
    merge_module(dir.path())?;
    merge_level(dir.path())?;
    Ok(())
}
