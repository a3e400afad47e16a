//! The study for people and programs: the terminal table, `study.csv`
//! (one line per case and configuration) and `study.json`.

use golden::output::write_atomic;
use std::fmt::Write as _;
use std::path::Path;

use super::distance::DistanceRow;
use super::run::Study;
use super::sweep::Row;

/// What an absent measurement prints.
pub const NOT_MEASURED: &str = "not measured";

/// `v` to one decimal, prefixed with `sign` when the row's Fmax is a bound
/// (the top not placed, SPEC 13.4).
fn bounded(r: &Row, v: Option<f64>, sign: &str) -> String {
    match v {
        None => NOT_MEASURED.to_string(),
        Some(v) if r.synth.as_ref().is_some_and(|s| s.fmax_bound) => format!("{sign}{v:.1}"),
        Some(v) => format!("{v:.1}"),
    }
}

/// The columns of a row: header and value.
pub fn columns(r: &Row) -> Vec<(&'static str, String)> {
    let opt = |v: Option<f64>, digits: usize| {
        v.map_or(NOT_MEASURED.to_string(), |v| format!("{v:.digits$}"))
    };
    vec![
        ("case", r.case.clone()),
        ("D", r.max_lod.to_string()),
        ("Q", r.quant_bits.to_string()),
        (
            "default",
            if r.default_config {
                "*".into()
            } else {
                String::new()
            },
        ),
        ("bits/record", r.record_bits.to_string()),
        ("bytes", r.bytes.to_string()),
        ("bytes/tri", format!("{:.2}", r.bytes_per_triangle)),
        ("loose mean", format!("{:.3}", r.looseness.all.mean)),
        ("loose p99", format!("{:.3}", r.looseness.all.p99)),
        ("false hits/ray", format!("{:.2}", r.false_hits_per_ray)),
        ("node tests/ray", format!("{:.2}", r.node_tests_per_ray)),
        ("prim tests/ray", format!("{:.2}", r.prim_tests_per_ray)),
        (
            "box tests vs exact",
            format!("{:+.1}%", r.extra_box_tests_vs_exact * 100.0),
        ),
        ("build ms", format!("{:.2}", r.build_ms)),
        ("trace us/ray", format!("{:.2}", r.trace_us_per_ray)),
        ("merge ms", format!("{:.3}", r.merge_ms)),
        (
            "cycles/merge",
            opt(r.rtl.as_ref().map(|f| f.cycles_per_merge), 1),
        ),
        (
            "cycles/tr record",
            opt(r.rtl.as_ref().map(|f| f.cycles_per_translated_record), 2),
        ),
        (
            "NAND2-eq",
            opt(r.synth.as_ref().and_then(|s| s.nand2_eq), 0),
        ),
        (
            "ECP5 LUT4",
            opt(
                r.synth.as_ref().and_then(|s| s.ecp5_lut4.map(|n| n as f64)),
                0,
            ),
        ),
        (
            "Fmax MHz",
            bounded(r, r.synth.as_ref().and_then(|s| s.fmax_mhz), "≤"),
        ),
        ("ns/merge", bounded(r, r.ns_per_merge, "≥")),
    ]
}

/// The rows the terminal table and the README show: per case, the Q sweep
/// at the default D and the D sweep at the default Q.
pub fn main_rows(s: &Study) -> Vec<&Row> {
    let mut out: Vec<&Row> = Vec::new();
    for c in &s.cases {
        out.extend(
            s.rows
                .iter()
                .filter(|r| r.case == c.name && r.max_lod == s.default_max_lod),
        );
        out.extend(s.rows.iter().filter(|r| {
            r.case == c.name
                && r.quant_bits == s.default_quant_bits
                && r.max_lod != s.default_max_lod
        }));
    }
    out
}

/// A text table, columns padded (`markdown`: a Markdown table).
pub fn render(rows: &[&Row], markdown: bool) -> String {
    let cols: Vec<Vec<(&str, String)>> = rows.iter().map(|r| columns(r)).collect();
    let Some(first) = cols.first() else {
        return String::new();
    };
    let widths: Vec<usize> = (0..first.len())
        .map(|i| {
            cols.iter()
                .map(|c| c[i].1.len())
                .max()
                .unwrap_or(0)
                .max(first[i].0.len())
        })
        .collect();
    let line = |cells: Vec<String>| {
        let padded: Vec<String> = cells
            .iter()
            .zip(&widths)
            .map(|(c, w)| format!("{c:>w$}"))
            .collect();
        if markdown {
            format!("| {} |\n", padded.join(" | "))
        } else {
            format!("{}\n", padded.join("  "))
        }
    };
    let mut s = line(first.iter().map(|(h, _)| h.to_string()).collect());
    if markdown {
        s += &line(
            widths
                .iter()
                .map(|w| format!("{:->w$}:", "", w = w - 1))
                .collect(),
        );
    }
    for c in &cols {
        s += &line(c.iter().map(|(_, v)| v.clone()).collect());
    }
    s
}

