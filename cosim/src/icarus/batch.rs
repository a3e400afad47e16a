//! Icarus batch mode: a whole stream bench inside one `vvp` run.
//!
//! The pipe engine (`super::IcarusEngine`) pays one round trip per clock
//! (~15-22 k cycles/s); here the generated testbench
//! (`super::batch_testbench`) drives the input beats from a file and the
//! valid gaps and ready back-pressure from per-cycle stall masks that Rust
//! draws from the seeded `tb::Prng` (the driver's and the monitor's streams,
//! `Prng::derived(seed, 1 + 2 * lane)` and `(seed, 2 + 2 * lane)`, a bit
//! per cycle: go with probability `1 - stall`) and streams through a named
//! pipe ahead of vvp; while `valid` is low the payload shows a random value (from
//! a pool drawn from `Prng::derived(seed, 1000 + lane)`, a new one after
//! each beat the lane delivers: held, not redrawn every cycle, because a
//! changing input makes vvp re-evaluate the design's whole input cone).
//! The testbench checks every output for X/Z after reset (4-state, as the
//! pipe engine does), runs the watchdog and the drain, and records every
//! output transfer (lane, cycle, data) to a file. Rust then feeds the transfers in order to the
//! usual `tb::Scoreboard` (with its `Accounting`) and builds a
//! `tb::BenchReport`, so a mismatch is decoded exactly as in a pipe run.
//!
//! A run is one or more *lanes* (an input stream and the output stream its
//! results leave on). The input beats form one sequence across the lanes:
//! one beat is offered at a time, on its own lane, so the order of the
//! vectors is the order the design sees them. A beat marked
//! `wait_for_earlier_outputs` is offered only once every output expected
//! from the earlier beats has been accepted (by an earlier cycle), which is
//! how a testbench keeps runs apart (the translation unit's table writes).
//! Each lane's outputs are compared in order with that lane's expected
//! outputs.
//!
//! With one lane and no waits a run follows `tb::run_stream_bench` step for
//! step (same cycle order, reset, watchdog, drain, counts); the stall
//! pattern differs from a pipe run with the same seed (a bit per cycle
//! here, a draw per opportunity there) but has the same law. Unlike the
//! pipe bench it does not stop at the first mismatch (the testbench cannot
//! know): it runs to the end and counts every mismatch.

use super::batch_testbench::{
    generate_batch_testbench, meta_file, payload_file, pool_file, BatchTbSpec, LanePorts,
    BATCH_TB_MODULE, GARBAGE_POOL, STIM_CHUNK,
};
use crate::bitvec::BitVec;
use crate::design::{Design, PortId};
use crate::error::{io_err, CosimError, Result};
use crate::tb::{
    AccountingReport, BenchConfig, BenchReport, FieldDecoder, Hang, Mismatch, Prng, Scoreboard,
    StreamNames, Transaction, Vector,
};
use crate::tools::INSTALL_HINT;
use std::fs;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, ExitStatus, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Engine name in batch reports.
pub const BATCH_ENGINE_NAME: &str = "iverilog-batch";

/// How long one `vvp` run may take before it is killed and reported hung.
pub const DEFAULT_RUN_TIMEOUT: Duration = Duration::from_secs(3600);

/// What a batch simulator is built for: its lanes, the outputs whose every
/// change is logged, and inputs held constant.
#[derive(Clone, Debug, Default)]
pub struct BatchSpec {
    /// The lanes, numbered from 0 in this order.
    pub lanes: Vec<StreamNames>,
    /// Outputs whose changes are logged (see `WatchLog`).
    pub watch: Vec<String>,
    /// Inputs that are not part of a lane, held at a value for the whole run
    /// (every other such input is 0).
    pub constants: Vec<(String, BitVec)>,
}

impl BatchSpec {
    /// One lane and nothing else: the shape of `tb::run_stream_bench`.
    pub fn single(names: &StreamNames) -> BatchSpec {
        BatchSpec {
            lanes: vec![names.clone()],
            ..BatchSpec::default()
        }
    }
}

