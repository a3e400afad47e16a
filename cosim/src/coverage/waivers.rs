//! The checked-in waivers: coverage points unreachable by design, each with
//! its reason (SPEC 10.5). One per line, fields separated by `|`:
//!
//! ```text
//! # module | point | generator line | reason
//! merge_level_d16_q8_i24_h4 | toggle h_rec[125:102] | rtl-gen/src/merge/merge_level.rs:53 | ...
//! ```
//!
//! A point is `toggle NET` (every bit), `toggle NET[i]` or `toggle
//! NET[hi:lo]` (bits of the emitted net), `line N` or `branch N` (the
//! emitted Verilog's line; `branch N if` or `branch N else` one arm of a
//! line that has both), or `toggle *`, `line *`, `branch *`: every
//! point of that type in the module that maps to the generator line. The
//! generator line must be the one the point maps to, so a waiver goes
//! stale, and fails, when the generator moves.
//!
//! A point written `open ...` (`open toggle *`) waives nothing: it states
//! why points the regression does not reach are still below the aims
//! (reachable, no stimulus yet), and is stale when it matches no uncovered
//! point; its generator line may be `*` (any). The first entry that
//! matches a point gives its reason.

use super::dat::{Kind, Point};
use crate::error::{io_err, CosimError, Result};
use serde::Serialize;
use std::path::Path;

/// One waiver.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Waiver {
    /// The module (the emitted file's name without `.v`).
    pub module: String,
    /// The point's type.
    #[serde(serialize_with = "kind_name")]
    pub kind: Kind,
    /// Toggle: the net; line/branch: the arm (`if`, `else`, ...) or empty
    /// (every point of the line).
    pub net: String,
    /// Toggle: the bits `(hi, lo)` waived (`None`: every bit);
    /// line/branch: the Verilog line as `(n, n)`.
    pub range: Option<(u32, u32)>,
    /// The generator line the point maps to.
    pub source: String,
    /// Why it cannot be covered.
    pub reason: String,
    /// Where the waiver is written (`file:line`).
    pub at: String,
    /// `open`: a reason for points left uncovered, not a waiver.
    pub open: bool,
}

fn kind_name<S: serde::Serializer>(k: &Kind, s: S) -> std::result::Result<S::Ok, S::Error> {
    s.serialize_str(k.name())
}

/// The waivers of one file.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Waivers {
    /// Every waiver, in file order.
    pub entries: Vec<Waiver>,
}

fn bits(s: &str) -> Option<(u32, u32)> {
    let inner = s.strip_prefix('[')?.strip_suffix(']')?;
    match inner.split_once(':') {
        Some((h, l)) => Some((h.trim().parse().ok()?, l.trim().parse().ok()?)),
        None => {
            let b = inner.trim().parse().ok()?;
            Some((b, b))
        }
    }
}

impl Waivers {
    /// Reads `path` (a missing file is an error: name the file you mean).
    pub fn read(path: &Path) -> Result<Waivers> {
        let text = std::fs::read_to_string(path).map_err(io_err(path))?;
        let mut entries = Vec::new();
        for (n, line) in text.lines().enumerate() {
            let line = line.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let at = format!("{}:{}", path.display(), n + 1);
            let bad = |what: String| CosimError::Protocol {
                what: format!("{at}: {what}"),
            };
            let f: Vec<&str> = line.splitn(4, '|').map(str::trim).collect();
            if f.len() != 4 || f.iter().any(|x| x.is_empty()) {
                return Err(bad(
                    "expected `module | point | generator line | reason`, none empty".into(),
                ));
            }
            let (open, point) = match f[1].strip_prefix("open ") {
                Some(rest) => (true, rest.trim()),
                None => (false, f[1]),
            };
            let (kind, target) = point.split_once(' ').ok_or_else(|| {
                bad(format!(
                    "point `{}`: expected `toggle NET`, `line N` or `branch N`",
                    f[1]
                ))
            })?;
            let target = target.trim();
            let (kind, net, range) = match kind {
                "toggle" => {
                    let (net, sel) = match target.find('[') {
                        Some(i) => (&target[..i], Some(&target[i..])),
                        None => (target, None),
                    };
                    let range = match sel {
                        None => None,
                        Some(s) => Some(bits(s).filter(|(h, l)| h >= l).ok_or_else(|| {
                            bad(format!("`{s}`: expected [i] or [hi:lo] with hi >= lo"))
                        })?),
                    };
                    (Kind::Toggle, net.to_string(), range)
                }
                "line" | "branch" if target == "*" => {
                    let k = if kind == "line" {
                        Kind::Line
                    } else {
                        Kind::Branch
                    };
                    (k, String::new(), None)
                }
                "line" | "branch" => {
                    let (line, arm) = target.split_once(' ').unwrap_or((target, ""));
                    let n: u32 = line.parse().map_err(|_| {
                        bad(format!(
                            "`{target}`: expected a Verilog line number [and an arm]"
                        ))
                    })?;
                    let k = if kind == "line" {
                        Kind::Line
                    } else {
                        Kind::Branch
                    };
                    (k, arm.trim().to_string(), Some((n, n)))
                }
                other => return Err(bad(format!("`{other}`: expected toggle, line or branch"))),
            };
            if f[2] == "*" && !open {
                return Err(bad(
                    "a waiver names the generator line of its points (`*` is for open points only)"
                        .into(),
                ));
            }
            entries.push(Waiver {
                module: f[0].to_string(),
                kind,
                net,
                range,
                source: f[2].to_string(),
                reason: f[3].to_string(),
                at,
                open,
            });
        }
        Ok(Waivers { entries })
    }

