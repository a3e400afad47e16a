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
//! Hierarchy merger top (`IcarusMultiBatch`, `cosim::units::merger`):
//! default design, 16 random merges against 3, stall 0.3; also the same
//! design with each register block's registers packed into vectors of at
//! most 512 bits (`packed_registers`: one nonblocking assignment per
//! vector instead of one per register; an experiment on the emitted text,
//! the report must equal the real one). Merging module
//! (`IcarusMultiBatch`): default design, 300 merges, stall 0.3;
//! merge-level stage (`IcarusBatch`): default design, 1,500 levels,
//! stall 0.3.

use cosim::icarus::{BatchSpec, IcarusBatch, IcarusMultiBatch, LaneVector};
use cosim::tb::{BenchConfig, StreamBeats, StreamNames, Vector};
use cosim::units::{merge, merge_module, merger};
use cosim::{Design, PortDir};
use golden::translate::stimulus::SplitMix64;
use golden::vectors::merge::MergeDesign;
use std::path::Path;
use std::time::Duration;

const RUNS: usize = 3;

type Res<T> = Result<T, Box<dyn std::error::Error>>;

fn config() -> BenchConfig {
    BenchConfig {
        seed: 5,
        in_stall: 0.3,
        out_stall: 0.3,
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

fn merging_module(dir: &Path) -> Res<()> {
    let d = MergeDesign::default();
    let design = cosim::from_rtl::design_from_module(&merge_module::merge_module(&d), dir)?;
    let most = merge_module::DEFAULT_MOST_VOXELS;
    let long = merge_module::generate_streams(&d, 5, 300, most, None)?;
    let short = merge_module::generate_streams(&d, 5, 10, most, None)?;
    let names = merge_module::input_names(&d);
    let names: Vec<&str> = names.iter().map(String::as_str).collect();
    let c = config();
    let batch = IcarusMultiBatch::new(&design, &names, &merge_module::OUTPUT_NAMES)?;
    let real = per_cycle(|is_long| {
        let s = if is_long { &long } else { &short };
        let r = batch.run(&s.inputs, &s.outputs, &c)?;
        assert!(r.report.passed(), "{}", r.report);
        Ok(r.report.cycles)
    })?;
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
    Ok(())
}

/// Merges of the hierarchy merger bench's long and short runs.
const MERGER_LONG: usize = 16;
const MERGER_SHORT: usize = 3;

/// Registers packed at most this many bits to a vector (`packed_registers`).
const PACK_BITS: usize = 512;

fn hierarchy_merger(dir: &Path) -> Res<()> {
    let c = rtl_gen::merge::MergerConfig::new(MergeDesign::default());
    let module = rtl_gen::merge::hierarchy_merger_unit(&c)?;
    let design = cosim::from_rtl::design_from_module(&module, dir)?;
    let mut rng = SplitMix64(5);
    let txs = (0..MERGER_LONG)
        .map(|_| merger::random_merge(&mut rng, &c))
        .collect::<cosim::Result<Vec<_>>>()?;
    let long = merger::merger_streams(&c, &txs)?;
    let short = merger::merger_streams(&c, &txs[..MERGER_SHORT])?;
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
    let pack_dir = tempfile::tempdir()?;
    let packed = packed_design(&design, PACK_BITS, pack_dir.path())?;
    let (pack, pack_wall, pack_report) = run_on(&packed)?;
    assert_eq!(
        (
            pack_report.cycles,
            &pack_report.received,
            pack_report.matched
        ),
        (
            real_report.cycles,
            &real_report.received,
            real_report.matched
        ),
        "the packed design must behave as the emitted one"
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
    println!(
        "hierarchy merger top: {real_wall:.0} cycles/s of a long run's wall (files, vvp, compare); \
         registers packed in vectors of <= {PACK_BITS} bits: {:.2} us/cycle of vvp CPU ({:.0} cycles/s), \
         {pack_wall:.0} cycles/s of wall",
        pack.1,
        1e6 / pack.1
    );
    Ok(())
}

/// `real` with every Verilog file rewritten by `packed_registers`, into `dir`.
fn packed_design(real: &Design, bits: usize, dir: &Path) -> Res<Design> {
    let mut files = Vec::new();
    for f in &real.verilog_files {
        let text = std::fs::read_to_string(f)?;
        let to = dir.join(f.file_name().ok_or("a Verilog file without a name")?);
        std::fs::write(&to, packed_registers(&text, bits))?;
        files.push(to);
    }
    Ok(Design {
        verilog_files: files,
        ..real.clone()
    })
}

/// The emitted Verilog with each `always @(posedge clk)` register block
/// (`if (rst) <r <= const;>... else <r <= next;>...`, the same registers in
/// both branches) rewritten to assign vectors of at most `bits` bits: per
/// vector `reg [..] hm_pk_<n>`, `wire [..] hm_pk_<n>_next = {nexts}`,
/// `assign {regs} = hm_pk_<n>` (the registers become wires). vvp runs a
/// procedural load and a nonblocking assignment per statement every cycle,
/// changed or not; a vector of registers costs one of each. Blocks of any
/// other shape are left as they are.
fn packed_registers(text: &str, bits: usize) -> String {
    let lines: Vec<&str> = text.lines().collect();
    let widths = reg_widths(&lines);
    let mut out = Vec::new();
    let mut packed = std::collections::HashSet::new();
    let mut n = 0;
    let mut i = 0;
    while i < lines.len() {
        match register_block(&lines[i..]) {
            Some((len, reset, next)) if same_registers(&reset, &next, &widths) => {
                let (code, names) = packed_block(&reset, &next, &widths, bits, &mut n);
                out.push(code);
                packed.extend(names);
                i += len;
            }
            _ => {
                out.push(lines[i].to_string());
                i += 1;
            }
        }
    }
    out.iter()
        .map(|l| match reg_decl(l) {
            Some((name, _)) if packed.contains(name) => l.replacen("reg", "wire", 1) + "\n",
            _ => format!("{l}\n"),
        })
        .collect()
}

/// `reg [w-1:0] name;` (comment allowed after): the name and width.
fn reg_decl(line: &str) -> Option<(&str, usize)> {
    let rest = line.trim_start().strip_prefix("reg")?.trim_start();
    let (width, rest) = match rest.strip_prefix('[') {
        Some(r) => {
            let (msb, r) = r.split_once(":0]")?;
            (msb.trim().parse::<usize>().ok()? + 1, r.trim_start())
        }
        None => (1, rest),
    };
    let name = rest.split_once(';')?.0.trim();
    let plain = !name.is_empty() && name.chars().all(|c| c.is_alphanumeric() || c == '_');
    plain.then_some((name, width))
}

fn reg_widths<'a>(lines: &[&'a str]) -> std::collections::HashMap<&'a str, usize> {
    lines.iter().filter_map(|l| reg_decl(l)).collect()
}

