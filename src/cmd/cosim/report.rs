//! The report of a `hiermerge cosim` run: its counts and rates, its first
//! mismatch decoded field by field, the text form, and the failure of a
//! multi-stream run that ended without a mismatched beat.

use std::path::PathBuf;

use cosim::units::chunked::ChunkTotals;
use cosim::units::merge_module::ModuleMismatch;
use serde::Serialize;

use super::command_line::reproduce;
use super::{Args, Unit};

#[derive(Serialize, Clone, Debug)]
pub(super) struct FieldReport {
    pub(super) name: String,
    pub(super) expected: String,
    pub(super) got: String,
    pub(super) differs: bool,
}

#[derive(Serialize, Clone, Debug)]
pub(super) struct MismatchReport {
    pub(super) transaction: u64,
    /// Merging module: the output stream (`report`, `out`) and the beat's
    /// index on it.
    pub(super) stream: Option<String>,
    pub(super) beat: Option<u64>,
    pub(super) kind: String,
    pub(super) cycle: u64,
    pub(super) seed: u64,
    pub(super) what: String,
    pub(super) fields: Vec<FieldReport>,
}

#[derive(Serialize)]
pub(super) struct Report {
    pub(super) unit: Unit,
    pub(super) stage: &'static str,
    pub(super) engine: &'static str,
    pub(super) seed: u64,
    /// The coin's probability (null with another pattern).
    pub(super) stall: Option<f64>,
    /// The stall pattern (`coin:0.3`, `bursty:16,16`, `periodic:1/3`, `none`).
    pub(super) stalls: String,
    /// Streams with their own pattern (`--stall-stream`), `STREAM=PATTERN`.
    pub(super) stream_stalls: Vec<String>,
    pub(super) vectors: Option<String>,
    pub(super) passed: bool,
    #[serde(flatten)]
    pub(super) counts: Counts,
    pub(super) records_per_cycle: f64,
    pub(super) nodes_per_cycle: f64,
    /// Simulation speed of the engine under the testbench: cycles / wall_seconds.
    pub(super) cycles_per_second: f64,
    pub(super) first_mismatch: Option<MismatchReport>,
    pub(super) vcd: Option<String>,
    pub(super) reproduce: Option<String>,
    /// --unit merger: what the merges exercised.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) merger: Option<MergerReport>,
    /// --unit hierarchy: what the cases exercised.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) hierarchy: Option<HierarchyReport>,
}

/// What `--unit hierarchy`'s cases exercised.
#[derive(Serialize)]
pub(super) struct HierarchyReport {
    /// Determine commands; those that rewrote an entry an earlier merge of
    /// their chunk read; those whose placement lay off the grid.
    pub(super) determines: u64,
    pub(super) rewrites: u64,
    pub(super) residuals: u64,
    /// Merges of golden's named hard cases (`--merges hard`).
    pub(super) hard_cases: u64,
    /// Merges golden refused, and merges with a fetcher error.
    pub(super) refused: u64,
    pub(super) fetch_errors: u64,
    /// Wall time of generating the golden stimulus (not in wall_seconds).
    pub(super) golden_seconds: f64,
    /// The simulated top module: the configuration, as the generator names it.
    pub(super) top: String,
    /// Digests of the simulated netlist and of the stimulus (SPEC 10.2).
    pub(super) netlist_sha256: String,
    pub(super) stimulus_sha256: String,
}

/// What `--unit merger`'s merges exercised.
#[derive(Serialize)]
pub(super) struct MergerReport {
    /// Chunks of at most 10,000 merges, each run from reset.
    pub(super) chunks: u64,
    pub(super) refused: u64,
    pub(super) fetch_errors: u64,
    /// References written (`refs` beats).
    pub(super) refs_written: u64,
    /// Beats accepted on every input stream and out on every output stream.
    pub(super) beats_in: u64,
    pub(super) beats_out: u64,
    pub(super) leaves_above: u64,
    /// Merges whose leaves overflow a leaf FIFO (`leaf_overflow`).
    pub(super) leaf_overflows: u64,
    pub(super) materialized: u64,
    pub(super) several_roots: u64,
    /// Per-node merges of more than one pass, and voxels that descended.
    pub(super) multi_pass: u64,
    pub(super) descents: u64,
    /// One `done` pulse per merge expected.
    pub(super) done_pulses: u64,
    /// Wall time of generating the golden stimulus (not in wall_seconds).
    pub(super) golden_seconds: f64,
    /// The simulated top module: the configuration, as the generator names it.
    pub(super) top: String,
    /// Digests of the simulated netlist and of the stimulus (SPEC 10.2).
    pub(super) netlist_sha256: String,
    pub(super) stimulus_sha256: String,
    /// `--store-port shared`: the port's reads and throughput.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) store: Option<StoreReport>,
}

