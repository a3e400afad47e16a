//! Icarus multi-stream batch mode: `tb::run_multi_stream_bench` inside one
//! `vvp` run, for units whose streams are related only through the design
//! (the merging module: `cfg`, `in0`..`in{k-1}` in, `report`, `out` out).
//!
//! The one-sequence batch (`super::IcarusBatch`) offers one beat at a time
//! across its lanes, which deadlocks a merge network that needs a head on
//! every input stream at once; here every input stream has its own driver
//! and every output stream its own back-pressure, as in the pipe bench.
//!
//! Same stall patterns as `tb::run_multi_stream_bench` for the same seed:
//! input stream `j`'s driver draws from `Prng::derived(seed_of(j), 1)` once
//! per opportunity (not presenting, a beat left: go with probability
//! `1 - stall`) and, after a stall, the garbage payload words; since those
//! draws do not depend on the design, Rust replays them ahead and gives each
//! beat its *gap* (stalled opportunities before it goes), and the testbench
//! counts the gap down. Output stream `j`'s `ready` is one draw per cycle
//! from `Prng::derived(seed_of(100 + j), 2)`, streamed to vvp through a
//! named pipe (see `batch_runner::MaskFifo`).
//! `seed_of(j) = seed ^ (0x9e3779b97f4a7c15 * (j + 1))`. So cycles, counts
//! and transfer cycles equal a pipe run's; only the garbage shown while
//! `valid` is low differs (from a pool of random values per stream drawn
//! from `Prng::derived(seed, 1000 + j)`, a new one after each accepted beat
//! rather than every cycle), which matters only to a design that samples
//! data without `valid`.
//!
//! Every output is checked for X/Z each cycle after reset (X/Z is
//! `CosimError::UnknownOutput` naming the port and cycle); the testbench
//! runs the watchdog and the drain and records every output transfer
//! (stream, cycle, data); Rust feeds each stream's transfers in order to a
//! `tb::Scoreboard` and builds a `tb::MultiReport`. Unlike the pipe bench
//! it cannot stop at the first mismatch: it runs to the end and counts
//! every mismatch (`BenchConfig::stop_on_mismatch` is ignored). On a
//! mismatch or hang, when `BenchConfig::vcd_path` is set, the run is
//! repeated with a VCD of the cycles within `vcd_radius` of the first
//! failure (the earliest mismatch on any stream, else the hang), written
//! there. Pulse outputs named at `new_watching` (the merging module's
//! `done`, `idle`) have their high cycles counted as
//! `tb::run_multi_stream_bench_watching` counts them, and their values at
//! the end reported.

use super::batch_runner::{
    asked_window, dump_is_fst, failure_window, keep_window_vcd, mask_line, read_out, write_lines,
    write_params, BatchImage, BATCH_ENGINE_NAME,
};
use super::batch_tb_frame::{frame_params, pool_file};
use super::batch_testbench::GARBAGE_POOL;
use super::multi_batch_testbench::{
    beat_file, gap_file, generate_multi_testbench, MultiTbSpec, MULTI_STIM_CHUNK, MULTI_TB_MODULE,
};
use crate::design::{Design, PortDir, PortId};
use crate::error::{io_err, CosimError, Result};
use crate::tb::{
    BenchConfig, MultiReport, Prng, PulseCounts, Scoreboard, StallGen, Stalls, StreamBeats,
    StreamPorts,
};
use std::fs;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Engine name in multi-stream batch reports.
pub const MULTI_BATCH_ENGINE_NAME: &str = BATCH_ENGINE_NAME;

/// How long one `vvp` run may take before it is killed and reported hung.
pub const MULTI_RUN_TIMEOUT: Duration = Duration::from_secs(6 * 3600);

/// The per-stream seed of `tb::run_multi_stream_bench`, the same function,
/// so that a batch run replays a stepped run's stalls.
pub use crate::tb::multi::stream_seed;

/// A design compiled once for multi-stream batch runs over fixed input and
/// output stream names (ports `<name>_valid`, `<name>_ready`,
/// `<name>_data`); `run` may be called any number of times, also from
/// several threads at once (each run has its own directory).
pub struct IcarusMultiBatch {
    design: Design,
    inputs: Vec<(String, StreamPorts)>,
    outputs: Vec<(String, StreamPorts)>,
    pulses: Vec<(String, PortId)>,
    image: BatchImage,
}

