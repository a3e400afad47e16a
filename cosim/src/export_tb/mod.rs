//! A portable self-checking testbench (`hiermerge export-tb`, SPEC 9.1):
//! a unit's streams, their stimulus, stall masks and golden expected
//! outputs written as `$readmemh` files beside a plain Verilog-2005
//! testbench, the unit's Verilog and a run script, so that any simulator
//! runs the check without this workspace.
//!
//! One exporter serves every unit: a unit describes itself as an
//! [`ExportSpec`] (its design, its input and output streams by port name
//! with their beats, each output's field map from golden's layouts, and
//! the status rules its cosim bench checks); [`write()`] does the rest. The
//! stalls are the cosim benches': each input stream's gaps come from
//! [`crate::icarus::multi_batch::driver_gaps`] and each output stream's
//! `ready` from [`crate::icarus::multi_batch::ready_masks`], the same
//! [`crate::tb::StallGen`] draws as the multi-stream batch.

mod store;
mod verilog;

use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};

use golden::layout::Layout;

use crate::design::{Design, PortDir};
use crate::error::{io_err, CosimError, Result};
use crate::icarus::multi_batch::{driver_gaps, ready_masks, stream_seed};
use crate::tb::{BenchConfig, Stalls, StreamStalls};
use golden::bits::Bits;

pub use store::StoreSpec;

/// The testbench's file name (its module is `tb`).
pub const TB_FILE: &str = "tb.v";

/// The run script's file name.
pub const RUN_SCRIPT: &str = "run.sh";

/// Folder of the unit's Verilog, inside the output folder.
pub const RTL_DIR: &str = "rtl";

/// Folder of the `$readmemh` files, inside the output folder.
pub const VECTORS_DIR: &str = "vectors";

/// Cycles the testbench lets pass without a handshake before it reports a
/// hang (the cosim benches' watchdog).
pub const WATCHDOG_CYCLES: u64 = 1000;

/// A stream's three ports and its beats (sent, or expected in order).
#[derive(Clone, Debug)]
pub struct StreamSpec {
    /// The stream's name (file names, messages).
    pub name: String,
    /// Its `valid`, `ready` and payload ports.
    pub valid: String,
    /// See `valid`.
    pub ready: String,
    /// See `valid`.
    pub data: String,
    /// One payload value per beat.
    pub beats: Vec<Bits>,
}

impl StreamSpec {
    /// Stream `name` on ports `<name>_valid`, `<name>_ready`, `<name>_data`.
    pub fn prefixed(name: &str, beats: Vec<Bits>) -> StreamSpec {
        StreamSpec {
            name: name.to_string(),
            valid: format!("{name}_valid"),
            ready: format!("{name}_ready"),
            data: format!("{name}_data"),
            beats,
        }
    }
}

/// An input stream.
#[derive(Clone, Debug)]
pub struct InputSpec {
    /// Ports and beats.
    pub stream: StreamSpec,
    /// Per beat, the output beats (over every output stream) that must
    /// have arrived before it may go: the translation unit's runs, each
    /// after the previous run's outputs; empty means none (all 0).
    pub after: Vec<u64>,
}

/// An output stream.
#[derive(Clone, Debug)]
pub struct OutputSpec {
    /// Ports and expected beats.
    pub stream: StreamSpec,
    /// Per expected beat, the transaction it belongs to.
    pub transaction: Vec<u64>,
    /// The beat's layout, golden's (a 0-bit field is not shown).
    pub fields: Layout,
}

/// A status rule the testbench checks besides the streams.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum StatusCheck {
    /// The 1-bit output `port` high in exactly `cycles` cycles.
    Pulses {
        /// Port name.
        port: String,
        /// Cycles it must be high.
        cycles: u64,
        /// Why, in words (`one per merge`).
        why: String,
    },
    /// Output `port` equal to `value` at the end.
    AtEnd {
        /// Port name.
        port: String,
        /// Its value.
        value: u64,
    },
    /// Every cycle, `done` high exactly when `idle` rose (is high, was low).
    DoneWhenIdleRises {
        /// The pulse.
        done: String,
        /// The level.
        idle: String,
    },
}

/// Everything a unit's exported testbench is made of.
#[derive(Clone, Debug)]
pub struct ExportSpec {
    /// The design, its Verilog files already written.
    pub design: Design,
    /// What a transaction is called in messages (`transaction`, `merge`, `level`).
    pub transaction: String,
    /// Transactions in the stimulus.
    pub transactions: u64,
    /// Input streams, in port order.
    pub inputs: Vec<InputSpec>,
    /// Output streams.
    pub outputs: Vec<OutputSpec>,
    /// Status rules.
    pub checks: Vec<StatusCheck>,
    /// Seed of the stall patterns.
    pub seed: u64,
    /// The stall pattern of every driver and monitor.
    pub stalls: Stalls,
    /// Named streams' own patterns, replacing `stalls` on them (the store
    /// model's as `store_req` and `store_resp`).
    pub stream_stalls: StreamStalls,
    /// The command line that wrote it (in the testbench's header).
    pub command: String,
    /// A shared store port's store (`store_req` / `store_resp`), answered
    /// by a store model in the testbench; None for a unit without one.
    pub store: Option<StoreSpec>,
}