/// One input beat of a batch run and the outputs it must produce on its lane.
#[derive(Clone, Debug)]
pub struct LaneVector {
    /// Lane number (index in `BatchSpec::lanes`).
    pub lane: usize,
    /// Offer this beat only once every output of the earlier beats has arrived.
    pub wait_for_earlier_outputs: bool,
    /// The input payload and its expected outputs.
    pub vector: Vector,
}

/// Every change of the watched outputs: `(cycle, values in watch order)`,
/// the first entry at the first cycle after reset.
#[derive(Clone, Debug, Default)]
pub struct WatchLog {
    /// Watched port names.
    pub ports: Vec<String>,
    /// Changes in cycle order.
    pub changes: Vec<(u64, Vec<BitVec>)>,
}

impl WatchLog {
    /// Calls `f(cycle, values)` for every cycle from the first logged one to
    /// `last` (inclusive), with the values the watched outputs had at it.
    pub fn for_each_cycle(&self, last: u64, mut f: impl FnMut(u64, &[BitVec])) {
        let Some(first) = self.changes.first() else {
            return;
        };
        let mut k = 0;
        for cycle in first.0..=last {
            while k + 1 < self.changes.len() && self.changes[k + 1].0 <= cycle {
                k += 1;
            }
            f(cycle, &self.changes[k].1);
        }
    }
}

/// What a batch run found.
#[derive(Clone, Debug)]
pub struct BatchReport {
    /// Counts, first mismatch, accounting, hang, VCD, wall time (the whole
    /// run: files, `vvp`, comparison); `engine` is `iverilog-batch`.
    pub bench: BenchReport,
    /// Changes of the watched outputs.
    pub watch: WatchLog,
    /// Wall time of `vvp` alone.
    pub sim_wall: Duration,
}

impl BatchReport {
    /// Simulated cycles per second of `vvp` wall time.
    pub fn cycles_per_second(&self) -> f64 {
        self.bench.cycles as f64 / self.sim_wall.as_secs_f64().max(1e-9)
    }
}

/// A design compiled once for batch runs; `run` may be called any number of
/// times, from several threads at once (each run has its own files).
pub struct IcarusBatch {
    design: Design,
    lanes: Vec<LanePorts>,
    out_names: Vec<Vec<String>>,
    watch: Vec<PortId>,
    watch_names: Vec<String>,
    work: tempfile::TempDir,
    image: PathBuf,
    timeout: Duration,
}

impl IcarusBatch {
    /// Generate the batch testbench for `design` and `spec` and compile it
    /// with `iverilog -g2005`. The design must have a clock; every lane port
    /// must exist with the right direction (valid/ready 1 bit wide).
    pub fn new(design: &Design, spec: &BatchSpec) -> Result<IcarusBatch> {
        design.validate()?;
        if design.clock.is_none() {
            return Err(CosimError::Unsupported {
                what: format!(
                    "batch mode of `{}`: a stream bench needs a clock",
                    design.top
                ),
            });
        }
        if spec.lanes.is_empty() {
            return Err(CosimError::Design {
                what: "batch mode needs at least one lane".to_string(),
            });
        }
        let lanes = spec
            .lanes
            .iter()
            .map(|n| lane_ports(design, n))
            .collect::<Result<Vec<_>>>()?;
        let watch = spec
            .watch
            .iter()
            .map(|n| {
                let id = design.port_id(n)?;
                expect_dir(design, id, crate::design::PortDir::Output, "watched")?;
                Ok(id)
            })
            .collect::<Result<Vec<_>>>()?;
        let constants = spec
            .constants
            .iter()
            .map(|(n, v)| {
                let id = design.port_id(n)?;
                design.check_poke(id, v)?;
                Ok((id, v.to_hex()))
            })
            .collect::<Result<Vec<_>>>()?;
        let work = tempfile::Builder::new()
            .prefix("hm-icarus-batch-")
            .tempdir()
            .map_err(io_err(std::env::temp_dir()))?;
        let tb = work.path().join("hm_batch_tb.v");
        let text = generate_batch_testbench(&BatchTbSpec {
            design,
            lanes: &lanes,
            watch: &watch,
            constants: &constants,
        });
        fs::write(&tb, text).map_err(io_err(&tb))?;
        let image = work.path().join("hm_batch_tb.vvp");
        super::engine::compile_top(design, &tb, &image, BATCH_TB_MODULE)?;
        Ok(IcarusBatch {
            design: design.clone(),
            lanes,
            out_names: spec.lanes.iter().map(|n| n.out_payload.clone()).collect(),
            watch,
            watch_names: spec.watch.clone(),
            work,
            image,
            timeout: DEFAULT_RUN_TIMEOUT,
        })
    }

