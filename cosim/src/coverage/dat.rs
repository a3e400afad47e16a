//! Verilator's `coverage.dat` (SystemC::Coverage-3): one point per
//! `C '<key/value pairs>' <count>` line, keys and values separated by the
//! control characters 0x01 and 0x02. The keys used here: `f` file, `l`
//! line, `page` (`v_line/<module>`, `v_branch/<module>`,
//! `v_toggle/<module>`), `o` (the block kind, `if`/`else`, or the toggled
//! signal bit), `S` (the lines the point spans), `h` (the instance).

use crate::error::{io_err, CosimError, Result};
use std::path::Path;

/// Which of Verilator's coverage types a point is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Kind {
    /// `v_line`: a block of statements was entered.
    Line,
    /// `v_branch`: an `if` or `else` arm was taken (part of Verilator's
    /// line coverage, reported with it as "line/branch").
    Branch,
    /// `v_toggle`: one bit of a signal changed.
    Toggle,
}

impl Kind {
    /// The name used in reports and waivers.
    pub fn name(self) -> &'static str {
        match self {
            Kind::Line => "line",
            Kind::Branch => "branch",
            Kind::Toggle => "toggle",
        }
    }
}

/// One coverage point and its count.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Point {
    /// Its type.
    pub kind: Kind,
    /// The module it belongs to (the `page`'s suffix).
    pub module: String,
    /// The Verilog file as Verilator was given it.
    pub file: String,
    /// Its line in that file.
    pub line: u32,
    /// The lines it spans (`S`), when given: `5-6`.
    pub span: Option<String>,
    /// `block`, `if`, `else`, ... or the toggled bit (`h_rec[3]`).
    pub what: String,
    /// The instance (`TOP.merge_level_d16_q8_i24_h4`).
    pub instance: String,
    /// How often it was hit (toggles: how often the bit changed).
    pub count: u64,
    /// The line of the file as read, for rewriting it (`f` replaced).
    raw: String,
}

impl Point {
    /// Covered: a line or branch entered once, a bit that changed at least
    /// twice (rose and fell).
    pub fn covered(&self) -> bool {
        match self.kind {
            Kind::Line | Kind::Branch => self.count >= 1,
            Kind::Toggle => self.count >= 2,
        }
    }

    /// The point's line with its file field replaced by `file`.
    pub fn with_file(&self, file: &str) -> String {
        let from = format!("\u{1}f\u{2}{}\u{1}", self.file);
        let to = format!("\u{1}f\u{2}{file}\u{1}");
        self.raw.replacen(&from, &to, 1)
    }
}

impl Point {
    /// What names this point in every run of its unit, whichever folder
    /// the run's Verilog was in (the file's name, not its path).
    fn key(&self) -> (Kind, &str, &str, u32, Option<&str>, &str, &str) {
        let name = self.file.rsplit('/').next().unwrap_or(&self.file);
        let span = self.span.as_deref();
        (
            self.kind,
            &self.module,
            name,
            self.line,
            span,
            &self.what,
            &self.instance,
        )
    }

    /// The point with its count set to `count`, its line too.
    fn with_count(mut self, count: u64) -> Point {
        if let Some((fields, _)) = self.raw.rsplit_once("' ") {
            self.raw = format!("{fields}' {count}");
        }
        self.count = count;
        self
    }
}

/// `merged` (the runs' counts summed, as `verilator_coverage --write`
/// merges them) with every toggle count replaced by the most changes one
/// run of `runs` saw. A run starts from Verilator's initial zeros, so a bit
/// it counts once only rose; summed over two runs it would count as rising
/// and falling. A bit toggled in the union of the runs only if one of them
/// saw it change twice.
pub fn toggles_per_run(merged: Vec<Point>, runs: &[std::path::PathBuf]) -> Result<Vec<Point>> {
    let per_run: Vec<Vec<Point>> = runs.iter().map(|r| read_points(r)).collect::<Result<_>>()?;
    let mut most = std::collections::HashMap::new();
    for p in per_run.iter().flatten().filter(|p| p.kind == Kind::Toggle) {
        let m = most.entry(p.key()).or_insert(0u64);
        *m = (*m).max(p.count);
    }
    Ok(merged
        .into_iter()
        .map(|p| match p.kind {
            Kind::Toggle => {
                let count = most.get(&p.key()).copied().unwrap_or(0);
                p.with_count(count)
            }
            _ => p,
        })
        .collect())
}

