//! One stream-in, stream-out testbench run: driver, monitor, scoreboard,
//! accounting and watchdog around any `Engine`, and the re-run that writes a
//! VCD around the first mismatch.
//!
//! Per cycle: driver and monitor poke their inputs, `eval`, handshakes are
//! observed (`valid && ready`), outputs go to the scoreboard, then `step`.

use super::accounting::AccountingReport;
use super::driver::StreamDriver;
use super::monitor::StreamMonitor;
use super::scoreboard::{FieldDecoder, Mismatch, Scoreboard};
use super::stalls::{Stalls, StreamStalls};
use super::stop_rule::StopRule;
use super::stream::{StreamPorts, Transaction};
use super::trace_window::TraceWindow;
use super::watchdog::Hang;
use crate::engine::Engine;
use crate::error::Result;
use std::fmt;
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// Port names of the input and output streams.
#[derive(Clone, Debug)]
pub struct StreamNames {
    /// Input stream valid.
    pub in_valid: String,
    /// Input stream ready.
    pub in_ready: String,
    /// Input stream payload ports.
    pub in_payload: Vec<String>,
    /// Output stream valid.
    pub out_valid: String,
    /// Output stream ready.
    pub out_ready: String,
    /// Output stream payload ports.
    pub out_payload: Vec<String>,
}

impl StreamNames {
    /// The common shape: `in_valid`/`in_ready` with one payload port
    /// `in_<payload>`, and the same for `out`.
    pub fn single(payload: &str) -> Self {
        StreamNames {
            in_valid: "in_valid".into(),
            in_ready: "in_ready".into(),
            in_payload: vec![format!("in_{payload}")],
            out_valid: "out_valid".into(),
            out_ready: "out_ready".into(),
            out_payload: vec![format!("out_{payload}")],
        }
    }
}

/// One input record and the outputs it must produce, in order.
#[derive(Clone, Debug)]
pub struct Vector {
    /// Input payload.
    pub input: Transaction,
    /// Expected outputs (possibly none).
    pub outputs: Vec<Transaction>,
}

/// Knobs of a run.
#[derive(Clone, Debug)]
pub struct BenchConfig {
    /// Seed of the stall patterns (and garbage payloads).
    pub seed: u64,
    /// When the driver leaves valid low.
    pub in_stall: Stalls,
    /// When the monitor holds ready low.
    pub out_stall: Stalls,
    /// Named streams' own patterns, replacing `in_stall` or `out_stall` on
    /// those streams (multi-stream benches).
    pub stream_stalls: StreamStalls,
    /// Rising edges with reset held.
    pub reset_cycles: u32,
    /// Watchdog limit: cycles without any handshake.
    pub watchdog_cycles: u64,
    /// Stop at the first mismatch (otherwise run to the end and count them).
    pub stop_on_mismatch: bool,
    /// Where to write the VCD around the first mismatch (None: no VCD).
    pub vcd_path: Option<PathBuf>,
    /// Cycles traced either side of the mismatch.
    pub vcd_radius: u64,
    /// Trace only this instance path of the design (`u_a.u_b`), when given.
    pub wave_scope: Option<String>,
    /// Trace these cycles (first, last) into `vcd_path` in every run, passed
    /// or failed, instead of the cycles around a failure.
    pub wave_window: Option<(u64, u64)>,
    /// Command that reproduces this run, copied into the report.
    pub reproduce: Option<String>,
    /// Cycles run after the last expected output, so a duplicate that comes
    /// late is still counted.
    pub drain_cycles: u64,
}

impl BenchConfig {
    /// The pattern of input stream `name`'s driver.
    pub fn in_stall_of(&self, name: &str) -> Stalls {
        self.stream_stalls.of(name, self.in_stall)
    }

    /// The pattern of output stream `name`'s monitor.
    pub fn out_stall_of(&self, name: &str) -> Stalls {
        self.stream_stalls.of(name, self.out_stall)
    }
}

impl Default for BenchConfig {
    fn default() -> Self {
        BenchConfig {
            seed: 1,
            in_stall: Stalls::None,
            out_stall: Stalls::None,
            stream_stalls: StreamStalls::default(),
            reset_cycles: 2,
            watchdog_cycles: 1000,
            stop_on_mismatch: true,
            vcd_path: None,
            vcd_radius: 20,
            wave_scope: None,
            wave_window: None,
            reproduce: None,
            drain_cycles: 16,
        }
    }
}

/// What a run found.
#[derive(Clone, Debug)]
pub struct BenchReport {
    /// Engine name.
    pub engine: String,
    /// Seed used.
    pub seed: u64,
    /// Rising edges simulated, reset included.
    pub cycles: u64,
    /// Input records accepted by the design.
    pub inputs_sent: u64,
    /// Output transactions collected.
    pub outputs_received: u64,
    /// Outputs that matched.
    pub matched: u64,
    /// Outputs that did not.
    pub mismatches: u64,
    /// The first mismatch, decoded.
    pub first_mismatch: Option<Mismatch>,
    /// Nothing lost, nothing duplicated?
    pub accounting: AccountingReport,
    /// Set when the watchdog fired.
    pub hang: Option<Hang>,
    /// VCD written around the first mismatch or hang.
    pub vcd: Option<PathBuf>,
    /// Wall time of the run (not of a VCD re-run).
    pub wall: Duration,
    /// Command that reproduces the run.
    pub reproduce: Option<String>,
}