    /// Change how long one `vvp` run may take.
    pub fn set_timeout(&mut self, timeout: Duration) {
        self.timeout = timeout;
    }

    /// The scratch directory (testbench, compiled image, one directory per run).
    pub fn work_dir(&self) -> &Path {
        self.work.path()
    }

    /// The design this simulator was built for.
    pub fn design(&self) -> &Design {
        &self.design
    }

    /// One-lane run with the shape of `tb::run_stream_bench`: every vector
    /// on lane 0, no waits; `decoder` decodes a mismatch.
    pub fn run_stream(
        &self,
        vectors: &[Vector],
        decoder: Option<Box<FieldDecoder>>,
        config: &BenchConfig,
    ) -> Result<BenchReport> {
        let lane_vectors: Vec<LaneVector> = vectors
            .iter()
            .map(|v| LaneVector {
                lane: 0,
                wait_for_earlier_outputs: false,
                vector: v.clone(),
            })
            .collect();
        let mut decoder = Some(decoder);
        let mut decoders = |_| decoder.take().flatten();
        Ok(self.run(&lane_vectors, &mut decoders, config)?.bench)
    }

    /// Run `vectors`; `decoders(lane)` gives the field decoder of a lane's
    /// scoreboard (None: payload ports in hex). On a mismatch or hang, when
    /// `config.vcd_path` is set, the run is repeated with a VCD of the
    /// cycles within `config.vcd_radius` of the failure, written there.
    /// Output X/Z after reset is `CosimError::UnknownOutput`.
    pub fn run(
        &self,
        vectors: &[LaneVector],
        decoders: &mut dyn FnMut(usize) -> Option<Box<FieldDecoder>>,
        config: &BenchConfig,
    ) -> Result<BatchReport> {
        let mut report = self.run_once(vectors, decoders, config, None)?;
        let failure_cycle = report
            .bench
            .first_mismatch
            .as_ref()
            .map(|m| m.cycle)
            .or(report.bench.hang.as_ref().map(|h| h.cycle));
        if let (Some(cycle), Some(path)) = (failure_cycle, config.vcd_path.clone()) {
            let window = (
                cycle.saturating_sub(config.vcd_radius),
                cycle.saturating_add(config.vcd_radius),
            );
            let rerun = self.run_once(vectors, &mut |_| None, config, Some((window, path)))?;
            report.bench.vcd = rerun.bench.vcd;
        }
        Ok(report)
    }

    fn run_once(
        &self,
        vectors: &[LaneVector],
        decoders: &mut dyn FnMut(usize) -> Option<Box<FieldDecoder>>,
        config: &BenchConfig,
        dump: Option<((u64, u64), PathBuf)>,
    ) -> Result<BatchReport> {
        let start = Instant::now();
        crate::tb::driver::check_stall(config.in_stall)?;
        crate::tb::driver::check_stall(config.out_stall)?;
        let dir = tempfile::Builder::new()
            .prefix("run-")
            .tempdir_in(self.work.path())
            .map_err(io_err(self.work.path()))?;
        let total_out = self.write_stimulus(dir.path(), vectors)?;
        let totals = (vectors.len() as u64, total_out);
        self.write_params(dir.path(), config, totals, dump.as_ref().map(|d| d.0))?;
        self.write_pools(dir.path(), config.seed)?;
        let sim_start = Instant::now();
        self.run_vvp(dir.path(), config)?;
        let sim_wall = sim_start.elapsed();
        let text = fs::read_to_string(dir.path().join("out.txt"))
            .map_err(io_err(dir.path().join("out.txt")))?;
        let mut report = self.compare(&text, vectors, decoders, config)?;
        if let Some((_, path)) = dump {
            let vcd = dir.path().join("window.vcd");
            if vcd.exists() {
                if let Some(parent) = path.parent() {
                    fs::create_dir_all(parent).map_err(io_err(parent))?;
                }
                fs::copy(&vcd, &path).map_err(io_err(&path))?;
                report.bench.vcd = Some(path);
            }
        }
        report.sim_wall = sim_wall;
        report.bench.wall = start.elapsed();
        Ok(report)
    }

