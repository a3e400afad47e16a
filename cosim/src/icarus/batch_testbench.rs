//! The generated Verilog testbench of the Icarus batch mode: the stream
//! driver, the monitor's back-pressure, the output recorder, the X/Z check,
//! the watchdog and the drain all run inside `vvp`, so a cycle costs no pipe
//! round trip.
//!
//! The frame (files, reset, masks, X/Z check, drain, watchdog, VCD
//! window, the `X`/`H`/`M`/`E` records) is `super::batch_tb_frame`'s; this
//! testbench's own files (in vvp's working directory, written by
//! `super::batch`):
//! - `params.txt`, after the frame's words: the input beat count.
//! - `pool_<lane>_<k>.hex` (`$readmemh`): `GARBAGE_POOL` random values of
//!   payload port `k` of the lane, shown while its `valid` is low (entry
//!   `n mod GARBAGE_POOL` after the lane's `n`-th accepted beat).
//! - the input beats in chunks of `STIM_CHUNK` (`$readmemh` when the
//!   first beat of a chunk is needed; `$fscanf` costs ~5 us a beat in vvp):
//!   `meta_<c>.hex`, per beat `lane << 48 | after` (the beat may be
//!   presented once `after` outputs, all lanes together, have been accepted
//!   by earlier cycles), and `pay_<c>_<lane>_<k>.hex`, per beat payload port
//!   `k` of `lane` (0 on beats of other lanes); every file holds exactly
//!   `STIM_CHUNK` lines (zero padded).
//! - `masks.fifo`: per lane the driver's and the monitor's word (1 = the
//!   driver may raise `valid`, the monitor raises `ready`). Rust writes
//!   them ahead from the seeded generators, as many as vvp reads.
//! - `out.txt`: `O <lane> <cycle> <hex>...` per output transfer,
//!   `W <cycle> <hex>...` whenever a watched output changes (and once at the
//!   first cycle); the end record is `E <cycle> <outputs> <inputs accepted>`.
//!
//! Per cycle, in the order of `crate::tb::run_stream_bench`: each lane's
//! driver (an available beat is raised on a go bit and held until
//! accepted; while `valid` is low the payload shows a pool value, a new one
//! after each accepted beat), each
//! lane's monitor (`ready` = its go bit), `#1`, the X/Z check, accepted
//! inputs, output transfers, watched outputs, end and watchdog, then the
//! clock edge. Random numbers are not drawn in Verilog: vvp's 64-bit shifts
//! cost microseconds each, which made a SplitMix64 draw per decision the
//! bottleneck.

use super::batch_tb_frame::{self, pool_file, sig, TbBody};
use crate::design::{Design, PortId};

/// Name of the generated module.
pub const BATCH_TB_MODULE: &str = "hm_batch_tb";

/// Input beats per stimulus chunk file (a power of two).
pub const STIM_CHUNK: usize = 1 << 14;

/// Random payload values per lane and payload port, shown while the
/// lane's `valid` is low (a new one after each beat the lane delivers).
pub const GARBAGE_POOL: usize = 1024;

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

fn lane_reg(kind: &str, lane: usize, k: usize) -> String {
    format!("hm_{kind}_{lane}_{k}")
}

/// `$readmemh` file of chunk `chunk`'s beat lanes and waits.
pub fn meta_file(chunk: usize) -> String {
    format!("meta_{chunk}.hex")
}

/// `$readmemh` file of chunk `chunk`'s payload port `k` of lane `lane`.
pub fn payload_file(chunk: usize, lane: usize, k: usize) -> String {
    format!("pay_{chunk}_{lane}_{k}.hex")
}