/// The distance table: per distance and format, hit errors and position error.
pub fn render_distance(rows: &[DistanceRow], markdown: bool) -> String {
    let mut s = String::new();
    let sep = if markdown { " | " } else { "  " };
    let (l, r) = if markdown { ("| ", " |") } else { ("", "") };
    let head = [
        "distance",
        "D",
        "format",
        "L",
        "wrong",
        "missed",
        "extra",
        "grazing",
        "t err max",
        "position error",
        "nodes added",
    ];
    let _ = writeln!(s, "{l}{}{r}", head.map(|h| format!("{h:>14}")).join(sep));
    if markdown {
        let _ = writeln!(
            s,
            "{l}{}{r}",
            head.map(|_| format!("{:->13}:", "")).join(sep)
        );
    }
    for d in rows {
        if let Some(why) = &d.refused {
            let _ = writeln!(
                s,
                "{l}{:>14}{sep}{:>14}{sep}{:>14}{sep}{:>14}{sep}refused: {why}{r}",
                format!("{:e}", d.distance),
                d.max_lod,
                d.format,
                d.level
                    .map_or("-".into(), |v| format!("{v} {}", d.level_role)),
            );
            continue;
        }
        let cells = [
            format!("{:e}", d.distance),
            d.max_lod.to_string(),
            d.format.clone(),
            d.level
                .map_or("-".into(), |v| format!("{v} {}", d.level_role)),
            d.hits.wrong_triangle.to_string(),
            d.hits.missed.to_string(),
            d.hits.extra.to_string(),
            d.hits.grazing.to_string(),
            format!("{:.3e}", d.hits.t_error_max),
            format!("{:.3e}", d.position_error),
            d.nodes_added.map_or("-".into(), |v| v.to_string()),
        ];
        let _ = writeln!(s, "{l}{}{r}", cells.map(|c| format!("{c:>14}")).join(sep));
    }
    s
}

/// The terminal report.
pub fn print(s: &Study) {
    println!(
        "hiermerge study: {} cases, D {:?}, Q {:?}, {} rays, median of {} (machine: {}, {} cores, load {})",
        s.cases.len(), s.max_lod, s.quant_bits, s.rays, s.repeats, s.machine.cpu, s.machine.cores, s.machine.load()
    );
    print!("{}", render(&main_rows(s), false));
    println!(
        "\nmerging modes at D{} Q{} (the pair: a case and its copy moved by half its extent):",
        s.default_max_lod, s.default_quant_bits
    );
    for m in &s.modes {
        println!(
            "  {:>10} {:>16} level {:>4} created {:>6} reused {:>6} merge {:.3} ms{}",
            m.case,
            m.mode,
            m.merging_level.map_or("-".into(), |l| l.to_string()),
            m.nodes_created,
            m.nodes_reused,
            m.merge_ms,
            if m.default_mode { " (default)" } else { "" }
        );
    }
    println!(
        "\nhit error against the binary64 reference, {} placed at distance d:",
        s.distance_case
    );
    print!("{}", render_distance(&s.distance, false));
    for n in &s.notes {
        println!("note: {n}");
    }
    println!(
        "wall time {:.1} s; wrote {}",
        s.wall_seconds,
        s.outputs.join(", ")
    );
}

/// Writes `study.csv` (every row); returns the paths written.
pub fn write_files(s: &Study, out: &Path) -> Result<Vec<String>, String> {
    let mut csv = String::new();
    for (i, r) in s.rows.iter().enumerate() {
        let cols = columns(r);
        if i == 0 {
            let head: Vec<&str> = cols.iter().map(|(h, _)| *h).collect();
            let _ = writeln!(csv, "{},nodes,leaves,boxes_equal_voxel", head.join(","));
        }
        let vals: Vec<String> = cols.iter().map(|(_, v)| v.replace(',', ";")).collect();
        let _ = writeln!(
            csv,
            "{},{},{},{}",
            vals.join(","),
            r.nodes,
            r.leaves,
            r.looseness.boxes_equal_voxel
        );
    }
    let path = out.join("study.csv");
    write_atomic(&path, csv.as_bytes())?;
    Ok(vec![path.display().to_string()])
}

/// Writes `study.json`.
pub fn write_json(s: &Study, out: &Path) -> Result<(), String> {
    let text = serde_json::to_string_pretty(s).map_err(|e| format!("study.json: {e}"))?;
    write_atomic(&out.join("study.json"), text.as_bytes())
}