    /// The stimulus chunks (`meta_<c>.hex`, `pay_<c>_<lane>_<k>.hex`, see
    /// `batch_testbench`); returns the number of outputs expected in total.
    fn write_stimulus(&self, dir: &Path, vectors: &[LaneVector]) -> Result<u64> {
        let mut expected = 0u64;
        let mut after = Vec::with_capacity(vectors.len());
        for (i, v) in vectors.iter().enumerate() {
            let lane = self.lanes.get(v.lane).ok_or_else(|| CosimError::Design {
                what: format!(
                    "vector {i}: lane {} but the batch simulator has {} lanes",
                    v.lane,
                    self.lanes.len()
                ),
            })?;
            if v.vector.input.len() != lane.in_payload.len() {
                return Err(CosimError::Design {
                    what: format!(
                        "vector {i}: {} input fields, lane {} has {} payload ports",
                        v.vector.input.len(),
                        v.lane,
                        lane.in_payload.len()
                    ),
                });
            }
            for (value, &port) in v.vector.input.iter().zip(&lane.in_payload) {
                self.design
                    .check_poke(port, value)
                    .map_err(|e| CosimError::Design {
                        what: format!("vector {i}: {e}"),
                    })?;
            }
            let wait = if v.wait_for_earlier_outputs {
                expected
            } else {
                0
            };
            if wait >= 1 << 48 || v.lane >= 1 << 16 {
                return Err(CosimError::Unsupported {
                    what: format!("vector {i}: more than 2^48 outputs or 2^16 lanes"),
                });
            }
            after.push((v.lane as u64) << 48 | wait);
            expected += v.vector.outputs.len() as u64;
        }
        for (c, beats) in vectors.chunks(STIM_CHUNK).enumerate() {
            let first = c * STIM_CHUNK;
            let meta: Vec<String> = (0..STIM_CHUNK)
                .map(|j| format!("{:x}", after.get(first + j).copied().unwrap_or(0)))
                .collect();
            write_lines(&dir.join(meta_file(c)), &meta)?;
            for (l, lane) in self.lanes.iter().enumerate() {
                for (k, &port) in lane.in_payload.iter().enumerate() {
                    let zero = BitVec::zeros(self.design.ports[port.0].width).to_hex();
                    let lines: Vec<String> = (0..STIM_CHUNK)
                        .map(|j| match beats.get(j) {
                            Some(v) if v.lane == l => v.vector.input[k].to_hex(),
                            _ => zero.clone(),
                        })
                        .collect();
                    write_lines(&dir.join(payload_file(c, l, k)), &lines)?;
                }
            }
        }
        Ok(expected)
    }

    fn write_params(
        &self,
        dir: &Path,
        config: &BenchConfig,
        (total_in, total_out): (u64, u64),
        dump: Option<(u64, u64)>,
    ) -> Result<()> {
        let (dump_on, from, to) = match dump {
            Some((from, to)) => (1, from, to),
            None => (0, 0, 0),
        };
        let text = format!(
            "{:x} {:x} {:x} {:x} {:x} {:x} {:x} {:x}\n",
            config.reset_cycles,
            config.watchdog_cycles,
            config.drain_cycles,
            total_in,
            total_out,
            dump_on,
            from,
            to
        );
        let path = dir.join("params.txt");
        fs::write(&path, text).map_err(io_err(&path))
    }