/// The shared store port of a `--unit merger` run: its reads against the
/// one read per clock it allows.
#[derive(Serialize)]
pub(super) struct StoreReport {
    /// `shared:T` (a tag FIFO of 2^T reads).
    pub(super) port: String,
    /// Clocks from a read taken to its answer, at the earliest.
    pub(super) latency: u64,
    /// `store_req` beats, and the reads golden's units make.
    pub(super) reads: u64,
    pub(super) expected_reads: u64,
    pub(super) reads_per_cycle: f64,
    /// Records into the merging module per cycle, and per cycle at one
    /// read per clock (`records / reads`).
    pub(super) records_per_cycle: f64,
    pub(super) records_allowed_per_cycle: f64,
    /// Node records written per cycle, and per cycle at one read per clock.
    pub(super) nodes_per_cycle: f64,
    pub(super) nodes_allowed_per_cycle: f64,
    /// Records per cycle against what the port allows (= reads per cycle).
    pub(super) of_port: f64,
    /// Cycles from some merge's first read to its last (overlapping merges'
    /// common cycles once), and the reads per such cycle: the port's use
    /// while the merges read, the
    /// rest of the cycles being the merger's phases without reads (`cfg`,
    /// the choice between the passes, the builder and the writer's tail).
    pub(super) read_window_cycles: u64,
    pub(super) reads_per_window_cycle: f64,
}

/// What a run counted (the report's counts, [`finish_report`]).
#[derive(Serialize)]
pub(super) struct Counts {
    pub(super) transactions: u64,
    /// Input records (translate: transactions; merge: beats on in0..;
    /// merge-level: input beats; merger: beats into its merging module;
    /// hierarchy: determine commands).
    pub(super) records: u64,
    /// Output records (translate: transactions; merge: report and out
    /// beats; merge-level: base-node/reference beats; merger, hierarchy:
    /// node records written).
    pub(super) nodes: u64,
    pub(super) mismatches: u64,
    pub(super) cycles: u64,
    /// Of the bench: the Verilator build and the Icarus compile excluded.
    pub(super) wall_seconds: f64,
}

/// The report of a finished run: its counts, the rates derived from them,
/// and on a failure the reproduce command.
pub(super) fn finish_report(
    a: &Args,
    stage: &'static str,
    flip: Option<usize>,
    counts: Counts,
    first_mismatch: Option<MismatchReport>,
    vcd: Option<&PathBuf>,
) -> Result<Report, String> {
    let passed = first_mismatch.is_none();
    let per_cycle = |n: u64| n as f64 / counts.cycles.max(1) as f64;
    Ok(Report {
        unit: a.unit,
        stage,
        engine: a.engine.name(),
        seed: a.seed,
        stall: match super::stalls(a)? {
            cosim::tb::Stalls::Coin(p) => Some(p),
            _ => None,
        },
        stalls: super::stalls(a)?.to_string(),
        stream_stalls: super::stream_stalls(a)?
            .iter()
            .map(|(name, s)| format!("{name}={s}"))
            .collect(),
        vectors: a.vectors.as_ref().map(|p| p.display().to_string()),
        passed,
        records_per_cycle: per_cycle(counts.records),
        nodes_per_cycle: per_cycle(counts.nodes),
        cycles_per_second: crate::report::per_second(counts.cycles as f64, counts.wall_seconds),
        counts,
        first_mismatch,
        vcd: vcd.map(|p| p.display().to_string()),
        reproduce: if passed {
            None
        } else {
            Some(reproduce(a, flip)?)
        },
        merger: None,
        hierarchy: None,
    })
}

