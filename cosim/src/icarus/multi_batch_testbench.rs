//! The generated Verilog testbench of the multi-stream Icarus batch mode
//! (`super::multi_batch`): every input stream has its own driver, every
//! output stream its own back-pressure and recorder, all inside one `vvp`
//! run, so the design meets all its streams at once (the merging module's
//! network needs a head on every input stream before anything moves).
//!
//! The frame (files, reset, masks, X/Z check, drain, watchdog, VCD
//! window, the `X`/`H`/`M`/`E` records) is `super::batch_tb_frame`'s; this
//! testbench's own files (in vvp's working directory, written by
//! `super::multi_batch`):
//! - `params.txt`, after the frame's words: the beat count of each input
//!   stream.
//! - `pool_<s>_<k>.hex` (`$readmemh`): `GARBAGE_POOL` random values of
//!   payload port `k` of input stream `s`, shown (beats accepted modulo
//!   the pool) while its `valid` is low.
//! - per input stream `s`, in chunks of [`MULTI_STIM_CHUNK`] beats (read with
//!   `$readmemh` when the stream reaches the chunk's first beat):
//!   `gap_<s>_<c>.hex`, per beat the number of cycles the driver lets pass
//!   (stalls) before raising `valid` for it, and `in_<s>_<c>_<k>.hex`, per
//!   beat payload port `k`; a file holds the chunk's beats only (the last
//!   chunk is short; `$readmemh` is given the range).
//! - `masks.fifo`: one word per output stream, bit `k` = `ready` in cycle
//!   `k` of the block.
//! - `out.txt`: `O <stream> <cycle> <hex>...` per output transfer; with
//!   watched pulses, before the end record, `P <cycle> <count>... <value>...`: per
//!   pulse output the cycles it was high and its value at the end; the end
//!   record is `E <cycle> <outputs> <accepted beats of each input stream>...`.
//!
//! Per cycle, in the order of `crate::tb::run_multi_stream_bench`: each
//! input stream's driver (not presenting and a beat left: raise `valid` if
//! the beat's gap is used up, else use up one gap cycle; while `valid` is
//! low the payload shows a pool value, a new one after each accepted beat:
//! inputs change only when they must, a changed input costs vvp the
//! re-evaluation of its cone), `#1`, the X/Z check, accepted inputs (the
//! next beat becomes the head), output transfers, end and watchdog, then
//! the clock edge. Each output stream's `ready` is a continuous assignment
//! of its mask bit of the cycle.
//!
//! Why it is written this way (vvp spends ~0.2 us on every load of a
//! variable in procedural code, a dynamic cast; a net updates only when
//! its inputs change): the per-stream conditions are continuous vectors
//! (`hm_busy`: waiting or just taken; `hm_acc`: presented and ready;
//! `hm_fire`: output valid and ready; `hm_outs_x` in the frame) and the
//! per-cycle code tests one group of 8 streams at a time for any set bit
//! before it tests the streams; "every stream sent" is a counter
//! (`hm_streams_left`) rather than an OR over the streams. vvp updates a
//! continuous assignment in a later event of the same time step, so each
//! vector is read only after a delay since its sources last changed (the
//! drivers' flags change in the observe phase, before the clock's two
//! delays; the first cycle follows a `#1` after the first heads are loaded).

use super::batch_tb_frame::{self, pool_file, sig, TbBody};
use super::batch_testbench::GARBAGE_POOL;
use crate::design::{Design, PortId};
use crate::tb::StreamPorts;

/// Name of the generated module.
pub const MULTI_TB_MODULE: &str = "hm_multi_tb";

/// Input beats per stimulus chunk file, per input stream (a power of two).
pub const MULTI_STIM_CHUNK: usize = 1 << 14;

/// Everything the generated testbench is built from.
pub struct MultiTbSpec<'a> {
    /// The design under test (must have a clock).
    pub design: &'a Design,
    /// Input streams, numbered from 0 in this order.
    pub inputs: &'a [StreamPorts],
    /// Output streams, numbered from 0 in this order.
    pub outputs: &'a [StreamPorts],
    /// 1-bit outputs whose high cycles are counted (`P` record).
    pub pulses: &'a [PortId],
}

/// `$readmemh` file of input stream `s`'s gaps in chunk `c`.
pub fn gap_file(s: usize, c: usize) -> String {
    format!("gap_{s}_{c}.hex")
}

