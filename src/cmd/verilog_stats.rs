//! `hiermerge verilog-stats`: how the emitted Verilog reads and what Yosys
//! makes of it, per file and in total, optionally beside another folder
//! (the same files emitted by an older emitter).
//!
//! A declaration is a `wire`, `reg` or `localparam` line of a module body;
//! it is auto-named when its name is a derived one (`<source>_<operator>`,
//! [`rtl_gen::is_auto_name`]). Cells are counted by Yosys with the modules
//! a file instantiates as black boxes: "raw" after `proc; opt_clean` (the
//! operators the text spells out) and "synth" after `synth -run
//! begin:fine` (Yosys' coarse netlist, after its own optimisations).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use serde::Serialize;

use crate::progress::Progress;
use crate::report::{emit, CmdResult};

#[derive(clap::Args)]
pub struct Args {
    /// The folder of emitted Verilog files (`<module>.v`).
    #[arg(long, default_value = "verilog")]
    dir: PathBuf,
    /// Another emission of the same modules to compare with (files matched by name).
    #[arg(long)]
    before: Option<PathBuf>,
    /// Also count Yosys cells (minutes: one Yosys run per file and folder).
    #[arg(long)]
    yosys: bool,
    /// Print one JSON object on stdout.
    #[arg(long)]
    json: bool,
}

/// The figures of one file.
#[derive(Serialize, Clone, Default)]
pub struct FileStats {
    pub bytes: u64,
    pub declarations: u64,
    pub auto_named: u64,
    /// Cells after `proc; opt_clean` (with `--yosys`).
    pub cells_raw: Option<u64>,
    /// Cells after `synth -run begin:fine` (with `--yosys`).
    pub cells_synth: Option<u64>,
}

impl FileStats {
    fn add(&mut self, o: &FileStats) {
        self.bytes += o.bytes;
        self.declarations += o.declarations;
        self.auto_named += o.auto_named;
        let sum = |a: Option<u64>, b: Option<u64>| a.zip(b).map(|(a, b)| a + b);
        self.cells_raw = sum(self.cells_raw, o.cells_raw);
        self.cells_synth = sum(self.cells_synth, o.cells_synth);
    }

    fn auto_percent(&self) -> f64 {
        100.0 * self.auto_named as f64 / self.declarations.max(1) as f64
    }
}

#[derive(Serialize)]
struct Row {
    file: String,
    after: FileStats,
    before: Option<FileStats>,
}

#[derive(Serialize)]
struct Report {
    dir: String,
    before_dir: Option<String>,
    files: Vec<Row>,
    total: FileStats,
    total_before: Option<FileStats>,
}

/// The `.v` files of `dir` by name.
fn verilog_files(dir: &Path) -> Result<BTreeMap<String, PathBuf>, String> {
    let entries = std::fs::read_dir(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let mut out = BTreeMap::new();
    for e in entries {
        let p = e.map_err(|e| format!("{}: {e}", dir.display()))?.path();
        if p.extension().is_some_and(|x| x == "v") {
            let name = p
                .file_name()
                .unwrap_or_default()
                .to_string_lossy()
                .into_owned();
            out.insert(name, p);
        }
    }
    if out.is_empty() {
        return Err(format!(
            "{}: no .v file (expected emitted Verilog, e.g. verilog/)",
            dir.display()
        ));
    }
    Ok(out)
}

/// The declared name of a body line, if it declares one.
fn declared_name(line: &str) -> Option<&str> {
    let rest = ["wire ", "reg ", "localparam "]
        .iter()
        .find_map(|k| line.trim_start().strip_prefix(k))?;
    let rest = rest.trim_start();
    let rest = match rest.strip_prefix('[') {
        Some(r) => r.split_once(']')?.1.trim_start(),
        None => rest,
    };
    let end = rest
        .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
        .unwrap_or(rest.len());
    (end > 0).then(|| &rest[..end])
}

fn text_stats(path: &Path) -> Result<FileStats, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let names: Vec<&str> = text.lines().filter_map(declared_name).collect();
    Ok(FileStats {
        bytes: text.len() as u64,
        declarations: names.len() as u64,
        auto_named: names.iter().filter(|n| rtl_gen::is_auto_name(n)).count() as u64,
        cells_raw: None,
        cells_synth: None,
    })
}

/// "Number of cells" of module `top` in a Yosys `stat` report.
fn cells_of(stat: &str, top: &str) -> Option<u64> {
    let head = format!("=== {top} ===");
    let section = &stat[stat.find(&head)? + head.len()..];
    let line = section.lines().find(|l| l.contains("Number of cells:"))?;
    line.split(':').nth(1)?.trim().parse().ok()
}

