//! What the multi-stream units (the merging module, the hierarchy merger)
//! share: the engine choice, how a run is driven, the test hooks (a Verilog
//! patch, a flipped expectation), the first mismatch decoded field by field,
//! the status-output rule, the stepped engines' factory, and one run of a
//! unit's streams on a stepped engine or the Icarus batch ([`run_multi`]).

use std::path::PathBuf;

use golden::bits::Bits;
use golden::layout::Layout;

use crate::design::Design;
use crate::engines::{open_engine, open_tracing_engine, EngineKind};
use crate::error::{CosimError, Result};
use crate::export_tb::{InputSpec, OutputSpec, StatusCheck, StreamSpec};
use crate::ir_engine::IrEngine;
use crate::tb::{
    run_multi_stream_bench_watching, BenchConfig, FieldDecoder, MultiReport, PulseCounts,
    StreamBeats, Transaction,
};
use crate::waves::WaveFormat;

/// `bits` decoded field by field: `(name, value in hex)` per field of
/// `layout`, in bit order; a field the beat does not hold shows its error.
pub fn decode_fields(bits: &Bits, layout: &Layout) -> Vec<(String, String)> {
    layout
        .fields()
        .map(|f| {
            let shown = match bits.get(f) {
                Ok(x) => format!("{x:#x}"),
                Err(e) => format!("({e})"),
            };
            (f.name.to_string(), shown)
        })
        .collect()
}

/// Decodes a single-payload beat with `layout` (a beat without payload
/// decodes to nothing).
pub fn beat_decoder(layout: Layout) -> Box<FieldDecoder> {
    Box::new(move |t: &Transaction| t.first().map_or(Vec::new(), |v| decode_fields(v, &layout)))
}

/// `expected` and `got` decoded with `decoder`, side by side: `(field,
/// expected, got)`, `(none)` where one side has fewer fields.
pub fn decoded_pair(
    decoder: &FieldDecoder,
    expected: &Transaction,
    got: &Transaction,
) -> Vec<(String, String, String)> {
    let (e, g) = (decoder(expected), decoder(got));
    let shown = |v: &[(String, String)], i: usize| {
        v.get(i)
            .map_or_else(|| "(none)".to_string(), |f| f.1.clone())
    };
    (0..e.len().max(g.len()))
        .map(|i| {
            let name = e.get(i).or(g.get(i)).map(|f| f.0.clone());
            (name.unwrap_or_default(), shown(&e, i), shown(&g, i))
        })
        .collect()
}

/// Where one multi-stream run goes.
pub enum MultiSim<'a> {
    /// An engine stepped from Rust (the IR simulator, Verilator, Icarus's
    /// pipe engine), kept by the caller so that chunks of a long run share
    /// one build.
    Stepped(&'a mut dyn crate::Engine),
    /// Icarus's multi-stream batch ([`crate::icarus::IcarusMultiBatch`]):
    /// the testbench is built for this run's streams, so each run builds it.
    Batch(&'a Design),
}

/// One run of `inputs` -> `outputs` on `sim`: every output beat compared bit
/// for bit with its expected beat, in order per stream, and the cycles each
/// 1-bit output of `pulses` is high counted. The report says whether the run
/// passed; an `Err` is a bench that could not run (a build, a missing port).
pub fn run_multi(
    sim: MultiSim,
    inputs: &[StreamBeats],
    outputs: &[StreamBeats],
    config: &BenchConfig,
    pulses: &[&str],
) -> Result<(MultiReport, PulseCounts)> {
    match sim {
        MultiSim::Stepped(engine) => {
            run_multi_stream_bench_watching(engine, inputs, outputs, config, pulses)
        }
        MultiSim::Batch(design) => {
            let names = |s: &[StreamBeats]| s.iter().map(|b| b.name.clone()).collect::<Vec<_>>();
            let (i, o) = (names(inputs), names(outputs));
            let i: Vec<&str> = i.iter().map(String::as_str).collect();
            let o: Vec<&str> = o.iter().map(String::as_str).collect();
            let batch = crate::icarus::IcarusMultiBatch::new_watching(design, &i, &o, pulses)?;
            let r = batch.run(inputs, outputs, config)?;
            Ok((r.report, r.pulses))
        }
    }
}

/// A unit's streams for a list of transactions (input beats, expected
/// output beats, in the unit's port order) with what the transactions
/// reached (`S`, per unit), so that a test can tell its stimulus met the
/// cases it is there for.
#[derive(Clone, Debug)]
pub struct StreamSet<S> {
    /// The input streams.
    pub inputs: Vec<StreamBeats>,
    /// The output streams: the beats expected, in order.
    pub outputs: Vec<StreamBeats>,
    /// What the transactions reached.
    pub seen: S,
}

impl<S> StreamSet<S> {
    /// One run of these streams on `sim` ([`run_multi`]).
    pub fn run(
        &self,
        sim: MultiSim,
        config: &BenchConfig,
        pulses: &[&str],
    ) -> Result<(MultiReport, PulseCounts)> {
        run_multi(sim, &self.inputs, &self.outputs, config, pulses)
    }
}

/// A packed beat as a one-payload transaction; a layout error names `unit`.
pub fn packed(
    beat: std::result::Result<Bits, golden::layout::LayoutError>,
    unit: &str,
) -> Result<Transaction> {
    beat.map(|b| vec![b]).map_err(|e| CosimError::Design {
        what: format!("{unit} beat: {e}"),
    })
}

/// Which simulator runs the unit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ModuleEngine {
    /// rtl-gen's IR simulator (`run_multi_stream_bench`).
    Ir,
    /// Verilator (`run_multi_stream_bench`).
    Verilator,
    /// Icarus, the multi-stream batch (one `vvp` run).
    Iverilog,
}

