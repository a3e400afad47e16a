//! The frame both generated batch testbenches share (`super::batch_testbench`:
//! one beat sequence over lanes; `super::multi_batch_testbench`: a driver
//! per stream): the design's ports as testbench signals, the clock tick and
//! its VCD window, reset, the stall masks read every 64 cycles, the X/Z
//! check, and the end of every cycle (drain, watchdog, tick); a testbench
//! fills in its own declarations, drivers, acceptance and recording.
//!
//! Files every batch testbench reads or writes (in vvp's working directory):
//! - `params.txt` (read once, all `%h`): reset cycles, watchdog limit, drain
//!   cycles, expected output count, dump flag, first and last dumped cycle,
//!   then the testbench's own words.
//! - `masks.fifo` (a named pipe): one line of 64-bit words (`%h`) per 64
//!   cycles of the main loop; bit `k` of a word is cycle `k` of the block,
//!   1 = go.
//! - `window.vcd` (written when the dump flag is set): every signal of the
//!   testbench in the cycles `first..=last`, and after a stop until `last`.
//! - `out.txt` (written): the testbench's own records, `X <cycle> <hex>...`
//!   (every output) at the first X/Z on any output after reset,
//!   `H <cycle> <idle> <hex>...` (every port) when the watchdog fires,
//!   `M <cycle>` when the masks ran out, last `E <cycle> <outputs> <sent>...`.
//!
//! Per cycle: masks (each 64th), the testbench's drive code, `#1`, the X/Z
//! check, its acceptance and recording code, then: everything sent and
//! received starts the drain (the watchdog limit becomes the drain length
//! plus one), an empty drain stops, else a watchdog timeout stops with `H`,
//! else the clock ticks.

use crate::design::{Design, PortDir, PortId};

pub use super::testbench::sig;

/// `$readmemh` file of the garbage pool of payload port `k` of lane or
/// input stream `s` (what a stalled driver shows on its payload).
pub fn pool_file(s: usize, k: usize) -> String {
    format!("pool_{s}_{k}.hex")
}

/// What a batch testbench puts into the frame (Verilog text, indented as
/// the frame's slots are: declarations and tasks 4 spaces, `init` and
/// `after_reset` 8, `drive` 12, `observe` 16).
pub struct TbBody<'a> {
    /// Module name of the testbench.
    pub module: &'a str,
    /// What the header comment calls it.
    pub title: &'a str,
    /// Input ports the body drives with continuous assignments (declared
    /// `wire`, assigned in `decls`); every other input is a `reg`.
    pub wired: Vec<PortId>,
    /// Its own declarations.
    pub decls: String,
    /// Its own tasks.
    pub tasks: String,
    /// Registers read from `params.txt` after the frame's seven words.
    pub params: Vec<String>,
    /// Statements after the files are open, before reset.
    pub init: String,
    /// Statements after reset is released and settled.
    pub after_reset: String,
    /// The 64-bit registers each mask line is read into (none: no masks read).
    pub masks: Vec<String>,
    /// Every cycle before `#1`: present inputs, raise ready.
    pub drive: String,
    /// Every cycle after `#1` and the X/Z check: accepted inputs, output
    /// transfers (`hm_received`), progress (`hm_last_progress`).
    pub observe: String,
    /// True when every beat is sent (the frame adds `hm_received >= hm_total_out`).
    pub all_sent: String,
    /// Counters written after the output count in the `E` record.
    pub sent: Vec<String>,
    /// Statements after the main loop (and the trailing VCD cycles), before `E`.
    pub before_end: String,
}

