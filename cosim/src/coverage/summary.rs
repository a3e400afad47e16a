//! Per unit: merge the raw counts, annotate the sources, summarize, name
//! every uncovered point by its generator line, apply the waivers.

use super::dat::{read_points, Kind, Point};
use super::waivers::Waivers;
use crate::error::{io_err, CosimError, Result};
use crate::synth::path::{comment_location, SourceIndex};
use crate::synth::sources::Netlist;
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The aims of SPEC 10.5, in percent.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Aims {
    /// Line/branch points covered.
    pub line: f64,
    /// Toggle bits covered.
    pub toggle: f64,
}

impl Default for Aims {
    fn default() -> Self {
        Aims {
            line: 95.0,
            toggle: 90.0,
        }
    }
}

/// One uncovered point.
#[derive(Clone, Debug, Serialize)]
pub struct UncoveredPoint {
    /// `line`, `branch` or `toggle`.
    pub kind: &'static str,
    /// The module.
    pub module: String,
    /// The instance (`TOP.<top>.u_a`).
    pub instance: String,
    /// Toggle: the bit (`h_rec[3]`); line/branch: `<file>:<line> <if|else|block>`.
    pub point: String,
    /// The generator line it maps to, when the emitted Verilog names one.
    pub source: Option<String>,
    /// Its count (a toggle bit that rose once and never fell has 1).
    pub count: u64,
    /// Toggle: the field of golden's layouts the bit is, when its net
    /// carries one LOD's records (`rec.count[11]`, `index[5]`;
    /// `by_design::field_of`).
    pub field: Option<String>,
    /// The waiver's reason (`file:line: reason`), when waived.
    pub waived: Option<String>,
    /// Not waived: why it is still uncovered (`file:line: reason`), when
    /// an `open` entry says.
    pub open: Option<String>,
}

/// One unit (an emitted top and everything below it).
#[derive(Clone, Debug, Serialize)]
pub struct UnitSummary {
    /// The top module.
    pub unit: String,
    /// Runs (engines) whose counts were merged.
    pub runs: usize,
    /// Line/branch points: covered, waived (uncovered), total.
    pub line: (u64, u64, u64),
    /// Toggle bits: covered, waived (uncovered), total.
    pub toggle: (u64, u64, u64),
    /// Of the waived toggle bits, those Yosys proves constant.
    pub toggle_constant: u64,
    /// Of the waived toggle bits, those a rule of
    /// [`super::by_design`] names.
    pub toggle_by_design: u64,
    /// Of the covered toggle bits, those of a module instantiated `m > 1`
    /// times that changed at most `m` times: Verilator counts the
    /// instances on one counter, so each may only have risen once.
    pub toggle_uncertain: u64,
    /// The merged `coverage.dat`.
    pub dat: PathBuf,
    /// The annotated sources.
    pub annotated: PathBuf,
    /// Every uncovered point.
    pub uncovered: Vec<UncoveredPoint>,
}

/// `covered / (total - waived)` in percent (100 when nothing is left).
fn percent((covered, waived, total): (u64, u64, u64)) -> f64 {
    let counted = total.saturating_sub(waived);
    if counted == 0 {
        100.0
    } else {
        100.0 * covered as f64 / counted as f64
    }
}

impl UnitSummary {
    /// Line/branch coverage in percent, waived points not counted.
    pub fn line_percent(&self) -> f64 {
        percent(self.line)
    }

    /// Toggle coverage in percent, waived bits not counted.
    pub fn toggle_percent(&self) -> f64 {
        percent(self.toggle)
    }

    /// Toggle coverage in percent counting none of the uncertain bits
    /// ([`UnitSummary::toggle_uncertain`]): the true figure lies between
    /// this and [`UnitSummary::toggle_percent`].
    pub fn toggle_percent_certain(&self) -> f64 {
        let (covered, waived, total) = self.toggle;
        percent((covered - self.toggle_uncertain, waived, total))
    }