/// The report of a multi-stream unit's first mismatched beat: its merge,
/// stream and beat, each field of the stream's layout expected against got.
/// The beat index counts from the start of its chunk.
fn stream_mismatch(kind: &str, m: &ModuleMismatch, seed: u64) -> MismatchReport {
    MismatchReport {
        transaction: m.merge as u64,
        stream: Some(m.stream.clone()),
        beat: Some(m.beat),
        kind: kind.to_string(),
        cycle: m.cycle,
        seed,
        what: format!(
            "`{}` beat {} of its chunk (merge {}) differs",
            m.stream, m.beat, m.merge
        ),
        fields: m
            .fields
            .iter()
            .map(|(name, expected, got)| FieldReport {
                name: name.clone(),
                expected: expected.clone(),
                got: got.clone(),
                differs: expected != got,
            })
            .collect(),
    }
}

pub(super) fn print_text(r: &Report) {
    println!(
        "{} ({}) on {}, stalls {}{}: {} transactions, {} records in, {} out, {} cycles ({:.3} records/cycle, {:.3} nodes/cycle), {} mismatches, {:.2} s",
        r.unit.name(),
        r.stage,
        r.engine,
        r.stalls,
        if r.stream_stalls.is_empty() {
            String::new()
        } else {
            format!(" ({})", r.stream_stalls.join(" "))
        },
        r.counts.transactions,
        r.counts.records,
        r.counts.nodes,
        r.counts.cycles,
        r.records_per_cycle,
        r.nodes_per_cycle,
        r.counts.mismatches,
        r.counts.wall_seconds
    );
    if let Some(st) = r.merger.as_ref().and_then(|m| m.store.as_ref()) {
        println!(
            "store port {} (latency {}): {} reads ({} by golden's units) in {} cycles, {:.3} reads/cycle; {:.3} records/cycle of the {:.3} the port allows ({:.3} nodes/cycle of {:.3}): {:.3} of the port; {:.3} reads/cycle in the cycles from some merge's first read to its last ({} cycles)",
            st.port,
            st.latency,
            st.reads,
            st.expected_reads,
            r.counts.cycles,
            st.reads_per_cycle,
            st.records_per_cycle,
            st.records_allowed_per_cycle,
            st.nodes_per_cycle,
            st.nodes_allowed_per_cycle,
            st.of_port,
            st.reads_per_window_cycle,
            st.read_window_cycles
        );
    }
    if let Some(m) = &r.first_mismatch {
        println!(
            "MISMATCH: transaction {} ({}), cycle {}, seed {}: {}",
            m.transaction, m.kind, m.cycle, m.seed, m.what
        );
        for f in &m.fields {
            println!(
                "  {}{}: expected {} got {}",
                if f.differs { "*" } else { " " },
                f.name,
                f.expected,
                f.got
            );
        }
    }
    if let Some(v) = &r.vcd {
        println!("VCD: {v}");
    }
    if let Some(c) = &r.reproduce {
        println!("reproduce: {c}");
    }
}

/// The first failure of a chunked multi-stream run (merging module,
/// hierarchy merger): its first mismatched beat ([`stream_mismatch`]), else,
/// when it failed, [`no_mismatch_failure`]; None when it passed.
pub(super) fn chunked_failure(kind: &str, seed: u64, t: &ChunkTotals) -> Option<MismatchReport> {
    match &t.first_mismatch {
        Some(m) => Some(stream_mismatch(kind, m, seed)),
        None if !t.passed() => Some(no_mismatch_failure(kind, seed, t)),
        None => None,
    }
}

/// The report of a chunked run that failed without a mismatched beat: a
/// hang, expected beats that never came, or a status output (`done`,
/// `idle`) that broke its rule; its transaction is the last one started.
fn no_mismatch_failure(kind: &str, seed: u64, t: &ChunkTotals) -> MismatchReport {
    let missing: Vec<String> = t
        .missing
        .iter()
        .filter(|m| m.1 > 0)
        .map(|(s, n)| format!("{n} `{s}` beats"))
        .collect();
    MismatchReport {
        transaction: t.cfg_accepted.saturating_sub(1),
        stream: None,
        beat: None,
        kind: kind.to_string(),
        cycle: t.hang.as_ref().map_or(t.cycles, |h| h.cycle),
        seed,
        what: match (&t.hang, missing.is_empty()) {
            (Some(h), _) => format!(
                "no handshake for {} cycles; missing {}",
                h.idle_cycles,
                missing.join(", ")
            ),
            (None, false) => format!("missing {}", missing.join(", ")),
            (None, true) => t.status_failure().unwrap_or_default(),
        },
        fields: Vec::new(),
    }
}
