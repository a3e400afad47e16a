//! Verilog -> Verilated C++ -> shared library, through the build cache.
//!
//! Debian's Verilator 5.006 ships no prebuilt `libverilated.a`, so the runtime
//! sources the model needs (`VM_GLOBAL_FAST/SLOW` in `Vhm_classes.mk`:
//! verilated.cpp, verilated_threads.cpp, verilated_vcd_c.cpp, ...) are compiled
//! here with `-fPIC`, once per Verilator/flags combination (their own cache
//! entry), and linked with the model's `.cpp` files and the shim into one `.so`.

use super::header::{check_ports, parse_header_ports};
use super::shim::{generate_shim, MODEL_PREFIX, SHIM_VERSION};
use crate::cache::{get_or_build, CacheEntry, CacheKey};
use crate::design::Design;
use crate::error::{io_err, CosimError, Result};
use crate::tools::{verilator_facts, VerilatorFacts};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

/// File name of the built model inside its cache entry.
pub const LIBRARY_NAME: &str = "libhm_model.so";

/// The C++ optimization of the model's slow units (`VM_CLASSES_SLOW`,
/// `VM_SUPPORT_SLOW`).
const SLOW_OPT: &str = "-O0";

/// How to build a Verilated model.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct VerilatorOptions {
    /// Build with `--trace` so the engine can write VCDs (a separate cache entry).
    pub trace: bool,
    /// With `trace`: `--trace-fst`, the engine writes FST instead of VCD.
    pub fst: bool,
    /// Build with `--coverage-line --coverage-toggle` (a separate cache
    /// entry): the engine writes Verilator's `coverage.dat` (SPEC 10.5).
    pub coverage: bool,
    /// Extra Verilator flags (e.g. `-Wno-WIDTH`), part of the cache key.
    pub verilator_flags: Vec<String>,
    /// C++ optimization flag, e.g. `-O1`.
    pub cxx_opt: String,
    /// Parallel compiler processes.
    pub jobs: usize,
}

impl Default for VerilatorOptions {
    fn default() -> Self {
        VerilatorOptions {
            trace: false,
            fst: false,
            coverage: false,
            verilator_flags: Vec::new(),
            cxx_opt: "-O1".to_string(),
            jobs: default_jobs(),
        }
    }
}

fn default_jobs() -> usize {
    std::env::var("HIERMERGE_JOBS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| {
            std::thread::available_parallelism()
                .map(|n| n.get())
                .unwrap_or(1)
                .min(2)
        })
        .max(1)
}

/// Build (or find in the cache) the shared library for `design`.
pub fn build_model(
    design: &Design,
    options: &VerilatorOptions,
    cache_root: &Path,
) -> Result<CacheEntry> {
    design.validate()?;
    let facts = verilator_facts(&cache_root.join("tools"))?;
    let sources = design.read_sources()?;
    let mut key = CacheKey::new();
    key.add("shim_version", &SHIM_VERSION.to_le_bytes())
        .add("verilator", facts.version.as_bytes())
        .add("verilator_root", facts.root.to_string_lossy().as_bytes())
        .add("cxx", facts.cxx_version.as_bytes())
        .add("trace", &[options.trace as u8])
        .add("fst", &[options.fst as u8])
        .add("coverage", &[options.coverage as u8])
        .add("cxx_opt", options.cxx_opt.as_bytes())
        .add("slow_opt", SLOW_OPT.as_bytes())
        .add("top", design.top.as_bytes())
        .add("ports", format!("{:?}", design.ports).as_bytes());
    for f in &options.verilator_flags {
        key.add("flag", f.as_bytes());
    }
    for (path, bytes) in &sources {
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy())
            .unwrap_or_default();
        key.add("file_name", name.as_bytes()).add("file", bytes);
    }
    let mut label = match (options.trace, options.fst) {
        (true, true) => format!("{}-trace-fst", design.top),
        (true, false) => format!("{}-trace", design.top),
        _ => design.top.clone(),
    };
    if options.coverage {
        label.push_str("-cov");
    }
    get_or_build(cache_root, "verilator", &label, &key.finish(), |dir| {
        build_into(dir, design, options, &facts, cache_root)
    })
}