    /// Uncovered, unwaived points of a kind whose coverage is below its aim.
    pub fn below_aim(&self, aims: &Aims) -> Vec<&UncoveredPoint> {
        let line_low = self.line_percent() < aims.line;
        let toggle_low = self.toggle_percent() < aims.toggle;
        self.uncovered
            .iter()
            .filter(|u| u.waived.is_none())
            .filter(|u| {
                if u.kind == "toggle" {
                    toggle_low
                } else {
                    line_low
                }
            })
            .collect()
    }
}

/// The code coverage of every unit collected under one directory.
#[derive(Clone, Debug, Serialize)]
pub struct CoverageReport {
    /// The aims.
    pub aims: Aims,
    /// Per unit, by top name.
    pub units: Vec<UnitSummary>,
    /// Waivers that matched no uncovered point (`file:line`): stale.
    pub stale_waivers: Vec<String>,
    /// Toggle bits Yosys proves constant that toggled: the proof and the
    /// run disagree, so neither is trusted.
    pub contradictions: Vec<String>,
}

impl CoverageReport {
    /// True when every unit meets the aims or has each point below them
    /// waived, and no waiver is stale.
    pub fn passed(&self) -> bool {
        self.stale_waivers.is_empty()
            && self.contradictions.is_empty()
            && self
                .units
                .iter()
                .all(|u| u.below_aim(&self.aims).is_empty())
    }

    /// The summary table (markdown), one row per unit.
    pub fn table(&self) -> String {
        let mut s = String::from(
            "| unit | runs | line/branch | covered / points (waived) | toggle (certain) | covered / bits (waived: constant by Yosys + by design + by hand) | at aim |\n|---|---|---|---|---|---|---|\n",
        );
        for u in &self.units {
            let ok = u.below_aim(&self.aims).is_empty();
            s += &format!(
                "| `{}` | {} | {:.1}% | {} / {} ({}) | {:.1}% ({:.1}%) | {} / {} ({}: {} + {} + {}) | {} |\n",
                u.unit,
                u.runs,
                u.line_percent(),
                u.line.0,
                u.line.2,
                u.line.1,
                u.toggle_percent(),
                u.toggle_percent_certain(),
                u.toggle.0,
                u.toggle.2,
                u.toggle.1,
                u.toggle_constant,
                u.toggle_by_design,
                u.toggle.1 - u.toggle_constant - u.toggle_by_design,
                if ok { "yes" } else { "NO" }
            );
        }
        s
    }
}

fn run_tool(mut cmd: Command) -> Result<()> {
    let shown = format!("{cmd:?}");
    let out = cmd.output().map_err(|e| CosimError::ToolMissing {
        tool: "verilator_coverage".into(),
        hint: format!("{e}; {}", crate::tools::INSTALL_HINT),
    })?;
    if !out.status.success() {
        return Err(CosimError::ToolFailed {
            tool: "verilator_coverage".into(),
            command: shown,
            log: format!(
                "{}{}",
                String::from_utf8_lossy(&out.stdout),
                String::from_utf8_lossy(&out.stderr)
            ),
        });
    }
    Ok(())
}

fn files_in(dir: &Path, ext: &str) -> Result<Vec<PathBuf>> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(io_err(dir))?
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == ext))
        .collect();
    v.sort();
    Ok(v)
}

/// The generator line of a line or branch point: the comment of its line;
/// else, for `if (net)`, the net's declaration; else the first commented
/// line it spans; else the line that generated the module (line 1).
fn line_source(p: &Point, text: &[&str], index: &SourceIndex) -> Option<String> {
    let at = |l: u32| text.get((l as usize).checked_sub(1)?).copied();
    let line = at(p.line)?;
    if let Some(loc) = comment_location(line) {
        return Some(loc);
    }
    if let Some(cond) = line
        .trim()
        .strip_prefix("if (")
        .and_then(|r| r.split(')').next())
    {
        if let Some(loc) = index.declared_in(&p.module, cond.trim()) {
            return Some(loc.to_string());
        }
    }
    let (from, to) = match p
        .span
        .as_deref()
        .map(|s| s.split_once('-').unwrap_or((s, s)))
    {
        Some((a, b)) => (a.parse().unwrap_or(p.line), b.parse().unwrap_or(p.line)),
        None => (p.line, p.line),
    };
    (from..=to)
        .filter_map(|l| at(l).and_then(comment_location))
        .next()
        .or_else(|| at(1).and_then(comment_location))
}