/// What a multi-stream batch run found, and how long `vvp` took.
#[derive(Clone, Debug)]
pub struct MultiBatchReport {
    /// The report, as `tb::run_multi_stream_bench` gives it (`wall`: the
    /// whole run: files, `vvp`, comparison; engine `iverilog-batch`).
    pub report: MultiReport,
    /// Wall time of `vvp` alone.
    pub sim_wall: Duration,
    /// Per pulse output named at `new_watching`, the cycles it was high.
    pub pulses: PulseCounts,
    /// Per pulse output, whether it was high in the last cycle.
    pub pulses_at_end: Vec<(String, bool)>,
}

impl MultiBatchReport {
    /// Simulated cycles per second of the whole run's wall time.
    pub fn cycles_per_second(&self) -> f64 {
        self.report.cycles as f64 / self.report.wall.as_secs_f64().max(1e-9)
    }
}

fn stream_ports(design: &Design, name: &str, input: bool) -> Result<StreamPorts> {
    let (into, from) = if input {
        (PortDir::Input, PortDir::Output)
    } else {
        (PortDir::Output, PortDir::Input)
    };
    let p = StreamPorts::new(
        design,
        &format!("{name}_valid"),
        &format!("{name}_ready"),
        &[&format!("{name}_data")],
    )?;
    for (id, dir, one_bit) in [(p.valid, into, true), (p.ready, from, true)]
        .into_iter()
        .chain(p.payload.iter().map(|&id| (id, into, false)))
    {
        let port = design.port(id)?;
        if port.dir != dir || (one_bit && port.width != 1) {
            return Err(CosimError::PortMismatch {
                port: port.name.clone(),
                what: format!(
                    "stream `{name}` needs it as a{} {dir:?}",
                    if one_bit { " 1-bit" } else { "n" }
                ),
            });
        }
    }
    Ok(p)
}

impl IcarusMultiBatch {
    /// Generate the testbench for `design` with these input and output
    /// streams and compile it with `iverilog -g2005`. The design must have
    /// a clock and every stream's three ports with the right directions.
    pub fn new(design: &Design, inputs: &[&str], outputs: &[&str]) -> Result<IcarusMultiBatch> {
        Self::new_watching(design, inputs, outputs, &[])
    }

