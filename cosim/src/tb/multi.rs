//! A testbench run over any number of input and output streams: one
//! [`StreamDriver`] per input, one [`StreamMonitor`] and in-order
//! [`Scoreboard`] per output, each with its own seeded stall pattern, one
//! watchdog over all handshakes. For units whose streams are related only
//! through the design (the merging module's `cfg`, `in*`, `report`, `out`):
//! the drivers present every stream's beats as soon as they may, so the
//! design meets every interleaving the stall patterns produce.

use super::bench::Progress;
use super::driver::StreamDriver;
use super::monitor::StreamMonitor;
use super::scoreboard::{Mismatch, Scoreboard};
use super::stalls::StreamStalls;
use super::stop_rule::StopRule;
use super::stream::{StreamPorts, Transaction};
use super::trace_window::TraceWindow;
use super::watchdog::Hang;
use super::BenchConfig;
use crate::engine::Engine;
use crate::error::{CosimError, Result};
use std::fmt;
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// The seed of stream `j`'s stall pattern in a multi-stream bench run from
/// `seed` (input `j`: `j`, output `j`: `100 + j`): distinct per stream, and
/// the one definition the Icarus batch replays.
pub fn stream_seed(seed: u64, j: usize) -> u64 {
    seed ^ 0x9e37_79b9_7f4a_7c15u64.wrapping_mul(j as u64 + 1)
}

/// One stream: ports `<name>_valid`, `<name>_ready`, `<name>_data`, and its
/// beats (to send, or expected in order).
#[derive(Clone, Debug)]
pub struct StreamBeats {
    /// The stream's port prefix.
    pub name: String,
    /// Its beats in order, each the values of its payload ports.
    pub beats: Vec<Transaction>,
}

/// What a multi-stream run found, per stream and in all.
#[derive(Clone, Debug)]
pub struct MultiReport {
    /// The engine that ran the bench.
    pub engine: String,
    /// The seed of the stall patterns.
    pub seed: u64,
    /// Rising clock edges the engine has taken ([`Engine::cycle`], reset included).
    pub cycles: u64,
    /// Beats accepted per input stream, in the order given.
    pub sent: Vec<(String, u64)>,
    /// Beats received per output stream.
    pub received: Vec<(String, u64)>,
    /// Output beats equal to the expected beat, all streams.
    pub matched: u64,
    /// Output beats that differ from the expected beat, all streams.
    pub mismatches: u64,
    /// The first mismatch and the stream it was on.
    pub first_mismatch: Option<(String, Mismatch)>,
    /// Expected beats that never came, per output stream.
    pub missing: Vec<(String, usize)>,
    /// The watchdog's report when no stream moved for too long.
    pub hang: Option<Hang>,
    /// VCD written around the first mismatch or hang.
    pub vcd: Option<PathBuf>,
    /// Wall time of the bench (the build excluded).
    pub wall: Duration,
    /// Per stream (inputs, then outputs): the cycles of its first and last
    /// transfer (stepped engines; empty from the Icarus batch).
    pub active: Vec<ActiveWindow>,
}

/// When a stream moved beats: its first and last transfer.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ActiveWindow {
    /// The stream.
    pub name: String,
    /// Beats it moved.
    pub beats: u64,
    /// The cycle of its first transfer.
    pub first: u64,
    /// The cycle of its last transfer.
    pub last: u64,
}

impl ActiveWindow {
    /// Beats per cycle from the first transfer to the last: 1.0 is a
    /// stream with no bubble while it was busy.
    pub fn rate(&self) -> f64 {
        self.beats as f64 / (self.last - self.first + 1) as f64
    }
}

/// Cycles each watched 1-bit output was high, by name.
pub type PulseCounts = Vec<(String, u64)>;

/// What the watched 1-bit outputs did in a run.
#[derive(Clone, Debug, Default)]
pub struct PulseWatch {
    /// Cycles each was high.
    pub counts: PulseCounts,
    /// Whether each was high in the last cycle.
    pub at_end: Vec<(String, bool)>,
    /// The first cycle each was high (stepped engines; empty from a batch).
    pub first_high: Vec<(String, Option<u64>)>,
}

impl MultiReport {
    /// Every beat matched, none missing, nothing hung.
    pub fn passed(&self) -> bool {
        self.mismatches == 0 && self.hang.is_none() && self.missing.iter().all(|m| m.1 == 0)
    }

    /// The cycle a VCD should show: the earliest mismatch on any stream,
    /// else the hang's.
    pub fn failure_cycle(&self) -> Option<u64> {
        let mismatch = self.first_mismatch.as_ref().map(|m| m.1.cycle);
        mismatch.or(self.hang.as_ref().map(|h| h.cycle))
    }

