//! Icarus batch mode: a whole stream bench inside one `vvp` run.
//!
//! The pipe engine (`super::IcarusEngine`) pays one round trip per clock
//! (~15-22 k cycles/s); here the generated testbench
//! (`super::batch_testbench`) drives the input beats from a file and the
//! valid gaps and ready back-pressure from per-cycle stall masks that Rust
//! draws from the seeded `tb::Prng` (the driver's and the monitor's streams,
//! `Prng::derived(seed, 1 + 2 * lane)` and `(seed, 2 + 2 * lane)`, a bit
//! per cycle: go with probability `1 - stall`) and streams through a named
//! pipe ahead of vvp (the bits of `tb::StallGen`, any pattern); while `valid` is low the payload shows a random value (from
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

use super::batch_runner::{
    asked_window, dump_is_fst, failure_window, keep_window_vcd, mask_line, read_out, write_lines,
    write_params, BatchImage,
};
use super::batch_tb_frame::{frame_params, pool_file};
use super::batch_testbench::{
    generate_batch_testbench, meta_file, payload_file, BatchTbSpec, LanePorts, BATCH_TB_MODULE,
    GARBAGE_POOL, STIM_CHUNK,
};
use crate::design::{Design, PortId};
use crate::error::{io_err, CosimError, Result};
use crate::tb::{
    AccountingReport, BenchConfig, BenchReport, FieldDecoder, Hang, Mismatch, Prng, Scoreboard,
    StallGen, StreamNames, Vector,
};
use golden::bits::Bits;
use std::fs;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

pub use super::batch_runner::{BATCH_ENGINE_NAME, MASKS_FIFO};

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
    pub constants: Vec<(String, Bits)>,
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

impl LaneVector {
    /// `vector` on lane `lane`, offered as soon as the lane may.
    pub fn new(lane: usize, vector: Vector) -> LaneVector {
        LaneVector {
            lane,
            wait_for_earlier_outputs: false,
            vector,
        }
    }
}

/// Every change of the watched outputs: `(cycle, values in watch order)`,
/// the first entry at the first cycle after reset.
#[derive(Clone, Debug, Default)]
pub struct WatchLog {
    /// Watched port names.
    pub ports: Vec<String>,
    /// Changes in cycle order.
    pub changes: Vec<(u64, Vec<Bits>)>,
}

impl WatchLog {
    /// Calls `f(cycle, values)` for every cycle from the first logged one to
    /// `last` (inclusive), with the values the watched outputs had at it.
    pub fn for_each_cycle(&self, last: u64, mut f: impl FnMut(u64, &[Bits])) {
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
    image: BatchImage,
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
        let text = generate_batch_testbench(&BatchTbSpec {
            design,
            lanes: &lanes,
            watch: &watch,
            constants: &constants,
        });
        let image = BatchImage::compile(
            design,
            "hm-icarus-batch-",
            "hm_batch_tb",
            BATCH_TB_MODULE,
            &text,
            DEFAULT_RUN_TIMEOUT,
        )?;
        Ok(IcarusBatch {
            design: design.clone(),
            lanes,
            out_names: spec.lanes.iter().map(|n| n.out_payload.clone()).collect(),
            watch,
            watch_names: spec.watch.clone(),
            image,
        })
    }

    /// Change how long one `vvp` run may take.
    pub fn set_timeout(&mut self, timeout: Duration) {
        self.image.timeout = timeout;
    }

    /// The scratch directory (testbench, compiled image, one directory per run).
    pub fn work_dir(&self) -> &Path {
        self.image.work_dir()
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
            .map(|v| LaneVector::new(0, v.clone()))
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
        let mut report = self.run_once(vectors, decoders, config, asked_window(config))?;
        if config.wave_window.is_some() {
            return Ok(report);
        }
        let failure = failure_window(report.bench.failure_cycle(), config);
        if let Some(dump) = failure {
            let rerun = self.run_once(vectors, &mut |_| None, config, Some(dump))?;
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
        crate::tb::driver::check_stalls(&config.in_stall)?;
        crate::tb::driver::check_stalls(&config.out_stall)?;
        let dir = self.image.run_dir()?;
        let total_out = self.write_stimulus(dir.path(), vectors)?;
        let mut params = frame_params(config, total_out, dump.as_ref().map(|d| d.0));
        params.push(vectors.len() as u64);
        write_params(dir.path(), &params)?;
        self.write_pools(dir.path(), config.seed)?;
        let mut masks = StallMasks::new(config, self.lanes.len());
        let fst = dump_is_fst(dump.as_ref().map(|d| d.1.as_path()), config)?;
        let sim_wall = self.image.run_vvp(dir.path(), fst, move || {
            mask_line(masks.next_block().into_iter())
        })?;
        let text = fs::read_to_string(dir.path().join("out.txt"))
            .map_err(io_err(dir.path().join("out.txt")))?;
        let mut report = self.compare(&text, vectors, decoders, config)?;
        if let Some((_, path)) = dump {
            report.bench.vcd = keep_window_vcd(dir.path(), &path, config.wave_scope.as_deref())?;
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
                    let zero = Bits::zero(self.design.ports[port.0].width).to_hex();
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

    /// The garbage pools: `GARBAGE_POOL` random values per payload port.
    fn write_pools(&self, dir: &Path, seed: u64) -> Result<()> {
        for (l, lane) in self.lanes.iter().enumerate() {
            let mut rng = Prng::derived(seed, 1000 + l as u64);
            for (k, &port) in lane.in_payload.iter().enumerate() {
                let width = self.design.ports[port.0].width;
                let mut text = String::with_capacity(GARBAGE_POOL * (width as usize / 4 + 2));
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
        let mut end = None;
        let mut received = 0u64;
        let hang = read_out(text, &self.design, "batch", |l| {
            match l.tag {
                "O" => {
                    let lane = l.number(0)? as usize;
                    let cycle = l.number(1)?;
                    let ports = &self
                        .lanes
                        .get(lane)
                        .ok_or_else(|| l.bad("unknown lane"))?
                        .out_payload;
                    let txn = l.values(&self.design, ports, 2, cycle)?;
                    boards[lane].check(txn, cycle);
                    received += 1;
                }
                "W" => {
                    let cycle = l.number(0)?;
                    let txn = l.values(&self.design, &self.watch, 1, cycle)?;
                    watch.changes.push((cycle, txn));
                }
                "E" => end = Some((l.number(0)?, l.number(2)?, l.number(1)?)),
                _ => return Ok(false),
            }
            Ok(true)
        })?;
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
/// monitor's generator and pattern, a bit per cycle, 1 = go.
pub struct StallMasks {
    streams: Vec<(Prng, StallGen)>,
}

impl StallMasks {
    /// The masks of `lanes` lanes for `config`'s seed and stalls.
    pub fn new(config: &BenchConfig, lanes: usize) -> StallMasks {
        let streams = (0..lanes as u64)
            .flat_map(|l| {
                [
                    (
                        Prng::derived(config.seed, 1 + 2 * l),
                        StallGen::new(config.in_stall),
                    ),
                    (
                        Prng::derived(config.seed, 2 + 2 * l),
                        StallGen::new(config.out_stall),
                    ),
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
            .map(|(rng, stalls)| stalls.go_word(rng))
            .collect()
    }
}