/// What the hand-written waivers did, by index, over every unit.
struct WaiverUse {
    /// Waived an uncovered point.
    used: Vec<bool>,
    /// Named a point the regression reached.
    reached: Vec<bool>,
    /// Named a point Yosys proves constant (the proof waives it).
    redundant: Vec<bool>,
    /// Toggle points Yosys proves constant that toggled.
    contradictions: Vec<String>,
}

/// Merge, annotate and summarize the unit whose raw counts are in
/// `dir/raw/<top>` and sources in `dir/sources/<top>`.
fn unit_summary(
    dir: &Path,
    top: &str,
    waivers: &Waivers,
    uses: &mut WaiverUse,
) -> Result<UnitSummary> {
    let raws = files_in(&dir.join("raw").join(top), "dat")?;
    let out = dir.join(top);
    std::fs::create_dir_all(&out).map_err(io_err(&out))?;
    let merged = out.join("merged-raw.dat");
    let mut cmd = Command::new("verilator_coverage");
    cmd.arg("--write").arg(&merged).args(&raws);
    run_tool(cmd)?;
    let points = super::dat::toggles_per_run(read_points(&merged)?, &raws)?;
    let sources_dir = dir.join("sources").join(top);
    let sources = files_in(&sources_dir, "v")?;
    // The Verilog as the engines ran it, under this directory, so that the
    // merged file and its annotation name files that exist.
    let local = |f: &str| {
        let name = Path::new(f).file_name().unwrap_or_default();
        sources_dir.join(name)
    };
    let dat = out.join("coverage.dat");
    let mut text = String::from("# SystemC::Coverage-3\n");
    for p in &points {
        text += &p.with_file(&local(&p.file).to_string_lossy());
        text.push('\n');
    }
    std::fs::write(&dat, text).map_err(io_err(&dat))?;
    let _ = std::fs::remove_file(&merged);
    let annotated = out.join("annotated");
    let mut cmd = Command::new("verilator_coverage");
    cmd.arg("--annotate")
        .arg(&annotated)
        .arg("--annotate-min")
        .arg("1")
        .arg(&dat);
    run_tool(cmd)?;

    let netlist = Netlist::read(&sources)?;
    let index = SourceIndex::new(&netlist, top);
    let constant = super::constants::prove(&sources, top, &out.join("constants"))?;
    let mut texts: BTreeMap<PathBuf, String> = BTreeMap::new();
    for f in &sources {
        texts.insert(f.clone(), std::fs::read_to_string(f).map_err(io_err(f))?);
    }
    let (mut line, mut toggle) = ((0, 0, 0), (0, 0, 0));
    let (mut toggle_constant, mut toggle_by_design, mut toggle_uncertain) = (0, 0, 0);
    let mut uncovered = Vec::new();
    for p in &points {
        let tally = if p.kind == Kind::Toggle {
            &mut toggle
        } else {
            &mut line
        };
        tally.2 += 1;
        let mut proven = match p.kind {
            Kind::Toggle => constant.value(&p.module, &p.what),
            _ => None,
        };
        if let Some(v) = proven.filter(|&v| p.count > constant.max_count(&p.module, v)) {
            uses.contradictions.push(format!(
                "{} {} {}: changed {} times in {} instances, yet {}",
                p.module,
                p.instance,
                p.what,
                p.count,
                constant.instances(&p.module),
                super::constants::reason(v)
            ));
            proven = None;
        }
        let mut by_design = match (p.kind, proven) {
            (Kind::Toggle, None) => super::by_design::reason(&p.module, &p.what),
            _ => None,
        };
        if let Some(why) = by_design.as_ref().filter(|_| p.count > 0) {
            uses.contradictions.push(format!(
                "{} {} {}: changed {} times, yet {why}",
                p.module, p.instance, p.what, p.count
            ));
            by_design = None;
        }
        let file = local(&p.file);
        let source_of = |p: &Point| match p.kind {
            Kind::Toggle => index.declared_in(&p.module, &p.what).map(str::to_string),
            _ => {
                let t = texts.get(&file).map(String::as_str).unwrap_or("");
                line_source(p, &t.lines().collect::<Vec<_>>(), &index)
            }
        };
        // A proven bit Verilator counts covered only rose from its initial
        // 0 in two instances or more: it never toggled, so it is waived.
        if p.covered() && proven.is_none() {
            tally.0 += 1;
            let instances = constant.instances(&p.module);
            if p.kind == Kind::Toggle && instances > 1 && p.count <= instances {
                toggle_uncertain += 1;
            }
            // A waiver of a point the regression reached is wrong (an open
            // reason may name a group of which some points were reached).
            if waivers.find(p, None, false).is_some() {
                let s = source_of(p);
                if let Some(i) = s.and_then(|s| waivers.find(p, Some(&s), false)) {
                    uses.reached[i] = true;
                }
            }
            continue;
        }
        let source = source_of(p);
        let at = source.as_deref().unwrap_or("(no generator line)");
        let waiver = waivers.find(p, Some(at), false);
        let open = waivers.find(p, Some(at), true);
        if let Some(i) = open {
            uses.used[i] = true;
        }
        let waived = match (proven, waiver) {
            (Some(v), w) => {
                if let Some(i) = w {
                    uses.redundant[i] = true;
                }
                toggle_constant += 1;
                Some(super::constants::reason(v))
            }
            (None, w) if by_design.is_some() => {
                if let Some(i) = w {
                    uses.redundant[i] = true;
                }
                toggle_by_design += 1;
                by_design
            }
            (None, Some(i)) => {
                uses.used[i] = true;
                let w = &waivers.entries[i];
                Some(format!("{}: {}", w.at, w.reason))
            }
            (None, None) => None,
        };
        if waived.is_some() {
            tally.1 += 1;
        }
        uncovered.push(UncoveredPoint {
            kind: p.kind.name(),
            module: p.module.clone(),
            instance: p.instance.clone(),
            point: match p.kind {
                Kind::Toggle => p.what.clone(),
                _ => format!(
                    "{}:{} {}",
                    file.file_name().unwrap_or_default().to_string_lossy(),
                    p.line,
                    p.what
                ),
            },
            source,
            count: p.count,
            field: match p.kind {
                Kind::Toggle => super::by_design::field_of(&p.module, &p.what),
                _ => None,
            },
            open: open
                .filter(|_| waived.is_none())
                .map(|i| format!("{}: {}", waivers.entries[i].at, waivers.entries[i].reason)),
            waived,
        });
    }
    Ok(UnitSummary {
        unit: top.to_string(),
        runs: raws.len(),
        line,
        toggle,
        toggle_constant,
        toggle_by_design,
        toggle_uncertain,
        dat,
        annotated,
        uncovered,
    })
}

