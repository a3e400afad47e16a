//! The emitted Verilog as synthesis sees it: one module per file, the files
//! a top needs (itself and what it instantiates), and the digest that keys
//! the cache.

use crate::cache::CacheKey;
use crate::error::{io_err, CosimError, Result};
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Bumped when the flow changes what a cached figure means.
pub const FLOW_FORMAT: &str = "hiermerge-synth-1";

/// One emitted module: its name, its file and its Verilog text.
#[derive(Clone, Debug)]
pub struct Source {
    /// The module name (the file name without `.v`).
    pub module: String,
    /// The file it was read from.
    pub path: PathBuf,
    /// The whole text, comments included (they carry the generator lines).
    pub text: String,
}

/// Every module of one configuration, by name.
#[derive(Clone, Debug, Default)]
pub struct Netlist {
    /// The modules, by name.
    pub modules: BTreeMap<String, Source>,
}

impl Netlist {
    /// Reads emitted files (one module per file, named like the file).
    pub fn read(files: &[PathBuf]) -> Result<Netlist> {
        let mut modules = BTreeMap::new();
        for f in files
            .iter()
            .filter(|f| f.extension().is_some_and(|e| e == "v"))
        {
            let text = std::fs::read_to_string(f).map_err(io_err(f))?;
            let module = module_name(f)?;
            modules.insert(
                module.clone(),
                Source {
                    module,
                    path: f.clone(),
                    text,
                },
            );
        }
        Ok(Netlist { modules })
    }

    /// The instances of `module`'s text: (module instantiated, instance name).
    pub fn instances(&self, module: &str) -> Vec<(String, String)> {
        let Some(src) = self.modules.get(module) else {
            return Vec::new();
        };
        src.text
            .lines()
            .filter_map(|l| {
                let mut words = l.split_whitespace();
                let (m, i, paren) = (words.next()?, words.next()?, words.next()?);
                (paren == "(" && self.modules.contains_key(m)).then(|| (m.into(), i.into()))
            })
            .collect()
    }

    /// `top` and every module below it, in name order.
    pub fn closure(&self, top: &str) -> Vec<&Source> {
        let mut seen = BTreeSet::new();
        let mut todo = vec![top.to_string()];
        while let Some(m) = todo.pop() {
            if self.modules.contains_key(&m) && seen.insert(m.clone()) {
                todo.extend(self.instances(&m).into_iter().map(|(m, _)| m));
            }
        }
        seen.iter().map(|m| &self.modules[m]).collect()
    }

    /// SHA-256 over the files `top` needs (names and whole texts, comments
    /// included, since the critical path reads generator lines from them).
    pub fn digest(&self, top: &str) -> String {
        let mut key = CacheKey::new();
        key.add("format", FLOW_FORMAT.as_bytes());
        key.add("top", top.as_bytes());
        for s in self.closure(top) {
            key.add("module", s.module.as_bytes());
            key.add("text", s.text.as_bytes());
        }
        key.finish()
    }

    /// The files `top` needs.
    pub fn files(&self, top: &str) -> Vec<PathBuf> {
        self.closure(top).iter().map(|s| s.path.clone()).collect()
    }
}

fn module_name(f: &Path) -> Result<String> {
    f.file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .ok_or_else(|| CosimError::Design {
            what: format!("{}: not a Verilog file name", f.display()),
        })
}

/// A port of a module header: direction, name, width in bits.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct HeaderPort {
    /// True for an input.
    pub input: bool,
    /// The port name.
    pub name: String,
    /// Its width in bits.
    pub width: u32,
}

/// The ports of the module in `text` (the emitted `input wire [h:l] name,` form).
pub fn header_ports(text: &str) -> Vec<HeaderPort> {
    let mut ports = Vec::new();
    for line in text.lines() {
        let code = line.split("//").next().unwrap_or("").trim();
        if code.starts_with(");") {
            break;
        }
        let input = code.starts_with("input ");
        if !input && !code.starts_with("output ") {
            continue;
        }
        let code = code.trim_end_matches(',');
        let width = match (code.find('['), code.find(']')) {
            (Some(a), Some(b)) => {
                let range = &code[a + 1..b];
                let mut it = range
                    .split(':')
                    .map(|v| v.trim().parse::<i64>().unwrap_or(0));
                let (h, l) = (it.next().unwrap_or(0), it.next().unwrap_or(0));
                (h - l).unsigned_abs() as u32 + 1
            }
            _ => 1,
        };
        if let Some(name) = code.split_whitespace().last() {
            ports.push(HeaderPort {
                input,
                name: name.to_string(),
                width,
            });
        }
    }
    ports
}