    /// The index of the first entry, a waiver or (`open`) a reason for an
    /// open point, that names `p` at generator line `source` (`None`: any
    /// line, for points whose line is not looked up).
    pub fn find(&self, p: &Point, source: Option<&str>, open: bool) -> Option<usize> {
        self.entries.iter().position(|w| {
            if w.module != p.module || w.kind != p.kind || w.open != open {
                return false;
            }
            if source.is_some_and(|s| s != w.source && !(w.open && w.source == "*")) {
                return false;
            }
            match p.kind {
                Kind::Toggle => {
                    let (net, sel) = match p.what.find('[') {
                        Some(i) => (&p.what[..i], Some(&p.what[i..])),
                        None => (p.what.as_str(), None),
                    };
                    // Memories give `mem[word][bit]`: the word is not a bit.
                    let bit = sel.and_then(|s| bits(&s[s.rfind('[').unwrap_or(0)..]));
                    (w.net == "*" || net == w.net)
                        && match (w.range, bit) {
                            (None, _) => true,
                            (Some((h, l)), Some((b, _))) => l <= b && b <= h,
                            (Some(_), None) => false,
                        }
                }
                Kind::Line | Kind::Branch => {
                    w.range.is_none_or(|r| r == (p.line, p.line))
                        && (w.net.is_empty() || w.net == p.what)
                }
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_and_matches_and_refuses_bad_lines() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("w.txt");
        std::fs::write(
            &p,
            "# c\nm | toggle h_rec[7:4] | g.rs:3 | tied\nm | branch 12 | g.rs:9 | never\n",
        )
        .unwrap();
        let w = Waivers::read(&p).unwrap();
        assert_eq!(w.entries.len(), 2);
        assert_eq!(w.entries[0].range, Some((7, 4)));
        let dat = dir.path().join("c.dat");
        let rec = |page: &str, o: &str, l: u32| {
            format!("C '\u{1}f\u{2}m.v\u{1}l\u{2}{l}\u{1}page\u{2}{page}\u{1}o\u{2}{o}\u{1}h\u{2}TOP.m' 0\n")
        };
        std::fs::write(
            &dat,
            rec("v_toggle/m", "h_rec[5]", 1)
                + &rec("v_toggle/m", "h_rec[3]", 1)
                + &rec("v_branch/m", "if", 12),
        )
        .unwrap();
        let pts = super::super::read_points(&dat).unwrap();
        assert_eq!(w.find(&pts[0], None, false), Some(0));
        assert_eq!(w.find(&pts[0], Some("g.rs:3"), false), Some(0));
        assert_eq!(w.find(&pts[0], Some("g.rs:3"), true), None);
        assert_eq!(w.find(&pts[0], Some("g.rs:4"), false), None);
        assert_eq!(w.find(&pts[1], None, false), None);
        assert_eq!(w.find(&pts[2], None, false), Some(1));
        std::fs::write(
            &p,
            "m | open toggle * | g.rs:3 | no stimulus yet\nm | branch * | g.rs:9 | never\n",
        )
        .unwrap();
        let w = Waivers::read(&p).unwrap();
        assert!(w.entries[0].open && !w.entries[1].open);
        assert_eq!(w.find(&pts[1], Some("g.rs:3"), true), Some(0));
        assert_eq!(w.find(&pts[1], Some("g.rs:3"), false), None);
        assert_eq!(w.find(&pts[2], Some("g.rs:9"), false), Some(1));
        assert_eq!(w.find(&pts[2], Some("g.rs:3"), false), None);
        // One arm of a line: the `if` point is named by `if`, not `else`.
        std::fs::write(
            &p,
            "m | branch 12 else | g.rs:9 | never\nm | branch 12 if | g.rs:9 | never\n",
        )
        .unwrap();
        let w = Waivers::read(&p).unwrap();
        assert_eq!(w.find(&pts[2], Some("g.rs:9"), false), Some(1));
        std::fs::write(&p, "m | open line * | * | any line\n").unwrap();
        let w = Waivers::read(&p).unwrap();
        assert_eq!(w.find(&pts[2], Some("g.rs:7"), true), None, "a branch");
        std::fs::write(&p, "m | branch * | * | never\n").unwrap();
        let e = Waivers::read(&p).unwrap_err().to_string();
        assert!(
            e.contains("w.txt:1") && e.contains("open points only"),
            "{e}"
        );
        std::fs::write(&p, "m | toggle x[1:2] | g.rs:1 | r\n").unwrap();
        let e = Waivers::read(&p).unwrap_err().to_string();
        assert!(e.contains("w.txt:1") && e.contains("hi >= lo"), "{e}");
        std::fs::write(&p, "m | toggle x | g.rs:1\n").unwrap();
        assert!(Waivers::read(&p).is_err());
    }
}