/// `name <= expr;`
fn nonblocking(line: &str) -> Option<(String, String)> {
    let (name, expr) = line.trim().strip_suffix(';')?.split_once(" <= ")?;
    Some((name.to_string(), expr.to_string()))
}

type Assigns = Vec<(String, String)>;

/// A register block at the start of `lines`: its length in lines, the
/// reset branch's assignments and the other branch's.
fn register_block(lines: &[&str]) -> Option<(usize, Assigns, Assigns)> {
    if lines.len() < 4
        || lines[0] != "    always @(posedge clk) begin"
        || lines[1] != "        if (rst) begin"
    {
        return None;
    }
    let mut i = 2;
    let mut reset = Vec::new();
    while lines.get(i)? != &"        end else begin" {
        reset.push(nonblocking(lines[i])?);
        i += 1;
    }
    i += 1;
    let mut next = Vec::new();
    while lines.get(i)? != &"        end" {
        next.push(nonblocking(lines[i])?);
        i += 1;
    }
    (lines.get(i + 1)? == &"    end").then_some((i + 2, reset, next))
}

fn same_registers(
    reset: &Assigns,
    next: &Assigns,
    widths: &std::collections::HashMap<&str, usize>,
) -> bool {
    let names = |a: &Assigns| {
        let mut v: Vec<String> = a.iter().map(|x| x.0.clone()).collect();
        v.sort();
        v
    };
    !next.is_empty()
        && names(reset) == names(next)
        && next.iter().all(|x| widths.contains_key(x.0.as_str()))
}