impl BenchReport {
    /// True when every output matched, the books balance and nothing hung.
    pub fn passed(&self) -> bool {
        self.mismatches == 0 && self.hang.is_none() && self.accounting.balanced()
    }

    /// Input records per cycle.
    pub fn inputs_per_cycle(&self) -> f64 {
        self.inputs_sent as f64 / self.cycles.max(1) as f64
    }

    /// The cycle a VCD should show: the first mismatch's, else the hang's.
    pub fn failure_cycle(&self) -> Option<u64> {
        let mismatch = self.first_mismatch.as_ref().map(|m| m.cycle);
        mismatch.or(self.hang.as_ref().map(|h| h.cycle))
    }
}

impl BenchReport {
    /// The report as JSON: counts, cycles, rate, wall time, and the first
    /// mismatch with its decoded fields.
    pub fn to_json(&self) -> serde_json::Value {
        use serde_json::json;
        let mismatch = self.first_mismatch.as_ref().map(|m| {
            json!({
                "cycle": m.cycle,
                "output_index": m.output_index,
                "input_record": m.input_id,
                "fields": m.fields.iter().map(|f| json!({
                    "name": f.name, "expected": f.expected, "got": f.got, "differs": f.differs(),
                })).collect::<Vec<_>>(),
            })
        });
        json!({
            "engine": self.engine,
            "seed": self.seed,
            "passed": self.passed(),
            "cycles": self.cycles,
            "transactions_in": self.inputs_sent,
            "transactions_out": self.outputs_received,
            "matched": self.matched,
            "mismatches": self.mismatches,
            "inputs_per_cycle": self.inputs_per_cycle(),
            "wall_seconds": self.wall.as_secs_f64(),
            "accounting": {
                "inputs": self.accounting.inputs,
                "expected_outputs": self.accounting.expected_outputs,
                "delivered_outputs": self.accounting.delivered_outputs,
                "duplicated_outputs": self.accounting.duplicated_outputs,
                "inputs_with_lost_outputs": self.accounting.inputs_with_lost_outputs,
                "balanced": self.accounting.balanced(),
            },
            "first_mismatch": mismatch,
            "hang": self.hang.as_ref().map(|h| json!({
                "cycle": h.cycle,
                "idle_cycles": h.idle_cycles,
                "ports": h.ports.iter().map(|(n, v)| json!({"name": n, "value": v})).collect::<Vec<_>>(),
            })),
            "vcd": self.vcd.as_ref().map(|p| p.display().to_string()),
            "reproduce": self.reproduce,
        })
    }
}

impl fmt::Display for BenchReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "{} seed {}: {} cycles, {} inputs, {} outputs, {} matched, {} mismatched, {:.3} inputs/cycle, {:?}",
            self.engine,
            self.seed,
            self.cycles,
            self.inputs_sent,
            self.outputs_received,
            self.matched,
            self.mismatches,
            self.inputs_per_cycle(),
            self.wall
        )?;
        writeln!(f, "{}", self.accounting)?;
        if let Some(m) = &self.first_mismatch {
            write!(f, "{m}")?;
        }
        if let Some(h) = &self.hang {
            write!(f, "{h}")?;
        }
        if let Some(v) = &self.vcd {
            writeln!(f, "VCD: {}", v.display())?;
        }
        if let Some(r) = &self.reproduce {
            writeln!(f, "reproduce: {r}")?;
        }
        Ok(())
    }
}

/// Progress of a run, given to the callback of `run_stream_bench_with_progress`.
#[derive(Clone, Copy, Debug)]
pub struct Progress {
    /// Cycles so far.
    pub cycle: u64,
    /// Outputs compared so far.
    pub outputs: u64,
    /// Outputs expected in total.
    pub expected_outputs: u64,
}

/// Cycles between two progress callbacks.
pub const PROGRESS_EVERY: u64 = 4096;

/// Run `vectors` through `engine` once; `window` optionally traces some cycles.
pub fn run_stream_bench(
    engine: &mut dyn Engine,
    names: &StreamNames,
    vectors: &[Vector],
    decoder: Option<Box<FieldDecoder>>,
    config: &BenchConfig,
    window: Option<TraceWindow>,
) -> Result<BenchReport> {
    run_stream_bench_with_progress(engine, names, vectors, decoder, config, window, &mut |_| {})
}

