//! The last figures `hiermerge synth` made for each module digest and
//! target, kept under `<cache root>/synth-record/<module>-<digest>/` so that
//! a reader (the study) finds them without running any tool (SPEC 14.5).

use super::ecp5::Ecp5Figures;
use super::generic::GenericFigures;
use super::ice40::Ice40Figures;
use super::sources::Netlist;
use super::{compose, Target};
use crate::error::{io_err, Result};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The cache kind of the records.
pub const KIND: &str = "synth-record";

/// One target's figures as recorded, with what made them.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Recorded<T> {
    /// The module.
    pub module: String,
    /// Its `Netlist::digest`.
    pub digest: String,
    /// The tool versions of the run that recorded it.
    pub tools: String,
    /// Its `--seeds`.
    pub seeds: u64,
    /// Its `--freq`, MHz.
    pub goal_mhz: f64,
    /// The figures.
    pub figures: T,
}

/// Every recorded figure of one module.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct Lookup {
    /// The module.
    pub module: String,
    /// Its digest in the configuration looked up.
    pub digest: String,
    /// Generic figures, when recorded.
    pub generic: Option<Recorded<GenericFigures>>,
    /// ECP5 figures, when recorded.
    pub ecp5: Option<Recorded<Ecp5Figures>>,
    /// iCE40 figures, when recorded.
    pub ice40: Option<Recorded<Ice40Figures>>,
    /// Its parts, for a composed module (SPEC 14.6).
    pub composed_of: Vec<compose::Part>,
}

fn dir(root: &Path, module: &str, digest: &str) -> PathBuf {
    root.join(KIND)
        .join(format!("{module}-{}", &digest[..digest.len().min(24)]))
}

fn file(target: Target) -> &'static str {
    match target {
        Target::Generic => "generic.json",
        Target::Ecp5 => "ecp5.json",
        Target::Ice40 => "ice40.json",
    }
}

/// Records `figures` of `target` (written to a temporary file, then renamed).
pub fn store<T: Serialize>(root: &Path, target: Target, r: &Recorded<T>) -> Result<()> {
    let d = dir(root, &r.module, &r.digest);
    std::fs::create_dir_all(&d).map_err(io_err(&d))?;
    let tmp = d.join(format!(".{}.{}", file(target), std::process::id()));
    super::write_json(&tmp, r)?;
    let path = d.join(file(target));
    std::fs::rename(&tmp, &path).map_err(io_err(&path))
}

fn load<T: for<'de> Deserialize<'de>>(d: &Path, target: Target) -> Option<Recorded<T>> {
    let path = d.join(file(target));
    path.is_file()
        .then(|| super::read_json(&path).ok())
        .flatten()
}

/// What the cache at `root` records for `module` of `netlist`: runs no
/// tool, builds nothing; a target never synthesized is `None`.
pub fn lookup(root: &Path, netlist: &Netlist, module: &str) -> Lookup {
    let digest = netlist.digest(module);
    let d = dir(root, module, &digest);
    Lookup {
        module: module.to_string(),
        generic: load(&d, Target::Generic),
        ecp5: load(&d, Target::Ecp5),
        ice40: load(&d, Target::Ice40),
        composed_of: if compose::is_composed(module) {
            compose::parts(netlist, module)
        } else {
            Vec::new()
        },
        digest,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::{run_all, sources::Source, Flow};

    fn netlist(dir: &Path) -> Netlist {
        let leaf = "module leaf (\n    input  wire clk,\n    input  wire d,\n    output wire q\n);\n    reg r; // g/leaf.rs:3\n    always @(posedge clk) r <= ~d;\n    assign q = r;\nendmodule\n";
        let top = "module hierarchy_merger_t (\n    input  wire clk,\n    input  wire d,\n    output wire q\n);\n    wire a; // g/top.rs:4\n    wire b; // g/top.rs:5\n    reg r; // g/top.rs:6\n    leaf u_a ( // g/top.rs:7\n        .clk(clk), .d(d), .q(a)\n    );\n    leaf u_b ( // g/top.rs:8\n        .clk(clk), .d(a), .q(b)\n    );\n    always @(posedge clk) r <= a ^ b;\n    assign q = r;\nendmodule\n";
        let mut n = Netlist::default();
        for (m, text) in [("leaf", leaf), ("hierarchy_merger_t", top)] {
            let path = dir.join(format!("{m}.v"));
            std::fs::write(&path, text).unwrap();
            n.modules.insert(
                m.into(),
                Source {
                    module: m.into(),
                    path,
                    text: text.into(),
                },
            );
        }
        n
    }

    /// A run records what it computed; the lookup, which runs no tool,
    /// returns the same figures; a composed top adds up its parts.
    #[test]
    fn lookup_returns_what_a_run_recorded() {
        let dir = tempfile::tempdir().unwrap();
        let n = netlist(dir.path());
        let root = dir.path().join("cache");
        assert_eq!(lookup(&root, &n, "leaf").generic, None, "an empty cache");
        let flow = match Flow::new(
            &[Target::Generic],
            root.clone(),
            std::time::Duration::from_secs(120),
            100.0,
        ) {
            Ok(f) => f,
            Err(e) if !crate::tools::ci_mode() => return eprintln!("SKIPPING: {e}"),
            Err(e) => panic!("CI=true and Yosys is missing: {e}"),
        };
        let tops = vec!["hierarchy_merger_t".to_string(), "leaf".to_string()];
        let reports = run_all(&flow, &n, &tops, &[Target::Generic], 1, 2).unwrap();
        for r in &reports {
            let l = lookup(&root, &n, &r.module);
            let g = l.generic.expect("recorded");
            assert_eq!(Some(&g.figures), r.generic.as_ref());
            assert_eq!(g.digest, n.digest(&r.module));
            assert_eq!(g.tools, flow.yosys.version);
        }
        let leaf = reports[1].generic.as_ref().unwrap();
        let top = &reports[0];
        assert_eq!(leaf.flip_flops, 1);
        assert_eq!(
            top.generic.as_ref().unwrap().flip_flops,
            3,
            "own register + 2 x leaf"
        );
        assert_eq!(
            top.composed_of,
            vec![compose::Part {
                module: "leaf".into(),
                count: 2
            }]
        );
        // Another configuration's text: nothing recorded for it.
        let mut other = n.clone();
        other
            .modules
            .get_mut("leaf")
            .unwrap()
            .text
            .push_str("// changed\n");
        assert_eq!(lookup(&root, &other, "leaf").generic, None);
    }
}