/// The report of every unit whose counts were collected under `dir`
/// ([`super::collect_into`]), against `aims`, with `waivers`.
pub fn report(dir: &Path, aims: Aims, waivers: &Waivers) -> Result<CoverageReport> {
    let raw = dir.join("raw");
    let mut tops: Vec<String> = std::fs::read_dir(&raw)
        .map_err(io_err(&raw))?
        .flatten()
        .filter(|e| e.path().is_dir())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    tops.sort();
    let n = waivers.entries.len();
    let mut uses = WaiverUse {
        used: vec![false; n],
        reached: vec![false; n],
        redundant: vec![false; n],
        contradictions: Vec::new(),
    };
    let mut units = Vec::new();
    for top in &tops {
        units.push(unit_summary(dir, top, waivers, &mut uses)?);
    }
    // Stale: a waiver of a module this report saw that waives nothing
    // (the point moved, or its generator line did, or Yosys now proves it
    // constant) or names a point the regression reached.
    let stale_waivers = (0..n)
        .filter(|&i| !uses.used[i] || uses.reached[i])
        .map(|i| (i, &waivers.entries[i]))
        .filter(|(_, w)| units.iter().any(|u| module_in(u, &w.module, dir)))
        .map(|(i, w)| {
            let why = match (uses.reached[i], uses.redundant[i] && !uses.used[i]) {
                (true, _) => "names a point the regression reached",
                (false, true) => "Yosys proves its points constant, or a by-design rule names them: they are waived without it",
                (false, false) if w.open => "matches no uncovered point",
                (false, false) => "waives nothing",
            };
            format!(
                "{}: {} {} {} ({}): {why}",
                w.at,
                w.module,
                w.kind.name(),
                w.net,
                w.source
            )
        })
        .collect();
    Ok(CoverageReport {
        aims,
        units,
        stale_waivers,
        contradictions: uses.contradictions,
    })
}

