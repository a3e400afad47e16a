//! The fetcher (S610 + S612 in hardware, SPEC.md section 8.13): walks one
//! input hierarchy in the store, translating every node it reads, and sends
//! the merging module's per-input stream (`golden::merge::merge_module::input_stream`
//! order) and the leaves above the walked level.
//!
//! A read pipeline, one node per clock: the roots are read in stored
//! order, checked, moved and handed to a root sorter instance (the only
//! level a translation can put out of Morton order); the sorted roots start
//! a breadth-first walk whose frontier is a FIFO of the inner nodes'
//! `(first, count, parent)` ranges and one end-of-level marker. Stages,
//! each with a small FIFO of the reads in flight beside it: the range stage
//! issues one `ref` read a clock; the reference stage checks each answer
//! and issues its `node` read; the visit stage checks and moves the node,
//! pushes ranges, sends leaves, and passes the level's nodes to the out
//! stage, which issues the held inner nodes' `cref` reads and sends `out`.
//! Reads are issued from validated data only and all of them are made even
//! after an error (`out` stops after its error beat), so every request
//! stream is fixed by the data, never by timing.

//!
//! One file per stage, in the order a node goes through them: `command`
//! (`cfg`, `cmd`, START's header checks), `walk` (the walk state, the roots
//! into the sorter, the frontier, the range and reference stages), `visit`
//! (the visit stage, the per-node join, `leaves`), `order` (the out
//! ordering stage) and `out` (the out stage; per-node, its answer and send
//! stages); `parts` holds the prioritized register updates, the node check
//! and move, and the beats. Each stage names its nets in a scope (`visit_go`).

mod command;
mod order;
mod out;
mod parts;
mod root_sorter;
mod visit;
mod walk;

use golden::merge::fetcher::{fetch_err, FetchLayout, FetchSizes};
use golden::params::Params;

use crate::{Module, Signal, Stream};

pub use root_sorter::{root_sorter_name, root_sorter_unit};

/// Module name of the fetcher.
pub fn fetcher_name(p: &Params, sizes: &FetchSizes) -> String {
    format!("fetcher_{}_r{}_f{}", p.tag(), sizes.roots, sizes.frontier)
}

/// Module name of the fetcher built with the per-node command.
pub fn fetcher_per_node_name(p: &Params, sizes: &FetchSizes) -> String {
    format!("{}_pn", fetcher_name(p, sizes))
}

/// The command's phases.
mod ph {
    pub const IDLE: u64 = 0;
    pub const START: u64 = 1;
    pub const ROOTS: u64 = 2;
    pub const WALK: u64 = 3;
    pub const DONE: u64 = 4;
    /// PREFETCH: the roots are in the sorter, the command not yet taken.
    pub const ARMED: u64 = 5;
    pub const BITS: u32 = 3;
    /// Every phase by name (the Verilog's `localparam`s).
    pub const STATES: &[(&str, u64)] = &[
        ("IDLE", IDLE),
        ("START", START),
        ("ROOTS", ROOTS),
        ("WALK", WALK),
        ("DONE", DONE),
        ("ARMED", ARMED),
    ];
}

/// The phase codes in which the level fetcher reads a command's roots
/// before taking its `cmd` beat (PREFETCH): START, ROOTS, ARMED (the
/// formal harness names them by code).
pub fn fetcher_prefetch_phases() -> [u64; 3] {
    [ph::START, ph::ROOTS, ph::ARMED]
}

/// Kinds of the reference stage's in-flight words (`node_ctx`).
mod nk {
    /// Width of the encoding (internal to the fetcher, no golden format).
    pub const BITS: u32 = 2;
    pub const NODE: u64 = 0;
    pub const ERR: u64 = 1;
    pub const END: u64 = 2;
}

/// Kinds of the out stage's words (`out_items` from the visit stage; the
/// ordered `out_tokens`).
mod ok {
    /// Width of both encodings (internal to the fetcher, no golden format).
    pub const BITS: u32 = 2;
    pub const NODE: u64 = 0;
    pub const ERR: u64 = 1;
    /// The last level's `End`: the command is over once it has left.
    pub const FINAL: u64 = 2;
    /// Another sent level's `End`.
    pub const LEVEL_END: u64 = 3;
    pub const TOK_BEAT: u64 = 0;
    pub const TOK_ERR: u64 = 1;
    pub const TOK_CREF: u64 = 2;
    pub const TOK_FINAL: u64 = 3;
}

/// Words in flight per read port: enough for a memory answering a few
/// clocks after the request at one read a clock.
const IN_FLIGHT: u32 = 8;

/// What every stage is built from: the module, the parameters, the
/// fetcher's layouts and sizes.
struct Ctx<'a, 'm> {
    m: &'m Module,
    p: &'a Params,
    l: &'a FetchLayout,
    sizes: &'a FetchSizes,
    /// Bits of a node index and of a LOD.
    ib: u32,
    lb: u32,
}

impl<'m> Ctx<'_, 'm> {
    fn lit(&self, v: u64, w: u32) -> Signal<'m> {
        self.m.lit(v as u128, w)
    }

    /// An error code of `golden::merge::fetcher::fetch_err`.
    fn code4(&self, c: u64) -> Signal<'m> {
        self.lit(c, fetch_err::BITS)
    }
}

/// The store's read ports (requests driven by the stages, skid-buffered
/// onto the ports at the end) and the fetcher's output streams.
struct Ports<'m> {
    node_req: Stream<'m>,
    ref_req: Stream<'m>,
    cref_req: Stream<'m>,
    out: Stream<'m>,
    leaves: Stream<'m>,
    node_resp: Stream<'m>,
    ref_resp: Stream<'m>,
    cref_resp: Stream<'m>,
}

