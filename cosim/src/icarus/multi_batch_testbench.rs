//! The generated Verilog testbench of the multi-stream Icarus batch mode
//! (`super::multi_batch`): every input stream has its own driver, every
//! output stream its own back-pressure and recorder, all inside one `vvp`
//! run, so the design meets all its streams at once (the merging module's
//! network needs a head on every input stream before anything moves).
//!
//! Files (in vvp's working directory, written by `super::multi_batch`):
//! - `params.txt` (read once, all `%h`): reset cycles, watchdog limit,
//!   drain cycles, expected output beats (all output streams), then the
//!   beat count of each input stream.
//! - `pool_<s>_<k>.hex` (`$readmemh`): `GARBAGE_POOL` random values of
//!   payload port `k` of input stream `s`, shown (beats accepted modulo
//!   the pool) while its `valid` is low.
//! - per input stream `s`, in chunks of `STIM_CHUNK` beats (read with
//!   `$readmemh` when the stream reaches the chunk's first beat):
//!   `gap_<s>_<c>.hex`, per beat the number of cycles the driver lets pass
//!   (stalls) before raising `valid` for it, and `in_<s>_<c>_<k>.hex`, per
//!   beat payload port `k`; every file holds exactly `STIM_CHUNK` lines.
//! - `masks.fifo` (a named pipe): the ready masks, one line per 64 cycles
//!   of the main loop, one 64-bit word (`%h`) per output stream; bit `k` =
//!   `ready` in cycle `k` of the block. Rust writes them ahead from the
//!   seeded generators.
//! - `out.txt` (written): `O <stream> <cycle> <hex>...` per output transfer,
//!   `X <cycle> <hex>...` (every output) at the first X/Z on any output
//!   after reset, `H <cycle> <idle> <hex>...` (every port) when the
//!   watchdog fires, `M <cycle>` when the ready masks ran out, and last
//!   `E <cycle> <outputs> <accepted beats of each input stream>...`.
//!
//! Per cycle, in the order of `crate::tb::run_multi_stream_bench`: each
//! input stream's driver (not presenting and a beat left: raise `valid` if
//! the beat's gap is used up, else use up one gap cycle; while `valid` is
//! low the payload shows a pool value, a new one after each accepted beat:
//! inputs change only when they must, a changed input costs vvp the
//! re-evaluation of its cone), each output stream's `ready`, `#1`,
//! the X/Z check, accepted inputs (the next beat becomes the head), output
//! transfers, end and watchdog, then the clock edge.

use super::batch_testbench::GARBAGE_POOL;
use crate::design::{Design, PortDir, PortId};
use crate::tb::StreamPorts;

/// Name of the generated module.
pub const MULTI_TB_MODULE: &str = "hm_multi_tb";

/// The named pipe the ready masks come through.
pub const MASKS_FIFO: &str = "masks.fifo";

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
}

/// `$readmemh` file of input stream `s`'s payload port `k` garbage pool.
pub fn multi_pool_file(s: usize, k: usize) -> String {
    format!("pool_{s}_{k}.hex")
}

/// `$readmemh` file of input stream `s`'s gaps in chunk `c`.
pub fn gap_file(s: usize, c: usize) -> String {
    format!("gap_{s}_{c}.hex")
}

/// `$readmemh` file of input stream `s`'s payload port `k` in chunk `c`.
pub fn beat_file(s: usize, c: usize, k: usize) -> String {
    format!("in_{s}_{c}_{k}.hex")
}

fn sig(id: PortId) -> String {
    format!("hm_p{id}", id = id.0)
}

