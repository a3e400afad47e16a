//! The generated Verilog testbench of the Icarus batch mode: the stream
//! driver, the monitor's back-pressure, the output recorder, the X/Z check,
//! the watchdog and the drain all run inside `vvp`, so a cycle costs no pipe
//! round trip.
//!
//! Files (in vvp's working directory, written by `super::batch`):
//! - `params.txt` (read once, all `%h`): reset cycles, watchdog limit, drain
//!   cycles, expected output count, driver threshold, monitor threshold,
//!   dump flag, first and last dumped cycle, then per lane the driver's and
//!   the monitor's SplitMix64 state.
//! - `stim.txt` (read one beat ahead): per input beat `<lane> <after>
//!   <payload hex>...`; the beat may be presented once `after` outputs
//!   (all lanes together) have been accepted by earlier cycles.
//! - `out.txt` (written): `O <lane> <cycle> <hex>...` per output transfer,
//!   `W <cycle> <hex>...` whenever a watched output changes (and once at the
//!   first cycle), `X <cycle> <hex>...` (every output) at the first X/Z on
//!   any output after reset, `H <cycle> <idle> <hex>...` (every port) when
//!   the watchdog fires, and last `E <cycle> <inputs accepted> <outputs>`.
//!
//! Per cycle, in the order of `crate::tb::run_stream_bench`: each lane's
//! driver (a SplitMix64 draw against the threshold decides whether an
//! available beat is raised; while `valid` is low each payload port gets
//! random words from the same generator), each lane's monitor (one draw for
//! `ready`), `#1`, the X/Z check, accepted inputs, output transfers, watched
//! outputs, end and watchdog, then the clock edge. With one lane and no
//! `after` constraints this is draw for draw the pipe engine's
//! `StreamDriver`/`StreamMonitor`, so both runs see the same cycles.

use crate::design::{Design, PortDir, PortId};

/// Name of the generated module.
pub const BATCH_TB_MODULE: &str = "hm_batch_tb";

/// The SplitMix64 increment (`golden::scenes::splitmix64_next`).
pub const SPLITMIX_GAMMA: u64 = 0x9E37_79B9_7F4A_7C15;

/// Port ids of one valid/ready lane pair (an input stream and the output
/// stream its results leave on).
#[derive(Clone, Debug)]
pub struct LanePorts {
    /// Input stream valid.
    pub in_valid: PortId,
    /// Input stream ready.
    pub in_ready: PortId,
    /// Input payload ports.
    pub in_payload: Vec<PortId>,
    /// Output stream valid.
    pub out_valid: PortId,
    /// Output stream ready.
    pub out_ready: PortId,
    /// Output payload ports.
    pub out_payload: Vec<PortId>,
}

/// Everything the generated testbench is built from.
pub struct BatchTbSpec<'a> {
    /// The design under test (must have a clock).
    pub design: &'a Design,
    /// The lanes, in lane-number order.
    pub lanes: &'a [LanePorts],
    /// Outputs whose changes are logged (`W` lines).
    pub watch: &'a [PortId],
    /// Inputs held at a fixed value for the whole run (`(port, hex)`).
    pub constants: &'a [(PortId, String)],
}

fn sig(id: PortId) -> String {
    format!("hm_p{}", id.0)
}

fn lane_reg(kind: &str, lane: usize, k: usize) -> String {
    format!("hm_{kind}_{lane}_{k}")
}