/// The testbench source.
pub fn generate_batch_testbench(spec: &BatchTbSpec) -> String {
    let d = spec.design;
    let width = |id: PortId| d.ports[id.0].width;
    let mut lane_decls = String::new();
    let mut load_pools = String::new();
    let mut load_chunk = String::new();
    let mut read_head = String::new();
    let mut drive = String::new();
    let mut accept = String::new();
    let mut transfer = String::new();
    let mut any_presenting = Vec::new();
    let mut mask_regs = Vec::new();
    for (l, lane) in spec.lanes.iter().enumerate() {
        lane_decls.push_str(&format!(
            "    reg [63:0] hm_go_{l}, hm_rd_{l}, hm_taken_{l};\n    reg hm_pres_{l}, hm_rdy_{l};\n"
        ));
        mask_regs.push(format!("hm_go_{l}"));
        mask_regs.push(format!("hm_rd_{l}"));
        for (k, &p) in lane.in_payload.iter().enumerate() {
            let w = width(p) - 1;
            lane_decls.push_str(&format!(
                "    reg [{w}:0] {};\n    reg [{w}:0] {} [0:{}];\n    reg [{w}:0] {} [0:{}];\n",
                lane_reg("head", l, k),
                lane_reg("pool", l, k),
                GARBAGE_POOL - 1,
                lane_reg("stim", l, k),
                STIM_CHUNK - 1
            ));
            load_chunk.push_str(&format!(
                "                $sformat(hm_fname, \"pay_%0d_{l}_{k}.hex\", hm_next / {STIM_CHUNK});\n                $readmemh(hm_fname, {});\n",
                lane_reg("stim", l, k)
            ));
            load_pools.push_str(&format!(
                "        $readmemh(\"{}\", {});\n",
                pool_file(l, k),
                lane_reg("pool", l, k)
            ));
        }
        let reads: String = (0..lane.in_payload.len())
            .map(|k| {
                format!(
                    "                    {} = {}[hm_index];\n",
                    lane_reg("head", l, k),
                    lane_reg("stim", l, k)
                )
            })
            .collect();
        read_head.push_str(&format!(
            "                {l}: begin\n{reads}                end\n"
        ));
        // One garbage value per beat of the lane (not per cycle): a payload
        // that does not change costs vvp nothing, and an idle lane of a
        // multi-lane design would otherwise re-evaluate its whole datapath
        // every cycle.
        let pool_index = format!("hm_taken_{l}[{}:0]", GARBAGE_POOL.trailing_zeros() - 1);
        let (present, garbage): (String, String) = lane
            .in_payload
            .iter()
            .enumerate()
            .map(|(k, &p)| {
                (
                    format!("                {} = {};\n", sig(p), lane_reg("head", l, k)),
                    format!(
                        "                {} = {}[{pool_index}];\n",
                        sig(p),
                        lane_reg("pool", l, k)
                    ),
                )
            })
            .unzip();
        drive.push_str(&format!(
            r#"            if (!hm_pres_{l} && hm_go_{l}[hm_bit] && hm_head_ok && hm_head_lane == {l} && hm_received >= hm_head_after)
                hm_pres_{l} = 1'b1;
            {valid} = hm_pres_{l};
            if (hm_pres_{l}) begin
{present}            end else begin
{garbage}            end
            hm_rdy_{l} = hm_rd_{l}[hm_bit];
            {ready} = hm_rdy_{l};
"#,
            valid = sig(lane.in_valid),
            ready = sig(lane.out_ready),
        ));
        accept.push_str(&format!(
            r#"                if (hm_pres_{l} && {in_ready} === 1'b1) begin
                    hm_pres_{l} = 1'b0;
                    hm_sent = hm_sent + 1;
                    hm_taken_{l} = hm_taken_{l} + 1;
                    hm_last_progress = hm_cycle;
                    load_head;
                end
"#,
            in_ready = sig(lane.in_ready)
        ));
        transfer.push_str(&record_transfer(
            l,
            &format!("hm_rdy_{l}"),
            lane.out_valid,
            &lane.out_payload,
        ));
        any_presenting.push(format!("hm_pres_{l}"));
    }
    let (watch_decl, watch_init, watch_log) = watch_code(spec);
    let mut constants = String::new();
    for (id, hex) in spec.constants {
        constants.push_str(&format!("        {} = {}'h{hex};\n", sig(*id), width(*id)));
    }
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
    let clear_lanes: String = (0..spec.lanes.len())
        .map(|l| format!("        hm_pres_{l} = 1'b0; hm_rdy_{l} = 1'b0; hm_taken_{l} = 0;\n"))
        .collect();
    let presenting = if any_presenting.is_empty() {
        "1'b0".to_string()
    } else {
        any_presenting.join(" || ")
    };
    let chunk_last = STIM_CHUNK - 1;
    let index_msb = STIM_CHUNK.trailing_zeros() - 1;
    let body = TbBody {
        module: BATCH_TB_MODULE,
        title: "Icarus batch mode",
        wired: Vec::new(),
        decls: format!(
            r#"{lane_decls}{watch_decl}    reg [63:0] hm_sent, hm_head_after, hm_total_in, hm_next;
    reg [63:0] hm_meta [0:{chunk_last}];
    reg [{index_msb}:0] hm_index;
    integer hm_head_lane;
    reg hm_head_ok;
"#
        ),
        tasks: format!(
            r#"    // The next beat into the head registers (hm_head_ok = 0 after the last).
    task load_head;
        begin
            hm_head_ok = hm_next < hm_total_in;
            if (hm_head_ok) begin
                hm_index = hm_next[{index_msb}:0];
                if (hm_index == 0) begin
                    $sformat(hm_fname, "meta_%0d.hex", hm_next / {STIM_CHUNK});
                    $readmemh(hm_fname, hm_meta);
{load_chunk}                end
                hm_head_lane = hm_meta[hm_index][63:48];
                hm_head_after = {{16'd0, hm_meta[hm_index][47:0]}};
                hm_next = hm_next + 1;
                case (hm_head_lane)
{read_head}                default: hm_head_ok = 1'b0;
                endcase
            end
        end
    endtask

"#
        ),
        params: vec!["hm_total_in".to_string()],
        init: format!(
            "{load_pools}        hm_next = 0; hm_sent = 0;\n{clear_lanes}{watch_init}{constants}{clear_handshakes}"
        ),
        after_reset: "        load_head;\n".to_string(),
        masks: mask_regs,
        drive,
        observe: format!("{accept}{transfer}{watch_log}"),
        all_sent: format!("!hm_head_ok && !({presenting})"),
        sent: vec!["hm_sent".to_string()],
        before_end: String::new(),
    };
    batch_tb_frame::generate(d, &body)
}

/// Records an output transfer of stream `n` (`ready` high, `valid` high)
/// as `O <n> <cycle> <hex>...`, and counts it as progress.
pub fn record_transfer(n: usize, ready: &str, valid: PortId, payload: &[PortId]) -> String {
    let fmt = " %h".repeat(payload.len());
    let args: String = payload.iter().map(|&p| format!(", {}", sig(p))).collect();
    format!(
        r#"                if ({ready} && {valid} === 1'b1) begin
                    $fwrite(out, "O {n} %0d{fmt}\n", hm_cycle{args});
                    hm_received = hm_received + 1;
                    hm_last_progress = hm_cycle;
                end
"#,
        valid = sig(valid)
    )
}

/// Declarations, initialisation and per-cycle logging (`W` records) of the
/// watched outputs.
fn watch_code(spec: &BatchTbSpec) -> (String, String, String) {
    if spec.watch.is_empty() {
        return (String::new(), String::new(), String::new());
    }
    let total: u32 = spec
        .watch
        .iter()
        .map(|&p| spec.design.ports[p.0].width)
        .sum();
    let cat: Vec<String> = spec.watch.iter().map(|&p| sig(p)).collect();
    let fmt = " %h".repeat(spec.watch.len());
    (
        format!(
            "    reg [{}:0] hm_watch_prev;\n    reg hm_watch_first;\n",
            total - 1
        ),
        "        hm_watch_first = 1'b1;\n".to_string(),
        format!(
            r#"                if (hm_watch_first || {{{cat}}} !== hm_watch_prev) begin
                    $fwrite(out, "W %0d{fmt}\n", hm_cycle, {cat});
                    hm_watch_prev = {{{cat}}};
                    hm_watch_first = 1'b0;
                end
"#,
            cat = cat.join(", "),
        ),
    )
}