fn build_into(
    dir: &Path,
    design: &Design,
    options: &VerilatorOptions,
    facts: &VerilatorFacts,
    cache_root: &Path,
) -> Result<()> {
    let obj = dir.join("obj");
    run_verilator(dir, &obj, design, options)?;
    let header_path = obj.join(format!("{MODEL_PREFIX}.h"));
    let header = std::fs::read_to_string(&header_path).map_err(io_err(&header_path))?;
    check_ports(design, &parse_header_ports(&header))?;

    let classes_path = obj.join(format!("{MODEL_PREFIX}_classes.mk"));
    let classes =
        parse_make_vars(&std::fs::read_to_string(&classes_path).map_err(io_err(&classes_path))?);
    let mk_path = facts.root.join("include").join("verilated.mk");
    let mk = parse_make_vars(&std::fs::read_to_string(&mk_path).map_err(io_err(&mk_path))?);
    let flags = CxxFlags::new(facts, &classes, &mk);

    let runtime = build_runtime(
        &classes,
        &flags,
        &options.cxx_opt,
        facts,
        cache_root,
        options.jobs,
    )?;

    let shim_path = dir.join("hm_shim.cpp");
    std::fs::write(&shim_path, generate_shim(design)).map_err(io_err(&shim_path))?;
    let units_of = |vars: [&str; 2]| -> Vec<PathBuf> {
        vars.iter()
            .flat_map(|v| classes.get(*v).cloned().unwrap_or_default())
            .map(|name| obj.join(format!("{name}.cpp")))
            .collect()
    };
    let mut fast = units_of(["VM_CLASSES_FAST", "VM_SUPPORT_FAST"]);
    fast.push(shim_path);
    let slow = units_of(["VM_CLASSES_SLOW", "VM_SUPPORT_SLOW"]);
    // The slow units (constructors, reset, the first evaluation) run once
    // per model, yet are four tenths of the code: built without
    // optimization they cost the simulation nothing measurable and save a
    // quarter of the build (cosim/README.md).
    let fast_args = flags.compile_args(&obj, &options.cxx_opt);
    let slow_args = flags.compile_args(&obj, SLOW_OPT);
    let mut jobs: Vec<(PathBuf, &[String])> = Vec::new();
    for (name, list, args) in [("fast", &fast, &fast_args), ("slow", &slow, &slow_args)] {
        for group in group_units(list, &obj, name, options.jobs)? {
            jobs.push((group, args.as_slice()));
        }
    }
    let objects = compile_all(&jobs, &obj, options.jobs)?;

    let library = dir.join(LIBRARY_NAME);
    let mut link = Command::new("g++");
    link.arg("-shared")
        .arg("-o")
        .arg(&library)
        .args(&objects)
        .args(&runtime)
        .arg("-Wl,--no-undefined")
        .args(&flags.link_libs);
    run_logged(link, "g++", &dir.join("link.log"))?;
    for o in objects {
        let _ = std::fs::remove_file(o);
    }
    Ok(())
}

fn run_verilator(
    dir: &Path,
    obj: &Path,
    design: &Design,
    options: &VerilatorOptions,
) -> Result<()> {
    let mut cmd = Command::new("verilator");
    cmd.arg("--cc")
        .arg("-Mdir")
        .arg(obj)
        .arg("--prefix")
        .arg(MODEL_PREFIX)
        .arg("--top-module")
        .arg(&design.top);
    match (options.trace, options.fst) {
        (true, true) => {
            cmd.arg("--trace-fst");
        }
        (true, false) => {
            cmd.arg("--trace");
        }
        _ => {}
    }
    if options.coverage {
        cmd.args(crate::coverage::VERILATOR_FLAGS);
    }
    cmd.args(&options.verilator_flags);
    cmd.args(&design.verilog_files);
    run_logged(cmd, "verilator", &dir.join("verilator.log"))
}

/// Run `cmd`, writing its combined output to `log`; failure returns the log text.
fn run_logged(mut cmd: Command, tool: &str, log: &Path) -> Result<()> {
    let shown = format!("{cmd:?}");
    let out = cmd.output().map_err(|e| CosimError::ToolMissing {
        tool: tool.to_string(),
        hint: format!("{e}; {}", crate::tools::INSTALL_HINT),
    })?;
    let mut text = String::from_utf8_lossy(&out.stdout).into_owned();
    text.push_str(&String::from_utf8_lossy(&out.stderr));
    std::fs::write(log, &text).map_err(io_err(log))?;
    if !out.status.success() {
        return Err(CosimError::ToolFailed {
            tool: tool.to_string(),
            command: shown,
            log: text,
        });
    }
    Ok(())
}