/// Declarations and per-cycle code of one input stream's driver.
struct InputCode {
    decls: String,
    load_pools: String,
    load_task: String,
    drive: String,
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
        "                    $sformat(hm_fname, \"gap_{s}_%0d.hex\", hm_next_{s} / {MULTI_STIM_CHUNK});\n                    $readmemh(hm_fname, hm_gaps_{s});\n"
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
            multi_pool_file(s, k)
        ));
        load_chunk.push_str(&format!(
            "                    $sformat(hm_fname, \"in_{s}_%0d_{k}.hex\", hm_next_{s} / {MULTI_STIM_CHUNK});\n                    $readmemh(hm_fname, hm_stim_{s}_{k});\n"
        ));
        read_head.push_str(&format!(
            "                hm_head_{s}_{k} = hm_stim_{s}_{k}[hm_index_{s}];\n"
        ));
        present.push_str(&format!(
            "                    {} = hm_head_{s}_{k};\n",
            sig(p)
        ));
        garbage.push_str(&format!(
            "                    {} = hm_pool_{s}_{k}[{pool_index}];\n",
            sig(p)
        ));
    }
    let load_task = format!(
        r#"    // Stream {s}'s next beat and its gap into the head registers.
    task load_head_{s};
        begin
            hm_ok_{s} = hm_next_{s} < hm_total_{s};
            hm_wait_{s} = hm_ok_{s};
            if (hm_ok_{s}) begin
                hm_index_{s} = hm_next_{s}[{index_msb}:0];
                if (hm_index_{s} == 0) begin
{load_chunk}                end
                hm_gap_{s} = hm_gaps_{s}[hm_index_{s}];
{read_head}                hm_next_{s} = hm_next_{s} + 1;
            end
        end
    endtask

"#
    );
    // Inputs are assigned only when they change: an assignment makes vvp
    // re-evaluate the input's cone.
    let drive = format!(
        r#"            if (hm_wait_{s}) begin
                if (hm_gap_{s} == 0) begin
                    hm_wait_{s} = 1'b0;
                    hm_pres_{s} = 1'b1;
                    hm_taken_{s} = 1'b0;
                    {valid} = 1'b1;
{present}                end else begin
                    hm_gap_{s} = hm_gap_{s} - 1;
                    if (hm_taken_{s}) begin
                        hm_taken_{s} = 1'b0;
                        {valid} = 1'b0;
{garbage_deep}                    end
                end
            end else if (hm_taken_{s}) begin
                hm_taken_{s} = 1'b0;
                {valid} = 1'b0;
{garbage}            end
"#,
        valid = sig(ports.valid),
        garbage_deep = garbage.replace("                    ", "                        "),
        garbage = garbage.replace("                    ", "                "),
    );
    let accept = format!(
        r#"                if (hm_pres_{s} && {ready} === 1'b1) begin
                    hm_pres_{s} = 1'b0;
                    hm_taken_{s} = 1'b1;
                    hm_sent_{s} = hm_sent_{s} + 1;
                    hm_last_progress = hm_cycle;
                    load_head_{s};
                end
"#,
        ready = sig(ports.ready),
    );
    let show_garbage = garbage.replace("                    ", "        ");
    InputCode {
        decls,
        load_pools,
        load_task,
        drive,
        accept,
        show_garbage,
    }
}