/// What [`write()`] wrote.
#[derive(Clone, Debug)]
pub struct Exported {
    /// Every file written, relative to the output folder.
    pub files: Vec<PathBuf>,
    /// Beats sent over every input stream.
    pub beats_in: u64,
    /// Beats expected over every output stream.
    pub beats_out: u64,
    /// Cycles each output's `ready` mask holds before it repeats.
    pub mask_cycles: u64,
}

/// Per input stream, its gaps.
struct InputFiles {
    gaps: Vec<u32>,
}

fn design_err(what: String) -> CosimError {
    CosimError::Design { what }
}

/// Refuses a spec the testbench cannot run: unknown ports, wrong
/// directions or widths, beats of another width, fields outside a beat,
/// names that are not Verilog identifiers.
fn check(spec: &ExportSpec) -> Result<()> {
    let d = &spec.design;
    d.validate()?;
    if d.clock.is_none() {
        return Err(design_err(format!("`{}` has no clock", d.top)));
    }
    let port = |name: &str, dir: PortDir, width: Option<u32>, stream: &str| -> Result<u32> {
        let p = d.port(d.port_id(name)?)?;
        let ok_width = !matches!(width, Some(w) if p.width != w);
        if p.dir != dir || !ok_width {
            return Err(CosimError::PortMismatch {
                port: name.to_string(),
                what: format!(
                    "stream `{stream}` needs it as {dir:?}{}",
                    match width {
                        Some(w) => format!(", {w} bit(s)"),
                        None => String::new(),
                    }
                ),
            });
        }
        Ok(p.width)
    };
    let mut names: Vec<&str> = Vec::new();
    let streams = spec
        .inputs
        .iter()
        .map(|i| (&i.stream, true))
        .chain(spec.outputs.iter().map(|o| (&o.stream, false)));
    for (s, input) in streams {
        let ident = |c: char| c.is_ascii_alphanumeric() || c == '_';
        if s.name.is_empty() || !s.name.chars().all(ident) || names.contains(&s.name.as_str()) {
            return Err(design_err(format!(
                "stream name `{}`: expected a unique identifier",
                s.name
            )));
        }
        names.push(&s.name);
        let (into, from) = match input {
            true => (PortDir::Input, PortDir::Output),
            false => (PortDir::Output, PortDir::Input),
        };
        port(&s.valid, into, Some(1), &s.name)?;
        port(&s.ready, from, Some(1), &s.name)?;
        let width = port(&s.data, into, None, &s.name)?;
        if let Some((i, b)) = s.beats.iter().enumerate().find(|(_, b)| b.width() != width) {
            return Err(design_err(format!(
                "stream `{}` beat {i}: {} bits for the {width}-bit port `{}`",
                s.name,
                b.width(),
                s.data
            )));
        }
    }
    for o in &spec.outputs {
        let width = o.stream.beats.first().map(Bits::width);
        let port_width = d.port(d.port_id(&o.stream.data)?)?.width;
        if let Some(f) = o.fields.fields().find(|f| f.offset + f.width > port_width) {
            return Err(design_err(format!(
                "stream `{}`: field `{}` (bits {}..{}) outside the {port_width}-bit beat",
                o.stream.name,
                f.name,
                f.offset,
                f.offset + f.width
            )));
        }
        if o.transaction.len() != o.stream.beats.len() {
            return Err(design_err(format!(
                "stream `{}`: {} transaction indices for {} beats (width {width:?})",
                o.stream.name,
                o.transaction.len(),
                o.stream.beats.len()
            )));
        }
    }
    // The testbench counts in 32 bits.
    let beats: u64 = spec
        .outputs
        .iter()
        .map(|o| o.stream.beats.len() as u64)
        .sum();
    let most_in = spec
        .inputs
        .iter()
        .map(|i| i.stream.beats.len() as u64)
        .max();
    if beats.max(most_in.unwrap_or(0)) >= 1 << 31 {
        return Err(design_err(format!(
            "{beats} output beats, or an input stream of {most_in:?}: the testbench counts at most 2^31 - 1"
        )));
    }
    if let Some(st) = &spec.store {
        check_store(spec, st)?;
    }
    for i in &spec.inputs {
        if !i.after.is_empty() && i.after.len() != i.stream.beats.len() {
            return Err(design_err(format!(
                "stream `{}`: {} `after` counts for {} beats",
                i.stream.name,
                i.after.len(),
                i.stream.beats.len()
            )));
        }
    }
    Ok(())
}

