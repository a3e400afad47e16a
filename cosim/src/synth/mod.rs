//! Area and timing of emitted modules (issue 17, SPEC 14): a generic
//! gate-level flow in Yosys, ECP5 and iCE40 place and route in nextpnr, the
//! critical path mapped back onto the generator lines of the emitted nets,
//! every result cached by the digest of the Verilog it came from.

pub mod compose;
pub mod ecp5;
pub mod generic;
pub mod ice40;
pub mod path;
pub mod record;
pub mod run;
pub mod sources;
pub mod stat;
pub mod tools;

use crate::error::{io_err, CosimError, Result};
use serde::{Deserialize, Serialize};
use sources::Netlist;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// A flow target.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Target {
    /// Yosys `synth` + `abc` onto generic gates.
    Generic,
    /// Lattice ECP5 LFE5U-85F, speed grade 8.
    Ecp5,
    /// Lattice iCE40 HX8K.
    Ice40,
}

/// Min, median and max of a measurement over seeds.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Spread {
    /// Lowest.
    pub min: f64,
    /// Median (the mean of the middle two for an even count).
    pub median: f64,
    /// Highest.
    pub max: f64,
}

impl Spread {
    /// The spread of `v` (all zero when empty).
    pub fn of(mut v: Vec<f64>) -> Spread {
        if v.is_empty() {
            return Spread {
                min: 0.0,
                median: 0.0,
                max: 0.0,
            };
        }
        v.sort_by(f64::total_cmp);
        let n = v.len();
        let median = if n % 2 == 1 {
            v[n / 2]
        } else {
            (v[n / 2 - 1] + v[n / 2]) / 2.0
        };
        Spread {
            min: v[0],
            median,
            max: v[n - 1],
        }
    }
}

/// The tools, the cache and the limits of one synthesis run.
pub struct Flow {
    /// Where results are cached (`<cache root>/synth-*`).
    pub cache_root: PathBuf,
    /// The time limit of each tool run.
    pub timeout: Duration,
    /// The clock goal given to nextpnr (`--freq`), MHz.
    pub freq_mhz: f64,
    /// Yosys.
    pub yosys: tools::Tool,
    /// nextpnr-ecp5, when the ECP5 target runs.
    pub ecp5: Option<tools::Tool>,
    /// nextpnr-ice40, when the iCE40 target runs.
    pub ice40: Option<tools::Tool>,
    /// Progress lines (stderr in the CLI).
    pub progress: Box<dyn Fn(&str) + Sync>,
}

impl Flow {
    /// Finds the tools `targets` need; a missing one is `ToolMissing`.
    pub fn new(
        targets: &[Target],
        cache_root: PathBuf,
        timeout: Duration,
        freq_mhz: f64,
    ) -> Result<Flow> {
        let yosys = tools::yosys()?;
        let ecp5 = targets
            .contains(&Target::Ecp5)
            .then(tools::nextpnr_ecp5)
            .transpose()?;
        let ice40 = targets
            .contains(&Target::Ice40)
            .then(tools::nextpnr_ice40)
            .transpose()?;
        Ok(Flow {
            cache_root,
            timeout,
            freq_mhz,
            yosys,
            ecp5,
            ice40,
            progress: Box::new(|_| {}),
        })
    }

    fn tool_ecp5(&self) -> Result<&tools::Tool> {
        self.ecp5.as_ref().ok_or_else(|| CosimError::ToolMissing {
            tool: "nextpnr-ecp5".into(),
            hint: tools::SYNTH_INSTALL_HINT.into(),
        })
    }

    fn tool_ice40(&self) -> Result<&tools::Tool> {
        self.ice40.as_ref().ok_or_else(|| CosimError::ToolMissing {
            tool: "nextpnr-ice40".into(),
            hint: tools::SYNTH_INSTALL_HINT.into(),
        })
    }

