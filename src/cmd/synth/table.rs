//! `hiermerge synth` for people: one Markdown table row per module, then
//! each module's ECP5 critical path by generator line.

use super::Report;

fn fmax(s: &cosim::synth::Spread, seeds: u64) -> String {
    if seeds == 1 {
        format!("{:.1}", s.min)
    } else {
        format!("{:.1} / {:.1} / {:.1}", s.min, s.median, s.max)
    }
}

fn or_dash<T>(v: Option<T>, f: impl FnOnce(T) -> String) -> String {
    v.map_or_else(|| "-".to_string(), f)
}

pub fn print(r: &Report) {
    println!("hiermerge {}", r.command);
    println!(
        "tools: {}; {}; {}",
        r.tools.yosys,
        r.tools.nextpnr_ecp5.as_deref().unwrap_or("no nextpnr-ecp5"),
        r.tools
            .nextpnr_ice40
            .as_deref()
            .unwrap_or("no nextpnr-ice40")
    );
    println!();
    let fmax_head = if r.seeds == 1 {
        "ECP5 Fmax MHz (seed 1)".to_string()
    } else {
        format!("ECP5 Fmax MHz min / median / max ({} seeds)", r.seeds)
    };
    println!("| module | NAND2-eq | FF | memory bits | depth | ECP5 LUT4 | ECP5 FF | CCU2C | EBR | DSP | {fmax_head} | iCE40 HX8K |");
    println!("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|");
    for m in &r.modules {
        let g = m.generic.as_ref();
        let e = m.ecp5.as_ref();
        let ice = or_dash(m.ice40.as_ref(), |i| match &i.fmax_mhz {
            Some(f) => format!("{}, {} MHz", i.verdict, fmax(f, r.seeds)),
            None => i.verdict.clone(),
        });
        println!(
            "| `{}` | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            m.module,
            or_dash(g, |g| format!("{:.0}", g.nand2_eq)),
            or_dash(g, |g| g.flip_flops.to_string()),
            or_dash(g, |g| g.memory_bits.to_string()),
            or_dash(g, |g| if m.composed_of.is_empty() {
                g.depth.to_string()
            } else {
                format!("≥{}", g.depth)
            }),
            or_dash(e, |e| e.synth.lut4.to_string()),
            or_dash(e, |e| e.synth.ff.to_string()),
            or_dash(e, |e| e.synth.ccu2c.to_string()),
            or_dash(e, |e| e.synth.ebr.to_string()),
            or_dash(e, |e| e.synth.dsp.to_string()),
            or_dash(e, |e| match &e.fmax_mhz {
                Some(f) => fmax(f, r.seeds),
                None => e.verdict.clone(),
            }),
            ice,
        );
    }
    for m in r.modules.iter().filter(|m| !m.composed_of.is_empty()) {
        let parts: Vec<String> = m
            .composed_of
            .iter()
            .map(|p| format!("{} x {}", p.count, p.module))
            .collect();
        println!();
        println!(
            "{}: composed (SPEC 14.6): its own logic plus {}; depth: the deepest part",
            m.module,
            parts.join(", ")
        );
    }
    for m in &r.modules {
        let Some(run) = m.ecp5.as_ref().and_then(|e| e.runs.first()) else {
            continue;
        };
        let Some(cp) = &run.critical_path else {
            continue;
        };
        println!();
        println!(
            "{}: ECP5 critical path (seed {}, {:.2} ns, {} logic levels) {} -> {}",
            m.module, run.seed, cp.delay_ns, cp.logic_levels, cp.from, cp.to
        );
        for (name, source, delay, nets) in chain(&cp.steps) {
            let nets = if nets > 1 {
                format!(" ({nets} nets)")
            } else {
                String::new()
            };
            println!(
                "  {delay:>6.3} ns  {:<56} {source}",
                format!("{name}{nets}")
            );
        }
    }
    println!();
    if r.modules.iter().any(|m| m.ecp5.is_some()) {
        if r.below_goal.is_empty() {
            println!("every placed module reaches {} MHz on ECP5", r.goal_mhz);
        } else {
            println!(
                "below {} MHz on ECP5: {}",
                r.goal_mhz,
                r.below_goal.join(", ")
            );
        }
    }
    println!(
        "{} results computed, the rest from the cache; {:.1} s",
        r.computed, r.seconds
    );
}

/// The path's nets, consecutive nets of the same emitted net merged:
/// (emitted net, generator line, delay in ns, nets merged).
fn chain(steps: &[cosim::synth::path::PathStep]) -> Vec<(String, String, f64, usize)> {
    let mut out: Vec<(String, String, f64, usize)> = Vec::new();
    for s in steps {
        let name = s.emitted.clone().unwrap_or_else(|| s.net.clone());
        let source = s
            .source
            .clone()
            .unwrap_or_else(|| "(no generator line: a synthesis-internal net)".into());
        match out.last_mut() {
            Some(last) if last.0 == name => {
                last.2 += s.delay_ns;
                last.3 += 1;
            }
            _ => out.push((name, source, s.delay_ns, 1)),
        }
    }
    out
}