fn ports<'m>(cx: &Ctx<'_, 'm>) -> Ports<'m> {
    let (m, l, ib) = (cx.m, cx.l, cx.ib);
    Ports {
        node_req: Stream::wires(m, "node_req_core", ib),
        ref_req: Stream::wires(m, "ref_req_core", ib),
        cref_req: Stream::wires(m, "cref_req_core", ib),
        out: Stream::wires(m, "out_core", l.out.width()),
        leaves: Stream::wires(m, "leaves_core", l.leaves.width()),
        node_resp: Stream::input(m, "node_resp", l.node.width()),
        ref_resp: Stream::input(m, "ref_resp", l.reference.width()),
        cref_resp: Stream::input(m, "cref_resp", l.reference.width()),
    }
}

/// The fetcher for `p` with a root sorter of `sizes.roots` entries and a
/// frontier FIFO of `2 * sizes.frontier + 1` words, rounded up to a power of
/// two (a level's ranges popped while the next's are pushed, a marker).
/// Streams (beats of `golden::merge::fetcher::FetchLayout`): `cfg`,
/// `cmd`, `node_resp`, `ref_resp`, `cref_resp` in; `node_req`, `ref_req`,
/// `cref_req`, `out`, `leaves` out. `idle` is high while no command is in
/// progress.
pub fn fetcher_unit(p: &Params, sizes: &FetchSizes) -> Module {
    fetcher_unit_with(p, sizes, false)
}

/// [`fetcher_unit`] with the per-node command (SPEC 8.13): `cmd`'s
/// `per_node` bit, `out`'s `probe` bit, the `report` input (the glue's
/// narrow beat of the per-node module's `report`) and the `probe` read
/// port (`probe_req` out, `probe_resp` in: a node index, a record), all
/// from `golden::merge::fetcher::FetchLayout::per_node`. Level commands
/// run as in [`fetcher_unit`] (one more out stage: the probes' answers).
pub fn fetcher_per_node_unit(p: &Params, sizes: &FetchSizes) -> Module {
    fetcher_unit_with(p, sizes, true)
}

/// The fetcher, with the per-node command when `pn`: the stages in the
/// order a node goes through them.
fn fetcher_unit_with(p: &Params, sizes: &FetchSizes, pn: bool) -> Module {
    let name = match pn {
        true => fetcher_per_node_name(p, sizes),
        false => fetcher_name(p, sizes),
    };
    let m = Module::new(&name);
    let l = FetchLayout::build(p, pn);
    let cx = Ctx {
        m: &m,
        p,
        l: &l,
        sizes,
        ib: p.index_bits as u32,
        lb: p.lod_bits(),
    };
    let mut c = command::command(&cx);
    let io = ports(&cx);
    let mut first_err = command::header_checks(&cx, &mut c);
    let w = walk::walk_state(&cx);
    let roots = walk::roots_stage(&cx, &mut c, &mut first_err, &w, &io);
    let front = walk::frontier(&cx, &w);
    let ref_ctx = walk::range_stage(&cx, &c, &front, &io);
    let node_ctx = walk::reference_stage(&cx, &c, &roots, ref_ctx, &io);
    let head = visit::visit_head(&cx, &c, &mut first_err, &w, &roots, node_ctx, &front, &io);
    let visited = visit::visit_checks(&cx, &c, &w, &head);
    let join = visit::frontier_push(&cx, &mut c, &front, &head, &visited);
    visit::visit_out(&cx, &c, &w, &head, &visited, &io);
    let tokens = order::order_stage(&cx, &c, &head, &io);

    let pn_ports = match &l.pn {
        None => {
            out::level_out_stage(&cx, &mut c, w.out_errored, tokens, io.cref_resp, io.out);
            None
        }
        Some(f) => Some(out::per_node_out_stages(
            &m,
            p,
            &l,
            f,
            out::OutStageIo {
                walk: c.walk,
                start: c.start,
                hier: c.hier,
                nodes: c.nodes,
                mv: &c.mv,
                toks: tokens.0,
                tok_w: tokens.1,
                cref_resp: io.cref_resp,
                out: io.out,
                o_errored: w.out_errored,
            },
            &mut c.n_phase,
        )),
    };
    if let (Some(ps), Some(j)) = (&pn_ports, &join) {
        let lit = |v: u64| cx.lit(v, 1);
        j.end_left.next(c.start.mux(
            lit(0),
            j.take.mux(lit(0), ps.end_fire.mux(lit(1), j.end_left)),
        ));
    }

    // DONE
    let done = c.is(&cx, ph::DONE);
    c.cfg_have.next(
        c.cfg_fire
            .mux(cx.lit(1, 1), (done & c.last).mux(cx.lit(0, 1), c.cfg_have)),
    );
    // PREFETCH: a command not its `cfg`'s last is followed by another,
    // whose roots are read now (the first command's, from the `cfg`).
    let after = match command::prefetches(&cx) {
        true => c
            .last
            .mux(command::goto(&cx, ph::IDLE), command::goto(&cx, ph::START)),
        false => command::goto(&cx, ph::IDLE),
    };
    c.n_phase.when(done, after);

    io.node_req.skid_buffer("node_req_q").output("node_req");
    io.ref_req.skid_buffer("ref_req_q").output("ref_req");
    io.cref_req.skid_buffer("cref_req_q").output("cref_req");
    io.out.skid_buffer("out_q").output("out");
    io.leaves.skid_buffer("leaves_q").output("leaves");
    if let Some(ps) = pn_ports {
        ps.probe_req.skid_buffer("probe_req_q").output("probe_req");
    }
    m.output("idle", c.idle);

    for n in [
        c.n_phase,
        first_err.n_valid,
        first_err.n_code,
        first_err.n_node,
    ] {
        n.apply();
    }
    m
}