/// `$readmemh` file of input stream `s`'s payload port `k` in chunk `c`.
pub fn beat_file(s: usize, c: usize, k: usize) -> String {
    format!("in_{s}_{c}_{k}.hex")
}

/// Streams whose per-cycle test shares one guard: a cycle where none of
/// them acts costs one load for the group instead of one per stream.
const GUARD_GROUP: usize = 8;

/// `body(i)` for each bit `i` of the continuous vector `flags` (`n` bits)
/// that is set, the bits tested in groups of `GUARD_GROUP` behind one
/// zero test each (`indent`: of the group's `if`).
fn guarded(flags: &str, n: usize, indent: &str, body: impl Fn(usize) -> String) -> String {
    let mut code = String::new();
    for lo in (0..n).step_by(GUARD_GROUP) {
        let hi = (lo + GUARD_GROUP).min(n) - 1;
        code.push_str(&format!("{indent}if ({flags}[{hi}:{lo}] != 0) begin\n"));
        for i in lo..=hi {
            code.push_str(&format!("{indent}    if ({flags}[{i}]) begin\n"));
            code.push_str(&body(i));
            code.push_str(&format!("{indent}    end\n"));
        }
        code.push_str(&format!("{indent}end\n"));
    }
    code
}

/// `{terms[n-1], ..., terms[0]}`: bit `i` of the vector is `terms[i]`.
fn msb_first(terms: &[String]) -> String {
    let rev: Vec<&str> = terms.iter().rev().map(String::as_str).collect();
    format!("{{{}}}", rev.join(", "))
}

/// Declarations and per-cycle code of one input stream's driver.
struct InputCode {
    decls: String,
    load_pools: String,
    load_task: String,
    /// Driver statements, run while `hm_busy[s]` (waiting or just taken).
    drive: String,
    /// Acceptance statements, run when `hm_acc[s]` (presented and ready).
    accept: String,
    show_garbage: String,
}