/// Refuses a store the testbench cannot answer from: missing or
/// misdirected store ports, words of another width, a run table of
/// another size or runs outside the words, an unknown epoch stream.
fn check_store(spec: &ExportSpec, st: &StoreSpec) -> Result<()> {
    let d = &spec.design;
    let port = |name: &str, dir: PortDir| -> Result<u32> {
        let p = d.port(d.port_id(name)?)?;
        match p.dir == dir {
            true => Ok(p.width),
            false => Err(CosimError::PortMismatch {
                port: name.to_string(),
                what: format!("the store model needs it as {dir:?}"),
            }),
        }
    };
    port("store_req_valid", PortDir::Output)?;
    port("store_req_ready", PortDir::Input)?;
    port("store_resp_valid", PortDir::Input)?;
    port("store_resp_ready", PortDir::Output)?;
    let req = port("store_req_data", PortDir::Output)?;
    let resp = port("store_resp_data", PortDir::Input)?;
    let fields = [&st.index, &st.hier, &st.slot, &st.array];
    if let Some(f) = fields
        .iter()
        .find(|f| f.offset + f.width > req || f.width > 32)
    {
        return Err(design_err(format!(
            "store field `{}` (bits {}..{}) outside the {req}-bit `store_req_data`",
            f.name,
            f.offset,
            f.offset + f.width
        )));
    }
    if let Some(w) = st.words.iter().position(|w| w.width() != resp) {
        return Err(design_err(format!(
            "store word {w}: {} bits for the {resp}-bit `store_resp_data`",
            st.words[w].width()
        )));
    }
    let want = st.merges() * 2 * st.hierarchies() as usize;
    if st.runs.len() != want {
        return Err(design_err(format!(
            "store: {} runs for {} merges of 2 arrays of {} hierarchies",
            st.runs.len(),
            st.merges(),
            st.hierarchies()
        )));
    }
    if let Some(r) = st
        .runs
        .iter()
        .find(|r| r.0 as usize + r.1 as usize > st.words.len())
    {
        return Err(design_err(format!(
            "store run {r:?} outside its {} words",
            st.words.len()
        )));
    }
    if !spec.inputs.iter().any(|i| i.stream.name == st.epoch_input) {
        return Err(design_err(format!(
            "store: no input stream `{}` numbers the merges",
            st.epoch_input
        )));
    }
    if !spec
        .outputs
        .iter()
        .any(|o| o.stream.name == st.epoch_output)
    {
        return Err(design_err(format!(
            "store: no output stream `{}` ends the merges",
            st.epoch_output
        )));
    }
    Ok(())
}

/// Writes `lines` to `path`, one per line.
fn write_lines(path: &Path, lines: impl Iterator<Item = String>) -> Result<()> {
    let file = fs::File::create(path).map_err(io_err(path))?;
    let mut w = std::io::BufWriter::new(file);
    for l in lines {
        writeln!(w, "{l}").map_err(io_err(path))?;
    }
    w.flush().map_err(io_err(path))
}

/// `$readmemh` file names of stream `name`'s `what` (`data`, `gap`, ...).
pub fn vector_file(name: &str, what: &str) -> String {
    format!("{VECTORS_DIR}/{name}.{what}.hex")
}

/// Words of each output's `ready` mask: a power of two, enough for the
/// cycles the run is likely to take so that the pattern rarely repeats.
fn mask_words(inputs: &[InputFiles], spec: &ExportSpec) -> usize {
    let sent: u64 = inputs
        .iter()
        .map(|i| i.gaps.iter().map(|&g| u64::from(g) + 1).sum::<u64>())
        .sum();
    let out: u64 = spec
        .outputs
        .iter()
        .map(|o| o.stream.beats.len() as u64)
        .sum();
    let cycles = sent + 2 * out + 1024;
    (cycles.div_ceil(64) as usize)
        .next_power_of_two()
        .min(1 << 20)
}