    /// `new`, also counting the cycles each 1-bit output in `pulses` is
    /// high (see `MultiBatchReport::pulses`).
    pub fn new_watching(
        design: &Design,
        inputs: &[&str],
        outputs: &[&str],
        pulses: &[&str],
    ) -> Result<IcarusMultiBatch> {
        design.validate()?;
        if design.clock.is_none() {
            return Err(CosimError::Unsupported {
                what: format!("multi-stream batch of `{}`: needs a clock", design.top),
            });
        }
        let named = |names: &[&str], input: bool| -> Result<Vec<(String, StreamPorts)>> {
            names
                .iter()
                .map(|n| Ok((n.to_string(), stream_ports(design, n, input)?)))
                .collect()
        };
        let inputs = named(inputs, true)?;
        let outputs = named(outputs, false)?;
        let pulses = pulses
            .iter()
            .map(|n| Ok((n.to_string(), pulse_port(design, n)?)))
            .collect::<Result<Vec<_>>>()?;
        let in_ports: Vec<StreamPorts> = inputs.iter().map(|s| s.1.clone()).collect();
        let out_ports: Vec<StreamPorts> = outputs.iter().map(|s| s.1.clone()).collect();
        let pulse_ids: Vec<PortId> = pulses.iter().map(|p| p.1).collect();
        let text = generate_multi_testbench(&MultiTbSpec {
            design,
            inputs: &in_ports,
            outputs: &out_ports,
            pulses: &pulse_ids,
        });
        let image = BatchImage::compile(
            design,
            "hm-icarus-multi-",
            "hm_multi_tb",
            MULTI_TB_MODULE,
            &text,
            MULTI_RUN_TIMEOUT,
        )?;
        Ok(IcarusMultiBatch {
            design: design.clone(),
            inputs,
            outputs,
            pulses,
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

    /// Run `inputs` into and `outputs` out of the design (the streams named
    /// at `new`, in that order) with the stalls, seed, reset, watchdog and
    /// drain of `config`; on a failure, the VCD rerun (see the module docs).
    pub fn run(
        &self,
        inputs: &[StreamBeats],
        outputs: &[StreamBeats],
        config: &BenchConfig,
    ) -> Result<MultiBatchReport> {
        let mut run = self.run_once(inputs, outputs, config, asked_window(config))?;
        if config.wave_window.is_some() {
            return Ok(run);
        }
        let failure = failure_window(run.report.failure_cycle(), config);
        if let Some(dump) = failure {
            run.report.vcd = self
                .run_once(inputs, outputs, config, Some(dump))?
                .report
                .vcd;
        }
        Ok(run)
    }

    fn run_once(
        &self,
        inputs: &[StreamBeats],
        outputs: &[StreamBeats],
        config: &BenchConfig,
        dump: Option<((u64, u64), PathBuf)>,
    ) -> Result<MultiBatchReport> {
        let start = Instant::now();
        crate::tb::driver::check_stalls(&config.in_stall)?;
        crate::tb::driver::check_stalls(&config.out_stall)?;
        crate::tb::multi::check_stream_stalls(&self.design, &config.stream_stalls)?;
        self.check_streams(inputs, &self.inputs, "input")?;
        self.check_streams(outputs, &self.outputs, "output")?;
        let dir = self.image.run_dir()?;
        let total_out: u64 = outputs.iter().map(|s| s.beats.len() as u64).sum();
        let mut params = frame_params(config, total_out, dump.as_ref().map(|d| d.0));
        params.extend(inputs.iter().map(|s| s.beats.len() as u64));
        write_params(dir.path(), &params)?;
        for (s, beats) in inputs.iter().enumerate() {
            self.write_input(dir.path(), s, beats, config)?;
        }
        let stalls: Vec<Stalls> = self
            .outputs
            .iter()
            .map(|(name, _)| config.out_stall_of(name))
            .collect();
        let mut masks = ready_masks(config.seed, &stalls);
        let fst = dump_is_fst(dump.as_ref().map(|d| d.1.as_path()), config)?;
        let sim_wall = self.image.run_vvp(dir.path(), fst, move || {
            mask_line(masks.iter_mut().map(|(rng, stalls)| stalls.go_word(rng)))
        })?;
        let out = dir.path().join("out.txt");
        let text = fs::read_to_string(&out).map_err(io_err(&out))?;
        let mut run = self.compare(&text, inputs, outputs, config)?;
        if let Some((_, path)) = dump {
            run.report.vcd = keep_window_vcd(dir.path(), &path, config.wave_scope.as_deref())?;
        }
        run.sim_wall = sim_wall;
        run.report.wall = start.elapsed();
        Ok(run)
    }

    fn check_streams(
        &self,
        given: &[StreamBeats],
        built: &[(String, StreamPorts)],
        what: &str,
    ) -> Result<()> {
        let names = |v: Vec<&str>| v.join(", ");
        if given.len() != built.len() || given.iter().zip(built).any(|(g, b)| g.name != b.0) {
            return Err(CosimError::Design {
                what: format!(
                    "{what} streams [{}] but the batch simulator was built for [{}]",
                    names(given.iter().map(|g| g.name.as_str()).collect()),
                    names(built.iter().map(|b| b.0.as_str()).collect())
                ),
            });
        }
        for (g, (_, ports)) in given.iter().zip(built) {
            if g.beats.len() >= 1 << 31 {
                return Err(CosimError::Unsupported {
                    what: format!(
                        "{what} stream `{}`: {} beats, the testbench counts at most 2^31 - 1",
                        g.name,
                        g.beats.len()
                    ),
                });
            }
            for (i, beat) in g.beats.iter().enumerate() {
                if beat.len() != ports.payload.len() {
                    return Err(CosimError::Design {
                        what: format!(
                            "{what} stream `{}` beat {i}: {} fields, the stream has {} payload ports",
                            g.name,
                            beat.len(),
                            ports.payload.len()
                        ),
                    });
                }
                for (value, &port) in beat.iter().zip(&ports.payload) {
                    let p = self.design.port(port)?;
                    if value.width() != p.width {
                        return Err(CosimError::Design {
                            what: format!(
                                "{what} stream `{}` beat {i}: a {}-bit value for the {}-bit port `{}`",
                                g.name,
                                value.width(),
                                p.width,
                                p.name
                            ),
                        });
                    }
                }
            }
        }
        Ok(())
    }

    /// Input stream `s`'s gaps, beats (chunked) and garbage pool.
    fn write_input(
        &self,
        dir: &Path,
        s: usize,
        stream: &StreamBeats,
        config: &BenchConfig,
    ) -> Result<()> {
        let ports = &self.inputs[s].1;
        let widths: Vec<u32> = ports
            .payload
            .iter()
            .map(|&p| self.design.ports[p.0].width)
            .collect();
        let gaps = driver_gaps(
            stream_seed(config.seed, s),
            config.in_stall_of(&self.inputs[s].0),
            &widths,
            stream.beats.len(),
        )?;
        for (c, chunk) in gaps.chunks(MULTI_STIM_CHUNK).enumerate() {
            let lines: Vec<String> = chunk.iter().map(|g| format!("{g:x}")).collect();
            write_lines(&dir.join(gap_file(s, c)), &lines)?;
        }
        for (k, &width) in widths.iter().enumerate() {
            for (c, chunk) in stream.beats.chunks(MULTI_STIM_CHUNK).enumerate() {
                let lines: Vec<String> = chunk.iter().map(|b| b[k].to_hex()).collect();
                write_lines(&dir.join(beat_file(s, c, k)), &lines)?;
            }
            let mut rng = Prng::derived(config.seed, 1000 + s as u64);
            let pool: Vec<String> = (0..GARBAGE_POOL)
                .map(|_| rng.bits(width).to_hex())
                .collect();
            write_lines(&dir.join(pool_file(s, k)), &pool)?;
        }
        Ok(())
    }

    /// Reads `out.txt` and checks each output stream in order.
    fn compare(
        &self,
        text: &str,
        inputs: &[StreamBeats],
        outputs: &[StreamBeats],
        config: &BenchConfig,
    ) -> Result<MultiBatchReport> {
        let mut boards: Vec<Scoreboard> = self
            .outputs
            .iter()
            .zip(outputs)
            .map(|((_, p), s)| {
                let mut b = Scoreboard::with_port_names(p.payload_names.clone());
                b.expect_input(s.beats.clone());
                b
            })
            .collect();
        let mut received = vec![0u64; outputs.len()];
        let mut end = None;
        let mut pulses = None;
        let hang = read_out(text, &self.design, "multi-stream batch", |l| {
            match l.tag {
                "O" => {
                    let o = l.number(0)? as usize;
                    let cycle = l.number(1)?;
                    let ports = &self
                        .outputs
                        .get(o)
                        .ok_or_else(|| l.bad("unknown stream"))?
                        .1;
                    let txn = l.values(&self.design, &ports.payload, 2, cycle)?;
                    boards[o].check(txn, cycle);
                    received[o] += 1;
                }
                "P" => {
                    let n = self.pulses.len();
                    if l.words.len() != 1 + 2 * n {
                        return Err(l.bad("expected the cycle, a count and a value per pulse"));
                    }
                    let counts = (1..=n).map(|i| l.number(i)).collect::<Result<Vec<u64>>>()?;
                    let ids: Vec<PortId> = self.pulses.iter().map(|p| p.1).collect();
                    let last = l.values(&self.design, &ids, 1 + n, l.number(0)?)?;
                    pulses = Some((counts, last));
                }
                "E" => {
                    if l.words.len() != 2 + inputs.len() {
                        return Err(l.bad("expected cycle, outputs and one count per input"));
                    }
                    let sent = (0..inputs.len())
                        .map(|s| l.number(2 + s))
                        .collect::<Result<Vec<u64>>>()?;
                    end = Some((l.number(0)?, l.number(1)?, sent));
                }
                _ => return Ok(false),
            }
            Ok(true)
        })?;
        let (cycles, counted, sent) = end.ok_or_else(|| CosimError::Protocol {
            what: "multi-stream batch out.txt has no end record (vvp stopped early)".to_string(),
        })?;
        if counted != received.iter().sum::<u64>() {
            return Err(CosimError::Protocol {
                what: format!("the batch run counted {counted} outputs but recorded {received:?}"),
            });
        }
        let first_mismatch = outputs
            .iter()
            .zip(&boards)
            .filter_map(|(s, b)| b.first_mismatch().map(|m| (s.name.clone(), m.clone())))
            .min_by_key(|(_, m)| m.cycle);
        let report = MultiReport {
            engine: MULTI_BATCH_ENGINE_NAME.to_string(),
            seed: config.seed,
            cycles,
            sent: inputs.iter().map(|s| s.name.clone()).zip(sent).collect(),
            received: outputs
                .iter()
                .map(|s| s.name.clone())
                .zip(received)
                .collect(),
            matched: boards.iter().map(|b| b.matched()).sum(),
            mismatches: boards.iter().map(|b| b.mismatches()).sum(),
            first_mismatch,
            missing: outputs
                .iter()
                .zip(&boards)
                .map(|(s, b)| (s.name.clone(), b.outstanding()))
                .collect(),
            hang,
            vcd: None,
            wall: Duration::ZERO,
            // The batch's records count beats, not when they moved.
            active: Vec::new(),
        };
        let (counts, last) = match pulses {
            Some(p) => p,
            None if self.pulses.is_empty() => (Vec::new(), Vec::new()),
            None => {
                return Err(CosimError::Protocol {
                    what: "multi-stream batch out.txt has no pulse record".to_string(),
                })
            }
        };
        let names = self.pulses.iter().map(|p| p.0.clone());
        Ok(MultiBatchReport {
            report,
            sim_wall: Duration::ZERO,
            pulses: names.clone().zip(counts).collect(),
            pulses_at_end: names.zip(last.iter().map(|v| !v.is_zero())).collect(),
        })
    }
}

/// Per beat, the stalled opportunities before the driver of
/// `tb::StreamDriver` (seeded `seed`, payload widths `widths`) raises
/// `valid` for it: each opportunity takes one decision of `stalls`, and a
/// stall then draws the garbage payload (`ceil(width / 64)` words per port).
pub fn driver_gaps(seed: u64, stalls: Stalls, widths: &[u32], beats: usize) -> Result<Vec<u32>> {
    let mut rng = Prng::derived(seed, 1);
    let mut stalls = StallGen::new(stalls);
    let garbage_words: usize = widths.iter().map(|w| w.div_ceil(64) as usize).sum();
    (0..beats)
        .map(|i| {
            let mut gap = 0u32;
            while !stalls.go(&mut rng) {
                gap = gap.checked_add(1).ok_or_else(|| CosimError::Unsupported {
                    what: format!("beat {i}: a gap of 2^32 stalled cycles"),
                })?;
                for _ in 0..garbage_words {
                    rng.next_u64();
                }
            }
            Ok(gap)
        })
        .collect()
}

/// The ready generators of the output streams, `stalls[j]` output `j`'s
/// pattern: output `j` takes one decision per cycle from
/// `Prng::derived(stream_seed(seed, 100 + j), 2)` (as `tb::StreamMonitor`).
pub fn ready_masks(seed: u64, stalls: &[Stalls]) -> Vec<(Prng, StallGen)> {
    stalls
        .iter()
        .enumerate()
        .map(|(j, &s)| {
            (
                Prng::derived(stream_seed(seed, 100 + j), 2),
                StallGen::new(s),
            )
        })
        .collect()
}

/// A 1-bit output whose high cycles are counted.
fn pulse_port(design: &Design, name: &str) -> Result<PortId> {
    let id = design.port_id(name)?;
    let port = design.port(id)?;
    if port.dir != PortDir::Output || port.width != 1 {
        return Err(CosimError::PortMismatch {
            port: name.to_string(),
            what: "a watched pulse must be a 1-bit output".to_string(),
        });
    }
    Ok(id)
}