/// `NAME = a b` / `NAME += \` continuation lines of a Makefile fragment.
fn parse_make_vars(text: &str) -> BTreeMap<String, Vec<String>> {
    let mut vars: BTreeMap<String, Vec<String>> = BTreeMap::new();
    let mut current: Option<String> = None;
    for raw in text.lines() {
        let line = raw.split('#').next().unwrap_or("");
        let (body, continues) = match line.trim_end().strip_suffix('\\') {
            Some(b) => (b, true),
            None => (line, false),
        };
        let words_part = if let Some(name) = current.clone() {
            Some((name, body))
        } else if let Some((lhs, rhs)) = body.split_once('=') {
            let name = lhs
                .trim()
                .trim_end_matches(['+', ':', '?'])
                .trim()
                .to_string();
            let plain =
                !name.is_empty() && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
            plain.then_some((name, rhs))
        } else {
            None
        };
        if let Some((name, words)) = words_part {
            vars.entry(name.clone())
                .or_default()
                .extend(words.split_whitespace().map(str::to_string));
            current = continues.then_some(name);
        } else {
            current = None;
        }
    }
    vars
}

struct CxxFlags {
    common: Vec<String>,
    link_libs: Vec<String>,
}

impl CxxFlags {
    fn new(
        facts: &VerilatorFacts,
        classes: &BTreeMap<String, Vec<String>>,
        mk: &BTreeMap<String, Vec<String>>,
    ) -> CxxFlags {
        let var = |m: &BTreeMap<String, Vec<String>>, n: &str, d: &str| {
            m.get(n)
                .and_then(|v| v.first().cloned())
                .unwrap_or_else(|| d.to_string())
        };
        let include = facts.root.join("include");
        let mut common = vec![
            "-fPIC".to_string(),
            "-fvisibility=hidden".to_string(),
            format!("-I{}", include.display()),
            format!("-I{}", include.join("vltstd").display()),
            format!("-DVM_COVERAGE={}", var(classes, "VM_COVERAGE", "0")),
            "-DVM_SC=0".to_string(),
            format!("-DVM_TRACE={}", var(classes, "VM_TRACE", "0")),
            format!("-DVM_TRACE_FST={}", var(classes, "VM_TRACE_FST", "0")),
            format!("-DVM_TRACE_VCD={}", var(classes, "VM_TRACE_VCD", "0")),
        ];
        common.extend(
            mk.get("CFG_CXXFLAGS_NO_UNUSED")
                .cloned()
                .unwrap_or_default(),
        );
        let std_flag = mk
            .get("CFG_CXXFLAGS_STD")
            .and_then(|v| v.first().cloned())
            .unwrap_or_else(|| "-std=gnu++17".to_string());
        common.push(std_flag);
        if var(classes, "VM_TIMING", "0") == "1" {
            common.extend(
                mk.get("CFG_CXXFLAGS_COROUTINES")
                    .cloned()
                    .unwrap_or_default(),
            );
        }
        let mut link_libs = mk
            .get("CFG_LDLIBS_THREADS")
            .cloned()
            .unwrap_or_else(|| vec!["-pthread".to_string()]);
        // The FST writer compresses with zlib.
        if var(classes, "VM_TRACE_FST", "0") == "1" {
            link_libs.push("-lz".to_string());
        }
        CxxFlags { common, link_libs }
    }

    fn runtime_args(&self, opt: &str) -> Vec<String> {
        let mut a = vec![opt.to_string()];
        a.extend(self.common.iter().cloned());
        a
    }

    fn compile_args(&self, model_dir: &Path, opt: &str) -> Vec<String> {
        let mut a = self.runtime_args(opt);
        a.push(format!("-I{}", model_dir.display()));
        a
    }
}

/// The runtime objects (`VM_GLOBAL_*`), compiled once per flags/version.
fn build_runtime(
    classes: &BTreeMap<String, Vec<String>>,
    flags: &CxxFlags,
    opt: &str,
    facts: &VerilatorFacts,
    cache_root: &Path,
    jobs: usize,
) -> Result<Vec<PathBuf>> {
    let names: Vec<String> = ["VM_GLOBAL_FAST", "VM_GLOBAL_SLOW"]
        .iter()
        .flat_map(|v| classes.get(*v).cloned().unwrap_or_default())
        .collect();
    let mut key = CacheKey::new();
    key.add("verilator", facts.version.as_bytes())
        .add("root", facts.root.to_string_lossy().as_bytes())
        .add("cxx", facts.cxx_version.as_bytes());
    let args = flags.runtime_args(opt);
    for f in &args {
        key.add("flag", f.as_bytes());
    }
    for n in &names {
        key.add("unit", n.as_bytes());
    }
    let include = facts.root.join("include");
    let entry = get_or_build(
        cache_root,
        "verilator-runtime",
        "rt",
        &key.finish(),
        |dir| {
            let units: Vec<(PathBuf, &[String])> = names
                .iter()
                .map(|n| (include.join(format!("{n}.cpp")), args.as_slice()))
                .collect();
            compile_all(&units, dir, jobs).map(|_| ())
        },
    )?;
    Ok(names
        .iter()
        .map(|n| entry.dir.join(format!("{n}.o")))
        .collect())
}