    /// Runs Yosys command `synth` on `top`'s files in `dir` (script
    /// `<name>.ys`) and returns the cell counts of its `stat`.
    fn synth_cells(
        &self,
        reads: &str,
        top: &str,
        dir: &Path,
        name: &str,
        synth: &str,
    ) -> Result<std::collections::BTreeMap<String, u64>> {
        (self.progress)(&format!("{top}: {name}: yosys {synth}"));
        let script = format!("{reads}{synth}\ntee -q -o stat.txt stat\n");
        let ys = dir.join(format!("{name}.ys"));
        std::fs::write(&ys, script).map_err(io_err(&ys))?;
        self.yosys_script(dir, &format!("{name}.ys"), "yosys.log")?;
        let path = dir.join("stat.txt");
        let text = std::fs::read_to_string(&path).map_err(io_err(&path))?;
        Ok(stat::cell_counts(&text))
    }

    /// The cache key of an FPGA synthesis of the module tree `digest`: the
    /// tree and the Yosys that synthesizes it.
    fn synth_key(&self, digest: &str) -> String {
        let mut key = crate::cache::CacheKey::new();
        key.add("digest", digest.as_bytes())
            .add("yosys", self.yosys.version.as_bytes());
        key.finish()
    }

    /// The cached result of the Yosys synthesis `kind` of `top` (tree
    /// digest `digest`): `build` fills a fresh entry with `figures.json`
    /// (read back as `T`) when there is none.
    fn synthesized<T: for<'de> Deserialize<'de>>(
        &self,
        kind: &str,
        top: &str,
        digest: &str,
        build: impl FnOnce(&Path) -> Result<()>,
    ) -> Result<(T, crate::cache::CacheEntry)> {
        let key = self.synth_key(digest);
        let entry = crate::cache::get_or_build(&self.cache_root, kind, top, &key, |d| {
            build(d)?;
            write_meta(d, top, digest, &self.yosys.version)
        })?;
        let figures = read_json(&entry.dir.join("figures.json"))?;
        Ok((figures, entry))
    }

    /// The cache key of one place-and-route run of the synthesis `synth_key`.
    fn pnr_key(&self, synth_key: &str, tool: &tools::Tool, device: &[&str], seed: u64) -> String {
        let mut key = crate::cache::CacheKey::new();
        key.add("synth", synth_key.as_bytes())
            .add("nextpnr", tool.version.as_bytes())
            .add("device", device.join(" ").as_bytes())
            .add("freq", self.freq_mhz.to_string().as_bytes())
            .add("seed", &seed.to_le_bytes());
        key.finish()
    }

    /// The tool versions, as one line.
    pub fn tools_line(&self) -> String {
        let mut line = self.yosys.version.clone();
        for t in [&self.ecp5, &self.ice40].into_iter().flatten() {
            line += "; ";
            line += &t.version;
        }
        line
    }

    fn recorded<T>(&self, top: &str, digest: &str, seeds: u64, figures: T) -> record::Recorded<T> {
        record::Recorded {
            module: top.to_string(),
            digest: digest.to_string(),
            tools: self.tools_line(),
            seeds,
            goal_mhz: self.freq_mhz,
            figures,
        }
    }

    /// Records `target`'s figures of `r` for cache-only lookups (`record`).
    fn record(
        &self,
        top: &str,
        digest: &str,
        target: Target,
        seeds: u64,
        r: &ModuleReport,
    ) -> Result<()> {
        let root = &self.cache_root;
        match target {
            Target::Generic => r
                .generic
                .as_ref()
                .map(|f| record::store(root, target, &self.recorded(top, digest, seeds, f))),
            Target::Ecp5 => r
                .ecp5
                .as_ref()
                .map(|f| record::store(root, target, &self.recorded(top, digest, seeds, f))),
            Target::Ice40 => r
                .ice40
                .as_ref()
                .map(|f| record::store(root, target, &self.recorded(top, digest, seeds, f))),
        }
        .unwrap_or(Ok(()))
    }

    /// Runs the Yosys script `script` in `dir`.
    fn yosys_script(&self, dir: &Path, script: &str, log: &str) -> Result<()> {
        let args = vec!["-q".to_string(), "-s".to_string(), script.to_string()];
        run::run_logged(&self.yosys.program, &args, dir, log, self.timeout)
    }
}