    /// The garbage pools: `GARBAGE_POOL` random values per payload port.
    fn write_pools(&self, dir: &Path, seed: u64) -> Result<()> {
        for (l, lane) in self.lanes.iter().enumerate() {
            let mut rng = Prng::derived(seed, 1000 + l as u64);
            for (k, &port) in lane.in_payload.iter().enumerate() {
                let width = self.design.ports[port.0].width;
                let mut text = String::with_capacity(GARBAGE_POOL * (width / 4 + 2));
                for _ in 0..GARBAGE_POOL {
                    text.push_str(&rng.bits(width).to_hex());
                    text.push('\n');
                }
                let path = dir.join(pool_file(l, k));
                fs::write(&path, text).map_err(io_err(&path))?;
            }
        }
        Ok(())
    }

    fn run_vvp(&self, dir: &Path, config: &BenchConfig) -> Result<()> {
        let log_path = dir.join("vvp.log");
        let log = fs::File::create(&log_path).map_err(io_err(&log_path))?;
        let log_err = log.try_clone().map_err(io_err(&log_path))?;
        let masks = MaskFifo::open(dir, StallMasks::new(config, self.lanes.len()))?;
        let child = Command::new("vvp")
            .arg("-n")
            .arg(&self.image)
            .current_dir(dir)
            .stdin(Stdio::null())
            .stdout(log)
            .stderr(log_err)
            .spawn()
            .map_err(|e| CosimError::ToolMissing {
                tool: "vvp".to_string(),
                hint: format!("{e}; {INSTALL_HINT}"),
            });
        let status = child.and_then(|mut child| self.wait_for(&mut child, dir));
        masks.close()?;
        let status = status?;
        if !status.success() {
            return Err(CosimError::ToolFailed {
                tool: "vvp".to_string(),
                command: format!("vvp -n {} (in {})", self.image.display(), dir.display()),
                log: fs::read_to_string(&log_path).unwrap_or_default(),
            });
        }
        Ok(())
    }

    /// Waits for `child` at most the run timeout (then kills it).
    fn wait_for(&self, child: &mut std::process::Child, dir: &Path) -> Result<ExitStatus> {
        let started = Instant::now();
        loop {
            if let Some(status) = child.try_wait().map_err(io_err(&self.image))? {
                return Ok(status);
            }
            if started.elapsed() > self.timeout {
                let _ = child.kill();
                let _ = child.wait();
                return Err(CosimError::Protocol {
                    what: format!(
                        "batch vvp run in {} did not finish within {:?} (hung simulation?)",
                        dir.display(),
                        self.timeout
                    ),
                });
            }
            std::thread::sleep(Duration::from_millis(5));
        }
    }

