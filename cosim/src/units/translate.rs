//! The translation unit's testbench, the same on rtl-gen's IR simulator
//! ([`crate::ir_engine::IrEngine`]), Verilator and Icarus Verilog.
//!
//! A transaction list (golden vectors) is cut into runs of one kind
//! (determine or apply). Each run goes through its stream with the
//! back-pressure of a stall pattern (`tb::Stalls`): the driver raises
//! `valid` when it says go and holds the payload until accepted; the
//! monitor raises `ready` when it says go. Outputs are compared in order, bit for bit,
//! with the golden expected outputs; a run ends when all its outputs
//! arrived (then nothing of it is in flight, so the next run's table
//! reads see every earlier write). Every cycle `done == idle && !idle
//! one cycle earlier`; at the end the sticky error bits equal what the
//! golden outputs imply. A watchdog fails a run that stops moving.

use std::fmt;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use golden::layout::{Layout, LayoutError};
use golden::translate::model::{ApplyCode, TranslateDesign, TranslateTxn};
use rtl_gen::translate::ports::{
    apply_out_layout, det_out_layout, pack_apply_in, pack_apply_out, pack_det_in, pack_det_out,
};
use rtl_gen::Bits;

use super::{EngineFactory, ProgressFn};
use crate::design::PortId;
use crate::engine::Engine;
use crate::error::CosimError;
use crate::export_tb::{ExportSpec, InputSpec, OutputSpec, StatusCheck, StreamSpec};
use crate::tb::{Prng, StallGen, TraceWindow};

/// Cycles without any handshake before the watchdog fails a run.
pub const WATCHDOG_CYCLES: u64 = 1000;

/// Cycles between two progress callbacks.
pub const PROGRESS_EVERY: u64 = 4096;

/// How one run is driven.
#[derive(Clone, Debug, Default)]
pub struct RunConfig {
    /// Seed of the driver's and the monitor's stall patterns.
    pub seed: u64,
    /// When the driver holds `valid` low / the monitor `ready` low.
    pub stall: crate::tb::Stalls,
    /// Trace only this instance path of the design (`u_a.u_b`), when given.
    pub wave_scope: Option<String>,
    /// Trace these cycles (first, last) whatever the outcome, instead of the
    /// cycles around a mismatch.
    pub wave_window: Option<(u64, u64)>,
    /// Test hook: the expected output of this transaction gets its lowest
    /// bit flipped, so a run that must fail can be made (`hiermerge cosim`
    /// reads it from `HIERMERGE_COSIM_FLIP_EXPECTED`).
    pub flip_expected: Option<usize>,
}

/// What a passing run measured.
#[derive(Clone, Debug, Default)]
pub struct Outcome {
    /// Engine name.
    pub engine: String,
    /// Transactions run (determine + apply).
    pub transactions: u64,
    /// Determine transactions.
    pub determine: u64,
    /// Apply transactions.
    pub apply: u64,
    /// Rising edges after reset.
    pub cycles: u64,
    /// Wall time of the run.
    pub wall: Duration,
}

impl Outcome {
    /// Transactions (records) per cycle.
    pub fn records_per_cycle(&self) -> f64 {
        self.transactions as f64 / self.cycles.max(1) as f64
    }
}

/// One field of an output record, expected against got.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FieldDiff {
    /// Field name (as in `rtl_gen::translate::ports`).
    pub name: String,
    /// Golden value.
    pub expected: u64,
    /// Value on the port.
    pub got: u64,
}

impl FieldDiff {
    /// True when the field differs.
    pub fn differs(&self) -> bool {
        self.expected != self.got
    }
}

/// The first failure of a run: a differing output (with `fields`), or a
/// protocol failure (`done`, `idle`, sticky error bits, a hang) described in `what`.
#[derive(Clone, Debug)]
pub struct Mismatch {
    /// Engine name.
    pub engine: String,
    /// Index in the transaction list of the failing transaction (for a
    /// failure at the end of the run: the number of transactions).
    pub transaction: usize,
    /// `determine`, `apply` or `end of run`.
    pub kind: &'static str,
    /// Engine cycle of the failure.
    pub cycle: u64,
    /// Seed of the stall patterns.
    pub seed: u64,
    /// Stall probability.
    pub stall: crate::tb::Stalls,
    /// Every output field, expected against got (empty for a protocol failure).
    pub fields: Vec<FieldDiff>,
    /// What went wrong, in words.
    pub what: String,
    /// A VCD of the cycles around the failure, when one was written.
    pub vcd: Option<PathBuf>,
}