fn module_in(unit: &UnitSummary, module: &str, dir: &Path) -> bool {
    dir.join("sources")
        .join(&unit.unit)
        .join(format!("{module}.v"))
        .is_file()
}

#[cfg(test)]
mod tests {
    use super::*;

    const VERILOG: &str = "// Module t generated by rtl-gen from g/t.rs:1. Do not edit.\n\
module t (\n\
    input  wire clk,      // clock (implicit)\n\
    input  wire a,        // g/t.rs:4\n\
    output reg [1:0] q    // g/t.rs:5\n\
);\n\
    wire b;               // g/t.rs:7\n\
    assign b = ~a;\n\
    always @(posedge clk) begin\n\
        if (a) begin\n\
            q <= 2'd1;    // g/t.rs:11\n\
        end else begin\n\
            q <= 2'd2;    // g/t.rs:13\n\
        end\n\
    end\n\
    wire [1:0] z;         // g/t.rs:17\n\
    assign z = {a, 1'b0};\n\
    wire k;               // g/t.rs:19\n\
    assign k = 1'b1;\n\
endmodule\n";

    fn point(f: &str, l: u32, page: &str, o: &str, span: &str, count: u64) -> String {
        format!(
            "C '\u{1}f\u{2}{f}\u{1}l\u{2}{l}\u{1}n\u{2}5\u{1}page\u{2}{page}\u{1}o\u{2}{o}{span}\u{1}h\u{2}TOP.t' {count}\n"
        )
    }