    /// The active window of stream `name`, if it moved any beat.
    pub fn active(&self, name: &str) -> Option<&ActiveWindow> {
        self.active.iter().find(|w| w.name == name)
    }

    /// Beats accepted on input stream `name` per cycle.
    pub fn sent_per_cycle(&self, name: &str) -> f64 {
        let n = self.sent.iter().find(|s| s.0 == name).map_or(0, |s| s.1);
        n as f64 / self.cycles.max(1) as f64
    }
}

impl fmt::Display for MultiReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "{} seed {}: {} cycles, {} matched, {} mismatches, {:.2?}",
            self.engine, self.seed, self.cycles, self.matched, self.mismatches, self.wall
        )?;
        for (name, n) in &self.sent {
            writeln!(f, "  in  {name}: {n} beats")?;
        }
        for ((name, n), (_, missing)) in self.received.iter().zip(&self.missing) {
            writeln!(
                f,
                "  out {name}: {n} beats, {missing} expected beats missing"
            )?;
        }
        if let Some((stream, m)) = &self.first_mismatch {
            writeln!(f, "  first mismatch on {stream}:\n{m}")?;
        }
        if let Some(h) = &self.hang {
            writeln!(f, "  {h}")?;
        }
        if let Some(v) = &self.vcd {
            writeln!(f, "  VCD: {}", v.display())?;
        }
        Ok(())
    }
}

fn ports(engine: &dyn Engine, name: &str) -> Result<StreamPorts> {
    StreamPorts::new(
        engine.design(),
        &format!("{name}_valid"),
        &format!("{name}_ready"),
        &[&format!("{name}_data")],
    )
}

/// Runs `inputs` into and `outputs` out of the design on `engine` with the
/// stall probabilities, seed, reset and watchdog of `config`.
pub fn run_multi_stream_bench(
    engine: &mut dyn Engine,
    inputs: &[StreamBeats],
    outputs: &[StreamBeats],
    config: &BenchConfig,
) -> Result<MultiReport> {
    run_multi_stream_bench_watching(engine, inputs, outputs, config, &[]).map(|r| r.0)
}

/// [`run_multi_stream_bench`] also counting, per cycle, the 1-bit outputs
/// named in `pulses` that are high (status pulses such as `done`).
pub fn run_multi_stream_bench_watching(
    engine: &mut dyn Engine,
    inputs: &[StreamBeats],
    outputs: &[StreamBeats],
    config: &BenchConfig,
    pulses: &[&str],
) -> Result<(MultiReport, PulseCounts)> {
    run_multi_stream_bench_traced(engine, inputs, outputs, config, pulses, None, &mut |_| {})
        .map(|(r, w)| (r, w.counts))
}

/// [`run_multi_stream_bench_watching`] with the watched outputs' values at
/// the end, `window` optionally tracing some cycles (and a few after a stop
/// on a failure), and `progress` called every `PROGRESS_EVERY` cycles.
pub fn run_multi_stream_bench_traced(
    engine: &mut dyn Engine,
    inputs: &[StreamBeats],
    outputs: &[StreamBeats],
    config: &BenchConfig,
    pulses: &[&str],
    window: Option<TraceWindow>,
    progress: &mut dyn FnMut(Progress),
) -> Result<(MultiReport, PulseWatch)> {
    let hooks = Hooks {
        pulses,
        window,
        progress,
        reactor: None,
    };
    bench_loop(engine, inputs, outputs, config, hooks)
}

/// Refuses a stall pattern for a stream `design` does not have (a stream:
/// a port `<name>_valid`), listing the streams it has.
pub fn check_stream_stalls(design: &crate::design::Design, own: &StreamStalls) -> Result<()> {
    let streams = design
        .ports
        .iter()
        .filter_map(|p| p.name.strip_suffix("_valid"));
    own.check_names(streams)
        .map_err(|what| CosimError::Bench { what })
}

/// A model the bench steps with the design that answers what the design
/// asks (a store answering `store_req` on `store_resp`), so its input
/// beats cannot be precomputed.
pub trait Reactor {
    /// Drives its inputs for this cycle (before `eval`); `sent`: the beats
    /// each input stream of the bench has sent so far.
    fn drive(&mut self, engine: &mut dyn Engine, sent: &[u64]) -> Result<()>;
    /// After `eval`: whether one of its handshakes moved.
    fn observe(&mut self, engine: &dyn Engine) -> Result<bool>;
    /// Nothing of its own is left to deliver.
    fn finished(&self) -> bool;
}