/// Writes the testbench of `spec` into `dir` (which holds the design's
/// Verilog under [`RTL_DIR`] already): `tb.v`, the vector files, `run.sh`.
pub fn write(spec: &ExportSpec, dir: &Path) -> Result<Exported> {
    check(spec)?;
    crate::tb::driver::check_stalls(&spec.stalls)?;
    let mut streams: Vec<&str> = spec.inputs.iter().map(|i| i.stream.name.as_str()).collect();
    streams.extend(spec.outputs.iter().map(|o| o.stream.name.as_str()));
    if spec.store.is_some() {
        streams.extend(["store_req", "store_resp"]);
    }
    spec.stream_stalls
        .check_names(streams.iter().copied())
        .map_err(|what| CosimError::Bench { what })?;
    let stalls_of = |name: &str| spec.stream_stalls.of(name, spec.stalls);
    let vectors = dir.join(VECTORS_DIR);
    fs::create_dir_all(&vectors).map_err(io_err(&vectors))?;
    let mut files = Vec::new();
    let mut put = |name: String, lines: Vec<String>| -> Result<()> {
        write_lines(&dir.join(&name), lines.into_iter())?;
        files.push(PathBuf::from(name));
        Ok(())
    };
    let mut ins = Vec::new();
    for (s, i) in spec.inputs.iter().enumerate() {
        let st = &i.stream;
        let widths = [st.beats.first().map_or(1, Bits::width)];
        let gaps = driver_gaps(
            stream_seed(spec.seed, s),
            stalls_of(&st.name),
            &widths,
            st.beats.len(),
        )?;
        let after = match i.after.is_empty() {
            true => vec![0; st.beats.len()],
            false => i.after.clone(),
        };
        if !st.beats.is_empty() {
            put(
                vector_file(&st.name, "data"),
                st.beats.iter().map(Bits::to_hex).collect(),
            )?;
            put(
                vector_file(&st.name, "gap"),
                gaps.iter().map(|g| format!("{g:08x}")).collect(),
            )?;
            put(
                vector_file(&st.name, "after"),
                after.iter().map(|a| format!("{a:08x}")).collect(),
            )?;
        }
        ins.push(InputFiles { gaps });
    }
    let words = mask_words(&ins, spec);
    let out_stalls: Vec<Stalls> = spec
        .outputs
        .iter()
        .map(|o| stalls_of(&o.stream.name))
        .collect();
    let masks = ready_masks(spec.seed, &out_stalls);
    for (o, (mut rng, mut gen)) in spec.outputs.iter().zip(masks) {
        let st = &o.stream;
        if !st.beats.is_empty() {
            put(
                vector_file(&st.name, "expected"),
                st.beats.iter().map(Bits::to_hex).collect(),
            )?;
            put(
                vector_file(&st.name, "transaction"),
                o.transaction.iter().map(|t| format!("{t:08x}")).collect(),
            )?;
        }
        let mask = (0..words)
            .map(|_| format!("{:016x}", gen.go_word(&mut rng)))
            .collect();
        put(vector_file(&st.name, "ready"), mask)?;
    }
    if let Some(st) = &spec.store {
        let hex32 = |v: u64| format!("{v:08x}");
        put(
            vector_file("store", "words"),
            match st.words.is_empty() {
                true => vec!["0".into()],
                false => st.words.iter().map(Bits::to_hex).collect(),
            },
        )?;
        put(
            vector_file("store", "base"),
            st.runs.iter().map(|r| hex32(r.0.into())).collect(),
        )?;
        put(
            vector_file("store", "len"),
            st.runs.iter().map(|r| hex32(r.1.into())).collect(),
        )?;
        put(
            vector_file("store", "expect"),
            st.reads.iter().map(|&r| hex32(r)).collect(),
        )?;
        // The store model's own stall draws, apart from every stream's.
        for (k, what, stream) in [(0, "req_ready", "store_req"), (1, "resp_go", "store_resp")] {
            let (mut rng, mut gen) = (
                crate::tb::Prng::derived(stream_seed(spec.seed, 1000 + k), 2),
                crate::tb::StallGen::new(stalls_of(stream)),
            );
            let mask = (0..words)
                .map(|_| format!("{:016x}", gen.go_word(&mut rng)))
                .collect();
            put(vector_file("store", what), mask)?;
        }
    }
    let tb = verilog::testbench(spec, words);
    put(TB_FILE.to_string(), vec![tb])?;
    let script = dir.join(RUN_SCRIPT);
    fs::write(&script, verilog::run_script(spec)).map_err(io_err(&script))?;
    set_executable(&script)?;
    files.push(PathBuf::from(RUN_SCRIPT));
    Ok(Exported {
        files,
        beats_in: spec
            .inputs
            .iter()
            .map(|i| i.stream.beats.len() as u64)
            .sum(),
        beats_out: spec
            .outputs
            .iter()
            .map(|o| o.stream.beats.len() as u64)
            .sum(),
        mask_cycles: 64 * words as u64,
    })
}

#[cfg(unix)]
fn set_executable(path: &Path) -> Result<()> {
    use std::os::unix::fs::PermissionsExt;
    fs::set_permissions(path, fs::Permissions::from_mode(0o755)).map_err(io_err(path))
}

#[cfg(not(unix))]
fn set_executable(_: &Path) -> Result<()> {
    Ok(())
}

/// The bench settings the testbench takes from the cosim benches: reset
/// cycles and the drain after the last expected beat.
fn bench() -> BenchConfig {
    BenchConfig::default()
}
