//! Toggle bits a tool proves constant (SPEC 10.5): Yosys reads the unit's
//! Verilog as the engines ran it, flattens it and optimizes it
//! ([`SCRIPT`]); a bit of a net that the optimized netlist drives with a
//! constant in every instance of its module can never toggle. Computed on
//! every report from the Verilog that ran, so such a waiver cannot outlive
//! the logic it excuses.

use crate::error::{io_err, CosimError, Result};
use crate::synth::sources::Netlist;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// The passes between reading and writing the netlist: `opt` propagates
/// constants through logic and registers (`opt_dff`: a register whose next
/// value is its reset value), never assuming a value for an `x`.
pub const SCRIPT: &str = "proc; flatten; opt";

/// The reason printed for a bit so proven.
pub fn reason(value: bool) -> String {
    format!(
        "constant {} under this configuration (Yosys: {SCRIPT})",
        u8::from(value)
    )
}

/// Per module and net: each bit's proven value (`None`: not constant in
/// every instance).
#[derive(Clone, Debug, Default)]
pub struct ConstantBits {
    nets: BTreeMap<(String, String), Vec<Option<bool>>>,
    instances: BTreeMap<String, u64>,
}

impl ConstantBits {
    /// The proven value of the toggle point `what` (`net` or `net[i]`) of
    /// `module`; `None` for a memory word (`mem[w][b]`), a net Yosys does not
    /// keep, or a bit not constant everywhere.
    pub fn value(&self, module: &str, what: &str) -> Option<bool> {
        let (net, bit) = match what.split_once('[') {
            None => (what, 0),
            Some((net, sel)) => (net, sel.strip_suffix(']')?.parse().ok()?),
        };
        *self
            .nets
            .get(&(module.to_string(), net.to_string()))?
            .get(bit)?
    }

    /// How many instances of `module` the unit has.
    pub fn instances(&self, module: &str) -> u64 {
        self.instances.get(module).copied().unwrap_or(0)
    }

    /// The most changes Verilator can count on a bit proven `value`: it
    /// starts every signal at 0 and sums a module's instances, so a bit
    /// tied 1 rises once in each instance and never falls.
    pub fn max_count(&self, module: &str, value: bool) -> u64 {
        match value {
            true => self.instances(module),
            false => 0,
        }
    }

    /// How many bits are proven constant.
    pub fn len(&self) -> usize {
        self.nets.values().flatten().filter(|b| b.is_some()).count()
    }

    /// True when no bit is proven constant.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Instance path (`u_fetch0.u_root_sorter`, `` for the top) to module.
fn instance_modules(netlist: &Netlist, top: &str) -> BTreeMap<String, String> {
    let mut paths = BTreeMap::from([(String::new(), top.to_string())]);
    let mut todo = vec![String::new()];
    while let Some(p) = todo.pop() {
        for (module, inst) in netlist.instances(&paths[&p].clone()) {
            let q = if p.is_empty() {
                inst
            } else {
                format!("{p}.{inst}")
            };
            paths.insert(q.clone(), module);
            todo.push(q);
        }
    }
    paths
}

/// The bits of `top` (its Verilog in `sources`) that Yosys proves constant,
/// Yosys's script, log and netlist kept in `work`.
pub fn prove(sources: &[PathBuf], top: &str, work: &Path) -> Result<ConstantBits> {
    std::fs::create_dir_all(work).map_err(io_err(work))?;
    // Yosys runs inside `work`, so every path it is given is absolute: a
    // relative `--out` (CI's `target/coverage`) would be read from there.
    let work = &std::path::absolute(work).map_err(io_err(work))?;
    let tool = crate::synth::tools::yosys()?;
    let netlist_path = work.join("netlist.json");
    let files = sources
        .iter()
        .map(|f| std::path::absolute(f).map(|f| format!("\"{}\"", f.display())))
        .collect::<std::io::Result<Vec<String>>>()
        .map_err(io_err(work))?;
    let script = format!(
        "read_verilog -sv {}\nhierarchy -check -top {top}\n{}\nwrite_json \"{}\"\n",
        files.join(" "),
        SCRIPT.replace("; ", "\n"),
        netlist_path.display()
    );
    let ys = work.join("constants.ys");
    std::fs::write(&ys, script).map_err(io_err(&ys))?;
    crate::synth::run::run_logged(
        &tool.program,
        &["-q".into(), "-s".into(), ys.display().to_string()],
        work,
        "yosys.log",
        Duration::from_secs(600),
    )?;
    let text = std::fs::read_to_string(&netlist_path).map_err(io_err(&netlist_path))?;
    let json: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| CosimError::Protocol {
            what: format!("{}: {e}", netlist_path.display()),
        })?;
    let netlist = Netlist::read(sources)?;
    Ok(from_json(&json, &instance_modules(&netlist, top), top))
}