/// [`run_multi_stream_bench_watching`] with `reactor` stepped alongside
/// the drivers and monitors: the run finishes only once it has nothing
/// left to deliver, and its handshakes count as progress for the watchdog.
/// It runs once, so it traces only the window `config` asks for
/// (`wave_window`; the engine opened with tracing), not one around a
/// failure.
pub fn run_multi_stream_bench_reactive(
    engine: &mut dyn Engine,
    inputs: &[StreamBeats],
    outputs: &[StreamBeats],
    config: &BenchConfig,
    pulses: &[&str],
    reactor: &mut dyn Reactor,
) -> Result<(MultiReport, PulseWatch)> {
    let hooks = Hooks {
        pulses,
        window: TraceWindow::asked(config),
        progress: &mut |_| {},
        reactor: Some(reactor),
    };
    bench_loop(engine, inputs, outputs, config, hooks)
}

/// What a bench run watches and calls besides its streams.
struct Hooks<'a> {
    pulses: &'a [&'a str],
    window: Option<TraceWindow>,
    progress: &'a mut dyn FnMut(Progress),
    reactor: Option<&'a mut dyn Reactor>,
}

fn bench_loop(
    engine: &mut dyn Engine,
    inputs: &[StreamBeats],
    outputs: &[StreamBeats],
    config: &BenchConfig,
    hooks: Hooks<'_>,
) -> Result<(MultiReport, PulseWatch)> {
    let Hooks {
        pulses,
        mut window,
        progress,
        mut reactor,
    } = hooks;
    let start = Instant::now();
    // Distinct stall patterns per stream from one seed.
    let seed_of = |j: usize| stream_seed(config.seed, j);
    check_stream_stalls(engine.design(), &config.stream_stalls)?;
    let mut drivers = Vec::new();
    for (j, s) in inputs.iter().enumerate() {
        let stalls = config.in_stall_of(&s.name);
        let mut d = StreamDriver::new(ports(engine, &s.name)?, seed_of(j), stalls)?;
        for b in &s.beats {
            d.push(b.clone());
        }
        engine.poke_u64(engine.design().port_id(&format!("{}_valid", s.name))?, 0)?;
        drivers.push(d);
    }
    let mut monitors = Vec::new();
    for (j, s) in outputs.iter().enumerate() {
        let p = ports(engine, &s.name)?;
        let mut board = Scoreboard::with_port_names(p.payload_names.clone());
        board.expect_input(s.beats.clone());
        let mon = StreamMonitor::new(p, seed_of(100 + j), config.out_stall_of(&s.name))?;
        engine.poke_u64(engine.design().port_id(&format!("{}_ready", s.name))?, 0)?;
        monitors.push((mon, board));
    }
    let expected_outputs: u64 = outputs.iter().map(|s| s.beats.len() as u64).sum();
    if let Some(w) = window.as_mut() {
        if w.from <= u64::from(config.reset_cycles) {
            w.update(engine)?;
        }
    }
    engine.reset(config.reset_cycles)?;
    let pulse_ids = pulses
        .iter()
        .map(|p| engine.design().port_id(p))
        .collect::<Result<Vec<_>>>()?;
    let mut pulse_counts = vec![0u64; pulses.len()];
    let mut first_high: Vec<Option<u64>> = vec![None; pulses.len()];

    let mut stop = StopRule::new(config, engine.cycle());
    // Per stream (inputs, then outputs): beats, first and last transfer.
    let mut windows: Vec<(u64, u64, u64)> = vec![(0, 0, 0); inputs.len() + outputs.len()];
    let moved = |w: &mut (u64, u64, u64), cycle: u64| {
        if w.0 == 0 {
            w.1 = cycle;
        }
        w.0 += 1;
        w.2 = cycle;
    };
    loop {
        if let Some(w) = window.as_mut() {
            w.update(engine)?;
        }
        for d in drivers.iter_mut() {
            d.drive(engine)?;
        }
        for (mon, _) in monitors.iter_mut() {
            mon.drive(engine)?;
        }
        if let Some(r) = reactor.as_mut() {
            let sent: Vec<u64> = drivers.iter().map(StreamDriver::sent).collect();
            r.drive(engine, &sent)?;
        }
        engine.eval()?;
        for ((n, id), first) in pulse_counts.iter_mut().zip(&pulse_ids).zip(&mut first_high) {
            let high = engine.peek_bool(*id)?;
            *n += high as u64;
            if high && first.is_none() {
                *first = Some(engine.cycle());
            }
        }
        for (j, d) in drivers.iter_mut().enumerate() {
            if d.observe(engine)?.is_some() {
                stop.progress(engine.cycle());
                moved(&mut windows[j], engine.cycle());
            }
        }
        for (j, (mon, board)) in monitors.iter_mut().enumerate() {
            if let Some(txn) = mon.observe(engine)? {
                stop.progress(engine.cycle());
                moved(&mut windows[inputs.len() + j], engine.cycle());
                board.check(txn, engine.cycle());
            }
        }
        if let Some(r) = reactor.as_mut() {
            if r.observe(engine)? {
                stop.progress(engine.cycle());
            }
        }
        let mismatched = monitors.iter().any(|(_, b)| b.mismatches() > 0);
        let finished = drivers.iter().all(|d| d.pending() == 0)
            && monitors.iter().all(|(_, b)| b.outstanding() == 0)
            && reactor.as_ref().is_none_or(|r| r.finished());
        if stop.stops_after(engine, finished, config.stop_on_mismatch && mismatched) {
            break;
        }
        if stop.progress_due(engine.cycle()) {
            progress(Progress {
                cycle: engine.cycle(),
                outputs: monitors.iter().map(|(_, b)| b.compared()).sum(),
                expected_outputs,
            });
        }
        engine.step()?;
    }
    let at_end = pulse_ids
        .iter()
        .map(|&id| engine.peek_bool(id))
        .collect::<Result<Vec<bool>>>()?;
    // Trace a few more cycles after a failure so the VCD shows what followed.
    if let Some(w) = window.as_mut() {
        let failed = stop.hang().is_some() || monitors.iter().any(|(_, b)| b.mismatches() > 0);
        while failed && engine.cycle() <= w.to {
            engine.step()?;
        }
        w.finish(engine)?;
    }
    let first_mismatch = outputs
        .iter()
        .zip(&monitors)
        .filter_map(|(s, (_, b))| b.first_mismatch().map(|m| (s.name.clone(), m.clone())))
        .min_by_key(|(_, m)| m.cycle);
    let report = MultiReport {
        engine: engine.name().to_string(),
        seed: config.seed,
        cycles: engine.cycle(),
        sent: inputs
            .iter()
            .zip(&drivers)
            .map(|(s, d)| (s.name.clone(), d.sent()))
            .collect(),
        received: outputs
            .iter()
            .zip(&monitors)
            .map(|(s, (m, _))| (s.name.clone(), m.received()))
            .collect(),
        matched: monitors.iter().map(|(_, b)| b.matched()).sum(),
        mismatches: monitors.iter().map(|(_, b)| b.mismatches()).sum(),
        first_mismatch,
        missing: outputs
            .iter()
            .zip(&monitors)
            .map(|(s, (_, b))| (s.name.clone(), b.outstanding()))
            .collect(),
        hang: stop.into_hang(),
        vcd: window.map(|w| w.path),
        wall: start.elapsed(),
        active: inputs
            .iter()
            .chain(outputs)
            .zip(&windows)
            .filter(|(_, w)| w.0 > 0)
            .map(|(s, w)| ActiveWindow {
                name: s.name.clone(),
                beats: w.0,
                first: w.1,
                last: w.2,
            })
            .collect(),
    };
    let names = pulses.iter().map(|p| p.to_string());
    let watch = PulseWatch {
        counts: names.clone().zip(pulse_counts).collect(),
        at_end: names.clone().zip(at_end).collect(),
        first_high: names.zip(first_high).collect(),
    };
    Ok((report, watch))
}