pub(crate) fn write_json<T: Serialize>(path: &Path, value: &T) -> Result<()> {
    let text = serde_json::to_string_pretty(value).map_err(|e| CosimError::Protocol {
        what: format!("serializing {}: {e}", path.display()),
    })?;
    std::fs::write(path, text).map_err(io_err(path))
}

/// What a cache entry was made from, for lookups that run no tool
/// (`lookup`): the module, its digest and the tool versions.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct EntryMeta {
    /// The module synthesized.
    pub module: String,
    /// Its `Netlist::digest`.
    pub digest: String,
    /// The tools (and for place and route, the goal) that made it.
    pub tools: String,
}

pub(crate) fn write_meta(dir: &Path, top: &str, digest: &str, tools: &str) -> Result<()> {
    let meta = EntryMeta {
        module: top.to_string(),
        digest: digest.to_string(),
        tools: tools.to_string(),
    };
    write_json(&dir.join("meta.json"), &meta)
}

pub(crate) fn read_json<T: for<'de> Deserialize<'de>>(path: &Path) -> Result<T> {
    let text = std::fs::read_to_string(path).map_err(io_err(path))?;
    serde_json::from_str(&text).map_err(|e| CosimError::Parse {
        text: path.display().to_string(),
        what: format!("a cached synthesis result: {e}"),
    })
}

/// Every figure of one module.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct ModuleReport {
    /// The module (the top synthesized).
    pub module: String,
    /// SHA-256 of the Verilog files it needs (the cache key's base).
    pub digest: String,
    /// Those files' names.
    pub files: Vec<String>,
    /// Generic figures.
    pub generic: Option<generic::GenericFigures>,
    /// ECP5 figures.
    pub ecp5: Option<ecp5::Ecp5Figures>,
    /// iCE40 figures.
    pub ice40: Option<ice40::Ice40Figures>,
    /// What this run computed rather than read from the cache.
    pub computed: Vec<String>,
    /// For a composed module (SPEC 14.6), the parts its figures add up;
    /// its generic depth is then the deepest of its parts and its own logic.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub composed_of: Vec<compose::Part>,
}

fn one_job(
    flow: &Flow,
    netlist: &Netlist,
    top: &str,
    digest: &str,
    target: Target,
    seeds: u64,
    r: &mut ModuleReport,
) -> Result<()> {
    // The Flow holds nextpnr-ecp5 exactly when the run has the ECP5 target.
    let with_ecp5 = flow.ecp5.is_some();
    if compose::is_composed(top) {
        match target {
            Target::Generic => {
                let (g, made) = compose::generic(flow, netlist, top, digest)?;
                r.generic = Some(g);
                r.computed.extend(made);
            }
            Target::Ecp5 => {
                let (e, made) = compose::ecp5(flow, netlist, top, digest)?;
                r.ecp5 = Some(e);
                r.computed.extend(made);
            }
            Target::Ice40 => {
                let ecp5 = if with_ecp5 {
                    let (e, made) = compose::ecp5_synth(flow, netlist, top, digest)?;
                    r.computed.extend(made);
                    Some(e)
                } else {
                    None
                };
                let (i, made) = compose::ice40(flow, netlist, top, digest, ecp5.as_ref())?;
                r.ice40 = Some(i);
                r.computed.extend(made);
            }
        }
        return Ok(());
    }
    match target {
        Target::Generic => {
            let (g, built) = generic::generic(flow, netlist, top, digest)?;
            r.generic = Some(g);
            if built {
                r.computed.push("generic".into());
            }
        }
        Target::Ecp5 => {
            let (e, made) = ecp5::ecp5(flow, netlist, top, digest, seeds)?;
            r.ecp5 = Some(e);
            r.computed.extend(made);
        }
        Target::Ice40 => {
            // With the ECP5 target in the run, its mapping (cached, or being
            // made by another job: the cache lock waits for it) may already
            // rule out an HX8K, and then synth_ice40 is not run.
            let ecp5 = if with_ecp5 {
                let (e, entry) = ecp5::synthesis(flow, netlist, top, digest)?;
                if entry.built {
                    r.computed.push("ecp5 synth".into());
                }
                Some(e)
            } else {
                None
            };
            let (i, made) = ice40::ice40(flow, netlist, top, digest, seeds, ecp5.as_ref())?;
            r.ice40 = Some(i);
            r.computed.extend(made);
        }
    }
    Ok(())
}