/// The testbench source: the frame around `body`, the design `d` as `dut`.
pub fn generate(d: &Design, body: &TbBody) -> String {
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
            PortDir::Input if body.wired.contains(&PortId(i)) => {
                decls.push_str(&format!("    wire [{}:0] {s};\n", p.width - 1))
            }
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
    let (reset_assert, reset_release) = reset_code(d);
    let params: Vec<String> = FRAME_PARAMS
        .iter()
        .map(|s| s.to_string())
        .chain(body.params.iter().cloned())
        .collect();
    let all_sent = if body.all_sent.is_empty() {
        String::new()
    } else {
        format!("{} && ", body.all_sent)
    };
    format!(
        r#"// Generated by hiermerge cosim ({title}) for top `{top}`. Do not edit.
module {module};
{decls}{x_wire}{body_decls}    reg [63:0] hm_reset_cycles, hm_watchdog, hm_drain, hm_total_out;
    reg [63:0] hm_dump, hm_dump_from, hm_dump_to;
    reg [63:0] hm_cycle, hm_received, hm_last_progress, hm_limit, hm_drain_left;
    reg [8*64-1:0] hm_fname;
    reg [5:0] hm_bit;
    reg hm_draining, hm_stop, hm_dumping;
    integer fd, out, got, hm_masks;

    {top} dut (
{conns}
    );

    task dump_window;
        begin
            if (hm_dump != 0 && !hm_dumping && hm_cycle >= hm_dump_from && hm_cycle <= hm_dump_to) begin
                $dumpfile("window.vcd");
                $dumpvars(0, {module});
                hm_dumping = 1'b1;
            end else if (hm_dumping && hm_cycle > hm_dump_to) begin
                $dumpoff;
                $dumpflush;
                hm_dump = 0;
                hm_dumping = 1'b0;
            end
        end
    endtask

    task tick;
        begin
            {clk} = 1'b0; #1; {clk} = 1'b1; #1;
            hm_cycle = hm_cycle + 1;
            if (hm_dump != 0) dump_window;
        end
    endtask

{tasks}    initial begin
        fd = $fopen("params.txt", "r");
        got = $fscanf(fd, "{params_fmt}", {params_args});
        $fclose(fd);
        hm_masks = $fopen("masks.fifo", "r");
        out = $fopen("out.txt", "w");
        hm_cycle = 0; hm_received = 0; hm_bit = 0;
        hm_draining = 1'b0; hm_stop = 1'b0; hm_dumping = 1'b0; hm_drain_left = 0;
{init}        dump_window;
{reset_assert}{reset_release}        #1;
{after_reset}        hm_limit = hm_watchdog;
        hm_last_progress = hm_cycle;
        while (!hm_stop) begin
{read_masks}{drive}            #1;
{x_check}            if (!hm_stop) begin
{observe}                if (!hm_draining) if ({all_sent}hm_received >= hm_total_out) begin
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
        // Trace the cycles after a stop too, so a VCD shows what followed.
        while (hm_dumping) tick;
{before_end}        $fwrite(out, "E %0d %0d{sent_fmt}\n", hm_cycle, hm_received{sent_args});
        $fclose(out);
        $finish;
    end
endmodule
"#,
        title = body.title,
        top = d.top,
        module = body.module,
        body_decls = body.decls,
        conns = conns.join(",\n"),
        tasks = body.tasks,
        params_fmt = vec!["%h"; params.len()].join(" "),
        params_args = params.join(", "),
        init = body.init,
        after_reset = body.after_reset,
        read_masks = read_masks(&body.masks),
        drive = body.drive,
        x_wire = x_wire(&outputs),
        x_check = x_check(&outputs),
        observe = body.observe,
        all_fmt = " %h".repeat(all_ports.len()),
        all_args = all_ports
            .iter()
            .map(|p| format!(", {p}"))
            .collect::<String>(),
        sent_fmt = " %0d".repeat(body.sent.len()),
        sent_args = body
            .sent
            .iter()
            .map(|s| format!(", {s}"))
            .collect::<String>(),
        before_end = body.before_end,
    )
}

/// The registers of the frame's words of `params.txt`, in file order.
const FRAME_PARAMS: [&str; 7] = [
    "hm_reset_cycles",
    "hm_watchdog",
    "hm_drain",
    "hm_total_out",
    "hm_dump",
    "hm_dump_from",
    "hm_dump_to",
];

/// The frame's words of `params.txt` for a run, in file order
/// (`FRAME_PARAMS`): `dump` is the VCD window, if any.
pub fn frame_params(
    config: &crate::tb::BenchConfig,
    total_out: u64,
    dump: Option<(u64, u64)>,
) -> Vec<u64> {
    let (dump_on, from, to) = match dump {
        Some((from, to)) => (1, from, to),
        None => (0, 0, 0),
    };
    vec![
        u64::from(config.reset_cycles),
        config.watchdog_cycles,
        config.drain_cycles,
        total_out,
        dump_on,
        from,
        to,
    ]
}

/// Reset asserted for `hm_reset_cycles` ticks, and released.
fn reset_code(d: &Design) -> (String, String) {
    match &d.reset {
        Some(r) => {
            let id = d.port_id(&r.port).map(sig).unwrap_or_default();
            let active = u8::from(!r.active_low);
            (
                format!("        {id} = 1'b{active};\n        repeat (hm_reset_cycles) tick;\n"),
                format!("        {id} = 1'b{};\n", 1 - active),
            )
        }
        None => (String::new(), String::new()),
    }
}

/// Every 64 cycles, the next mask line into `masks`; `M` when it is missing.
fn read_masks(masks: &[String]) -> String {
    if masks.is_empty() {
        return String::new();
    }
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
}

/// `hm_outs_x`: X when any output has an X or Z bit. A continuous
/// reduction per port is re-evaluated only when that port changes, where
/// the same expression in the per-cycle code loaded every output each cycle.
fn x_wire(outputs: &[String]) -> String {
    if outputs.is_empty() {
        return String::new();
    }
    let per_port: Vec<String> = outputs.iter().map(|o| format!("^{o}")).collect();
    format!("    wire hm_outs_x = ^{{{}}};\n", per_port.join(", "))
}

/// An X or Z on any output stops the run with an `X` record of every output.
fn x_check(outputs: &[String]) -> String {
    if outputs.is_empty() {
        return String::new();
    }
    format!(
        r#"            if (hm_outs_x === 1'bx) begin
                $fwrite(out, "X %0d{fmt}\n", hm_cycle{args});
                hm_stop = 1'b1;
            end
"#,
        fmt = " %h".repeat(outputs.len()),
        args = outputs.iter().map(|o| format!(", {o}")).collect::<String>(),
    )
}
