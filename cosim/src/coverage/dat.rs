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
}