/// The vectors of one block, and the registers they hold.
fn packed_block(
    reset: &Assigns,
    next: &Assigns,
    widths: &std::collections::HashMap<&str, usize>,
    bits: usize,
    n: &mut usize,
) -> (String, Vec<String>) {
    let width = |r: &String| widths[r.as_str()];
    let mut groups: Vec<Vec<&(String, String)>> = vec![Vec::new()];
    for a in next {
        let used: usize = groups
            .last()
            .map_or(0, |g| g.iter().map(|x| width(&x.0)).sum());
        if used > 0 && used + width(&a.0) > bits {
            groups.push(Vec::new());
        }
        groups.last_mut().expect("a group").push(a);
    }
    let mut code = String::new();
    let (mut on_reset, mut on_clock) = (String::new(), String::new());
    for g in &groups {
        let v = format!("hm_pk_{n}");
        *n += 1;
        let total: usize = g.iter().map(|x| width(&x.0)).sum();
        let join = |f: &dyn Fn(&(String, String)) -> String| {
            g.iter().map(|x| f(x)).collect::<Vec<_>>().join(", ")
        };
        let reset_of = |r: &String| {
            reset
                .iter()
                .find(|x| &x.0 == r)
                .expect("same registers")
                .1
                .clone()
        };
        code += &format!("    reg [{}:0] {v};\n", total - 1);
        code += &format!(
            "    wire [{}:0] {v}_next = {{{}}};\n",
            total - 1,
            join(&|x| x.1.clone())
        );
        code += &format!("    assign {{{}}} = {v};\n", join(&|x| x.0.clone()));
        on_reset += &format!("            {v} <= {{{}}};\n", join(&|x| reset_of(&x.0)));
        on_clock += &format!("            {v} <= {v}_next;\n");
    }
    code += &format!(
        "    always @(posedge clk) begin\n        if (rst) begin\n{on_reset}        end else begin\n{on_clock}        end\n    end"
    );
    let names = next.iter().map(|x| x.0.clone()).collect();
    (code, names)
}

fn merge_level(dir: &Path) -> Res<()> {
    let d = MergeDesign::default();
    let design = cosim::from_rtl::design_from_module(&merge::merge_level_module(&d.params), dir)?;
    let levels = merge::generate_levels(&d, 5, 1500)?;
    let vectors = merge::bench_vectors(&levels, None)?;
    let names: StreamNames = merge::stream_names();
    let c = config();
    let batch = IcarusBatch::new(&design, &BatchSpec::single(&names))?;
    let lanes: Vec<LaneVector> = vectors
        .iter()
        .map(|v| LaneVector::new(0, v.clone()))
        .collect();
    // A short run: whole levels (a level's beats belong together).
    let short = merge::bench_vectors(&levels[..levels.len() / 50], None)?.len();
    let real = per_cycle(|is_long| {
        let n = if is_long { lanes.len() } else { short };
        let r = batch.run(&lanes[..n], &mut |_| None, &c)?;
        assert!(r.bench.passed(), "{}", r.bench);
        Ok(r.bench.cycles)
    })?;
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
    Ok(())
}

fn main() -> Res<()> {
    if !cosim::tools::tool_available("iverilog") {
        eprintln!("iverilog missing: {}", cosim::tools::INSTALL_HINT);
        return Ok(());
    }
    let dir = tempfile::tempdir()?;
    hierarchy_merger(dir.path())?;
    merging_module(dir.path())?;
    merge_level(dir.path())?;
    Ok(())
}