    /// Two raw files of one unit merged by verilator_coverage; generator
    /// lines from the comments, a waiver applied, a stale one reported.
    #[test]
    fn merges_maps_waives_and_reports_stale_waivers() {
        if !crate::tools::tool_available("verilator_coverage") {
            assert!(std::env::var("CI").is_err(), "verilator_coverage missing");
            return;
        }
        let dir = tempfile::tempdir().unwrap();
        let (raw, src) = (dir.path().join("raw/t"), dir.path().join("sources/t"));
        std::fs::create_dir_all(&raw).unwrap();
        std::fs::create_dir_all(&src).unwrap();
        std::fs::write(src.join("t.v"), VERILOG).unwrap();
        // As built elsewhere: the file name is all that is kept.
        let f = "/gone/t.v";
        let first = point(f, 10, "v_branch/t", "if", "\u{1}S\u{2}10-11", 3)
            + &point(f, 12, "v_branch/t", "else", "\u{1}S\u{2}12-13", 0)
            + &point(f, 9, "v_line/t", "block", "\u{1}S\u{2}9", 3)
            + &point(f, 7, "v_toggle/t", "b", "", 1)
            + &point(f, 5, "v_toggle/t", "q[0]", "", 1)
            + &point(f, 5, "v_toggle/t", "q[1]", "", 0)
            + &point(f, 17, "v_toggle/t", "z[0]", "", 0)
            + &point(f, 17, "v_toggle/t", "z[1]", "", 2)
            + &point(f, 19, "v_toggle/t", "k", "", 1);
        std::fs::write(raw.join("1.dat"), &first).unwrap();
        std::fs::write(raw.join("2.dat"), point(f, 5, "v_toggle/t", "q[0]", "", 1)).unwrap();
        let w = dir.path().join("w.txt");
        std::fs::write(
            &w,
            "t | toggle q[1] | g/t.rs:5 | tied low in this test\n\
             t | toggle b | g/t.rs:7 | rose once only in this test\n\
             t | branch 12 | g/t.rs:99 | wrong generator line\n\
             t | toggle z[0] | g/t.rs:17 | tied 0 (Yosys proves it)\n",
        )
        .unwrap();
        let r = report(dir.path(), Aims::default(), &Waivers::read(&w).unwrap()).unwrap();
        let u = &r.units[0];
        assert_eq!((u.unit.as_str(), u.runs), ("t", 2));
        let by = |p: &str| {
            u.uncovered
                .iter()
                .find(|x| x.point == p || x.point.contains(p))
                .unwrap()
        };
        // q[0] changed once in each run, so it only rose: not covered,
        // though the runs' sum is 2; b changed once: not; z[1] toggled;
        // z[0] and k (one rise from the initial 0, one instance) are
        // proven constant by Yosys.
        assert_eq!(by("q[0]").waived, None);
        assert_eq!(u.toggle.0, 1);
        assert_eq!(u.toggle_constant, 2);
        assert!(by("z[0]").waived.as_deref().unwrap().contains("constant 0"));
        assert!(by("k").waived.as_deref().unwrap().contains("constant 1"));
        assert!(r.contradictions.is_empty(), "{:?}", r.contradictions);
        assert_eq!(u.line, (2, 0, 3));
        assert_eq!(by("t.v:12 else").source.as_deref(), Some("g/t.rs:13"));
        assert_eq!(by("b").source.as_deref(), Some("g/t.rs:7"));
        assert!(by("q[1]").waived.as_deref().unwrap().contains("tied low"));
        assert!(by("t.v:12").waived.is_none());
        // `toggle b` waives an uncovered point, but `branch 12` names the
        // wrong line, and Yosys proves `z[0]`.
        assert_eq!(r.stale_waivers.len(), 2, "{:?}", r.stale_waivers);
        assert!(r.stale_waivers[0].contains("w.txt:3"));
        assert!(r.stale_waivers[1].contains("w.txt:4") && r.stale_waivers[1].contains("Yosys"));
        assert!(!r.passed());
        let dat = std::fs::read_to_string(&u.dat).unwrap();
        assert!(dat.contains(&src.join("t.v").display().to_string()));
        assert!(u.annotated.join("t.v").is_file());
        // A proven bit that changed more often than its instances rose is
        // a contradiction, never waived.
        std::fs::write(raw.join("2.dat"), point(f, 19, "v_toggle/t", "k", "", 2)).unwrap();
        let r = report(dir.path(), Aims::default(), &Waivers::default()).unwrap();
        assert_eq!(r.contradictions.len(), 1, "{:?}", r.contradictions);
        assert!(r.contradictions[0].contains("TOP.t k: changed 2 times in 1 instances"));
        assert!(!r.passed());
    }

