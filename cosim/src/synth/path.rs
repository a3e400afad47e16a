//! The critical path of a nextpnr timing report as a chain of emitted nets,
//! each with the generator line its declaration's comment carries
//! (`// rtl-gen/src/translate/apply.rs:84`).

use super::sources::Netlist;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// One net on the critical path.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct PathStep {
    /// The net as nextpnr names it (after synthesis).
    pub net: String,
    /// The emitted net it comes from (`u_inst.name` below the top), when known.
    pub emitted: Option<String>,
    /// The generator line of that net's declaration, when known.
    pub source: Option<String>,
    /// Routing delay of this net plus the logic delay of the cell it drives, ns.
    pub delay_ns: f64,
}

/// The worst path of one clock domain.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct CriticalPath {
    /// Its start point (`cell.port`).
    pub from: String,
    /// Its end point (`cell.port`).
    pub to: String,
    /// Total delay, ns.
    pub delay_ns: f64,
    /// Logic cells on it.
    pub logic_levels: u64,
    /// Its nets, in order.
    pub steps: Vec<PathStep>,
    /// The distinct generator lines along it, in path order.
    pub sources: Vec<String>,
}

/// Declaration lines of one module: net name to generator line.
#[derive(Default)]
struct ModuleIndex {
    nets: BTreeMap<String, String>,
    instances: BTreeMap<String, String>,
}

/// Finds the emitted net and generator line of a synthesized net name.
pub struct SourceIndex {
    top: String,
    modules: BTreeMap<String, ModuleIndex>,
}

/// `// path.rs:N` at the end of a line, if any.
pub fn comment_location(line: &str) -> Option<String> {
    let comment = line.split_once("//")?.1.trim();
    let loc = comment.split_whitespace().find(|w| w.contains(".rs:"))?;
    Some(loc.trim_end_matches([',', ';', ')']).to_string())
}

fn declared_name(code: &str) -> Option<&str> {
    let code = code.trim();
    let rest = [
        "wire ",
        "reg ",
        "input  wire ",
        "output wire ",
        "input wire ",
        "output reg ",
    ]
    .iter()
    .find_map(|k| code.strip_prefix(k))?;
    let name = rest
        .trim_end_matches([';', ','])
        .split_whitespace()
        .find(|w| !w.starts_with('[') && !w.ends_with(']') && *w != "signed")?;
    Some(name.trim_end_matches([';', ',']))
}

impl SourceIndex {
    /// Indexes every declaration and instance of `netlist`, for top `top`.
    pub fn new(netlist: &Netlist, top: &str) -> SourceIndex {
        let mut modules = BTreeMap::new();
        for (name, src) in &netlist.modules {
            let mut m = ModuleIndex::default();
            for line in src.text.lines() {
                let code = line.split("//").next().unwrap_or("");
                if let (Some(n), Some(loc)) = (declared_name(code), comment_location(line)) {
                    m.nets.insert(n.to_string(), loc);
                }
            }
            m.instances = netlist
                .instances(name)
                .into_iter()
                .map(|(module, inst)| (inst, module))
                .collect();
            modules.insert(name.clone(), m);
        }
        SourceIndex {
            top: top.to_string(),
            modules,
        }
    }

    /// The same index seen from a wrapper module `wrapper` that holds the
    /// top as instance `inst`.
    pub fn below(mut self, wrapper: &str, inst: &str) -> SourceIndex {
        let mut m = ModuleIndex::default();
        m.instances.insert(inst.to_string(), self.top.clone());
        self.modules.insert(wrapper.to_string(), m);
        self.top = wrapper.to_string();
        self
    }

    /// The generator line of net `net` declared in module `module` (the
    /// name as emitted, a bit or word select allowed: `h_rec[3]`).
    pub fn declared_in(&self, module: &str, net: &str) -> Option<&str> {
        let bare = net.split('[').next().unwrap_or(net);
        self.modules.get(module)?.nets.get(bare).map(String::as_str)
    }

