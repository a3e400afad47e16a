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
//! named pipe (see `MaskPipe`).
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
//! every mismatch (`BenchConfig::stop_on_mismatch` is ignored, as is the VCD).

use super::batch_testbench::GARBAGE_POOL;
use super::multi_batch_testbench::{
    beat_file, gap_file, generate_multi_testbench, multi_pool_file, MultiTbSpec, MASKS_FIFO,
    MULTI_STIM_CHUNK, MULTI_TB_MODULE,
};
use crate::bitvec::BitVec;
use crate::design::{Design, PortDir, PortId};
use crate::error::{io_err, CosimError, Result};
use crate::tb::{
    BenchConfig, Hang, MultiReport, Prng, Scoreboard, StreamBeats, StreamPorts, Transaction,
};
use crate::tools::INSTALL_HINT;
use std::fs;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Engine name in multi-stream batch reports.
pub const MULTI_BATCH_ENGINE_NAME: &str = "iverilog-batch";

/// How long one `vvp` run may take before it is killed and reported hung.
pub const MULTI_RUN_TIMEOUT: Duration = Duration::from_secs(6 * 3600);

/// The per-stream seed of `tb::run_multi_stream_bench` (input `j`: `j`,
/// output `j`: `100 + j`).
pub fn stream_seed(seed: u64, j: usize) -> u64 {
    seed ^ 0x9e37_79b9_7f4a_7c15u64.wrapping_mul(j as u64 + 1)
}

/// A design compiled once for multi-stream batch runs over fixed input and
/// output stream names (ports `<name>_valid`, `<name>_ready`,
/// `<name>_data`); `run` may be called any number of times, also from
/// several threads at once (each run has its own directory).
pub struct IcarusMultiBatch {
    design: Design,
    inputs: Vec<(String, StreamPorts)>,
    outputs: Vec<(String, StreamPorts)>,
    work: tempfile::TempDir,
    image: PathBuf,
    timeout: Duration,
}