/// The testbench source.
pub fn generate_batch_testbench(spec: &BatchTbSpec) -> String {
    let d = spec.design;
    let width = |id: PortId| d.ports[id.0].width;
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
    let mut constants = String::new();
    for (id, hex) in spec.constants {
        constants.push_str(&format!("        {} = {}'h{hex};\n", sig(*id), width(*id)));
    }
    let all_ports: Vec<String> = (0..d.ports.len()).map(|i| sig(PortId(i))).collect();
    let max_payload = spec
        .lanes
        .iter()
        .flat_map(|l| l.in_payload.iter())
        .map(|&p| width(p).div_ceil(64) * 64)
        .max()
        .unwrap_or(64);

    let mut lane_decls = String::new();
    let mut read_params = String::new();
    let mut read_head = String::new();
    let mut drive = String::new();
    let mut accept = String::new();
    let mut transfer = String::new();
    let mut any_presenting = Vec::new();
    for (l, lane) in spec.lanes.iter().enumerate() {
        lane_decls.push_str(&format!(
            "    reg [63:0] hm_drv_{l}, hm_mon_{l};\n    reg hm_pres_{l}, hm_rdy_{l};\n"
        ));
        for (k, &p) in lane.in_payload.iter().enumerate() {
            lane_decls.push_str(&format!(
                "    reg [{}:0] {};\n",
                width(p) - 1,
                lane_reg("head", l, k)
            ));
        }
        read_params.push_str(&format!(
            "        got = $fscanf(fd, \"%h %h\", hm_drv_{l}, hm_mon_{l});\n        hm_pres_{l} = 0; hm_rdy_{l} = 0;\n"
        ));
        let reads: String = (0..lane.in_payload.len())
            .map(|k| {
                format!(
                    "                    got = $fscanf(stim, \" %h\", {});\n",
                    lane_reg("head", l, k)
                )
            })
            .collect();
        read_head.push_str(&format!(
            "                {l}: begin\n{reads}                end\n"
        ));

        // Driver: raise valid on an available beat unless the draw stalls;
        // while valid is low, random words on every payload port.
        let mut garbage = String::new();
        for &p in &lane.in_payload {
            let w = width(p);
            for word in 0..w.div_ceil(64) {
                garbage.push_str(&format!(
                    "                draw(hm_drv_{l}, hm_rnd); hm_garbage[{}:{}] = hm_rnd;\n",
                    word * 64 + 63,
                    word * 64
                ));
            }
            garbage.push_str(&format!(
                "                {} = hm_garbage[{}:0];\n",
                sig(p),
                w - 1
            ));
        }
        let present: String = lane
            .in_payload
            .iter()
            .enumerate()
            .map(|(k, &p)| format!("                {} = {};\n", sig(p), lane_reg("head", l, k)))
            .collect();
        drive.push_str(&format!(
            r#"            if (!hm_pres_{l} && hm_head_ok && hm_head_lane == {l} && hm_received >= hm_head_after) begin
                draw(hm_drv_{l}, hm_rnd);
                if (!((hm_rnd >> 11) < hm_in_thr)) hm_pres_{l} = 1'b1;
            end
            {valid} = hm_pres_{l};
            if (hm_pres_{l}) begin
{present}            end else begin
{garbage}            end
            draw(hm_mon_{l}, hm_rnd);
            hm_rdy_{l} = !((hm_rnd >> 11) < hm_out_thr);
            {ready} = hm_rdy_{l};
"#,
            valid = sig(lane.in_valid),
            ready = sig(lane.out_ready),
        ));
        accept.push_str(&format!(
            r#"            if (hm_pres_{l} && {in_ready} === 1'b1) begin
                hm_pres_{l} = 1'b0;
                hm_sent = hm_sent + 1;
                hm_last_progress = hm_cycle;
                load_head;
            end
"#,
            in_ready = sig(lane.in_ready)
        ));
        let fmt: String = lane.out_payload.iter().map(|_| " %h").collect();
        let args: String = lane
            .out_payload
            .iter()
            .map(|&p| format!(", {}", sig(p)))
            .collect();
        transfer.push_str(&format!(
            r#"            if (hm_rdy_{l} && {out_valid} === 1'b1) begin
                $fwrite(out, "O {l} %0d{fmt}\n", hm_cycle{args});
                hm_received = hm_received + 1;
                hm_last_progress = hm_cycle;
            end
"#,
            out_valid = sig(lane.out_valid)
        ));
        any_presenting.push(format!("hm_pres_{l}"));
    }
    let (watch_decl, watch_log) = if spec.watch.is_empty() {
        (String::new(), String::new())
    } else {
        let total: usize = spec.watch.iter().map(|&p| width(p)).sum();
        let cat: Vec<String> = spec.watch.iter().map(|&p| sig(p)).collect();
        let fmt: String = spec.watch.iter().map(|_| " %h").collect();
        (
            format!(
                "    reg [{}:0] hm_watch_prev;\n    reg hm_watch_first;\n",
                total - 1
            ),
            format!(
                r#"            if (hm_watch_first || {{{cat}}} !== hm_watch_prev) begin
                $fwrite(out, "W %0d{fmt}\n", hm_cycle, {args});
                hm_watch_prev = {{{cat}}};
                hm_watch_first = 1'b0;
            end
"#,
                cat = cat.join(", "),
                args = cat.join(", ")
            ),
        )
    };
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
    let clear_handshakes: String = spec
        .lanes
        .iter()
        .map(|l| {
            format!(
                "        {} = 1'b0; {} = 1'b0;\n",
                sig(l.in_valid),
                sig(l.out_ready)
            )
        })
        .collect();
    let presenting = if any_presenting.is_empty() {
        "1'b0".to_string()
    } else {
        any_presenting.join(" || ")
    };
    format!(
        r#"// Generated by hiermerge cosim (Icarus batch mode) for top `{top}`. Do not edit.
module {BATCH_TB_MODULE};
{decls}{lane_decls}{watch_decl}    reg [{gw}:0] hm_garbage;
    reg [63:0] hm_rnd;
    reg [63:0] hm_reset_cycles, hm_watchdog, hm_drain, hm_total_out, hm_in_thr, hm_out_thr;
    reg [63:0] hm_dump, hm_dump_from, hm_dump_to;
    reg [63:0] hm_cycle, hm_sent, hm_received, hm_last_progress, hm_limit, hm_drain_left;
    reg [63:0] hm_head_after;
    integer hm_head_lane;
    reg hm_head_ok, hm_draining, hm_stop, hm_dumping;
    integer fd, stim, out, got;

    {top} dut (
{conns}
    );

    function [63:0] splitmix_mix;
        input [63:0] s;
        reg [63:0] z;
        begin
            z = s;
            z = (z ^ (z >> 30)) * 64'hBF58476D1CE4E5B9;
            z = (z ^ (z >> 27)) * 64'h94D049BB133111EB;
            splitmix_mix = z ^ (z >> 31);
        end
    endfunction

    // One SplitMix64 step of `state`, its output in `r`.
    task draw;
        inout [63:0] state;
        output [63:0] r;
        begin
            state = state + 64'h{gamma:016X};
            r = splitmix_mix(state);
        end
    endtask

    task dump_window;
        begin
            if (hm_dump != 0 && !hm_dumping && hm_cycle >= hm_dump_from && hm_cycle <= hm_dump_to) begin
                $dumpfile("window.vcd");
                $dumpvars(0, {BATCH_TB_MODULE});
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
            dump_window;
        end
    endtask

    task load_head;
        begin
            got = $fscanf(stim, " %d %d", hm_head_lane, hm_head_after);
            hm_head_ok = (got == 2);
            if (hm_head_ok) begin
                case (hm_head_lane)
{read_head}                default: hm_head_ok = 1'b0;
                endcase
            end
        end
    endtask

    initial begin
        fd = $fopen("params.txt", "r");
        got = $fscanf(fd, "%h %h %h %h %h %h %h %h %h", hm_reset_cycles, hm_watchdog, hm_drain,
            hm_total_out, hm_in_thr, hm_out_thr, hm_dump, hm_dump_from, hm_dump_to);
{read_params}        $fclose(fd);
        stim = $fopen("stim.txt", "r");
        out = $fopen("out.txt", "w");
        hm_cycle = 0; hm_sent = 0; hm_received = 0;
        hm_draining = 1'b0; hm_stop = 1'b0; hm_dumping = 1'b0; hm_drain_left = 0;
{watch_init}{constants}{clear_handshakes}        dump_window;
{reset_assert}{reset_release}        #1;
        load_head;
        hm_limit = hm_watchdog;
        hm_last_progress = hm_cycle;
        while (!hm_stop) begin
{drive}            #1;
{x_check}            if (!hm_stop) begin
{accept}{transfer}{watch_log}                if (!hm_draining && !hm_head_ok && !({presenting}) && hm_received >= hm_total_out) begin
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
                    end
                end
            end
        end
        // Trace the cycles after a stop too, so a VCD shows what followed.
        while (hm_dumping) tick;
        $fwrite(out, "E %0d %0d %0d\n", hm_cycle, hm_sent, hm_received);
        $fclose(out);
        $fclose(stim);
        $finish;
    end
endmodule
"#,
        top = d.top,
        conns = conns.join(",\n"),
        gw = max_payload - 1,
        gamma = SPLITMIX_GAMMA,
        watch_init = if spec.watch.is_empty() {
            ""
        } else {
            "        hm_watch_first = 1'b1;\n"
        },
    )
}