    /// Reads `out.txt` and checks it against the expected outputs.
    fn compare(
        &self,
        text: &str,
        vectors: &[LaneVector],
        decoders: &mut dyn FnMut(usize) -> Option<Box<FieldDecoder>>,
        config: &BenchConfig,
    ) -> Result<BatchReport> {
        let mut boards: Vec<Scoreboard> = (0..self.lanes.len())
            .map(|l| match decoders(l) {
                Some(d) => Scoreboard::new(d),
                None => Scoreboard::with_port_names(self.out_names[l].clone()),
            })
            .collect();
        // Lane-local input ids back to vector indices.
        let mut global_ids: Vec<Vec<u64>> = vec![Vec::new(); self.lanes.len()];
        for (i, v) in vectors.iter().enumerate() {
            boards[v.lane].expect_input(v.vector.outputs.clone());
            global_ids[v.lane].push(i as u64);
        }
        let mut watch = WatchLog {
            ports: self.watch_names.clone(),
            changes: Vec::new(),
        };
        let mut hang = None;
        let mut end = None;
        let mut received = 0u64;
        for (n, line) in text.lines().enumerate() {
            let bad = |what: &str| CosimError::Protocol {
                what: format!("batch out.txt line {}: {what}: `{line}`", n + 1),
            };
            let mut tokens = line.split_whitespace();
            let tag = tokens.next().unwrap_or("");
            let mut number = || -> Result<u64> {
                tokens
                    .next()
                    .and_then(|t| t.parse().ok())
                    .ok_or_else(|| bad("expected a decimal number"))
            };
            match tag {
                "O" => {
                    let lane = number()? as usize;
                    let cycle = number()?;
                    let ports = self
                        .lanes
                        .get(lane)
                        .ok_or_else(|| bad("unknown lane"))?
                        .out_payload
                        .clone();
                    let values: Vec<&str> = line.split_whitespace().skip(3).collect();
                    let txn = self.values(&ports, &values, cycle, &bad)?;
                    boards[lane].check(txn, cycle);
                    received += 1;
                }
                "W" => {
                    let cycle = number()?;
                    let values: Vec<&str> = line.split_whitespace().skip(2).collect();
                    let txn = self.values(&self.watch, &values, cycle, &bad)?;
                    watch.changes.push((cycle, txn));
                }
                "X" => {
                    let cycle = number()?;
                    let values: Vec<&str> = line.split_whitespace().skip(2).collect();
                    let outputs = self.design.output_ids();
                    self.values(&outputs, &values, cycle, &bad)?;
                    return Err(bad("an output is X/Z but none was found"));
                }
                "H" => {
                    let cycle = number()?;
                    let idle_cycles = number()?;
                    let values: Vec<&str> = line.split_whitespace().skip(3).collect();
                    if values.len() != self.design.ports.len() {
                        return Err(bad("expected every port's value"));
                    }
                    let ports = self
                        .design
                        .ports
                        .iter()
                        .zip(values)
                        .map(|(p, v)| (p.name.clone(), format!("{}'h{v}", p.width)))
                        .collect();
                    hang = Some(Hang {
                        cycle,
                        idle_cycles,
                        ports,
                    });
                }
                "E" => end = Some((number()?, number()?, number()?)),
                "M" => return Err(bad("the stall masks ran out")),
                _ => return Err(bad("unknown record")),
            }
        }
        let (cycles, inputs_sent, outputs) = end.ok_or_else(|| CosimError::Protocol {
            what: "batch out.txt has no end record (vvp stopped early)".to_string(),
        })?;
        if outputs != received {
            return Err(CosimError::Protocol {
                what: format!("batch run counted {outputs} outputs but recorded {received}"),
            });
        }
        Ok(BatchReport {
            bench: merge_lanes(
                boards,
                &global_ids,
                config,
                cycles,
                inputs_sent,
                received,
                hang,
            ),
            watch,
            sim_wall: Duration::ZERO,
        })
    }

    /// Hex texts of `ports` as values; X/Z is `UnknownOutput`.
    fn values(
        &self,
        ports: &[PortId],
        texts: &[&str],
        cycle: u64,
        bad: &dyn Fn(&str) -> CosimError,
    ) -> Result<Transaction> {
        if texts.len() != ports.len() {
            return Err(bad(&format!("expected {} values", ports.len())));
        }
        ports
            .iter()
            .zip(texts)
            .map(|(&id, text)| {
                let port = &self.design.ports[id.0];
                if text.contains(['x', 'X', 'z', 'Z']) {
                    return Err(CosimError::UnknownOutput {
                        port: port.name.clone(),
                        cycle,
                        value: text.to_string(),
                    });
                }
                BitVec::from_hex(port.width, text).map_err(|e| bad(&e.to_string()))
            })
            .collect()
    }
}

/// `lines`, one per line, into `path`.
fn write_lines(path: &Path, lines: &[String]) -> Result<()> {
    let file = fs::File::create(path).map_err(io_err(path))?;
    let mut w = BufWriter::with_capacity(1 << 16, file);
    for l in lines {
        writeln!(w, "{l}").map_err(io_err(path))?;
    }
    w.flush().map_err(io_err(path))
}