/// Synthesizes every module of `tops` for every target, `jobs` at a time,
/// biggest first; stops at the first error, naming module and target.
pub fn run_all(
    flow: &Flow,
    netlist: &Netlist,
    tops: &[String],
    targets: &[Target],
    seeds: u64,
    jobs: usize,
) -> Result<Vec<ModuleReport>> {
    let reports: Vec<Mutex<ModuleReport>> = tops
        .iter()
        .map(|t| {
            Mutex::new(ModuleReport {
                module: t.clone(),
                digest: netlist.digest(t),
                files: netlist
                    .closure(t)
                    .iter()
                    .map(|s| format!("{}.v", s.module))
                    .collect(),
                generic: None,
                ecp5: None,
                ice40: None,
                computed: Vec::new(),
                composed_of: if compose::is_composed(t) {
                    compose::parts(netlist, t)
                } else {
                    Vec::new()
                },
            })
        })
        .collect();
    let size = |i: usize| {
        netlist
            .closure(&tops[i])
            .iter()
            .map(|s| s.text.len())
            .sum::<usize>()
    };
    let mut work: Vec<(usize, Target)> = (0..tops.len())
        .flat_map(|i| targets.iter().map(move |t| (i, *t)))
        .collect();
    // Biggest first, every iCE40 job after the others: it reads the same
    // module's ECP5 mapping, which is then made or being made.
    // Composed modules after their parts.
    work.sort_by_key(|(i, t)| {
        (
            *t == Target::Ice40,
            compose::is_composed(&tops[*i]),
            std::cmp::Reverse(size(*i)),
        )
    });
    let next = AtomicUsize::new(0);
    let done = AtomicUsize::new(0);
    let failed: Mutex<Option<CosimError>> = Mutex::new(None);
    let start = Instant::now();
    std::thread::scope(|s| {
        for _ in 0..jobs.max(1).min(work.len().max(1)) {
            s.spawn(|| loop {
                let k = next.fetch_add(1, Ordering::SeqCst);
                if k >= work.len() || failed.lock().map(|f| f.is_some()).unwrap_or(true) {
                    return;
                }
                let (i, target) = work[k];
                let (top, t0) = (&tops[i], Instant::now());
                let digest = reports[i]
                    .lock()
                    .map(|r| r.digest.clone())
                    .unwrap_or_default();
                let mut part = reports[i].lock().map(|r| r.clone()).expect("report lock");
                part.computed.clear();
                match one_job(flow, netlist, top, &digest, target, seeds, &mut part) {
                    Ok(()) => {
                        let n = done.fetch_add(1, Ordering::SeqCst) + 1;
                        let how = if part.computed.is_empty() {
                            "cached"
                        } else {
                            "done"
                        };
                        (flow.progress)(&format!(
                            "[{n}/{}] {top} {target:?}: {how} in {:.1} s ({:.0} s so far)",
                            work.len(),
                            t0.elapsed().as_secs_f64(),
                            start.elapsed().as_secs_f64()
                        ));
                        if let Err(e) = flow.record(top, &digest, target, seeds, &part) {
                            if let Ok(mut f) = failed.lock() {
                                f.get_or_insert(e);
                            }
                        }
                        let mut r = reports[i].lock().expect("report lock");
                        match target {
                            Target::Generic => r.generic = part.generic,
                            Target::Ecp5 => r.ecp5 = part.ecp5,
                            Target::Ice40 => r.ice40 = part.ice40,
                        }
                        r.computed.extend(part.computed);
                    }
                    Err(e) => {
                        let e = CosimError::Design {
                            what: format!("synthesis of `{top}` for {target:?} failed: {e}"),
                        };
                        if let Ok(mut f) = failed.lock() {
                            f.get_or_insert(e);
                        }
                    }
                }
            });
        }
    });
    if let Some(e) = failed.into_inner().ok().flatten() {
        return Err(e);
    }
    Ok(reports
        .into_iter()
        .filter_map(|m| m.into_inner().ok())
        .collect())
}