fn input_code(d: &Design, s: usize, ports: &StreamPorts) -> InputCode {
    let width = |id: PortId| d.ports[id.0].width;
    let index_msb = MULTI_STIM_CHUNK.trailing_zeros() - 1;
    let pool_index = format!("hm_sent_{s}[{}:0]", GARBAGE_POOL.trailing_zeros() - 1);
    let mut decls = format!(
        "    reg hm_pres_{s}, hm_ok_{s}, hm_wait_{s}, hm_taken_{s};\n    reg [31:0] hm_gap_{s};\n    reg [31:0] hm_gaps_{s} [0:{last}];\n    reg [31:0] hm_next_{s}, hm_total_{s}, hm_sent_{s};\n    reg [{index_msb}:0] hm_index_{s};\n",
        last = MULTI_STIM_CHUNK - 1
    );
    let mut load_pools = String::new();
    let mut load_chunk = format!(
        "                    $sformat(hm_fname, \"gap_{s}_%0d.hex\", hm_next_{s} / {MULTI_STIM_CHUNK});\n                    $readmemh(hm_fname, hm_gaps_{s}, 0, hm_chunk_last);\n"
    );
    let mut read_head = String::new();
    let mut present = String::new();
    let mut garbage = String::new();
    for (k, &p) in ports.payload.iter().enumerate() {
        let w = width(p) - 1;
        decls.push_str(&format!(
            "    reg [{w}:0] hm_head_{s}_{k};\n    reg [{w}:0] hm_pool_{s}_{k} [0:{}];\n    reg [{w}:0] hm_stim_{s}_{k} [0:{}];\n",
            GARBAGE_POOL - 1,
            MULTI_STIM_CHUNK - 1
        ));
        load_pools.push_str(&format!(
            "        $readmemh(\"{}\", hm_pool_{s}_{k});\n",
            pool_file(s, k)
        ));
        load_chunk.push_str(&format!(
            "                    $sformat(hm_fname, \"in_{s}_%0d_{k}.hex\", hm_next_{s} / {MULTI_STIM_CHUNK});\n                    $readmemh(hm_fname, hm_stim_{s}_{k}, 0, hm_chunk_last);\n"
        ));
        read_head.push_str(&format!(
            "                hm_head_{s}_{k} = hm_stim_{s}_{k}[hm_index_{s}];\n"
        ));
        present.push_str(&format!(
            "                        {} = hm_head_{s}_{k};\n",
            sig(p)
        ));
        garbage.push_str(&format!(
            "                        {} = hm_pool_{s}_{k}[{pool_index}];\n",
            sig(p)
        ));
    }
    // A chunk file holds the chunk's beats only (the last one is short).
    let load_task = format!(
        r#"    // Stream {s}'s next beat and its gap into the head registers; after
    // its last beat, one stream fewer is left to send.
    task load_head_{s};
        begin
            hm_ok_{s} = hm_next_{s} < hm_total_{s};
            hm_wait_{s} = hm_ok_{s};
            if (hm_ok_{s}) begin
                hm_index_{s} = hm_next_{s}[{index_msb}:0];
                if (hm_index_{s} == 0) begin
                    hm_chunk_last = hm_total_{s} - hm_next_{s} > {MULTI_STIM_CHUNK} ? {chunk_last} : hm_total_{s} - hm_next_{s} - 1;
{load_chunk}                end
                hm_gap_{s} = hm_gaps_{s}[hm_index_{s}];
{read_head}                hm_next_{s} = hm_next_{s} + 1;
            end else begin
                hm_streams_left = hm_streams_left - 1;
            end
        end
    endtask

"#,
        chunk_last = MULTI_STIM_CHUNK - 1
    );
    // Inputs are assigned only when they change: an assignment makes vvp
    // re-evaluate the input's cone.
    let drive = format!(
        r#"                if (hm_wait_{s}) begin
                    if (hm_gap_{s} == 0) begin
                        hm_wait_{s} = 1'b0;
                        hm_pres_{s} = 1'b1;
                        hm_taken_{s} = 1'b0;
                        {valid} = 1'b1;
{present}                    end else begin
                        hm_gap_{s} = hm_gap_{s} - 1;
                        if (hm_taken_{s}) begin
                            hm_taken_{s} = 1'b0;
                            {valid} = 1'b0;
{garbage_deep}                        end
                    end
                end else begin
                    hm_taken_{s} = 1'b0;
                    {valid} = 1'b0;
{garbage}                end
"#,
        valid = sig(ports.valid),
        garbage_deep = garbage.replace("                        ", "                            "),
        garbage = garbage.replace("                        ", "                    "),
    );
    let accept = format!(
        r#"                        hm_pres_{s} = 1'b0;
                        hm_taken_{s} = 1'b1;
                        hm_sent_{s} = hm_sent_{s} + 1;
                        hm_last_progress = hm_cycle;
                        load_head_{s};
"#
    );
    let show_garbage = garbage.replace("                        ", "        ");
    InputCode {
        decls,
        load_pools,
        load_task,
        drive,
        accept,
        show_garbage,
    }
}

/// Records output stream `o`'s transfer as `O <o> <cycle> <hex>...` and
/// counts it as progress.
fn record_output(o: usize, payload: &[PortId]) -> String {
    let fmt = " %h".repeat(payload.len());
    let args: String = payload.iter().map(|&p| format!(", {}", sig(p))).collect();
    format!(
        r#"                        $fwrite(out, "O {o} %0d{fmt}\n", hm_cycle{args});
                        hm_received = hm_received + 1;
                        hm_last_progress = hm_cycle;
"#
    )
}