impl fmt::Display for Mismatch {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "{}: transaction {} ({}), cycle {}, seed {}, stall {}: {}",
            self.engine, self.transaction, self.kind, self.cycle, self.seed, self.stall, self.what
        )?;
        for d in &self.fields {
            writeln!(
                f,
                "  {}{}: expected {:#x} got {:#x}",
                if d.differs() { "*" } else { " " },
                d.name,
                d.expected,
                d.got
            )?;
        }
        if let Some(v) = &self.vcd {
            writeln!(f, "VCD: {}", v.display())?;
        }
        Ok(())
    }
}

/// Why a run did not pass.
#[derive(Debug)]
pub enum Failure {
    /// The design disagreed with the golden model.
    Mismatch(Box<Mismatch>),
    /// The engine failed (build, port, simulator error).
    Engine(CosimError),
}

impl fmt::Display for Failure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Failure::Mismatch(m) => write!(f, "{m}"),
            Failure::Engine(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for Failure {}

impl From<CosimError> for Failure {
    fn from(e: CosimError) -> Failure {
        Failure::Engine(e)
    }
}

/// The ports the testbench drives or reads.
struct Ports {
    det: Side,
    app: Side,
    idle: PortId,
    done: PortId,
    det_error_seen: PortId,
    apply_error_seen: PortId,
}

struct Side {
    in_valid: PortId,
    in_data: PortId,
    in_ready: PortId,
    out_valid: PortId,
    out_data: PortId,
    out_ready: PortId,
    layout: Layout,
}

impl Ports {
    fn of(engine: &dyn Engine, d: &TranslateDesign) -> Result<Ports, CosimError> {
        let id = |n: &str| engine.port_id(n);
        let side = |p: &str, layout: Layout| -> Result<Side, CosimError> {
            Ok(Side {
                in_valid: id(&format!("{p}_in_valid"))?,
                in_data: id(&format!("{p}_in_data"))?,
                in_ready: id(&format!("{p}_in_ready"))?,
                out_valid: id(&format!("{p}_out_valid"))?,
                out_data: id(&format!("{p}_out_data"))?,
                out_ready: id(&format!("{p}_out_ready"))?,
                layout,
            })
        };
        Ok(Ports {
            det: side("det", det_out_layout(d))?,
            app: side("apply", apply_out_layout(d))?,
            idle: id("idle")?,
            done: id("done")?,
            det_error_seen: id("det_error_seen")?,
            apply_error_seen: id("apply_error_seen")?,
        })
    }
}

fn bit(engine: &dyn Engine, p: PortId) -> Result<bool, CosimError> {
    engine.peek_bool(p)
}

/// Flips bit 0 of `b` (the test hook of [`RunConfig::flip_expected`]).
fn flip_lowest_bit(b: &Bits) -> Bits {
    let mut flipped = b.clone();
    // A 0-bit value has no bit to flip; the hook then changes nothing.
    let _ = flipped.flip_bit(0);
    flipped
}

/// Packs a run's inputs and expected outputs; counts kinds and error
/// flags into `out` and `errs` (determine, apply).
fn pack_run(
    d: &TranslateDesign,
    txns: &[TranslateTxn],
    first: usize,
    flip: Option<usize>,
    out: &mut Outcome,
    errs: &mut (bool, bool),
) -> Result<(Vec<Bits>, Vec<Bits>), CosimError> {
    let refused = |i: usize, e: String| CosimError::Design {
        what: format!("transaction {i} does not fit the design's ports: {e}"),
    };
    let mut ins = Vec::new();
    let mut exps = Vec::new();
    for (k, t) in txns.iter().enumerate() {
        let i = first + k;
        let (input, mut expected) = match t {
            TranslateTxn::Determine(r) => {
                errs.0 |= r.outputs.ok == 0;
                out.determine += 1;
                (
                    pack_det_in(d, &r.inputs).map_err(|e| refused(i, format!("{e:?}")))?,
                    pack_det_out(d, &r.outputs).map_err(|e| refused(i, format!("{e:?}")))?,
                )
            }
            TranslateTxn::Apply(r) => {
                errs.1 |= r.outputs.code != ApplyCode::Ok;
                out.apply += 1;
                (
                    pack_apply_in(d, &r.inputs).map_err(|e| refused(i, format!("{e:?}")))?,
                    pack_apply_out(d, &r.outputs).map_err(|e| refused(i, format!("{e:?}")))?,
                )
            }
        };
        if flip == Some(i) {
            expected = flip_lowest_bit(&expected);
        }
        ins.push(input);
        exps.push(expected);
    }
    Ok((ins, exps))
}

/// Runs `txns` through `engine` (reset first) with the stall pattern
/// `config.stall` on both sides of every stream; returns what it measured,
/// or the first mismatch with every field decoded. `window` traces some
/// cycles to a VCD; `progress` is called every [`PROGRESS_EVERY`] cycles.
pub fn run(
    engine: &mut dyn Engine,
    d: &TranslateDesign,
    txns: &[TranslateTxn],
    config: &RunConfig,
    mut window: Option<&mut TraceWindow>,
    progress: &mut ProgressFn,
) -> Result<Outcome, Failure> {
    let started = Instant::now();
    let ports = Ports::of(engine, d)?;
    let (seed, stall) = (config.seed, config.stall);
    let mut drv_rng = Prng::new(seed ^ 0x5eed_d41e);
    let mut mon_rng = Prng::new(seed ^ 0x0b5e_77e5);
    crate::tb::driver::check_stalls(&stall)?;
    let (mut drv_stalls, mut mon_stalls) = (StallGen::new(stall), StallGen::new(stall));
    let fail = |engine: &dyn Engine, i: usize, kind: &'static str, what: String| {
        Failure::Mismatch(Box::new(Mismatch {
            engine: engine.name().to_string(),
            transaction: i,
            kind,
            cycle: engine.cycle(),
            seed,
            stall,
            fields: Vec::new(),
            what,
            vcd: None,
        }))
    };
    for p in [
        ports.det.in_valid,
        ports.app.in_valid,
        ports.det.out_ready,
        ports.app.out_ready,
    ] {
        engine.poke_u64(p, 0)?;
    }
    if let Some(w) = window.as_deref_mut() {
        w.update(engine)?;
    }
    engine.reset(2)?;
    let start = engine.cycle();
    let mut out = Outcome {
        engine: engine.name().to_string(),
        ..Outcome::default()
    };
    let mut idle_before = bit(engine, ports.idle)?;
    let mut errs = (false, false);
    let mut next_progress = start;
    let mut i = 0;
    let mut result = Ok(());
    'runs: while i < txns.len() {
        let is_det = matches!(txns[i], TranslateTxn::Determine(_));
        let kind = if is_det { "determine" } else { "apply" };
        let mut j = i;
        while j < txns.len() && matches!(txns[j], TranslateTxn::Determine(_)) == is_det {
            j += 1;
        }
        let side = if is_det { &ports.det } else { &ports.app };
        let (ins, exps) = pack_run(d, &txns[i..j], i, config.flip_expected, &mut out, &mut errs)?;
        let (mut sent, mut got, mut presenting) = (0usize, 0usize, false);
        let mut quiet = 0u64;
        while got < exps.len() {
            if let Some(w) = window.as_deref_mut() {
                w.update(engine)?;
            }
            if !presenting && sent < ins.len() && drv_stalls.go(&mut drv_rng) {
                presenting = true;
                engine.poke(side.in_data, &ins[sent])?;
            }
            engine.poke_u64(side.in_valid, presenting as u64)?;
            let ready = mon_stalls.go(&mut mon_rng);
            engine.poke_u64(side.out_ready, ready as u64)?;
            engine.eval()?;
            let mut moved = false;
            if presenting && bit(engine, side.in_ready)? {
                sent += 1;
                presenting = false;
                moved = true;
            }
            if ready && bit(engine, side.out_valid)? {
                let v = engine.peek(side.out_data)?;
                if v != exps[got] {
                    let mut f = fail(engine, i + got, kind, "output differs".into());
                    if let Failure::Mismatch(m) = &mut f {
                        match diff(&side.layout, &exps[got], &v) {
                            Ok(fields) => m.fields = fields,
                            Err(e) => m.what = format!("{}; {e}", m.what),
                        }
                    }
                    result = Err(f);
                    break 'runs;
                }
                got += 1;
                moved = true;
            }
            let idle = bit(engine, ports.idle)?;
            let done = bit(engine, ports.done)?;
            if done != (idle && !idle_before) {
                let what = format!(
                    "done = {done}, expected idle && !idle one cycle earlier = {}",
                    idle && !idle_before
                );
                result = Err(fail(engine, i + got, kind, what));
                break 'runs;
            }
            idle_before = idle;
            quiet = if moved { 0 } else { quiet + 1 };
            if quiet >= WATCHDOG_CYCLES {
                let what = format!("no handshake for {WATCHDOG_CYCLES} cycles");
                result = Err(fail(engine, i + got, kind, what));
                break 'runs;
            }
            if engine.cycle() >= next_progress {
                next_progress = engine.cycle() + PROGRESS_EVERY;
                progress((i + got) as u64, engine.cycle() - start);
            }
            engine.step()?;
        }
        engine.poke_u64(side.in_valid, 0)?;
        i = j;
    }
    if result.is_ok() {
        result = check_end(engine, &ports, errs, txns.len(), &fail);
    }
    if let Some(w) = window {
        // Trace the cycles after a failure too, so the VCD shows what followed.
        while result.is_err() && engine.cycle() <= w.to {
            w.update(engine)?;
            engine.step()?;
        }
        w.finish(engine)?;
    }
    result?;
    out.transactions = txns.len() as u64;
    out.cycles = engine.cycle() - start;
    out.wall = started.elapsed();
    progress(out.transactions, out.cycles);
    Ok(out)
}