/// Bundle the model's `.cpp` files into `jobs` translation units
/// (`hm_<tag>_<k>.cpp`, each `#include`-ing its share), as Verilator's own
/// non-parallel build does: every file re-parses the heavy Verilator headers,
/// so for small designs a few bundles compile several times faster.
fn group_units(units: &[PathBuf], dir: &Path, tag: &str, jobs: usize) -> Result<Vec<PathBuf>> {
    if units.is_empty() {
        return Ok(Vec::new());
    }
    let n = jobs.clamp(1, units.len());
    let mut texts = vec![String::from("// Generated by hiermerge cosim: bundled units.\n"); n];
    for (i, unit) in units.iter().enumerate() {
        texts[i % n].push_str(&format!("#include \"{}\"\n", unit.display()));
    }
    texts
        .into_iter()
        .enumerate()
        .map(|(k, text)| {
            let path = dir.join(format!("hm_{tag}_{k}.cpp"));
            std::fs::write(&path, text).map_err(io_err(&path))?;
            Ok(path)
        })
        .collect()
}

/// Compile each unit to `<out_dir>/<stem>.o`, at most `jobs` at a time.
fn compile_all(
    units: &[(PathBuf, &[String])],
    out_dir: &Path,
    jobs: usize,
) -> Result<Vec<PathBuf>> {
    let mut objects = Vec::new();
    let mut pending: Vec<(PathBuf, std::process::Child, PathBuf, String)> = Vec::new();
    let mut queue: Vec<(&PathBuf, &[String])> = units.iter().rev().map(|(u, a)| (u, *a)).collect();
    let mut first_error: Option<CosimError> = None;
    while !queue.is_empty() || !pending.is_empty() {
        while pending.len() < jobs.max(1) && first_error.is_none() {
            let Some((unit, args)) = queue.pop() else {
                break;
            };
            let stem = unit
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default();
            let object = out_dir.join(format!("{stem}.o"));
            let log = out_dir.join(format!("{stem}.log"));
            let log_file = std::fs::File::create(&log).map_err(io_err(&log))?;
            let err_file = log_file.try_clone().map_err(io_err(&log))?;
            let child = Command::new("g++")
                .args(args)
                .arg("-c")
                .arg(unit)
                .arg("-o")
                .arg(&object)
                .stdout(log_file)
                .stderr(err_file)
                .spawn()
                .map_err(|e| CosimError::ToolMissing {
                    tool: "g++".to_string(),
                    hint: format!("{e}; install with `apt-get install g++`"),
                })?;
            let shown = format!("g++ {} -c ... -o {}", args.join(" "), object.display());
            pending.push((object, child, log, shown));
        }
        if pending.is_empty() {
            break;
        }
        let (object, mut child, log, shown) = pending.remove(0);
        let status = child.wait().map_err(io_err(&object))?;
        if status.success() {
            objects.push(object);
        } else if first_error.is_none() {
            first_error = Some(CosimError::ToolFailed {
                tool: "g++".to_string(),
                command: shown,
                log: std::fs::read_to_string(&log).unwrap_or_default(),
            });
        }
    }
    match first_error {
        Some(e) => Err(e),
        None => Ok(objects),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn make_vars_with_continuations() {
        let text = "VM_TRACE = 1\nVM_CLASSES_FAST += \\\n\tVhm \\\n\tVhm_x \\\n\nVM_GLOBAL_FAST += \\\n\tverilated \\\n\n";
        let v = parse_make_vars(text);
        assert_eq!(v["VM_TRACE"], vec!["1"]);
        assert_eq!(v["VM_CLASSES_FAST"], vec!["Vhm", "Vhm_x"]);
        assert_eq!(v["VM_GLOBAL_FAST"], vec!["verilated"]);
    }
}