/// The points of one `coverage.dat`.
pub fn read_points(path: &Path) -> Result<Vec<Point>> {
    let text = std::fs::read_to_string(path).map_err(io_err(path))?;
    let mut points = Vec::new();
    for (n, line) in text.lines().enumerate() {
        if line.starts_with('#') || line.trim().is_empty() {
            continue;
        }
        let bad = |what: &str| CosimError::Protocol {
            what: format!("{}:{}: {what}", path.display(), n + 1),
        };
        let body = line
            .strip_prefix("C '")
            .ok_or_else(|| bad("expected `C '...' count`"))?;
        let (fields, count) = body
            .rsplit_once("' ")
            .ok_or_else(|| bad("expected `' count` at the end"))?;
        let count: u64 = count
            .trim()
            .parse()
            .map_err(|_| bad("the count is not a number"))?;
        let mut get = std::collections::BTreeMap::new();
        for kv in fields.split('\u{1}').filter(|s| !s.is_empty()) {
            if let Some((k, v)) = kv.split_once('\u{2}') {
                get.insert(k, v);
            }
        }
        let field = |k: &str| get.get(k).map(|v| v.to_string());
        let page = field("page").ok_or_else(|| bad("no `page` key"))?;
        let (ty, module) = page
            .split_once('/')
            .ok_or_else(|| bad("`page` is not `v_<type>/<module>`"))?;
        let kind = match ty {
            "v_line" => Kind::Line,
            "v_branch" => Kind::Branch,
            "v_toggle" => Kind::Toggle,
            other => return Err(bad(&format!("unknown coverage type `{other}`"))),
        };
        points.push(Point {
            kind,
            module: module.to_string(),
            file: field("f").ok_or_else(|| bad("no `f` key"))?,
            line: field("l")
                .and_then(|l| l.parse().ok())
                .ok_or_else(|| bad("no numeric `l` key"))?,
            span: field("S"),
            what: field("o").unwrap_or_default(),
            instance: field("h").unwrap_or_default(),
            count,
            raw: line.to_string(),
        });
    }
    Ok(points)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_the_three_types_and_rewrites_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("c.dat");
        std::fs::write(
            &p,
            "# SystemC::Coverage-3\n\
             C '\u{1}f\u{2}/tmp/x/t.v\u{1}l\u{2}1\u{1}n\u{2}57\u{1}page\u{2}v_toggle/t\u{1}o\u{2}q[1]\u{1}h\u{2}TOP.t' 1\n\
             C '\u{1}f\u{2}/tmp/x/t.v\u{1}l\u{2}5\u{1}n\u{2}10\u{1}page\u{2}v_branch/t\u{1}o\u{2}else\u{1}S\u{2}7-8\u{1}h\u{2}TOP.t' 0\n\
             C '\u{1}f\u{2}/tmp/x/t.v\u{1}l\u{2}4\u{1}n\u{2}5\u{1}page\u{2}v_line/t\u{1}o\u{2}block\u{1}S\u{2}4\u{1}h\u{2}TOP.t' 4\n",
        )
        .unwrap();
        let pts = read_points(&p).unwrap();
        assert_eq!(pts.len(), 3);
        assert_eq!(
            (pts[0].kind, pts[0].what.as_str(), pts[0].covered()),
            (Kind::Toggle, "q[1]", false)
        );
        assert_eq!(
            (pts[1].kind, pts[1].span.as_deref(), pts[1].covered()),
            (Kind::Branch, Some("7-8"), false)
        );
        assert!(pts[2].covered() && pts[2].module == "t" && pts[2].line == 4);
        assert!(pts[1]
            .with_file("/o/t.v")
            .contains("\u{1}f\u{2}/o/t.v\u{1}"));
        std::fs::write(&p, "C 'x' 1\n").unwrap();
        let e = read_points(&p).unwrap_err().to_string();
        assert!(e.contains("c.dat:1"), "{e}");
    }

    /// Two runs each saw `q` change once (it rose) and `r` change twice
    /// in one: `q` is not toggled though the sum is 2, `r` is; line
    /// counts stay summed.
    #[test]
    fn a_toggle_counts_what_one_run_saw() {
        let dir = tempfile::tempdir().unwrap();
        let pt = |dir: &str, what: &str, page: &str, count: u64| {
            format!("C '\u{1}f\u{2}/{dir}/t.v\u{1}l\u{2}3\u{1}page\u{2}{page}/t\u{1}o\u{2}{what}\u{1}h\u{2}TOP.t' {count}\n")
        };
        let runs = [dir.path().join("1.dat"), dir.path().join("2.dat")];
        let body = |d: &str, r: u64| {
            pt(d, "q", "v_toggle", 1) + &pt(d, "r", "v_toggle", r) + &pt(d, "block", "v_line", 2)
        };
        std::fs::write(&runs[0], body("a", 2)).unwrap();
        std::fs::write(&runs[1], body("b", 0)).unwrap();
        let merged = dir.path().join("m.dat");
        // As verilator_coverage sums them: q 2, r 2, the line 4.
        let sums = pt("m", "q", "v_toggle", 2)
            + &pt("m", "r", "v_toggle", 2)
            + &pt("m", "block", "v_line", 4);
        std::fs::write(&merged, sums).unwrap();
        let pts = toggles_per_run(read_points(&merged).unwrap(), &runs).unwrap();
        let got: Vec<(&str, u64, bool)> = pts
            .iter()
            .map(|p| (p.what.as_str(), p.count, p.covered()))
            .collect();
        assert_eq!(got, [("q", 1, false), ("r", 2, true), ("block", 4, true)]);
        assert!(pts[0].raw.ends_with("' 1"), "{}", pts[0].raw);
    }
}