/// How one run is driven.
#[derive(Clone, Debug, Default)]
pub struct RunConfig {
    /// Seed of the stall patterns.
    pub seed: u64,
    /// The stall pattern of every driver and every monitor (each stream
    /// its own seed).
    pub stall: crate::tb::Stalls,
    /// Named streams' own patterns, replacing `stall` on them.
    pub stream_stalls: crate::tb::StreamStalls,
    /// Where the VCD around the first failure goes (None: no VCD).
    pub vcd_path: Option<PathBuf>,
    /// Cycles traced either side of the failure.
    pub vcd_radius: u64,
    /// Trace only this instance path of the design (`u_a.u_b`), when given.
    pub wave_scope: Option<String>,
    /// Trace these cycles (of the first chunk) whatever the outcome.
    pub wave_window: Option<(u64, u64)>,
    /// A deliberate break of the emitted Verilog (the test hook): its one
    /// occurrence of `from` replaced by `to` before simulation (Verilator
    /// and Icarus only: the IR engine does not read the Verilog).
    pub verilog_patch: Option<VerilogPatch>,
}

impl RunConfig {
    /// The format of the failure's waveform (its file name's) and the scope
    /// traced, for [`stepped_engines`].
    pub(crate) fn waves(&self) -> (WaveFormat, Option<String>) {
        let format = self
            .vcd_path
            .as_deref()
            .map_or(WaveFormat::Vcd, WaveFormat::of);
        (format, self.wave_scope.clone())
    }
}

/// One text replacement in the emitted Verilog.
#[derive(Clone, Debug)]
pub struct VerilogPatch {
    /// Text that must occur exactly once in the emitted files.
    pub from: String,
    /// What replaces it.
    pub to: String,
}

/// The status outputs whose pulses a run counts.
pub const PULSES: [&str; 2] = ["done", "idle"];

/// The first failing output beat, decoded (also the hierarchy merger's,
/// `merger::MergerMismatch`).
#[derive(Clone, Debug)]
pub struct ModuleMismatch {
    /// Output stream (`report` or `out`; the merger's: any of its outputs).
    pub stream: String,
    /// 0-based index of the beat on its stream (the merger: in its chunk).
    pub beat: u64,
    /// The merge it belongs to (the merger: over the whole run).
    pub merge: usize,
    /// Cycle of the transfer (the merger: from the start of its chunk).
    pub cycle: u64,
    /// (field, expected, got), decoded per stream.
    pub fields: Vec<(String, String, String)>,
}

/// The engine factory of a stepped run (IR or Verilator) for
/// `run_multi_with_vcd_on_failure`. A patched design is there to fail, so
/// it gets the tracing Verilator build from the start: the VCD rerun then
/// reuses that build instead of compiling the design a second time.
pub(crate) fn stepped_engines<'a>(
    module: &'a rtl_gen::Module,
    design: &'a Design,
    engine: ModuleEngine,
    patched: bool,
    waves: (WaveFormat, Option<String>),
) -> impl FnMut(bool) -> Result<Box<dyn crate::Engine>> + 'a {
    move |trace| match (engine, trace || patched) {
        (ModuleEngine::Ir, _) => Ok(Box::new(IrEngine::new(module, design)?)),
        (_, true) => {
            open_tracing_engine(EngineKind::Verilator, design, waves.0, waves.1.as_deref())
        }
        (_, false) => open_engine(EngineKind::Verilator, design, false),
    }
}