/// One report from the lanes' scoreboards: counts summed, the earliest
/// first mismatch (its input id the vector index), the books together.
fn merge_lanes(
    boards: Vec<Scoreboard>,
    global_ids: &[Vec<u64>],
    config: &BenchConfig,
    cycles: u64,
    inputs_sent: u64,
    received: u64,
    hang: Option<Hang>,
) -> BenchReport {
    let mut accounting = AccountingReport {
        inputs: 0,
        expected_outputs: 0,
        delivered_outputs: 0,
        duplicated_outputs: 0,
        lost: Vec::new(),
        inputs_with_lost_outputs: 0,
    };
    let mut first: Option<Mismatch> = None;
    let (mut matched, mut mismatches) = (0, 0);
    for (lane, board) in boards.iter().enumerate() {
        let global = |id: u64| global_ids[lane].get(id as usize).copied().unwrap_or(id);
        matched += board.matched();
        mismatches += board.mismatches();
        let r = board.accounting().report();
        accounting.inputs += r.inputs;
        accounting.expected_outputs += r.expected_outputs;
        accounting.delivered_outputs += r.delivered_outputs;
        accounting.duplicated_outputs += r.duplicated_outputs;
        accounting.inputs_with_lost_outputs += r.inputs_with_lost_outputs;
        for (id, e, d) in r.lost {
            if accounting.lost.len() < 16 {
                accounting.lost.push((global(id), e, d));
            }
        }
        if let Some(m) = board.first_mismatch() {
            if first.as_ref().is_none_or(|f| m.cycle < f.cycle) {
                let mut m = m.clone();
                if m.input_id != u64::MAX {
                    m.input_id = global(m.input_id);
                }
                first = Some(m);
            }
        }
    }
    BenchReport {
        engine: BATCH_ENGINE_NAME.to_string(),
        seed: config.seed,
        cycles,
        inputs_sent,
        outputs_received: received,
        matched,
        mismatches,
        first_mismatch: first,
        accounting,
        hang,
        vcd: None,
        wall: Duration::ZERO,
        reproduce: config.reproduce.clone(),
    }
}

fn expect_dir(design: &Design, id: PortId, dir: crate::design::PortDir, what: &str) -> Result<()> {
    let p = design.port(id)?;
    if p.dir != dir {
        return Err(CosimError::PortMismatch {
            port: p.name.clone(),
            what: format!("{what} port must be an {dir:?}"),
        });
    }
    Ok(())
}

fn lane_ports(design: &Design, n: &StreamNames) -> Result<LanePorts> {
    use crate::design::PortDir::{Input, Output};
    let one_bit = |name: &str, dir| -> Result<PortId> {
        let id = design.port_id(name)?;
        expect_dir(design, id, dir, "handshake")?;
        if design.port(id)?.width != 1 {
            return Err(CosimError::PortMismatch {
                port: name.to_string(),
                what: "a valid/ready port must be 1 bit wide".to_string(),
            });
        }
        Ok(id)
    };
    let payload = |names: &[String], dir| -> Result<Vec<PortId>> {
        names
            .iter()
            .map(|p| {
                let id = design.port_id(p)?;
                expect_dir(design, id, dir, "payload")?;
                Ok(id)
            })
            .collect()
    };
    Ok(LanePorts {
        in_valid: one_bit(&n.in_valid, Input)?,
        in_ready: one_bit(&n.in_ready, Output)?,
        in_payload: payload(&n.in_payload, Input)?,
        out_valid: one_bit(&n.out_valid, Output)?,
        out_ready: one_bit(&n.out_ready, Input)?,
        out_payload: payload(&n.out_payload, Output)?,
    })
}

/// The per-cycle stall masks of a run: per lane the driver's and the
/// monitor's generator, a bit per cycle, 1 (go) with probability `1 - stall`.
pub struct StallMasks {
    streams: Vec<(Prng, f64)>,
}

