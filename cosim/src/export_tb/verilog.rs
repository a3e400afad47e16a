//! The exported testbench's text (`tb.v`) and its run script (`run.sh`).
//!
//! Per cycle, in order: `drive` (an accepted input beat makes way for the
//! next, whose `valid` rises once its gap is used up and its `after` count
//! of output beats has arrived; each output's `ready` is its mask bit of
//! the cycle), `#1` for the design to settle, `observe` (X/Z on any output,
//! accepted inputs, output beats against the expected ones, status rules,
//! then the drain, the end or the watchdog), then the clock edge.

use std::fmt::Write as _;

use super::{vector_file, ExportSpec, OutputSpec, StatusCheck, StreamSpec};
use super::{RTL_DIR, TB_FILE, WATCHDOG_CYCLES};
use crate::design::PortDir;
use golden::layout::Field;

/// Bits of an index into `n` entries (at least 1).
pub(super) fn index_bits(n: usize) -> u32 {
    (usize::BITS - n.saturating_sub(1).leading_zeros()).max(1)
}

/// `tb_<stream>_next[k:0]`-style index into a stream's arrays.
fn index(reg: &str, n: usize) -> String {
    format!("{reg}[{}:0]", index_bits(n) - 1)
}

fn width_of(spec: &ExportSpec, port: &str) -> u32 {
    spec.design
        .ports
        .iter()
        .find(|p| p.name == port)
        .map_or(1, |p| p.width)
}

fn decl(width: u32) -> String {
    match width {
        1 => String::new(),
        w => format!("[{}:0] ", w - 1),
    }
}

/// The unit's ports as testbench signals and the instance `dut`.
fn ports_and_instance(spec: &ExportSpec) -> String {
    let d = &spec.design;
    let mut s = String::from("    // The unit's ports.\n");
    let reset = d.reset.as_ref();
    for p in &d.ports {
        let w = decl(p.width);
        let _ = match p.dir {
            PortDir::Output => writeln!(s, "    wire {w}{};", p.name),
            PortDir::Input if reset.is_some_and(|r| r.port == p.name) => {
                let on = u8::from(!reset.is_some_and(|r| r.active_low));
                writeln!(s, "    reg {w}{} = 1'b{on};", p.name)
            }
            PortDir::Input if p.width == 1 => writeln!(s, "    reg {} = 1'b0;", p.name),
            PortDir::Input => writeln!(s, "    reg {w}{} = {}'h0;", p.name, p.width),
        };
    }
    let conns: Vec<String> = d
        .ports
        .iter()
        .map(|p| format!("        .{0}({0})", p.name))
        .collect();
    let _ = write!(s, "\n    {} dut (\n{}\n    );\n", d.top, conns.join(",\n"));
    s
}

/// Declarations of input stream `st` (beats, gaps, `after` counts, head).
fn input_decls(st: &StreamSpec, width: u32) -> String {
    let n = st.beats.len();
    let name = &st.name;
    if n == 0 {
        return format!(
            "\n    // Input stream `{name}`: no beats (`{}` stays low).\n",
            st.valid
        );
    }
    format!(
        r#"
    // Input stream `{name}`: {n} beats of {width} bits; per beat its gap
    // (cycles it waits before `valid` rises) and the output beats that
    // must have arrived before it may go.
    localparam [31:0] tb_{name}_beats = 32'd{n};
    reg {w}tb_{name}_data [0:{last}];
    reg [31:0] tb_{name}_gap [0:{last}];
    reg [31:0] tb_{name}_after [0:{last}];
    reg [31:0] tb_{name}_sent = 32'd0;
    reg [31:0] tb_{name}_wait = 32'd0;
    reg tb_{name}_taken = 1'b0;
"#,
        w = decl(width),
        last = n - 1,
    )
}

/// Declarations of output stream `o` (expected beats, their transactions,
/// the `ready` mask, the count received).
fn output_decls(o: &OutputSpec, width: u32, mask_words: usize) -> String {
    let st = &o.stream;
    let (name, n) = (&st.name, st.beats.len());
    let mut s = format!(
        "\n    // Output stream `{name}`: {n} beats of {width} bits expected; `{}`\n    // follows a mask of {} cycles, repeated.\n",
        st.ready,
        64 * mask_words
    );
    let _ = writeln!(s, "    localparam [31:0] tb_{name}_beats = 32'd{n};");
    if n > 0 {
        let _ = writeln!(
            s,
            "    reg {}tb_{name}_expected [0:{}];",
            decl(width),
            n - 1
        );
        let _ = writeln!(s, "    reg [31:0] tb_{name}_transaction [0:{}];", n - 1);
    }
    let _ = writeln!(s, "    reg [63:0] tb_{name}_ready [0:{}];", mask_words - 1);
    let _ = writeln!(s, "    reg [31:0] tb_{name}_got = 32'd0;");
    s
}