/// The testbench source.
pub fn generate_multi_testbench(spec: &MultiTbSpec) -> String {
    let d = spec.design;
    let clk = d
        .clock
        .as_deref()
        .and_then(|c| d.port_id(c).ok())
        .map(sig)
        .unwrap_or_default();
    let mut decls = String::new();
    let mut conns = Vec::new();
    let mut outputs = Vec::new();
    for (i, p) in d.ports.iter().enumerate() {
        let s = sig(PortId(i));
        match p.dir {
            PortDir::Input => decls.push_str(&format!(
                "    reg  [{}:0] {s} = {{{}{{1'b0}}}};\n",
                p.width - 1,
                p.width
            )),
            PortDir::Output => {
                decls.push_str(&format!("    wire [{}:0] {s};\n", p.width - 1));
                outputs.push(s.clone());
            }
        }
        conns.push(format!("        .{}({s})", p.name));
    }
    let all_ports: Vec<String> = (0..d.ports.len()).map(|i| sig(PortId(i))).collect();

    let mut stream_decls = String::new();
    let mut load_pools = String::new();
    let mut tasks = String::new();
    let mut drive = String::new();
    let mut accept = String::new();
    let mut init = String::new();
    let mut load_heads = String::new();
    let mut totals = Vec::new();
    let mut sent = Vec::new();
    let mut pending = Vec::new();
    for (s, ports) in spec.inputs.iter().enumerate() {
        let c = input_code(d, s, ports);
        stream_decls.push_str(&c.decls);
        load_pools.push_str(&c.load_pools);
        tasks.push_str(&c.load_task);
        drive.push_str(&c.drive);
        accept.push_str(&c.accept);
        init.push_str(&format!(
            "        hm_pres_{s} = 1'b0; hm_wait_{s} = 1'b0; hm_taken_{s} = 1'b0; hm_next_{s} = 0; hm_sent_{s} = 0; {} = 1'b0;\n",
            sig(ports.valid)
        ));
        load_heads.push_str(&format!("        load_head_{s};\n{}", c.show_garbage));
        totals.push(format!("hm_total_{s}"));
        sent.push(format!("hm_sent_{s}"));
        pending.push(format!("hm_ok_{s}"));
    }
    let mut masks = Vec::new();
    let mut transfer = String::new();
    for (o, ports) in spec.outputs.iter().enumerate() {
        stream_decls.push_str(&format!(
            "    reg [63:0] hm_mask_{o};\n    reg hm_rdy_{o};\n"
        ));
        masks.push(format!("hm_mask_{o}"));
        init.push_str(&format!(
            "        hm_rdy_{o} = 1'b0; {} = 1'b0;\n",
            sig(ports.ready)
        ));
        drive.push_str(&format!(
            "            hm_rdy_{o} = hm_mask_{o}[hm_bit];\n            {} = hm_rdy_{o};\n",
            sig(ports.ready)
        ));
        let fmt: String = ports.payload.iter().map(|_| " %h").collect();
        let args: String = ports
            .payload
            .iter()
            .map(|&p| format!(", {}", sig(p)))
            .collect();
        transfer.push_str(&format!(
            r#"                if (hm_rdy_{o} && {valid} === 1'b1) begin
                    $fwrite(out, "O {o} %0d{fmt}\n", hm_cycle{args});
                    hm_received = hm_received + 1;
                    hm_last_progress = hm_cycle;
                end
"#,
            valid = sig(ports.valid)
        ));
    }
    let (reset_assert, reset_release) = match &d.reset {
        Some(r) => {
            let id = d.port_id(&r.port).map(sig).unwrap_or_default();
            let active = u8::from(!r.active_low);
            (
                format!("        {id} = 1'b{active};\n        repeat (hm_reset_cycles) tick;\n"),
                format!("        {id} = 1'b{};\n", 1 - active),
            )
        }
        None => (String::new(), String::new()),
    };
    let out_fmt: String = outputs.iter().map(|_| " %h").collect();
    let out_args: String = outputs.iter().map(|o| format!(", {o}")).collect();
    let all_fmt: String = all_ports.iter().map(|_| " %h").collect();
    let all_args: String = all_ports.iter().map(|o| format!(", {o}")).collect();
    let x_check = if outputs.is_empty() {
        String::new()
    } else {
        format!(
            r#"            if (^{{{cat}}} === 1'bx) begin
                $fwrite(out, "X %0d{out_fmt}\n", hm_cycle{out_args});
                hm_stop = 1'b1;
            end
"#,
            cat = outputs.join(", ")
        )
    };
    let params_fmt = vec!["%h"; 4 + totals.len()].join(" ");
    let params_args = ["hm_reset_cycles", "hm_watchdog", "hm_drain", "hm_total_out"]
        .iter()
        .map(|s| s.to_string())
        .chain(totals.iter().cloned())
        .collect::<Vec<_>>()
        .join(", ");
    let sent_fmt: String = sent.iter().map(|_| " %0d").collect();
    let sent_args: String = sent.iter().map(|s| format!(", {s}")).collect();
    let busy = if pending.is_empty() {
        "1'b0".to_string()
    } else {
        pending.join(" || ")
    };
    let read_masks = if masks.is_empty() {
        String::new()
    } else {
        format!(
            r#"            if (hm_bit == 0) begin
                got = $fscanf(hm_masks, "{fmt}", {regs});
                if (got != {n}) begin
                    $fwrite(out, "M %0d\n", hm_cycle);
                    hm_stop = 1'b1;
                end
            end
"#,
            fmt = vec!["%h"; masks.len()].join(" "),
            regs = masks.join(", "),
            n = masks.len()
        )
    };
    format!(
        r#"// Generated by hiermerge cosim (Icarus multi-stream batch mode) for top `{top}`. Do not edit.
module {MULTI_TB_MODULE};
{decls}{stream_decls}    reg [63:0] hm_reset_cycles, hm_watchdog, hm_drain, hm_total_out;
    reg [63:0] hm_cycle, hm_received, hm_last_progress, hm_limit, hm_drain_left;
    reg [8*64-1:0] hm_fname;
    reg [5:0] hm_bit;
    reg hm_draining, hm_stop;
    integer fd, out, got, hm_masks;

    {top} dut (
{conns}
    );

    task tick;
        begin
            {clk} = 1'b0; #1; {clk} = 1'b1; #1;
            hm_cycle = hm_cycle + 1;
        end
    endtask

{tasks}    initial begin
        fd = $fopen("params.txt", "r");
        got = $fscanf(fd, "{params_fmt}", {params_args});
        $fclose(fd);
        hm_masks = $fopen("{MASKS_FIFO}", "r");
{load_pools}        out = $fopen("out.txt", "w");
        hm_cycle = 0; hm_received = 0; hm_bit = 0;
        hm_draining = 1'b0; hm_stop = 1'b0; hm_drain_left = 0;
{init}{reset_assert}{reset_release}        #1;
{load_heads}        hm_limit = hm_watchdog;
        hm_last_progress = hm_cycle;
        while (!hm_stop) begin
{read_masks}{drive}            #1;
{x_check}            if (!hm_stop) begin
{accept}{transfer}                if (!hm_draining) if (!({busy})) if (hm_received >= hm_total_out) begin
                    hm_draining = 1'b1;
                    hm_drain_left = hm_drain;
                    hm_limit = hm_drain + 1;
                    hm_last_progress = hm_cycle;
                end
                if (hm_draining && hm_drain_left == 0) begin
                    hm_stop = 1'b1;
                end else begin
                    if (hm_draining) hm_drain_left = hm_drain_left - 1;
                    if (hm_cycle - hm_last_progress > hm_limit) begin
                        $fwrite(out, "H %0d %0d{all_fmt}\n", hm_cycle, hm_cycle - hm_last_progress{all_args});
                        hm_stop = 1'b1;
                    end else begin
                        tick;
                        hm_bit = hm_bit + 1;
                    end
                end
            end
        end
        $fwrite(out, "E %0d %0d{sent_fmt}\n", hm_cycle, hm_received{sent_args});
        $fclose(out);
        $finish;
    end
endmodule
"#,
        top = d.top,
        conns = conns.join(",\n"),
    )
}