    /// (emitted net, generator line) for a synthesized net name such as
    /// `u_network.sel_q[3]` or Yosys's derived `apply_s1_data_shl_2_LUT4_Z_5_A`.
    pub fn locate(&self, net: &str) -> Option<(String, String)> {
        let bare = net
            .split('[')
            .next()
            .unwrap_or(net)
            .trim_start_matches('\\');
        if bare.starts_with('$') {
            return None;
        }
        let mut module = self.modules.get(&self.top)?;
        let mut prefix = String::new();
        let mut parts: Vec<&str> = bare.split('.').collect();
        let leaf = parts.pop()?;
        for inst in parts {
            let m = module.instances.get(inst)?;
            module = self.modules.get(m)?;
            prefix.push_str(inst);
            prefix.push('.');
        }
        // The longest declared name that is the net's name or a `_` prefix of it.
        let mut cut = leaf.len();
        loop {
            let cand = &leaf[..cut];
            if let Some(loc) = module.nets.get(cand) {
                return Some((format!("{prefix}{cand}"), loc.clone()));
            }
            cut = cand.rfind('_')?;
        }
    }
}

fn endpoint(v: &serde_json::Value) -> String {
    format!(
        "{}.{}",
        v["cell"].as_str().unwrap_or("?"),
        v["port"].as_str().unwrap_or("?")
    )
}

/// The critical path of clock `clock` (else the first) in a nextpnr
/// `--report` JSON, mapped onto the emitted nets.
pub fn critical_path(
    report: &serde_json::Value,
    clock: &str,
    index: &SourceIndex,
) -> Option<CriticalPath> {
    let paths = report["critical_paths"].as_array()?;
    let want = format!("posedge {clock}");
    let cp = paths
        .iter()
        .find(|p| p["from"].as_str() == Some(&want) && p["to"].as_str() == Some(&want))
        .or_else(|| paths.first())?;
    let items = cp["path"].as_array()?;
    let mut steps: Vec<PathStep> = Vec::new();
    let (mut total, mut levels) = (0.0, 0);
    for it in items {
        let delay = it["delay"].as_f64().unwrap_or(0.0);
        total += delay;
        match it["type"].as_str() {
            Some("routing") => {
                let net = it["net"].as_str().unwrap_or("?").to_string();
                let found = index.locate(&net);
                steps.push(PathStep {
                    emitted: found.as_ref().map(|f| f.0.clone()),
                    source: found.map(|f| f.1),
                    net,
                    delay_ns: delay,
                });
            }
            Some("logic") => {
                levels += 1;
                if let Some(last) = steps.last_mut() {
                    last.delay_ns += delay;
                }
            }
            _ => {}
        }
    }
    let mut sources: Vec<String> = Vec::new();
    for s in steps.iter().filter_map(|s| s.source.clone()) {
        if sources.last() != Some(&s) {
            sources.push(s);
        }
    }
    Some(CriticalPath {
        from: items
            .first()
            .map(|i| endpoint(&i["from"]))
            .unwrap_or_default(),
        to: items.last().map(|i| endpoint(&i["to"])).unwrap_or_default(),
        delay_ns: total,
        logic_levels: levels,
        steps,
        sources,
    })
}

/// Achieved Fmax in MHz of clock `clock` (else the first) in a nextpnr report.
pub fn fmax_mhz(report: &serde_json::Value, clock: &str) -> Option<f64> {
    let fmax = report["fmax"].as_object()?;
    let entry = fmax.get(clock).or_else(|| fmax.values().next())?;
    entry["achieved"].as_f64()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::sources::Source;

    #[test]
    fn locates_derived_and_hierarchical_names() {
        let mut n = Netlist::default();
        let top = "module t (\n);\n    wire [3:0] a_shl_2; // g/top.rs:5\n    sub u_s ( // g/top.rs:9\n    );\nendmodule\n";
        let sub = "module sub (\n);\n    reg q; // g/sub.rs:7\nendmodule\n";
        for (m, text) in [("t", top), ("sub", sub)] {
            n.modules.insert(
                m.into(),
                Source {
                    module: m.into(),
                    path: format!("{m}.v").into(),
                    text: text.into(),
                },
            );
        }
        let ix = SourceIndex::new(&n, "t");
        assert_eq!(
            ix.locate("a_shl_2_LUT4_Z_5_A[1]"),
            Some(("a_shl_2".into(), "g/top.rs:5".into()))
        );
        assert_eq!(
            ix.locate("u_s.q"),
            Some(("u_s.q".into(), "g/sub.rs:7".into()))
        );
        assert_eq!(ix.locate("$abc$12$n3"), None);
    }
}