/// The testbench source.
pub fn generate_multi_testbench(spec: &MultiTbSpec) -> String {
    let d = spec.design;
    let mut decls = String::new();
    let mut tasks = String::new();
    let mut init = String::new();
    let mut load_heads = String::new();
    let mut totals = Vec::new();
    let mut sent = Vec::new();
    let mut drives = Vec::new();
    let mut accepts = Vec::new();
    let mut busy = Vec::new();
    let mut acc = Vec::new();
    for (s, ports) in spec.inputs.iter().enumerate() {
        let c = input_code(d, s, ports);
        decls.push_str(&c.decls);
        init.push_str(&c.load_pools);
        tasks.push_str(&c.load_task);
        drives.push(c.drive);
        accepts.push(c.accept);
        init.push_str(&format!(
            "        hm_pres_{s} = 1'b0; hm_wait_{s} = 1'b0; hm_taken_{s} = 1'b0; hm_next_{s} = 0; hm_sent_{s} = 0; {} = 1'b0;\n",
            sig(ports.valid)
        ));
        load_heads.push_str(&format!("        load_head_{s};\n{}", c.show_garbage));
        totals.push(format!("hm_total_{s}"));
        sent.push(format!("hm_sent_{s}"));
        busy.push(format!("(hm_wait_{s} | hm_taken_{s})"));
        acc.push(format!("(hm_pres_{s} & {})", sig(ports.ready)));
    }
    let (n_in, n_out) = (spec.inputs.len(), spec.outputs.len());
    decls.push_str("    reg [31:0] hm_streams_left, hm_chunk_last;\n");
    init.push_str(&format!("        hm_streams_left = {n_in};\n"));
    let mut drive = String::new();
    let mut observe = String::new();
    if n_in > 0 {
        // Read after the testbench's own updates have settled (a delay
        // later), and after the X/Z check, so `ready` is 0 or 1 here.
        decls.push_str(&format!(
            "    wire [{m}:0] hm_busy = {};\n    wire [{m}:0] hm_acc = {};\n",
            msb_first(&busy),
            msb_first(&acc),
            m = n_in - 1
        ));
        drive = guarded("hm_busy", n_in, "            ", |s| drives[s].clone());
        observe.push_str(&guarded("hm_acc", n_in, "                ", |s| {
            accepts[s].clone()
        }));
    }
    let mut masks = Vec::new();
    let mut wired = Vec::new();
    let mut fire = Vec::new();
    for (o, ports) in spec.outputs.iter().enumerate() {
        // `ready` follows the mask bit of the cycle without a statement per
        // cycle; the masks are 0 until the first line is read (reset).
        decls.push_str(&format!(
            "    reg [63:0] hm_mask_{o};\n    assign {} = hm_mask_{o}[hm_bit];\n",
            sig(ports.ready)
        ));
        masks.push(format!("hm_mask_{o}"));
        wired.push(ports.ready);
        init.push_str(&format!("        hm_mask_{o} = 0;\n"));
        fire.push(format!("({} & {})", sig(ports.valid), sig(ports.ready)));
    }
    if n_out > 0 {
        decls.push_str(&format!(
            "    wire [{}:0] hm_fire = {};\n",
            n_out - 1,
            msb_first(&fire)
        ));
        observe.push_str(&guarded("hm_fire", n_out, "                ", |o| {
            record_output(o, &spec.outputs[o].payload)
        }));
    }
    let (pulse_decls, pulse_init, pulse_count, pulse_record) = pulse_code(spec.pulses);
    decls.push_str(&pulse_decls);
    init.push_str(&pulse_init);
    let body = TbBody {
        module: MULTI_TB_MODULE,
        title: "Icarus multi-stream batch mode",
        wired,
        decls,
        tasks,
        params: totals,
        init,
        // vvp schedules a continuous assignment's update: let `hm_busy`
        // see the first heads before the first cycle reads it.
        after_reset: format!("{load_heads}        #1;\n"),
        masks,
        drive,
        observe: format!("{pulse_count}{observe}"),
        all_sent: "hm_streams_left == 0".to_string(),
        sent,
        before_end: pulse_record,
    };
    batch_tb_frame::generate(d, &body)
}

/// Per watched 1-bit output, a counter of the cycles it is high (counted
/// after `#1`, as `tb::run_multi_stream_bench_watching` peeks after
/// `eval`), and the `P` record (`P <cycle> <count>... <value>...`) at the end.
fn pulse_code(pulses: &[PortId]) -> (String, String, String, String) {
    if pulses.is_empty() {
        return Default::default();
    }
    let counters: Vec<String> = (0..pulses.len()).map(|i| format!("hm_pulse_{i}")).collect();
    let count: String = pulses
        .iter()
        .zip(&counters)
        .map(|(&p, c)| format!("                if ({} === 1'b1) {c} = {c} + 1;\n", sig(p)))
        .collect();
    let args: String = counters
        .iter()
        .cloned()
        .chain(pulses.iter().map(|&p| sig(p)))
        .map(|a| format!(", {a}"))
        .collect();
    (
        format!("    reg [63:0] {};\n", counters.join(", ")),
        counters
            .iter()
            .map(|c| format!("        {c} = 0;\n"))
            .collect(),
        count,
        format!(
            "        $fwrite(out, \"P %0d{}{}\\n\", hm_cycle{args});\n",
            " %0d".repeat(pulses.len()),
            " %h".repeat(pulses.len())
        ),
    )
}