/// What the status outputs of a multi-stream unit got wrong, if anything:
/// `done` not high in exactly one cycle per merge, or `idle` low at the end
/// of `scope` (`the run`, `a chunk`).
pub fn status_failure(
    done_pulses: u64,
    merges: usize,
    idle_at_end: bool,
    scope: &str,
) -> Option<String> {
    let mut wrong = Vec::new();
    if done_pulses != merges as u64 {
        wrong.push(format!(
            "`done` pulsed {done_pulses} times for {merges} merges"
        ));
    }
    if !idle_at_end {
        wrong.push(format!("`idle` low at the end of {scope}"));
    }
    (!wrong.is_empty()).then(|| wrong.join("; "))
}

/// A multi-stream unit's streams for its exported testbench
/// ([`crate::export_tb`]): ports `<name>_valid`, `_ready`, `_data`, each
/// output beat under its merge, decoded with `fields(stream)`.
pub fn export_streams(
    streams: &super::chunked::UnitStreams,
    fields: impl Fn(&str) -> Layout,
) -> (Vec<InputSpec>, Vec<OutputSpec>) {
    let payload = |s: &crate::tb::StreamBeats| -> Vec<Bits> {
        s.beats.iter().filter_map(|t| t.first().cloned()).collect()
    };
    let inputs = streams
        .inputs
        .iter()
        .map(|s| InputSpec {
            stream: StreamSpec::prefixed(&s.name, payload(s)),
            after: Vec::new(),
        })
        .collect();
    let outputs = streams
        .outputs
        .iter()
        .enumerate()
        .map(|(o, s)| OutputSpec {
            stream: StreamSpec::prefixed(&s.name, payload(s)),
            transaction: (0..s.beats.len())
                .map(|b| streams.merge_of(o, b) as u64)
                .collect(),
            fields: fields(&s.name),
        })
        .collect();
    (inputs, outputs)
}

/// The status rules of [`status_failure`] for an exported testbench of
/// `merges` merges: `done` high once per merge, `idle` high at the end.
pub fn export_checks(merges: usize) -> Vec<StatusCheck> {
    vec![
        StatusCheck::Pulses {
            port: "done".into(),
            cycles: merges as u64,
            why: "one per merge".into(),
        },
        StatusCheck::AtEnd {
            port: "idle".into(),
            value: 1,
        },
    ]
}

/// Flips bit 0 of an expected beat (the `FLIP_EXPECTED` test hook).
pub(crate) fn flip_bit0(beat: &mut Bits) -> Result<()> {
    let mut w = beat.words().to_vec();
    if let Some(low) = w.first_mut() {
        *low ^= 1;
    }
    *beat = Bits::from_words(&w, beat.width())?;
    Ok(())
}

/// Replaces the one occurrence of `patch.from` in the design's Verilog;
/// refused on the IR engine, which simulates the module, not its Verilog.
pub(crate) fn apply_patch(
    design: &Design,
    patch: &VerilogPatch,
    engine: ModuleEngine,
) -> Result<()> {
    if engine == ModuleEngine::Ir {
        return Err(CosimError::Unsupported {
            what: "a Verilog patch on the IR engine (it simulates the module, not its Verilog)"
                .to_string(),
        });
    }
    patch_files(&design.verilog_files, patch, &design.top)
}

/// Replaces the one occurrence of `patch.from` in `files`, the emitted
/// Verilog of `top`; refused when it occurs other than once.
pub(crate) fn patch_files(
    files: &[std::path::PathBuf],
    patch: &VerilogPatch,
    top: &str,
) -> Result<()> {
    let mut found = Vec::new();
    for file in files {
        let text = std::fs::read_to_string(file).map_err(crate::error::io_err(file))?;
        let n = text.matches(patch.from.as_str()).count();
        if n > 0 {
            found.push((file, text, n));
        }
    }
    let total: usize = found.iter().map(|f| f.2).sum();
    if total != 1 {
        return Err(CosimError::Design {
            what: format!(
                "Verilog patch: `{}` occurs {total} times in the emitted files of `{top}`; expected exactly once",
                patch.from
            ),
        });
    }
    let (file, text, _) = &found[0];
    std::fs::write(file, text.replacen(patch.from.as_str(), &patch.to, 1))
        .map_err(crate::error::io_err(file.as_path()))
}