/// Raw and coarse cell counts of `top`, every other file a black box.
fn yosys_cells(files: &BTreeMap<String, PathBuf>, top: &str) -> Result<(u64, u64), String> {
    let tmp = tempfile::tempdir().map_err(|e| format!("temporary folder: {e}"))?;
    let (raw, synth) = (tmp.path().join("raw.txt"), tmp.path().join("synth.txt"));
    let all: Vec<String> = files.values().map(|p| p.display().to_string()).collect();
    let others: Vec<&str> = files
        .keys()
        .map(|n| n.trim_end_matches(".v"))
        .filter(|n| *n != top)
        .collect();
    let blackbox = if others.is_empty() {
        String::new()
    } else {
        format!("blackbox {}; ", others.join(" "))
    };
    let script = format!(
        "read_verilog {all}; {blackbox}hierarchy -check -top {top}; proc; opt_clean; tee -q -o {raw} stat; synth -top {top} -run begin:fine; tee -q -o {synth} stat",
        all = all.join(" "),
        raw = raw.display(),
        synth = synth.display(),
    );
    let out = Command::new("yosys")
        .args(["-q", "-p", &script])
        .output()
        .map_err(|e| format!("yosys: {e} (install it: apt-get install yosys)"))?;
    if !out.status.success() {
        return Err(format!(
            "yosys on {top}: {}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        ));
    }
    let read = |p: &Path| std::fs::read_to_string(p).map_err(|e| format!("{}: {e}", p.display()));
    let count = |text: String, what: &str| {
        cells_of(&text, top)
            .ok_or_else(|| format!("yosys on {top}: no cell count in its {what} stat"))
    };
    Ok((count(read(&raw)?, "raw")?, count(read(&synth)?, "synth")?))
}

fn folder_stats(
    dir: &Path,
    yosys: bool,
    progress: &mut Progress,
) -> Result<BTreeMap<String, FileStats>, String> {
    let files = verilog_files(dir)?;
    let mut out = BTreeMap::new();
    for (name, path) in &files {
        let mut s = text_stats(path)?;
        if yosys {
            progress.set_message(format!("{}: {name}", dir.display()));
            let (raw, synth) = yosys_cells(&files, name.trim_end_matches(".v"))?;
            s.cells_raw = Some(raw);
            s.cells_synth = Some(synth);
            progress.inc(1);
        }
        out.insert(name.clone(), s);
    }
    Ok(out)
}

fn total(stats: &BTreeMap<String, FileStats>, yosys: bool) -> FileStats {
    let mut t = FileStats {
        cells_raw: yosys.then_some(0),
        cells_synth: yosys.then_some(0),
        ..FileStats::default()
    };
    for s in stats.values() {
        t.add(s);
    }
    t
}

fn cell(v: Option<u64>) -> String {
    v.map_or("-".into(), |v| v.to_string())
}

/// One row: `s`, beside `before` when comparing (`compare`); a file only
/// in the compared folder reads "new" on the before side.
fn print_row(name: &str, s: &FileStats, before: Option<&FileStats>, compare: bool) {
    let line = |s: &FileStats| {
        format!(
            "{:>8} {:>6} {:>6} {:>6.1}% {:>7} {:>7}",
            s.bytes,
            s.declarations,
            s.auto_named,
            s.auto_percent(),
            cell(s.cells_raw),
            cell(s.cells_synth)
        )
    };
    match (before, compare) {
        (Some(b), _) => println!("{name:<58} {} | {}", line(b), line(s)),
        (None, true) => {
            let width = line(s).len();
            println!("{name:<58} {:>width$} | {}", "new", line(s))
        }
        (None, false) => println!("{name:<58} {}", line(s)),
    }
}

pub fn main(a: Args) -> CmdResult {
    let count = verilog_files(&a.dir)?.len() as u64
        + match &a.before {
            Some(b) => verilog_files(b)?.len() as u64,
            None => 0,
        };
    let mut progress = Progress::new(
        if a.yosys { count } else { 0 },
        !a.yosys || a.json,
        "yosys cell counts",
    );
    let after = folder_stats(&a.dir, a.yosys, &mut progress)?;
    let before = match &a.before {
        Some(b) => Some(folder_stats(b, a.yosys, &mut progress)?),
        None => None,
    };
    progress.finish_and_clear();
    let report = Report {
        dir: a.dir.display().to_string(),
        before_dir: a.before.as_ref().map(|b| b.display().to_string()),
        files: after
            .iter()
            .map(|(f, s)| Row {
                file: f.clone(),
                after: s.clone(),
                before: before.as_ref().and_then(|b| b.get(f).cloned()),
            })
            .collect(),
        total: total(&after, a.yosys),
        total_before: before.as_ref().map(|b| {
            let common: BTreeMap<String, FileStats> = b
                .iter()
                .filter(|(f, _)| after.contains_key(*f))
                .map(|(f, s)| (f.clone(), s.clone()))
                .collect();
            total(&common, a.yosys)
        }),
    };
    emit(a.json, &report, |r| {
        let cols = "   bytes  decls   auto  auto%  cells(raw) cells(synth)";
        match &r.before_dir {
            Some(b) => println!(
                "{:<58} {cols} | {cols}\n{:<58} before: {b} | after: {}",
                "file", "", r.dir
            ),
            None => println!("{:<58} {cols}", "file"),
        }
        let compare = r.before_dir.is_some();
        for row in &r.files {
            print_row(&row.file, &row.after, row.before.as_ref(), compare);
        }
        print_row("total", &r.total, r.total_before.as_ref(), compare);
        if let Some(b) = &before {
            for f in b.keys().filter(|f| !after.contains_key(*f)) {
                println!("only in {}: {f}", r.before_dir.as_deref().unwrap_or(""));
            }
        }
    })
}