/// After the last output: idle, and the sticky error bits as golden implies.
fn check_end(
    engine: &mut dyn Engine,
    ports: &Ports,
    (det_err, app_err): (bool, bool),
    n: usize,
    fail: &dyn Fn(&dyn Engine, usize, &'static str, String) -> Failure,
) -> Result<(), Failure> {
    engine.poke_u64(ports.det.out_ready, 0)?;
    engine.poke_u64(ports.app.out_ready, 0)?;
    engine.eval()?;
    let end = "end of run";
    if !bit(engine, ports.idle)? {
        return Err(fail(
            engine,
            n,
            end,
            "not idle after the last output".into(),
        ));
    }
    for (port, name, expected) in [
        (ports.det_error_seen, "det_error_seen", det_err),
        (ports.apply_error_seen, "apply_error_seen", app_err),
    ] {
        let got = bit(engine, port)?;
        if got != expected {
            return Err(fail(
                engine,
                n,
                end,
                format!("{name} = {got}, expected {expected}"),
            ));
        }
    }
    Ok(())
}

/// Every field of a payload, expected against got.
fn diff(layout: &Layout, expected: &Bits, got: &Bits) -> Result<Vec<FieldDiff>, LayoutError> {
    Ok(layout
        .unpack(expected)?
        .into_iter()
        .zip(layout.unpack(got)?)
        .map(|((name, e), (_, g))| FieldDiff {
            name: name.to_string(),
            expected: e,
            got: g,
        })
        .collect())
}

/// One side's streams of the exported testbench: inputs, their `after`
/// counts, expected outputs, their transactions.
#[derive(Default)]
struct ExportSide {
    ins: Vec<Bits>,
    after: Vec<u64>,
    expected: Vec<Bits>,
    transaction: Vec<u64>,
}

/// The exported testbench of `d` (`hiermerge export-tb --unit
/// translate`): `txns` on streams `det_in`/`det_out` and
/// `apply_in`/`apply_out`, each run of one kind after the previous run's
/// outputs (as [`run`] drives them), `done` checked against `idle` every
/// cycle and the sticky error bits at the end; the Verilog written to `rtl`.
pub fn export_spec(
    d: &TranslateDesign,
    txns: &[TranslateTxn],
    seed: u64,
    stalls: crate::tb::Stalls,
    rtl: &std::path::Path,
) -> Result<ExportSpec, CosimError> {
    let module = rtl_gen::translate::translate_unit(d);
    let design = crate::from_rtl::design_from_module(&module, rtl)?;
    let mut counts = Outcome::default();
    let mut errs = (false, false);
    let mut sides: [ExportSide; 2] = Default::default();
    let mut i = 0;
    while i < txns.len() {
        let is_det = matches!(txns[i], TranslateTxn::Determine(_));
        let mut j = i;
        while j < txns.len() && matches!(txns[j], TranslateTxn::Determine(_)) == is_det {
            j += 1;
        }
        let (ins, exps) = pack_run(d, &txns[i..j], i, None, &mut counts, &mut errs)?;
        let side = &mut sides[usize::from(!is_det)];
        for (k, (input, expected)) in ins.into_iter().zip(exps).enumerate() {
            side.ins.push(input);
            side.after.push(i as u64);
            side.expected.push(expected);
            side.transaction.push((i + k) as u64);
        }
        i = j;
    }
    let [det, app] = sides;
    let side = |p: &str, s: ExportSide, l: Layout| {
        (
            InputSpec {
                stream: StreamSpec::prefixed(&format!("{p}_in"), s.ins),
                after: s.after,
            },
            OutputSpec {
                stream: StreamSpec::prefixed(&format!("{p}_out"), s.expected),
                transaction: s.transaction,
                fields: l,
            },
        )
    };
    let (det_in, det_out) = side("det", det, det_out_layout(d));
    let (app_in, app_out) = side("apply", app, apply_out_layout(d));
    let at_end = |port: &str, value: bool| StatusCheck::AtEnd {
        port: port.into(),
        value: value.into(),
    };
    Ok(ExportSpec {
        design,
        transaction: "transaction".into(),
        transactions: txns.len() as u64,
        inputs: vec![det_in, app_in],
        outputs: vec![det_out, app_out],
        checks: vec![
            StatusCheck::DoneWhenIdleRises {
                done: "done".into(),
                idle: "idle".into(),
            },
            at_end("idle", true),
            at_end("det_error_seen", errs.0),
            at_end("apply_error_seen", errs.1),
        ],
        seed,
        stalls,
        stream_stalls: crate::tb::StreamStalls::default(),
        command: String::new(),
        store: None,
    })
}

/// Runs once on `make_engine(false)`; on a mismatch, when `vcd` is given,
/// runs the same transactions and seed again on `make_engine(true)` and
/// writes the cycles within `radius` of the failure to `vcd`.
pub fn run_with_vcd_on_mismatch(
    make_engine: &mut EngineFactory,
    d: &TranslateDesign,
    txns: &[TranslateTxn],
    config: &RunConfig,
    vcd: Option<PathBuf>,
    radius: u64,
    progress: &mut ProgressFn,
) -> Result<Outcome, Failure> {
    if let (Some((from, to)), Some(path)) = (config.wave_window, vcd.clone()) {
        // Asked for a window: one traced run, whatever its outcome.
        let mut traced = make_engine(true)?;
        let mut window = TraceWindow::cycles(from, to, path).with_scope(config.wave_scope.clone());
        let result = run(
            traced.as_mut(),
            d,
            txns,
            config,
            Some(&mut window),
            progress,
        );
        return match result {
            Err(Failure::Mismatch(mut m)) => {
                m.vcd = Some(window.path);
                Err(Failure::Mismatch(m))
            }
            other => other,
        };
    }
    let mut engine = make_engine(false)?;
    let first = run(engine.as_mut(), d, txns, config, None, progress);
    drop(engine);
    let (mut m, path) = match (first, vcd) {
        (Err(Failure::Mismatch(m)), Some(path)) => (m, path),
        (other, _) => return other,
    };
    let mut traced = make_engine(true)?;
    let mut window =
        TraceWindow::around(m.cycle, radius, path).with_scope(config.wave_scope.clone());
    // The re-run fails again at the same cycle (same seed, same vectors);
    // only its VCD is wanted.
    let _ = run(
        traced.as_mut(),
        d,
        txns,
        config,
        Some(&mut window),
        &mut |_, _| {},
    );
    m.vcd = Some(window.path);
    Err(Failure::Mismatch(m))
}