/// The constant bits of Yosys's flattened netlist of `top`: a net's bit is
/// proven when every instance of its module keeps the net with that bit
/// driven by the same constant.
fn from_json(
    json: &serde_json::Value,
    paths: &BTreeMap<String, String>,
    top: &str,
) -> ConstantBits {
    let mut per_instance: BTreeMap<(String, String), Vec<Vec<Option<bool>>>> = BTreeMap::new();
    let names = json["modules"][top]["netnames"].as_object();
    for (name, net) in names.into_iter().flatten() {
        if net["hide_name"].as_u64() == Some(1) {
            continue;
        }
        let (prefix, bare) = name.rsplit_once('.').unwrap_or(("", name));
        let Some(module) = paths.get(prefix) else {
            continue;
        };
        let bits: Vec<Option<bool>> = net["bits"]
            .as_array()
            .into_iter()
            .flatten()
            .map(|b| match b.as_str() {
                Some("0") => Some(false),
                Some("1") => Some(true),
                _ => None,
            })
            .collect();
        // Verilog's bit `offset + i` is the i-th of the list (reversed when
        // declared `[lo:hi]`), so index by the declared bit.
        let offset = net["offset"].as_u64().unwrap_or(0) as usize;
        let mut declared = vec![None; offset];
        match net["upto"].as_u64() == Some(1) {
            true => declared.extend(bits.into_iter().rev()),
            false => declared.extend(bits),
        }
        per_instance
            .entry((module.clone(), bare.to_string()))
            .or_default()
            .push(declared);
    }
    let mut instances: BTreeMap<String, u64> = BTreeMap::new();
    for m in paths.values() {
        *instances.entry(m.clone()).or_default() += 1;
    }
    let mut nets = BTreeMap::new();
    for ((module, net), seen) in per_instance {
        // A net Yosys removed in some instance proves nothing there.
        if seen.len() as u64 != instances.get(&module).copied().unwrap_or(0) {
            continue;
        }
        let width = seen.iter().map(Vec::len).max().unwrap_or(0);
        let bits: Vec<Option<bool>> = (0..width)
            .map(|i| {
                let v = seen[0].get(i).copied().flatten()?;
                seen.iter()
                    .all(|s| s.get(i).copied().flatten() == Some(v))
                    .then_some(v)
            })
            .collect();
        if bits.iter().any(Option::is_some) {
            nets.insert((module, net), bits);
        }
    }
    ConstantBits { nets, instances }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Yosys proves a tied output bit constant, with the sources and the
    /// work folder given relative to the current directory (as CI's
    /// `--out target/coverage` gives them).
    #[test]
    fn a_relative_work_folder_is_proven_in() {
        if crate::synth::tools::yosys().is_err() {
            assert!(!crate::tools::ci_mode(), "yosys missing");
            return;
        }
        let dir = tempfile::tempdir_in(".").expect("a folder here");
        let rel = dir
            .path()
            .strip_prefix(std::env::current_dir().unwrap())
            .expect("inside the current directory")
            .to_path_buf();
        let src = rel.join("tied.v");
        std::fs::write(
            &src,
            "module tied(input wire a, output wire [1:0] y);\n  assign y = {1'b0, a};\nendmodule\n",
        )
        .unwrap();
        let c = prove(&[src], "tied", &rel.join("constants")).expect("yosys proves");
        assert_eq!(c.value("tied", "y[1]"), Some(false));
        assert_eq!(c.value("tied", "y[0]"), None);
    }

    /// Two instances of `c`: its `k` is tied 1 in both, its `m` in one only;
    /// the top's `t[1]` is tied 0, `t[0]` is free, `s` is declared `[4:3]`.
    #[test]
    fn a_bit_is_constant_only_when_every_instance_ties_it() {
        let json = serde_json::json!({"modules": {"top": {"netnames": {
            "t": {"hide_name": 0, "bits": [5, "0"]},
            "s": {"hide_name": 0, "bits": ["1", 6], "offset": 3},
            "$auto$x": {"hide_name": 1, "bits": ["0"]},
            "u_a.k": {"hide_name": 0, "bits": ["1"]},
            "u_b.k": {"hide_name": 0, "bits": ["1"]},
            "u_a.m": {"hide_name": 0, "bits": ["0", "0"]},
            "u_b.m": {"hide_name": 0, "bits": ["0", 7]},
            "u_a.gone": {"hide_name": 0, "bits": ["0"]}
        }}}});
        let paths = BTreeMap::from([
            (String::new(), "top".to_string()),
            ("u_a".to_string(), "c".to_string()),
            ("u_b".to_string(), "c".to_string()),
        ]);
        let c = from_json(&json, &paths, "top");
        assert_eq!(c.value("top", "t[1]"), Some(false));
        assert_eq!(c.value("top", "t[0]"), None);
        assert_eq!(c.value("top", "s[3]"), Some(true));
        assert_eq!(c.value("top", "s[4]"), None);
        assert_eq!(c.value("c", "k"), Some(true));
        assert_eq!(c.value("c", "m[0]"), Some(false));
        assert_eq!(c.value("c", "m[1]"), None);
        assert_eq!(c.value("c", "gone"), None, "kept in one instance of two");
        assert_eq!(c.value("top", "t[1][0]"), None);
        assert_eq!(c.len(), 4);
        assert_eq!((c.max_count("c", true), c.max_count("c", false)), (2, 0));
    }
}