/// Run once untraced ([`run_multi_stream_bench_traced`]); on a mismatch or
/// hang, when `config.vcd_path` is set, run again on a tracing engine
/// (`make_engine(true)`) with the same seed and write the cycles within
/// `config.vcd_radius` of the first failure (the earliest mismatch on any
/// stream, else the hang) to that VCD (`MultiReport::vcd`).
pub fn run_multi_with_vcd_on_failure(
    make_engine: &mut dyn FnMut(bool) -> Result<Box<dyn Engine>>,
    inputs: &[StreamBeats],
    outputs: &[StreamBeats],
    config: &BenchConfig,
    pulses: &[&str],
    progress: &mut dyn FnMut(Progress),
) -> Result<(MultiReport, PulseWatch)> {
    // Asked for a window: one traced run, whatever its outcome.
    let window = TraceWindow::asked(config);
    let asked = window.is_some();
    let mut engine = make_engine(asked)?;
    let (mut report, watch) = run_multi_stream_bench_traced(
        engine.as_mut(),
        inputs,
        outputs,
        config,
        pulses,
        window,
        progress,
    )?;
    drop(engine);
    if asked {
        return Ok((report, watch));
    }
    if let (Some(cycle), Some(path)) = (report.failure_cycle(), config.vcd_path.clone()) {
        let mut traced = make_engine(true)?;
        let window = TraceWindow::around_failure(config, cycle, path);
        let (rerun, _) = run_multi_stream_bench_traced(
            traced.as_mut(),
            inputs,
            outputs,
            config,
            pulses,
            Some(window),
            &mut |_| {},
        )?;
        report.vcd = rerun.vcd;
    }
    Ok((report, watch))
}