/// The `$readmemh` calls and first gaps.
fn load(spec: &ExportSpec) -> String {
    let mut s = String::new();
    for i in &spec.inputs {
        let name = &i.stream.name;
        if i.stream.beats.is_empty() {
            continue;
        }
        for what in ["data", "gap", "after"] {
            let _ = writeln!(
                s,
                "        $readmemh(\"{}\", tb_{name}_{what});",
                vector_file(name, what)
            );
        }
        let _ = writeln!(s, "        tb_{name}_wait = tb_{name}_gap[0];");
    }
    for o in &spec.outputs {
        let name = &o.stream.name;
        let mut whats = vec!["ready"];
        if !o.stream.beats.is_empty() {
            whats.splice(0..0, ["expected", "transaction"]);
        }
        for what in whats {
            let _ = writeln!(
                s,
                "        $readmemh(\"{}\", tb_{name}_{what});",
                vector_file(name, what)
            );
        }
    }
    s
}

/// The `drive` task: inputs and readies of the cycle.
fn drive(spec: &ExportSpec, mask_words: usize) -> String {
    let mut s = String::new();
    for i in &spec.inputs {
        let st = &i.stream;
        let (name, n) = (&st.name, st.beats.len());
        if n == 0 {
            continue;
        }
        let at = index(&format!("tb_{name}_sent"), n);
        let _ = write!(
            s,
            r#"            // `{name}`: after an accepted beat, the next one's gap.
            if (tb_{name}_taken) begin
                tb_{name}_taken = 1'b0;
                {valid} = 1'b0;
                if (tb_{name}_sent < tb_{name}_beats) tb_{name}_wait = tb_{name}_gap[{at}];
            end
            if (!{valid} && tb_{name}_sent < tb_{name}_beats && tb_received >= tb_{name}_after[{at}]) begin
                if (tb_{name}_wait == 32'd0) begin
                    {valid} = 1'b1;
                    {data} = tb_{name}_data[{at}];
                end else begin
                    tb_{name}_wait = tb_{name}_wait - 32'd1;
                end
            end
"#,
            valid = st.valid,
            data = st.data,
        );
    }
    let word = format!("tb_cycle[{}:6]", index_bits(mask_words) + 5);
    for o in &spec.outputs {
        let st = &o.stream;
        let _ = writeln!(
            s,
            "            {} = tb_{}_ready[{word}][tb_cycle[5:0]];",
            st.ready, st.name
        );
    }
    s
}

/// Every line of `text` with `more` in front.
fn indented(text: &str, more: &str) -> String {
    text.lines().map(|l| format!("{more}{l}\n")).collect()
}

/// Pads `name` to `width` characters.
fn padded(name: &str, width: usize) -> String {
    format!("{name:<width$}")
}

/// The task that reports output `o`'s current beat as differing, field by
/// field (`*` marks a differing field), then the whole beat.
fn show_task(o: &OutputSpec, width: u32, what: &str) -> String {
    let st = &o.stream;
    let (name, n) = (&st.name, st.beats.len());
    if n == 0 {
        return String::new();
    }
    let at = index(&format!("tb_{name}_got"), n);
    let fields: Vec<&Field> = o.fields.fields().filter(|f| f.width > 0).collect();
    let pad = fields
        .iter()
        .map(|f| f.name.len())
        .chain([4])
        .max()
        .unwrap_or(4);
    let mut lines = String::new();
    for f in &fields {
        let bits = match f.width {
            1 => format!("[{}]", f.offset),
            w => format!("[{}:{}]", f.offset + w - 1, f.offset),
        };
        let _ = writeln!(
            lines,
            "            $display(\"  %s {} expected 'h%0h got 'h%0h\", (tb_e{bits} != {data}{bits}) ? \"*\" : \" \", tb_e{bits}, {data}{bits});",
            padded(f.name, pad),
            data = st.data
        );
    }
    format!(
        r#"
    // Output `{name}`'s beat differs from golden: every field, expected and got.
    task show_{name};
        reg {w}tb_e;
        begin
            tb_e = tb_{name}_expected[{at}];
            $display("FAIL: output `{name}` beat %0d ({what} %0d) at cycle %0d differs from golden (* marks a differing field):",
                     tb_{name}_got, tb_{name}_transaction[{at}], tb_cycle);
{lines}            $display("  %s {whole} expected 'h%h got 'h%h", (tb_e != {data}) ? "*" : " ", tb_e, {data});
        end
    endtask
"#,
        w = decl(width),
        whole = padded("beat", pad),
        data = st.data
    )
}

/// The `observe` task's checks of the output streams.
fn observe_outputs(spec: &ExportSpec) -> String {
    let mut s = String::new();
    for o in &spec.outputs {
        let st = &o.stream;
        let (name, n) = (&st.name, st.beats.len());
        let extra = format!(
            "$display(\"FAIL: output `{name}` beat %0d at cycle %0d: golden expects only {n} beats\", tb_{name}_got, tb_cycle);\n                    tb_failed = 1'b1;"
        );
        let check = match n {
            0 => format!("begin\n                    {extra}\n                end"),
            _ => format!(
                "if (tb_{name}_got >= tb_{name}_beats) begin\n                    {extra}\n                end else if ({} !== tb_{name}_expected[{}]) begin\n                    show_{name};\n                    tb_failed = 1'b1;\n                end",
                st.data,
                index(&format!("tb_{name}_got"), n)
            ),
        };
        let _ = write!(
            s,
            r#"            if ({valid} && {ready}) begin
                tb_moved = 1'b1;
                {check}
                tb_{name}_got = tb_{name}_got + 32'd1;
                tb_received = tb_received + 32'd1;
            end
"#,
            valid = st.valid,
            ready = st.ready,
        );
    }
    s
}

/// Declarations, per-cycle code and end code of the status rules.
struct Status {
    decls: String,
    after_reset: String,
    cycle: String,
    end: String,
}

fn status(spec: &ExportSpec) -> Status {
    let mut st = Status {
        decls: String::new(),
        after_reset: String::new(),
        cycle: String::new(),
        end: String::new(),
    };
    for c in &spec.checks {
        match c {
            StatusCheck::Pulses { port, cycles, why } => {
                let _ = writeln!(st.decls, "    reg [31:0] tb_{port}_high = 32'd0;");
                let _ = writeln!(
                    st.cycle,
                    "            if ({port}) tb_{port}_high = tb_{port}_high + 32'd1;"
                );
                let _ = write!(
                    st.end,
                    "        if (tb_{port}_high != 32'd{cycles}) begin\n            $display(\"FAIL: `{port}` was high in %0d cycles; expected {cycles} ({why})\", tb_{port}_high);\n            tb_failed = 1'b1;\n        end\n"
                );
            }
            StatusCheck::AtEnd { port, value } => {
                let w = width_of(spec, port);
                let _ = write!(
                    st.end,
                    "        if ({port} !== {w}'h{value:x}) begin\n            $display(\"FAIL: `{port}` = 'h%h at the end; expected 'h{value:x}\", {port});\n            tb_failed = 1'b1;\n        end\n"
                );
            }
            StatusCheck::DoneWhenIdleRises { done, idle } => {
                let _ = writeln!(st.decls, "    reg tb_{idle}_before = 1'b0;");
                let _ = writeln!(st.after_reset, "        tb_{idle}_before = {idle};");
                let _ = write!(
                    st.cycle,
                    "            if ({done} != ({idle} && !tb_{idle}_before)) begin\n                $display(\"FAIL: cycle %0d: `{done}` = %b, expected `{idle}` && !(`{idle}` a cycle earlier) = %b\", tb_cycle, {done}, {idle} && !tb_{idle}_before);\n                tb_failed = 1'b1;\n            end\n            tb_{idle}_before = {idle};\n"
                );
            }
        }
    }
    st
}

/// The watchdog's message: every stream's count so far.
fn hang_message(spec: &ExportSpec) -> String {
    let mut fmt = Vec::new();
    let mut args = Vec::new();
    for i in &spec.inputs {
        let n = &i.stream.name;
        match i.stream.beats.len() {
            0 => fmt.push(format!("{n} 0/0")),
            _ => {
                fmt.push(format!("{n} %0d/%0d"));
                args.push(format!("tb_{n}_sent, tb_{n}_beats"));
            }
        }
    }
    let sent = fmt.join(", ");
    fmt.clear();
    for o in &spec.outputs {
        let n = &o.stream.name;
        fmt.push(format!("{n} %0d/%0d"));
        args.push(format!("tb_{n}_got, tb_{n}_beats"));
    }
    format!(
        "                $display(\"FAIL: hang at cycle %0d: no handshake for %0d cycles; sent {sent}; received {}\", tb_cycle, WATCHDOG_CYCLES{});",
        fmt.join(", "),
        args.iter().map(|a| format!(", {a}")).collect::<String>()
    )
}

/// The testbench source; `mask_words`: 64-bit words of each `ready` mask.
pub(super) fn testbench(spec: &ExportSpec, mask_words: usize) -> String {
    let d = &spec.design;
    let bench = super::bench();
    let clk = d.clock.clone().unwrap_or_default();
    let mut decls = String::new();
    let mut accept = String::new();
    let mut all_done = Vec::new();
    for i in &spec.inputs {
        let st = &i.stream;
        decls.push_str(&input_decls(st, width_of(spec, &st.data)));
        if !st.beats.is_empty() {
            let _ = writeln!(
                accept,
                "            if ({} && {}) begin\n                tb_{n}_taken = 1'b1;\n                tb_{n}_sent = tb_{n}_sent + 32'd1;\n                tb_moved = 1'b1;\n            end",
                st.valid,
                st.ready,
                n = st.name
            );
            all_done.push(format!("tb_{0}_sent == tb_{0}_beats", st.name));
        }
    }
    let mut tasks = String::new();
    for o in &spec.outputs {
        let w = width_of(spec, &o.stream.data);
        decls.push_str(&output_decls(o, w, mask_words));
        tasks.push_str(&show_task(o, w, &spec.transaction));
        all_done.push(format!("tb_{0}_got == tb_{0}_beats", o.stream.name));
    }
    let mut st = status(spec);
    decls.push_str(&st.decls);
    let word = format!("tb_cycle[{}:6]", index_bits(mask_words) + 5);
    let store = spec.store.as_ref().map(|s| {
        let w = width_of(spec, "store_resp_data");
        super::store::parts(s, w, mask_words, &word)
    });
    let (mut load_store, mut drive_store, mut observe_store) = Default::default();
    if let Some(p) = store {
        decls.push_str(&p.decls);
        all_done.push(p.done);
        st.end.push_str(&p.end);
        (load_store, drive_store, observe_store) = (p.load, p.drive, p.observe);
    }
    let outputs: Vec<&str> = d
        .ports
        .iter()
        .filter(|p| p.dir == PortDir::Output)
        .map(|p| p.name.as_str())
        .collect();
    let (reset_on, reset_off) = match &d.reset {
        Some(r) => (
            format!("        {} = 1'b{};\n", r.port, u8::from(!r.active_low)),
            format!("        {} = 1'b{};\n", r.port, u8::from(r.active_low)),
        ),
        None => (String::new(), String::new()),
    };
    let all_done = match all_done.is_empty() {
        true => "1'b1".to_string(),
        false => all_done.join("\n                    && "),
    };
    let command = spec.command.replace('\n', " ");
    format!(
        r#"// Self-checking testbench of `{top}`, written by
//   {command}
// Plain Verilog-2005; the stimulus, the stall masks and golden's expected
// outputs are read from {vectors}/ (SPEC.md 9.1). Run: ./run.sh icarus, or
// ./run.sh verilator. Prints PASS, or FAIL and the first mismatch with its
// {what}, cycle and fields.
module tb;
{ports}
    localparam [31:0] RESET_CYCLES = 32'd{reset};
    localparam [31:0] WATCHDOG_CYCLES = 32'd{watchdog};
    localparam [31:0] DRAIN_CYCLES = 32'd{drain};

    reg [31:0] tb_cycle = 32'd0;     // cycles since reset
    reg [31:0] tb_quiet = 32'd0;     // cycles since the last handshake
    reg [31:0] tb_received = 32'd0;  // output beats, every stream
    reg [31:0] tb_drained = 32'd0;   // cycles after the last beat
    reg tb_moved = 1'b0;             // a handshake this cycle
    reg tb_draining = 1'b0;
    reg tb_failed = 1'b0;
    reg tb_finished = 1'b0;
{decls}
    task drive;
        begin
{drive}{drive_store}        end
    endtask

    task observe;
        begin
            tb_moved = 1'b0;
            if (^{{{outputs}}} === 1'bx) begin
                $display("FAIL: cycle %0d: an output is X or Z", tb_cycle);
                tb_failed = 1'b1;
            end
{observe_store}{accept}{observe_outputs}{status_cycle}            if (tb_failed) begin
                tb_finished = 1'b1;
            end else if (tb_draining) begin
                if (tb_drained == DRAIN_CYCLES) tb_finished = 1'b1;
                tb_drained = tb_drained + 32'd1;
            end else if ({all_done}) begin
                tb_draining = 1'b1;
            end else if (tb_moved) begin
                tb_quiet = 32'd0;
            end else if (tb_quiet == WATCHDOG_CYCLES) begin
{hang}
                tb_failed = 1'b1;
                tb_finished = 1'b1;
            end else begin
                tb_quiet = tb_quiet + 32'd1;
            end
        end
    endtask
{tasks}
    initial begin
{load}{load_store}{reset_on}        repeat (RESET_CYCLES) begin
            #5 {clk} = 1'b1;
            #5 {clk} = 1'b0;
        end
{reset_off}        #1;
{after_reset}        while (!tb_finished) begin
            drive;
            #1;
            observe;
            #4 {clk} = 1'b1;
            #5 {clk} = 1'b0;
            tb_cycle = tb_cycle + 32'd1;
        end
        if (!tb_failed) begin
{status_end}        end
        if (!tb_failed) begin
            $display("PASS: {top}: {transactions} {what}s, {beats_in} beats in, {beats_out} beats out, %0d cycles (seed {seed}, stalls {stalls})", tb_cycle);
        end
        $finish;
    end
endmodule
"#,
        top = d.top,
        vectors = super::VECTORS_DIR,
        what = spec.transaction,
        ports = ports_and_instance(spec),
        reset = bench.reset_cycles,
        watchdog = WATCHDOG_CYCLES,
        drain = bench.drain_cycles,
        drive = drive(spec, mask_words),
        outputs = outputs.join(", "),
        observe_outputs = observe_outputs(spec),
        status_cycle = st.cycle,
        hang = hang_message(spec),
        after_reset = st.after_reset,
        load = load(spec),
        status_end = indented(&st.end, "    "),
        transactions = spec.transactions,
        beats_in = spec
            .inputs
            .iter()
            .map(|i| i.stream.beats.len())
            .sum::<usize>(),
        beats_out = spec
            .outputs
            .iter()
            .map(|o| o.stream.beats.len())
            .sum::<usize>(),
        seed = spec.seed,
        stalls = match spec.stream_stalls.is_empty() {
            true => spec.stalls.to_string(),
            false => format!("{} {}", spec.stalls, spec.stream_stalls),
        },
    )
}

/// The run script: compiles and runs the testbench on Icarus or Verilator
/// and exits 0 only when it printed PASS.
pub(super) fn run_script(spec: &ExportSpec) -> String {
    let files: Vec<String> = spec
        .design
        .verilog_files
        .iter()
        .filter_map(|f| f.file_name())
        .map(|f| format!("{RTL_DIR}/{}", f.to_string_lossy()))
        .collect();
    format!(
        r#"#!/bin/sh
# Runs the self-checking testbench of `{top}` (written by hiermerge
# export-tb): ./run.sh [icarus|verilator]  (default: icarus).
# Needs Icarus Verilog (iverilog, vvp) or Verilator 5 (--binary); nothing
# else. Prints the testbench's PASS line, or FAIL and the first mismatch;
# exits 0 only on PASS. Build files and the log go to build/.
set -eu
cd "$(dirname "$0")"
sources="{tb} {files}"
mkdir -p build
case "${{1:-icarus}}" in
icarus)
    iverilog -g2005 -s tb -o build/tb.vvp $sources
    vvp -n build/tb.vvp | tee build/sim.log
    ;;
verilator)
    if ! verilator --binary --top-module tb --Mdir build/verilator -o tb $sources >build/verilator.log 2>&1; then
        cat build/verilator.log >&2
        exit 1
    fi
    build/verilator/tb | tee build/sim.log
    ;;
*)
    echo "usage: $0 [icarus|verilator]" >&2
    exit 2
    ;;
esac
grep -q '^PASS' build/sim.log
"#,
        top = spec.design.top,
        tb = TB_FILE,
        files = files.join(" "),
    )
}