impl StallMasks {
    /// The masks of `lanes` lanes for `config`'s seed and stalls.
    pub fn new(config: &BenchConfig, lanes: usize) -> StallMasks {
        let streams = (0..lanes as u64)
            .flat_map(|l| {
                [
                    (Prng::derived(config.seed, 1 + 2 * l), config.in_stall),
                    (Prng::derived(config.seed, 2 + 2 * l), config.out_stall),
                ]
            })
            .collect();
        StallMasks { streams }
    }

    /// The next 64 cycles: one word per stream (lane 0 driver, lane 0
    /// monitor, lane 1 driver, ...), bit `k` = cycle `k` of the block.
    pub fn next_block(&mut self) -> Vec<u64> {
        self.streams
            .iter_mut()
            .map(|(rng, stall)| {
                (0..64).fold(0u64, |w, k| w | (u64::from(!rng.chance(*stall)) << k))
            })
            .collect()
    }

    /// `blocks` blocks, one line of `%h` words each.
    fn lines(&mut self, blocks: usize) -> String {
        let mut text = String::new();
        for _ in 0..blocks {
            let words: Vec<String> = self.next_block().iter().map(|x| format!("{x:x}")).collect();
            text.push_str(&words.join(" "));
            text.push('\n');
        }
        text
    }
}

/// Name of the named pipe the stall masks go through (in the run directory).
pub const MASKS_FIFO: &str = "masks.fifo";

/// The line that tells `MaskFifo::close` the writer has stopped (no mask
/// line ends with it: hex words have no `n`).
const MASKS_END: &str = "end\n";

/// The named pipe `MASKS_FIFO` and the thread writing the stall masks into
/// it ahead of vvp. Rust holds the pipe open for reading and writing, so a
/// write never meets a closed pipe: no SIGPIPE when vvp has exited (a
/// process that restores SIGPIPE's default, as the `hiermerge` CLI does,
/// would otherwise end). `close` stops the writer and reads the pipe empty
/// until the writer's end line, so a writer blocked on a full pipe finishes.
struct MaskFifo {
    pipe: fs::File,
    path: PathBuf,
    stop: Arc<AtomicBool>,
    writer: std::thread::JoinHandle<()>,
}

impl MaskFifo {
    fn open(dir: &Path, mut masks: StallMasks) -> Result<MaskFifo> {
        let path = dir.join(MASKS_FIFO);
        let made =
            Command::new("mkfifo")
                .arg(&path)
                .output()
                .map_err(|e| CosimError::ToolMissing {
                    tool: "mkfifo".to_string(),
                    hint: e.to_string(),
                })?;
        if !made.status.success() {
            return Err(CosimError::ToolFailed {
                tool: "mkfifo".to_string(),
                command: format!("mkfifo {}", path.display()),
                log: String::from_utf8_lossy(&made.stderr).into_owned(),
            });
        }
        let pipe = fs::OpenOptions::new()
            .read(true)
            .write(true)
            .open(&path)
            .map_err(io_err(&path))?;
        let mut out = pipe.try_clone().map_err(io_err(&path))?;
        let stop = Arc::new(AtomicBool::new(false));
        let stopped = stop.clone();
        let writer = std::thread::spawn(move || loop {
            if stopped.load(Ordering::SeqCst) {
                let _ = out.write_all(MASKS_END.as_bytes());
                return;
            }
            if out.write_all(masks.lines(16).as_bytes()).is_err() {
                return;
            }
        });
        Ok(MaskFifo {
            pipe,
            path,
            stop,
            writer,
        })
    }

    /// Stop the writer, read what is left up to its end line, join it.
    fn close(mut self) -> Result<()> {
        use std::io::Read;
        self.stop.store(true, Ordering::SeqCst);
        let mut tail = Vec::new();
        let mut buf = vec![0u8; 1 << 16];
        while !tail.ends_with(MASKS_END.as_bytes()) {
            let n = self.pipe.read(&mut buf).map_err(io_err(&self.path))?;
            if n == 0 {
                break;
            }
            tail.extend_from_slice(&buf[..n]);
            let keep = tail.len().saturating_sub(MASKS_END.len());
            tail.drain(..keep);
        }
        let _ = self.writer.join();
        Ok(())
    }
}