/// `run_stream_bench` calling `progress` every `PROGRESS_EVERY` cycles (for a progress bar).
pub fn run_stream_bench_with_progress(
    engine: &mut dyn Engine,
    names: &StreamNames,
    vectors: &[Vector],
    decoder: Option<Box<FieldDecoder>>,
    config: &BenchConfig,
    mut window: Option<TraceWindow>,
    progress: &mut dyn FnMut(Progress),
) -> Result<BenchReport> {
    let start = Instant::now();
    let design = engine.design().clone();
    let in_payload: Vec<&str> = names.in_payload.iter().map(String::as_str).collect();
    let out_payload: Vec<&str> = names.out_payload.iter().map(String::as_str).collect();
    let in_ports = StreamPorts::new(&design, &names.in_valid, &names.in_ready, &in_payload)?;
    let out_ports = StreamPorts::new(&design, &names.out_valid, &names.out_ready, &out_payload)?;
    let mut driver = StreamDriver::new(in_ports, config.seed, config.in_stall)?;
    let mut monitor = StreamMonitor::new(out_ports, config.seed, config.out_stall)?;
    let mut scoreboard = match decoder {
        Some(d) => Scoreboard::new(d),
        None => Scoreboard::with_port_names(names.out_payload.clone()),
    };
    for v in vectors {
        driver.push(v.input.clone());
        scoreboard.expect_input(v.outputs.clone());
    }
    let expected_outputs = scoreboard.outstanding() as u64;

    if let Some(w) = window.as_mut() {
        if w.from <= u64::from(config.reset_cycles) {
            w.update(engine)?;
        }
    }
    // Hold the handshake inputs low through reset.
    engine.poke_u64(design.port_id(&names.in_valid)?, 0)?;
    engine.poke_u64(design.port_id(&names.out_ready)?, 0)?;
    engine.reset(config.reset_cycles)?;

    let mut stop = StopRule::new(config, engine.cycle());
    loop {
        if let Some(w) = window.as_mut() {
            w.update(engine)?;
        }
        driver.drive(engine)?;
        monitor.drive(engine)?;
        engine.eval()?;
        if driver.observe(engine)?.is_some() {
            stop.progress(engine.cycle());
        }
        if let Some(txn) = monitor.observe(engine)? {
            stop.progress(engine.cycle());
            scoreboard.check(txn, engine.cycle());
        }
        let mismatch_stop = config.stop_on_mismatch && scoreboard.mismatches() > 0;
        let finished = driver.pending() == 0 && scoreboard.outstanding() == 0;
        if stop.stops_after(engine, finished, mismatch_stop) {
            break;
        }
        if stop.progress_due(engine.cycle()) {
            progress(Progress {
                cycle: engine.cycle(),
                outputs: scoreboard.compared(),
                expected_outputs,
            });
        }
        engine.step()?;
    }
    // Trace a few more cycles after a stop so the VCD shows what followed.
    if let Some(w) = window.as_mut() {
        while engine.cycle() <= w.to && (scoreboard.mismatches() > 0 || stop.hang().is_some()) {
            engine.step()?;
        }
        w.finish(engine)?;
    }
    Ok(BenchReport {
        engine: engine.name().to_string(),
        seed: config.seed,
        cycles: engine.cycle(),
        inputs_sent: driver.sent(),
        outputs_received: monitor.received(),
        matched: scoreboard.matched(),
        mismatches: scoreboard.mismatches(),
        first_mismatch: scoreboard.first_mismatch().cloned(),
        accounting: scoreboard.accounting().report(),
        hang: stop.into_hang(),
        vcd: window.map(|w| w.path),
        wall: start.elapsed(),
        reproduce: config.reproduce.clone(),
    })
}

/// Run once untraced; on a mismatch or hang, when `config.vcd_path` is set,
/// run again on a tracing engine (`make_engine(true)`) with the same seed and
/// write the cycles around the failure to that VCD. `progress` follows the
/// first run.
pub fn run_with_vcd_on_failure(
    make_engine: &mut dyn FnMut(bool) -> Result<Box<dyn Engine>>,
    names: &StreamNames,
    vectors: &[Vector],
    make_decoder: &dyn Fn() -> Option<Box<FieldDecoder>>,
    config: &BenchConfig,
    progress: &mut dyn FnMut(Progress),
) -> Result<BenchReport> {
    // Asked for a window: one traced run, whatever its outcome.
    let window = TraceWindow::asked(config);
    let asked = window.is_some();
    let mut engine = make_engine(asked)?;
    let mut report = run_stream_bench_with_progress(
        engine.as_mut(),
        names,
        vectors,
        make_decoder(),
        config,
        window,
        progress,
    )?;
    drop(engine);
    if asked {
        return Ok(report);
    }
    if let (Some(cycle), Some(path)) = (report.failure_cycle(), config.vcd_path.clone()) {
        let mut traced = make_engine(true)?;
        let window = TraceWindow::around_failure(config, cycle, path);
        let rerun = run_stream_bench(
            traced.as_mut(),
            names,
            vectors,
            make_decoder(),
            config,
            Some(window),
        )?;
        report.vcd = rerun.vcd;
    }
    Ok(report)
}