    /// A by-design bit (`cosim::coverage::by_design`: at D = 2, `x` bit 1 of
    /// a level-1 beat) is waived while it never changed, and is a
    /// contradiction once it did; a bit the rule does not name is neither.
    #[test]
    fn by_design_bits_are_waived_until_they_toggle() {
        if !crate::tools::tool_available("verilator_coverage") {
            assert!(std::env::var("CI").is_err(), "verilator_coverage missing");
            return;
        }
        const TOP: &str = "upper_builder_d2_q0_i2_h1";
        let verilog = format!(
            "module {TOP} (\n    input wire [12:0] level1_data, // g/u.rs:3\n    output wire o\n);\n    assign o = ^level1_data;\nendmodule\n"
        );
        let dir = tempfile::tempdir().unwrap();
        let (raw, src) = (
            dir.path().join("raw").join(TOP),
            dir.path().join("sources").join(TOP),
        );
        std::fs::create_dir_all(&raw).unwrap();
        std::fs::create_dir_all(&src).unwrap();
        std::fs::write(src.join("u.v"), verilog).unwrap();
        let page = format!("v_toggle/{TOP}");
        let at = |what: &str, count: u64| {
            format!(
                "C '\u{1}f\u{2}/gone/u.v\u{1}l\u{2}2\u{1}n\u{2}5\u{1}page\u{2}{page}\u{1}o\u{2}{what}\u{1}h\u{2}TOP.{TOP}' {count}\n"
            )
        };
        // Record at D = 2: leaf 0, lod 1..=2, x 3..=4, y 5..=6, z 7..=8.
        std::fs::write(
            raw.join("1.dat"),
            at("level1_data[4]", 0) + &at("level1_data[3]", 0),
        )
        .unwrap();
        let r = report(dir.path(), Aims::default(), &Waivers::default()).unwrap();
        let u = &r.units[0];
        assert_eq!((u.toggle, u.toggle_by_design), ((0, 1, 2), 1));
        let x1 = u
            .uncovered
            .iter()
            .find(|p| p.point == "level1_data[4]")
            .unwrap();
        assert!(x1
            .waived
            .as_deref()
            .unwrap()
            .contains("`x` bit 1 of a level-1 beat"));
        assert!(r.contradictions.is_empty(), "{:?}", r.contradictions);
        std::fs::write(raw.join("1.dat"), at("level1_data[4]", 2)).unwrap();
        let r = report(dir.path(), Aims::default(), &Waivers::default()).unwrap();
        assert_eq!(r.contradictions.len(), 1, "{:?}", r.contradictions);
        assert!(r.contradictions[0].contains("level1_data[4]: changed 2 times"));
        assert!(!r.passed());
    }

    /// A bit of a module instantiated twice that changed twice may only
    /// have risen once in each instance: covered, but not certain; three
    /// changes are certain (one instance changed twice), and so is a bit of
    /// the top, which has one instance.
    #[test]
    fn a_shared_counter_at_most_its_instances_is_uncertain() {
        if !crate::tools::tool_available("verilator_coverage") {
            assert!(std::env::var("CI").is_err(), "verilator_coverage missing");
            return;
        }
        let child = "module c (\n    input wire [1:0] d, // g/c.rs:2\n    output wire o\n);\n    assign o = ^d;\nendmodule\n";
        let top = "module t (\n    input wire [1:0] a, // g/t.rs:8\n    input wire [1:0] b,\n    output wire o\n);\n\
            wire p, q;\n    c u_a (\n        .d(a),\n        .o(p)\n    );\n    c u_b (\n        .d(b),\n        .o(q)\n    );\n    assign o = p ^ q ^ a[0];\nendmodule\n";
        let dir = tempfile::tempdir().unwrap();
        let (raw, src) = (dir.path().join("raw/t"), dir.path().join("sources/t"));
        std::fs::create_dir_all(&raw).unwrap();
        std::fs::create_dir_all(&src).unwrap();
        std::fs::write(src.join("c.v"), child).unwrap();
        std::fs::write(src.join("t.v"), top).unwrap();
        let at = |module: &str, h: &str, what: &str, count: u64| {
            format!(
                "C '\u{1}f\u{2}/gone/t.v\u{1}l\u{2}2\u{1}n\u{2}5\u{1}page\u{2}v_toggle/{module}\u{1}o\u{2}{what}\u{1}h\u{2}{h}' {count}\n"
            )
        };
        std::fs::write(
            raw.join("1.dat"),
            at("c", "TOP.t.u_*", "d[0]", 2)
                + &at("c", "TOP.t.u_*", "d[1]", 3)
                + &at("t", "TOP.t", "a[0]", 2),
        )
        .unwrap();
        let r = report(dir.path(), Aims::default(), &Waivers::default()).unwrap();
        let u = &r.units[0];
        assert_eq!(
            (u.toggle.0, u.toggle.2, u.toggle_uncertain),
            (3, 3, 1),
            "{u:?}"
        );
        assert!((u.toggle_percent() - 100.0).abs() < 1e-9);
        assert!((u.toggle_percent_certain() - 200.0 / 3.0).abs() < 1e-9);
        assert!(r.table().contains("| 100.0% (66.7%) |"), "{}", r.table());
    }
}