/// What a multi-stream batch run found, and how long `vvp` took.
#[derive(Clone, Debug)]
pub struct MultiBatchReport {
    /// The report, as `tb::run_multi_stream_bench` gives it (`wall`: the
    /// whole run: files, `vvp`, comparison; engine `iverilog-batch`).
    pub report: MultiReport,
    /// Wall time of `vvp` alone.
    pub sim_wall: Duration,
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
        let work = tempfile::Builder::new()
            .prefix("hm-icarus-multi-")
            .tempdir()
            .map_err(io_err(std::env::temp_dir()))?;
        let tb = work.path().join("hm_multi_tb.v");
        let in_ports: Vec<StreamPorts> = inputs.iter().map(|s| s.1.clone()).collect();
        let out_ports: Vec<StreamPorts> = outputs.iter().map(|s| s.1.clone()).collect();
        let text = generate_multi_testbench(&MultiTbSpec {
            design,
            inputs: &in_ports,
            outputs: &out_ports,
        });
        fs::write(&tb, text).map_err(io_err(&tb))?;
        let image = work.path().join("hm_multi_tb.vvp");
        super::engine::compile_top(design, &tb, &image, MULTI_TB_MODULE)?;
        Ok(IcarusMultiBatch {
            design: design.clone(),
            inputs,
            outputs,
            work,
            image,
            timeout: MULTI_RUN_TIMEOUT,
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

    /// Run `inputs` into and `outputs` out of the design (the streams named
    /// at `new`, in that order) with the stalls, seed, reset, watchdog and
    /// drain of `config`.
    pub fn run(
        &self,
        inputs: &[StreamBeats],
        outputs: &[StreamBeats],
        config: &BenchConfig,
    ) -> Result<MultiBatchReport> {
        let start = Instant::now();
        crate::tb::driver::check_stall(config.in_stall)?;
        crate::tb::driver::check_stall(config.out_stall)?;
        self.check_streams(inputs, &self.inputs, "input")?;
        self.check_streams(outputs, &self.outputs, "output")?;
        let dir = tempfile::Builder::new()
            .prefix("run-")
            .tempdir_in(self.work.path())
            .map_err(io_err(self.work.path()))?;
        let total_out: u64 = outputs.iter().map(|s| s.beats.len() as u64).sum();
        self.write_params(dir.path(), config, inputs, total_out)?;
        for (s, beats) in inputs.iter().enumerate() {
            self.write_input(dir.path(), s, beats, config)?;
        }
        let sim_start = Instant::now();
        self.run_vvp(dir.path(), config)?;
        let sim_wall = sim_start.elapsed();
        let out = dir.path().join("out.txt");
        let text = fs::read_to_string(&out).map_err(io_err(&out))?;
        let mut report = self.compare(&text, inputs, outputs, config)?;
        report.wall = start.elapsed();
        Ok(MultiBatchReport { report, sim_wall })
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

    fn write_params(
        &self,
        dir: &Path,
        config: &BenchConfig,
        inputs: &[StreamBeats],
        total_out: u64,
    ) -> Result<()> {
        let mut words = vec![
            u64::from(config.reset_cycles),
            config.watchdog_cycles,
            config.drain_cycles,
            total_out,
        ];
        words.extend(inputs.iter().map(|s| s.beats.len() as u64));
        let text: Vec<String> = words.iter().map(|w| format!("{w:x}")).collect();
        let path = dir.join("params.txt");
        fs::write(&path, text.join(" ") + "\n").map_err(io_err(&path))
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
        let widths: Vec<usize> = ports
            .payload
            .iter()
            .map(|&p| self.design.ports[p.0].width)
            .collect();
        let gaps = driver_gaps(
            stream_seed(config.seed, s),
            config.in_stall,
            &widths,
            stream.beats.len(),
        )?;
        for (c, chunk) in gaps.chunks(MULTI_STIM_CHUNK).enumerate() {
            let lines = padded(chunk.iter().map(|g| format!("{g:x}")), "0");
            write_lines(&dir.join(gap_file(s, c)), &lines)?;
        }
        for (k, &width) in widths.iter().enumerate() {
            let zero = BitVec::zeros(width).to_hex();
            for (c, chunk) in stream.beats.chunks(MULTI_STIM_CHUNK).enumerate() {
                let lines = padded(chunk.iter().map(|b| b[k].to_hex()), &zero);
                write_lines(&dir.join(beat_file(s, c, k)), &lines)?;
            }
            let mut rng = Prng::derived(config.seed, 1000 + s as u64);
            let pool: Vec<String> = (0..GARBAGE_POOL)
                .map(|_| rng.bits(width).to_hex())
                .collect();
            write_lines(&dir.join(multi_pool_file(s, k)), &pool)?;
        }
        Ok(())
    }

    fn run_vvp(&self, dir: &Path, config: &BenchConfig) -> Result<()> {
        let masks = MaskPipe::open(dir, config, self.outputs.len())?;
        let status = self.wait_vvp(dir);
        masks.close()?;
        let status = status?;
        if !status.success() {
            let log_path = dir.join("vvp.log");
            return Err(CosimError::ToolFailed {
                tool: "vvp".to_string(),
                command: format!("vvp -n {} (in {})", self.image.display(), dir.display()),
                log: fs::read_to_string(&log_path).unwrap_or_default(),
            });
        }
        Ok(())
    }

    fn wait_vvp(&self, dir: &Path) -> Result<std::process::ExitStatus> {
        let log_path = dir.join("vvp.log");
        let log = fs::File::create(&log_path).map_err(io_err(&log_path))?;
        let log_err = log.try_clone().map_err(io_err(&log_path))?;
        let mut child = Command::new("vvp")
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
            })?;
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
                        "multi-stream vvp run in {} did not finish within {:?} (hung simulation?)",
                        dir.display(),
                        self.timeout
                    ),
                });
            }
            std::thread::sleep(Duration::from_millis(5));
        }
    }

    /// Reads `out.txt` and checks each output stream in order.
    fn compare(
        &self,
        text: &str,
        inputs: &[StreamBeats],
        outputs: &[StreamBeats],
        config: &BenchConfig,
    ) -> Result<MultiReport> {
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
        let mut hang = None;
        let mut end = None;
        for (n, line) in text.lines().enumerate() {
            let bad = |what: &str| CosimError::Protocol {
                what: format!(
                    "multi-stream batch out.txt line {}: {what}: `{line}`",
                    n + 1
                ),
            };
            let tokens: Vec<&str> = line.split_whitespace().collect();
            let number = |i: usize| -> Result<u64> {
                tokens
                    .get(i)
                    .and_then(|t| t.parse().ok())
                    .ok_or_else(|| bad("expected a decimal number"))
            };
            match tokens.first().copied().unwrap_or("") {
                "O" => {
                    let o = number(1)? as usize;
                    let cycle = number(2)?;
                    let ports = &self.outputs.get(o).ok_or_else(|| bad("unknown stream"))?.1;
                    let txn = self.values(&ports.payload, &tokens[3..], cycle, &bad)?;
                    boards[o].check(txn, cycle);
                    received[o] += 1;
                }
                "X" => {
                    let cycle = number(1)?;
                    self.values(&self.design.output_ids(), &tokens[2..], cycle, &bad)?;
                    return Err(bad("an output is X/Z but none was found"));
                }
                "H" => {
                    let (cycle, idle_cycles) = (number(1)?, number(2)?);
                    let values = &tokens[3..];
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
                "E" => {
                    if tokens.len() != 3 + inputs.len() {
                        return Err(bad("expected cycle, outputs and one count per input"));
                    }
                    let sent = (0..inputs.len())
                        .map(|s| number(3 + s))
                        .collect::<Result<Vec<u64>>>()?;
                    end = Some((number(1)?, number(2)?, sent));
                }
                "M" => return Err(bad("the ready masks ran out")),
                _ => return Err(bad("unknown record")),
            }
        }
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
        Ok(MultiReport {
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
            wall: Duration::ZERO,
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

/// Per beat, the stalled opportunities before the driver of
/// `tb::StreamDriver` (seeded `seed`, payload widths `widths`) raises
/// `valid` for it: each opportunity draws one chance, and a stall then
/// draws the garbage payload (`ceil(width / 64)` words per port).
pub fn driver_gaps(seed: u64, stall: f64, widths: &[usize], beats: usize) -> Result<Vec<u32>> {
    let mut rng = Prng::derived(seed, 1);
    let garbage_words: usize = widths.iter().map(|w| w.div_ceil(64)).sum();
    (0..beats)
        .map(|i| {
            let mut gap = 0u32;
            while rng.chance(stall) {
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

/// `lines` padded with `fill` to `MULTI_STIM_CHUNK` lines.
fn padded(lines: impl Iterator<Item = String>, fill: &str) -> Vec<String> {
    let mut v: Vec<String> = lines.collect();
    v.resize(MULTI_STIM_CHUNK, fill.to_string());
    v
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

/// The ready masks of the output streams: output `j` draws
/// `Prng::derived(stream_seed(seed, 100 + j), 2)` once per cycle, ready
/// with probability `1 - out_stall` (as `tb::StreamMonitor`).
struct ReadyMasks {
    streams: Vec<Prng>,
    stall: f64,
}

impl ReadyMasks {
    /// Lines of one 64-cycle word per stream, `lines` of them.
    fn next_lines(&mut self, lines: usize) -> String {
        let stall = self.stall;
        let mut text = String::new();
        for _ in 0..lines {
            let words: Vec<String> = self
                .streams
                .iter_mut()
                .map(|rng| {
                    let word = (0..64).fold(0u64, |w, k| w | (u64::from(!rng.chance(stall)) << k));
                    format!("{word:x}")
                })
                .collect();
            text.push_str(&words.join(" "));
            text.push('\n');
        }
        text
    }
}

/// The line that tells the draining reader the writer has stopped.
const MASKS_END: &str = "end\n";

/// The named pipe `MASKS_FIFO` and the thread writing the ready masks into
/// it ahead of vvp. Rust holds the pipe open for reading and writing, so a
/// write never meets a closed pipe (no SIGPIPE when vvp has exited; the
/// CLI restores SIGPIPE's default, which would end the process); when vvp
/// is done, `close` reads the pipe empty until the writer's end line, so a
/// writer blocked on a full pipe finishes.
struct MaskPipe {
    pipe: fs::File,
    path: PathBuf,
    stop: std::sync::Arc<std::sync::atomic::AtomicBool>,
    writer: std::thread::JoinHandle<()>,
}

impl MaskPipe {
    fn open(dir: &Path, config: &BenchConfig, outputs: usize) -> Result<MaskPipe> {
        let path = dir.join(MASKS_FIFO);
        let made = Command::new("mkfifo")
            .arg(&path)
            .status()
            .map_err(io_err(&path))?;
        if !made.success() {
            return Err(CosimError::ToolFailed {
                tool: "mkfifo".to_string(),
                command: format!("mkfifo {}", path.display()),
                log: String::new(),
            });
        }
        let pipe = fs::OpenOptions::new()
            .read(true)
            .write(true)
            .open(&path)
            .map_err(io_err(&path))?;
        let mut out = pipe.try_clone().map_err(io_err(&path))?;
        let mut masks = ReadyMasks {
            streams: (0..outputs)
                .map(|j| Prng::derived(stream_seed(config.seed, 100 + j), 2))
                .collect(),
            stall: config.out_stall,
        };
        let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let stopped = stop.clone();
        let writer = std::thread::spawn(move || loop {
            if stopped.load(std::sync::atomic::Ordering::SeqCst) {
                let _ = out.write_all(MASKS_END.as_bytes());
                return;
            }
            if out.write_all(masks.next_lines(16).as_bytes()).is_err() {
                return;
            }
        });
        Ok(MaskPipe {
            pipe,
            path,
            stop,
            writer,
        })
    }

    /// Stop the writer, read what is left until its end line, join it.
    fn close(mut self) -> Result<()> {
        use std::io::Read;
        self.stop.store(true, std::sync::atomic::Ordering::SeqCst);
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
