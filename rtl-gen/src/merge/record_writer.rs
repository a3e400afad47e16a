//! S618 in hardware (SPEC.md section 8.12): the record writer. It takes the
//! upper builder's level streams (8.11) and the created nodes' references,
//! buffers every level in its own memory while the builder streams, and once
//! the top is known lays out the merged hierarchy in the store's format:
//! records in store order on `nodes`, references on `refs`, one `header`.
//!
//! Why buffer: a record's index is its level's offset plus its position,
//! and a level's offset is the number of records above it, known only when
//! the top is decided, which the builder does last. Why two sequencers in
//! the drain: the records and the references are two arrays of the store;
//! each is written at one word per clock by its own sequencer walking the
//! same store order (a record's `first` is the running sum of the counts,
//! which the record sequencer keeps without waiting for the references).
//!
//! Why level `d`'s buffer may hold the next merge's beats: the builder
//! sends level `d` only in merges whose top is at or above `d`, and the
//! streams are independent, so level `d`'s next sequence belongs to the
//! next merge whose top is `<= d`. A merge ending with top `t` clears the
//! levels `d >= t` and leaves the others as they are.

use golden::merge::record_writer::{writer_err, CapacityError, WriterLayout};
use golden::merge::upper_builder::unit::level_out_kind;
use golden::params::Params;

use crate::{Instance, Memory, Module, Signal, Stream};

/// Module name of the record writer for `p` with `2^capacity_bits` entries
/// per level.
pub fn record_writer_name(p: &Params, capacity_bits: u32) -> String {
    format!("record_writer_{}_c{capacity_bits}", p.tag())
}

/// Module name of one level of the record writer for `p` with
/// `2^capacity_bits` entries per buffer: its buffers, its fill and its
/// counts (`record_writer_unit` instantiates one per level). Level 0 is
/// never below a top, so its module (`by_slot` false, `_top_only`) has no
/// by-record-slot buffers.
pub fn record_writer_level_name(p: &Params, capacity_bits: u32, by_slot: bool) -> String {
    let variant = if by_slot { "" } else { "_top_only" };
    format!("record_writer_level_{}_c{capacity_bits}{variant}", p.tag())
}

/// The instance of level `d`'s module in the record writer.
fn level_instance(d: usize) -> String {
    format!("u_level{d}")
}

/// One of the writer's buffers: a simple dual-port RAM of `depth` words of
/// `width` bits (one write port, one registered read port).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct WriterBuffer {
    /// The memory's hierarchical name below the writer, as Yosys names it
    /// once the writer is flattened: `crefs_mem` in the writer itself,
    /// `u_level<d>.<name>` in level `d`'s module.
    pub name: String,
    /// Word width in bits.
    pub width: u32,
    /// Words (`2^C`).
    pub depth: u32,
}

/// The writer's buffers for `p` and `2^capacity_bits` entries (SPEC.md
/// 8.12, "Buffers"), named as the emitted Verilog names them: `crefs_mem`;
/// in each level's module (`u_level<d>`) `rbody_mem` and `rpar_mem` for the
/// levels 1..=D (level 0 is never below a top), `nbody_mem`, `npar_mem`
/// and `child_mem` for every level. Each is read synchronously, so a flow
/// maps each onto RAM macros; `record_writer_unit` builds exactly these.
pub fn record_writer_buffers(
    p: &Params,
    capacity_bits: u32,
) -> Result<Vec<WriterBuffer>, CapacityError> {
    let wl = WriterLayout::new(p, capacity_bits)?;
    let w = BufferWidths::of(&wl);
    let depth = 1u32 << capacity_bits;
    let buf = |name: String, width: u32| WriterBuffer { name, width, depth };
    let mut out = vec![buf("crefs_mem".into(), w.cref)];
    for d in 0..=p.max_lod as usize {
        for b in Buffer::ALL.into_iter().filter(|b| d > 0 || !b.by_slot()) {
            out.push(buf(
                format!("{}.{}", level_instance(d), b.memory()),
                b.width(&w),
            ));
        }
    }
    Ok(out)
}

/// A level's buffers, each holding exactly what one reader takes. By
/// record slot (`records`), for the levels below the top: a record's body
/// and count (the record sequencer), its parent word (the reference
/// sequencer). By position (`index`), for the top, where every node is a
/// record: the same two words. By position, for the parents one level up:
/// the child word. Level 0 is never below a top: no by-record-slot words
/// there. It is nobody's child either, but its child word is what takes the
/// level beat's `ref` index and `records`, fields the builder's beat
/// carries at every level and nothing else reads at level 0 (SPEC 8.12).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Buffer {
    BodyBySlot,
    ParentBySlot,
    BodyAtTop,
    ParentAtTop,
    Child,
}

impl Buffer {
    const ALL: [Buffer; 5] = [
        Buffer::BodyBySlot,
        Buffer::ParentBySlot,
        Buffer::BodyAtTop,
        Buffer::ParentAtTop,
        Buffer::Child,
    ];

    /// The read port's name in a level's module (`<port>` the read word,
    /// `<port>_addr` and `<port>_en` its address and enable).
    fn port(self) -> &'static str {
        match self {
            Buffer::BodyBySlot => "rbody",
            Buffer::ParentBySlot => "rpar",
            Buffer::BodyAtTop => "nbody",
            Buffer::ParentAtTop => "npar",
            Buffer::Child => "child",
        }
    }

    /// The memory's name in a level's module.
    fn memory(self) -> String {
        format!("{}_mem", self.port())
    }

    /// Indexed by record slot, so only below a top (never at level 0).
    fn by_slot(self) -> bool {
        matches!(self, Buffer::BodyBySlot | Buffer::ParentBySlot)
    }

    fn width(self, w: &BufferWidths) -> u32 {
        match self {
            Buffer::BodyBySlot | Buffer::BodyAtTop => w.body,
            Buffer::ParentBySlot | Buffer::ParentAtTop => w.parent,
            Buffer::Child => w.child,
        }
    }
}

/// Word widths of the buffers: each holds exactly what its reader takes.
struct BufferWidths {
    /// A record below `first` (leaf .. hi_z) and its `count`.
    body: u32,
    /// `kind`, `count`, `first`, `hier`.
    parent: u32,
    /// `reused`, `ref`, `records`.
    child: u32,
    /// A created node's reference.
    cref: u32,
}

impl BufferWidths {
    /// Each word is the concatenation the fill side writes, so each width
    /// is the sum of those fields' widths in golden's layouts.
    fn of(wl: &WriterLayout) -> BufferWidths {
        let (bl, nl, rl) = (&wl.builder, &wl.node, &wl.reference);
        BufferWidths {
            body: nl.first().offset + nl.count().width,
            parent: bl.kind.width + nl.count().width + nl.first().width + rl.hier().width,
            child: 1 + bl.refer.width + bl.records.width,
            cref: rl.width(),
        }
    }
}

/// States of a merge.
mod state {
    /// Taking the level streams, `done`, `crefs` and `cfg`.
    pub const FILL: u64 = 0;
    /// Writing the records and the references.
    pub const DRAIN: u64 = 1;
    /// Sending the header.
    pub const HEADER: u64 = 2;
    /// Every state by name (the Verilog's `localparam`s).
    pub const STATES: &[(&str, u64)] = &[("FILL", FILL), ("DRAIN", DRAIN), ("HEADER", HEADER)];
}

/// `vals[d]` for the level index `d` (missing levels read as zero).
fn by_level<'m>(m: &'m Module, d: Signal<'m>, vals: &[Signal<'m>]) -> Signal<'m> {
    let w = vals[0].width();
    let opts: Vec<Signal<'m>> = (0..1usize << d.width())
        .map(|k| vals.get(k).copied().unwrap_or_else(|| m.lit(0, w)))
        .collect();
    d.select(&opts)
}

/// The 2-bit level-beat kind `k` is `code` ([`level_out_kind`]).
fn kind_is<'m>(m: &'m Module, k: Signal<'m>, code: u64) -> Signal<'m> {
    k.eq(m.lit(code as u128, 2))
}

/// Some `flags[d]` is set at a level where `take[d]`.
fn any_where<'m>(m: &'m Module, flags: &[Signal<'m>], take: &[Signal<'m>]) -> Signal<'m> {
    flags
        .iter()
        .zip(take)
        .fold(m.lit(0, 1), |acc, (f, t)| acc | (*f & *t))
}

/// Sum of `vals[d]` over the levels where `take[d]`, `width` bits.
fn sum_where<'m>(
    m: &'m Module,
    vals: &[Signal<'m>],
    take: &[Signal<'m>],
    width: u32,
) -> Signal<'m> {
    vals.iter().zip(take).fold(m.lit(0, width), |acc, (v, t)| {
        acc.add(t.mux(v.zext(width), m.lit(0, width)), width)
    })
}

/// The next level below `d` holding records: `(found, lod)`, the smallest
/// `e > d` with `records[e] > 0`. The sequencers step to it in the clock
/// they take a level's last word, so an empty level costs no clock.
fn next_level_with_records<'m>(
    m: &'m Module,
    d: Signal<'m>,
    records: &[Signal<'m>],
) -> (Signal<'m>, Signal<'m>) {
    let w = d.width();
    let mut found = m.lit(0, 1);
    let mut lod = m.lit(0, w);
    // Level 0 is below no level.
    for (e, r) in records.iter().enumerate().skip(1).rev() {
        let here = (m.lit(e as u128, w).gt(d) & r.ne(m.lit(0, r.width())))
            .named_after(d, &format!("has_l{e}"));
        found = found | here;
        lod = here.mux(m.lit(e as u128, w), lod);
    }
    (found, lod)
}

/// Whether a sequencer reads level `d`'s by-position buffer (`at_top`) or
/// its by-record-slot one this clock: while `reading`, the level its
/// pointer names in the next clock (`next_lod`), by position when that
/// level is the top, by record slot below it.
fn reads_level<'m>(
    reading: Signal<'m>,
    next_lod: Signal<'m>,
    next_is_top: Signal<'m>,
    d: usize,
    at_top: bool,
) -> Signal<'m> {
    let m = reading.module();
    let here = (reading & next_lod.eq(m.lit(d as u128, next_lod.width())))
        .named_after(next_lod, &format!("reads_l{d}"));
    match at_top {
        true => here & next_is_top,
        false => here & !next_is_top,
    }
}

/// Each level's buffer `buf` read a clock ahead: level `d`'s read register
/// takes the word at `addr` in a clock where `want(d)`, and holds it
/// otherwise (a RAM's registered read port with its enable). A level
/// without the buffer reads as zero.
fn read_ahead<'m>(
    w: &Ctx<'_, 'm>,
    levels: &[Instance<'m>],
    buf: Buffer,
    addr: Signal<'m>,
    want: impl Fn(usize) -> Signal<'m>,
) -> Vec<Signal<'m>> {
    levels
        .iter()
        .enumerate()
        .map(|(d, u)| {
            if d == 0 && buf.by_slot() {
                return w.lit(0, buf.width(&w.widths));
            }
            u.connect(&format!("{}_addr", buf.port()), addr);
            u.connect(&format!("{}_en", buf.port()), want(d));
            u.output(buf.port())
        })
        .collect()
}

/// A parent's word in the drain: `kind` (2), `count`, `first`, `hier`.
struct Parent<'m> {
    kind: Signal<'m>,
    count: Signal<'m>,
    first: Signal<'m>,
    hier: Signal<'m>,
}

fn parent<'m>(word: Signal<'m>, i: u32) -> Parent<'m> {
    Parent {
        kind: word.slice(1, 0),
        count: word.slice(i + 1, 2),
        first: word.slice(2 * i + 1, i + 2),
        hier: word.slice(word.width() - 1, 2 * i + 2),
    }
}

/// A node's word for its parent's references: `reused` (1), `ref`, `records`.
struct Child<'m> {
    reused: Signal<'m>,
    refer: Signal<'m>,
    records: Signal<'m>,
}

fn child<'m>(word: Signal<'m>, ref_w: u32) -> Child<'m> {
    Child {
        reused: word.bit(0),
        refer: word.slice(ref_w, 1),
        records: word.slice(word.width() - 1, ref_w + 1),
    }
}

/// The record writer for `p` with `2^capacity_bits` entries per level
/// buffer and for the created nodes' references (`capacity_bits` in
/// `1..I`). Streams ([`WriterLayout`]): in `cfg`, `level0` .. `level{D}`,
/// `done`, `crefs`, `ref_resp`; out `ref_req`, `nodes`, `refs`, `header`.
/// Status outputs: `filling` (taking a merge's beats), `drain_records` /
/// `drain_refs` (that sequencer has words left to write).
pub fn record_writer_unit(p: &Params, capacity_bits: u32) -> Result<Module, CapacityError> {
    let wl = WriterLayout::new(p, capacity_bits)?;
    let m = Module::new(&record_writer_name(p, capacity_bits));
    let w = Ctx::new(&m, &wl, p, capacity_bits);
    let i = w.i;
    let lit = |v: u64, width: u32| w.lit(v, width);

    let st = m.reg("state", 2);
    let states = m.states(2, state::STATES);
    let in_fill = st.eq(states.code(state::FILL)).name("in_fill");
    let in_drain = st.eq(states.code(state::DRAIN)).name("in_drain");
    let in_header = st.eq(states.code(state::HEADER)).name("in_header");
    let header_ready = m.wire("header_in_ready", 1);
    let clear = (in_header & header_ready).name("merge_clear");
    let f = fill_inputs(&w, in_fill, clear);
    let (b, levels) = level_units(&w, p, f.top, in_fill, clear);
    let chk = header_checks(&w, &f, &b, &levels, in_fill, clear);
    let seq = Drain {
        in_drain,
        clear,
        drain_start: chk.drain_start,
        top: f.top,
        n_top: chk.n_top,
        n_records: &levels.n_records,
    };
    let (rs_active, rs_done) = record_sequencer(&w, &b, &seq);
    let (fs_busy, fs_done) = reference_sequencer(&w, &b, &seq, &f);

    // The header; on an error every count and the top are 0.
    let (err_code, out_id) = (chk.err_code, f.out_id);
    let code = |v: u64| lit(v, 3);
    let header_data = m.concat(&[
        err_code,
        chk.h_refs,
        chk.h_nodes,
        chk.h_roots,
        f.top,
        out_id,
    ]);
    debug_assert_eq!(header_data.width(), wl.header.width());
    let header_ok = err_code.eq(code(writer_err::NONE));
    let failed = m.concat(&[err_code, lit(0, 3 * (i + 1) + w.lb), out_id]);
    Stream {
        valid: in_header,
        ready: header_ready,
        data: header_ok.mux(header_data, failed),
    }
    .skid_buffer("header_skid")
    .output("header");

    // State changes.
    let drain_done = in_drain & rs_done & fs_done;
    let next_state = clear.mux(
        states.code(state::FILL),
        chk.fill_done.mux(
            chk.fill_ok
                .mux(states.code(state::DRAIN), states.code(state::HEADER)),
            drain_done.mux(states.code(state::HEADER), st),
        ),
    );
    st.next(next_state);

    // Status, for throughput counts.
    m.output("filling", in_fill);
    m.output("drain_records", rs_active);
    m.output("drain_refs", fs_busy);
    Ok(m)
}

/// What every part of the writer is built from.
struct Ctx<'a, 'm> {
    m: &'m Module,
    wl: &'a WriterLayout,
    dmax: usize,
    /// Bits of a level buffer's address (`2^c` entries).
    c: u32,
    /// Bits of a node index, of a hierarchy id, of a LOD.
    i: u32,
    h: u32,
    lb: u32,
    widths: BufferWidths,
    /// Bits of a record below `first`.
    body_w: u32,
    /// Bits of a level's sum of counts.
    sum_w: u32,
}

impl<'a, 'm> Ctx<'a, 'm> {
    fn new(m: &'m Module, wl: &'a WriterLayout, p: &Params, c: u32) -> Self {
        let i = p.index_bits as u32;
        Ctx {
            m,
            wl,
            dmax: p.max_lod as usize,
            c,
            i,
            h: p.hier_bits as u32,
            lb: p.lod_bits(),
            widths: BufferWidths::of(wl),
            // A record without `first` and `count`: leaf .. hi_z.
            body_w: wl.node.first().offset,
            sum_w: i + c + 1,
        }
    }

    fn lit(&self, v: u64, w: u32) -> Signal<'m> {
        self.m.lit(v as u128, w)
    }
}

/// The merge-wide inputs: `cfg` (the output id), `done` (the top) and
/// `crefs` (the created nodes' references, buffered in arrival order).
struct Inputs<'m> {
    have_cfg: Signal<'m>,
    out_id: Signal<'m>,
    have_done: Signal<'m>,
    top: Signal<'m>,
    done_err: Signal<'m>,
    crefs_mem: Memory<'m>,
    cref_end: Signal<'m>,
    cref_cap_err: Signal<'m>,
}

fn fill_inputs<'m>(w: &Ctx<'_, 'm>, in_fill: Signal<'m>, clear: Signal<'m>) -> Inputs<'m> {
    let (m, wl, c, h, lb) = (w.m, w.wl, w.c, w.h, w.lb);
    let bl = &wl.builder;
    let widths = &w.widths;
    let zero = w.lit(0, 1);
    let lit = |v: u64, width: u32| w.lit(v, width);
    // cfg: the output id, one beat per merge.
    let cfg = Stream::input(m, "cfg", wl.cfg.width());
    let have_cfg = m.reg("have_cfg", 1);
    let out_id = m.reg("out_id", h);
    cfg.ready.drive(!have_cfg);
    let cfg_fire = cfg.valid & !have_cfg;
    have_cfg.next(clear.mux(zero, have_cfg | cfg_fire));
    out_id.next(cfg_fire.mux(cfg.data.view(&wl.cfg_out_id), out_id));

    // done: the top.
    let done = Stream::input(m, "done", bl.done.width());
    let have_done = m.reg("have_done", 1);
    let top = m.reg("top", lb);
    let done_err = m.reg("done_err", 1);
    let done_ready = in_fill & !have_done;
    done.ready.drive(done_ready);
    let done_fire = done.valid & done_ready;
    have_done.next(clear.mux(zero, have_done | done_fire));
    top.next(done_fire.mux(done.data.view(&bl.top), top));
    done_err.next(done_fire.mux(done.data.view(&bl.done_err), done_err));

    // crefs: the created nodes' references, buffered in arrival order.
    let crefs = Stream::input(m, "crefs", wl.crefs.width());
    let crefs_mem = m.memory("crefs_mem", widths.cref, 1 << c);
    let cref_end = m.reg("cref_end", 1);
    let cref_wptr = m.reg("cref_wptr", c + 1);
    let cref_cap_err = m.reg("cref_cap_err", 1);
    let cref_ready = in_fill & !cref_end;
    crefs.ready.drive(cref_ready);
    let cref_fire = crefs.valid & cref_ready;
    let cref_is_end = crefs.data.view(&wl.cref_end);
    let cref_ref_fire = cref_fire & !cref_is_end;
    let cref_full = cref_wptr.bit(c);
    crefs_mem.write(
        cref_wptr.slice(c - 1, 0),
        crefs.data.view(&wl.cref),
        cref_ref_fire & !cref_full,
    );
    cref_end.next(clear.mux(zero, cref_end | (cref_fire & cref_is_end)));
    let wptr_next = cref_full.mux(cref_wptr, cref_wptr.add(1, c + 1));
    cref_wptr.next(clear.mux(lit(0, c + 1), cref_ref_fire.mux(wptr_next, cref_wptr)));
    cref_cap_err.next(clear.mux(zero, cref_cap_err | (cref_ref_fire & cref_full)));

    Inputs {
        have_cfg,
        out_id,
        have_done,
        top,
        done_err,
        crefs_mem,
        cref_end,
        cref_cap_err,
    }
}

/// The levels, one module instance each, and which levels a merge with
/// top `top` holds.
struct Buffers<'m> {
    /// Level `d`'s module instance (its buffers are read through it).
    units: Vec<Instance<'m>>,
    /// Level `d` is at or below the top (`d >= top`).
    in_merge: Vec<Signal<'m>>,
    /// Level `d` is below the top (`d > top`).
    below_top: Vec<Signal<'m>>,
}

/// Per level: what its stream has brought this merge.
struct Levels<'m> {
    end_seen: Vec<Signal<'m>>,
    n_nodes: Vec<Signal<'m>>,
    n_records: Vec<Signal<'m>>,
    rec_sum: Vec<Signal<'m>>,
    reused_sum: Vec<Signal<'m>>,
    level_cap_err: Vec<Signal<'m>>,
    level_err: Vec<Signal<'m>>,
}

/// One instance of the level module per level, each taking its level
/// stream; the cross-level part here is which levels a merge holds (and so
/// which it clears).
fn level_units<'m>(
    w: &Ctx<'_, 'm>,
    p: &Params,
    top: Signal<'m>,
    in_fill: Signal<'m>,
    clear: Signal<'m>,
) -> (Buffers<'m>, Levels<'m>) {
    let (m, wl, c, dmax, lb) = (w.m, w.wl, w.c, w.dmax, w.lb);
    let lit = |v: u64, width: u32| w.lit(v, width);
    let (zero, one) = (lit(0, 1), lit(1, 1));
    // d >= top and d > top, with the comparisons that are constant (no LOD is
    // below 0 or above the widest field value) written as constants.
    let in_merge: Vec<Signal> = (0..=dmax)
        .map(|d| match d as u64 == (1u64 << lb) - 1 {
            true => one,
            false => lit(d as u64, lb).ge(top).name(&format!("l{d}_in_merge")),
        })
        .collect();
    let below_top: Vec<Signal> = (0..=dmax)
        .map(|d| match d {
            0 => zero,
            _ => lit(d as u64, lb).gt(top),
        })
        .collect();
    let top_only = level_unit(p, wl, c, false);
    let with_slots = level_unit(p, wl, c, true);
    let units: Vec<Instance> = (0..=dmax)
        .map(|d| {
            let s = Stream::input(m, &format!("level{d}"), wl.builder.level.width());
            let u = m.instance(
                &level_instance(d),
                if d == 0 { &top_only } else { &with_slots },
            );
            u.connect("level_valid", s.valid);
            u.connect("level_data", s.data);
            s.ready.drive(u.output("level_ready"));
            u.connect("in_fill", in_fill);
            // A merge with its top at or above d consumes the level.
            u.connect("clear", (clear & in_merge[d]).name(&format!("l{d}_clear")));
            u
        })
        .collect();
    let each = |port: &str| -> Vec<Signal<'m>> { units.iter().map(|u| u.output(port)).collect() };
    let levels = Levels {
        end_seen: each("ended"),
        n_nodes: each("n_nodes"),
        n_records: each("n_records"),
        rec_sum: each("rec_sum"),
        reused_sum: each("reused_sum"),
        level_cap_err: each("capacity_error"),
        level_err: each("level_error"),
    };
    let b = Buffers {
        units,
        in_merge,
        below_top,
    };
    (b, levels)
}

/// One level of the writer: its stream into its buffers
/// ([`Buffer`]), with the level's counts and errors, and the buffers' read
/// ports for the drain sequencers. `by_slot`: with the by-record-slot
/// buffers (every level but 0).
fn level_unit(p: &Params, wl: &WriterLayout, c: u32, by_slot: bool) -> Module {
    let m = Module::new(&record_writer_level_name(p, c, by_slot));
    let w = Ctx::new(&m, wl, p, c);
    let (i, sum_w, body_w) = (w.i, w.sum_w, w.body_w);
    let (bl, nl, rl) = (&wl.builder, &wl.node, &wl.reference);
    let lit = |v: u64, width: u32| w.lit(v, width);
    let zero = lit(0, 1);
    let s = Stream::input(&m, "level", bl.level.width());
    let in_fill = m.input("in_fill", 1);
    // This merge consumes the level: its counts start again.
    let clear = m.input("clear", 1);
    let seen = m.reg("end_seen", 1);
    let n = m.reg("nodes", c + 1);
    let r = m.reg("records", c + 1);
    let rsum = m.reg("record_counts", sum_w);
    let usum = m.reg("reused_counts", sum_w);
    let cerr = m.reg("cap_err", 1);
    let lerr = m.reg("err", 1);
    let ready = (in_fill & !seen).name("ready");
    s.ready.drive(ready);
    let fire = (s.valid & ready).name("fire");
    let kind = s.data.view(&bl.kind);
    let rec = s.data.view(&bl.rec);
    let refer = s.data.view(&bl.refer);
    let index = s.data.view(&bl.index);
    let records = s.data.view(&bl.records);
    let err = s.data.view(&bl.err);
    let count = rec.view(nl.count());
    let first = rec.view(nl.first());
    let hier = refer.view(rl.hier());
    let is_end = kind_is(&m, kind, level_out_kind::END).name("is_end");
    let reused = kind_is(&m, kind, level_out_kind::REUSED).name("reused");
    let node_fire = fire & !is_end;
    let fits = index.slice(i - 1, c).eq(lit(0, i - c)).name("fits");
    let body_word = m.concat(&[count, rec.slice(body_w - 1, 0)]);
    let parent_word = m.concat(&[hier, first, count, kind]);
    let slot = records.slice(c - 1, 0);
    let pos = index.slice(c - 1, 0);
    let put = (node_fire & fits).name("put");
    let put_slot = by_slot.then(|| (put & !reused).name("put_slot"));
    for buf in Buffer::ALL.into_iter().filter(|b| by_slot || !b.by_slot()) {
        let mem = m.memory(&buf.memory(), buf.width(&w.widths), 1 << c);
        let (addr, word, en) = match buf {
            Buffer::BodyBySlot => (slot, body_word, put_slot),
            Buffer::ParentBySlot => (slot, parent_word, put_slot),
            Buffer::BodyAtTop => (pos, body_word, Some(put)),
            Buffer::ParentAtTop => (pos, parent_word, Some(put)),
            Buffer::Child => (pos, m.concat(&[records, refer, reused]), Some(put)),
        };
        mem.write(
            addr,
            word,
            en.expect("a by-slot buffer exists only by_slot"),
        );
        let read = mem.read_sync(
            m.input(&format!("{}_addr", buf.port()), c),
            m.input(&format!("{}_en", buf.port()), 1),
        );
        m.output(buf.port(), read);
    }
    let end_fire = (fire & is_end).name("end_fire");
    seen.next(clear.mux(zero, seen | end_fire));
    n.next(clear.mux(lit(0, c + 1), end_fire.mux(index.slice(c, 0), n)));
    r.next(clear.mux(lit(0, c + 1), end_fire.mux(records.slice(c, 0), r)));
    let counted = count.zext(sum_w);
    let none = lit(0, sum_w);
    rsum.next(clear.mux(
        none,
        rsum.add((node_fire & !reused).mux(counted, none), sum_w),
    ));
    usum.next(clear.mux(
        none,
        usum.add((node_fire & reused).mux(counted, none), sum_w),
    ));
    cerr.next(clear.mux(zero, cerr | (node_fire & !fits)));
    // A node with no references would hold its parent's sequencer forever.
    let no_refs = node_fire & count.eq(lit(0, i));
    lerr.next(clear.mux(zero, lerr | (fire & err) | no_refs));
    for (port, v) in [
        ("ended", seen),
        ("n_nodes", n),
        ("n_records", r),
        ("rec_sum", rsum),
        ("reused_sum", usum),
        ("capacity_error", cerr),
        ("level_error", lerr),
    ] {
        m.output(port, v);
    }
    m
}

/// The fill's end and the header's checks.
struct Checks<'m> {
    fill_done: Signal<'m>,
    fill_ok: Signal<'m>,
    drain_start: Signal<'m>,
    n_top: Signal<'m>,
    err_code: Signal<'m>,
    h_roots: Signal<'m>,
    h_nodes: Signal<'m>,
    h_refs: Signal<'m>,
}

fn header_checks<'m>(
    w: &Ctx<'_, 'm>,
    f: &Inputs<'m>,
    b: &Buffers<'m>,
    l: &Levels<'m>,
    in_fill: Signal<'m>,
    clear: Signal<'m>,
) -> Checks<'m> {
    let (m, i, c, dmax) = (w.m, w.i, w.c, w.dmax);
    let lit = |v: u64, width: u32| w.lit(v, width);
    let one = lit(1, 1);
    // Wide enough for every sum the header checks against 2^I.
    let nodes_w = i + 7;
    let refs_w = i + c + 7;
    let (have_cfg, have_done, cref_end, top, done_err, cref_cap_err) = (
        f.have_cfg,
        f.have_done,
        f.cref_end,
        f.top,
        f.done_err,
        f.cref_cap_err,
    );
    let (in_merge, below_top) = (&b.in_merge, &b.below_top);
    let (end_seen, n_nodes, n_records, rec_sum, reused_sum, level_cap_err, level_err) = (
        &l.end_seen,
        &l.n_nodes,
        &l.n_records,
        &l.rec_sum,
        &l.reused_sum,
        &l.level_cap_err,
        &l.level_err,
    );
    // The fill is complete when every level of the merge has ended; then
    // every count is known and the header's checks are made.
    let levels_ended = (0..=dmax).fold(one, |acc, d| acc & (end_seen[d] | !in_merge[d]));
    let fill_done = (in_fill & have_cfg & have_done & cref_end & levels_ended).name("fill_done");
    let n_top = by_level(m, top, n_nodes).name("top_nodes");
    let nodes_total = n_top
        .zext(nodes_w)
        .add(sum_where(m, n_records, below_top, nodes_w), nodes_w)
        .name("nodes_total");
    let refs_total = by_level(m, top, reused_sum)
        .zext(refs_w)
        .add(sum_where(m, rec_sum, in_merge, refs_w), refs_w)
        .name("refs_total");
    let limit = |w: u32| m.lit(1u128 << i, w);
    let overflow = nodes_total.gt(limit(nodes_w)) | refs_total.gt(limit(refs_w));
    let cap_err = any_where(m, level_cap_err, in_merge) | cref_cap_err;
    let lev_err = any_where(m, level_err, in_merge);
    let code = |v: u64| lit(v, 3);
    let fill_code = m.first_of(
        &[
            (done_err, code(writer_err::NO_TOP)),
            (cap_err, code(writer_err::CAPACITY)),
            (lev_err, code(writer_err::LEVEL_OVERFLOW)),
            (overflow, code(writer_err::INDEX_OVERFLOW)),
        ],
        code(writer_err::NONE),
    );
    let fill_ok = fill_code.eq(code(writer_err::NONE)).name("fill_ok");
    let err_code = m.reg("err_code", 3);
    let h_roots = m.reg("h_roots", i + 1);
    let h_nodes = m.reg("h_nodes", i + 1);
    let h_refs = m.reg("h_refs", i + 1);
    err_code.next(clear.mux(code(0), fill_done.mux(fill_code, err_code)));
    h_roots.next(fill_done.mux(n_top.zext(i + 1), h_roots));
    h_nodes.next(fill_done.mux(nodes_total.slice(i, 0), h_nodes));
    h_refs.next(fill_done.mux(refs_total.slice(i, 0), h_refs));
    let drain_start = (fill_done & fill_ok).name("drain_start");

    Checks {
        fill_done,
        fill_ok,
        drain_start,
        n_top,
        err_code,
        h_roots,
        h_nodes,
        h_refs,
    }
}

/// What both drain sequencers start from.
struct Drain<'a, 'm> {
    in_drain: Signal<'m>,
    clear: Signal<'m>,
    drain_start: Signal<'m>,
    top: Signal<'m>,
    n_top: Signal<'m>,
    n_records: &'a [Signal<'m>],
}

/// The record sequencer; returns whether it is active and whether it is
/// done.
fn record_sequencer<'m>(
    w: &Ctx<'_, 'm>,
    b: &Buffers<'m>,
    s: &Drain<'_, 'm>,
) -> (Signal<'m>, Signal<'m>) {
    let (m, c, i, lb, body_w, widths) = (w.m, w.c, w.i, w.lb, w.body_w, &w.widths);
    let nl = &w.wl.node;
    let lit = |v: u64, width: u32| w.lit(v, width);
    let zero = lit(0, 1);
    let (in_drain, clear, drain_start, top, n_top, n_records) = (
        s.in_drain,
        s.clear,
        s.drain_start,
        s.top,
        s.n_top,
        s.n_records,
    );
    // Record sequencer: one record per clock in store order; a record's
    // `first` is the running sum of the counts before it. The buffers read
    // a clock ahead: each clock reads the word (rs_lod, rs_ptr) names in the
    // next clock (their next values), from drain_start on, so the first
    // record is in its read register in the drain's first clock.
    let rs_d = m.reg("rs_lod", lb);
    let rs_ptr = m.reg("rs_ptr", c + 1);
    let rs_first = m.reg("rs_first", i + 1);
    let rs_done = m.reg("rs_done", 1);
    let rs_top = rs_d.eq(top);
    let rs_len = rs_top.mux(n_top, by_level(m, rs_d, n_records));
    let rs_level_last = rs_ptr.add(1, c + 1).eq(rs_len);
    let rs_active = (in_drain & !rs_done).name("rs_active");
    let nodes_valid = rs_active.name("nodes_in_valid");
    let nodes_ready = m.wire("nodes_in_ready", 1);
    let rs_fire = nodes_valid & nodes_ready;
    // (rs_lod, rs_ptr) always names a record to write (the top has one).
    let (rs_more, rs_next_lod) = next_level_with_records(m, rs_d, n_records);
    let rs_level_done = rs_fire & rs_level_last;
    let rs_step_level = rs_level_done & rs_more;
    let rs_finish = rs_level_done & !rs_more;
    let rs_d_next = drain_start
        .mux(top, rs_step_level.mux(rs_next_lod, rs_d))
        .name("rs_lod_next");
    let rs_ptr_next = (drain_start | rs_step_level)
        .mux(lit(0, c + 1), rs_fire.mux(rs_ptr.add(1, c + 1), rs_ptr))
        .name("rs_ptr_next");
    rs_d.next(rs_d_next);
    rs_ptr.next(rs_ptr_next);
    let rs_reading = drain_start | rs_active;
    let rs_next_top = rs_d_next.eq(top);
    let rs_addr_next = rs_ptr_next.slice(c - 1, 0);
    let rs_reads =
        |at_top: bool| move |d| reads_level(rs_reading, rs_d_next, rs_next_top, d, at_top);
    let at_top = read_ahead(w, &b.units, Buffer::BodyAtTop, rs_addr_next, rs_reads(true));
    let below = read_ahead(
        w,
        &b.units,
        Buffer::BodyBySlot,
        rs_addr_next,
        rs_reads(false),
    );
    let body_word = rs_top.mux(by_level(m, rs_d, &at_top), by_level(m, rs_d, &below));
    let rs_count = body_word.slice(widths.body - 1, body_w);
    let record = m.concat(&[
        rs_count,
        rs_first.slice(i - 1, 0),
        body_word.slice(body_w - 1, 0),
    ]);
    debug_assert_eq!(record.width(), nl.width());
    let nodes_out = Stream {
        valid: nodes_valid,
        ready: nodes_ready,
        // Masked: an unwritten buffer word reads as X in 4-state simulation.
        data: nodes_valid.mux(record, lit(0, nl.width())),
    };
    nodes_out.skid_buffer("nodes_skid").output("nodes");
    rs_first.next(drain_start.mux(
        lit(0, i + 1),
        rs_fire.mux(rs_first.add(rs_count.zext(i + 1), i + 1), rs_first),
    ));
    rs_done.next(clear.mux(zero, rs_done | rs_finish));

    (rs_active, rs_done)
}

/// The reference sequencer; returns whether it is busy and whether it is
/// done.
fn reference_sequencer<'m>(
    w: &Ctx<'_, 'm>,
    b: &Buffers<'m>,
    s: &Drain<'_, 'm>,
    f: &Inputs<'m>,
) -> (Signal<'m>, Signal<'m>) {
    let (m, c, i, lb) = (w.m, w.c, w.i, w.lb);
    let ref_w = w.wl.reference.width();
    let lit = |v: u64, width: u32| w.lit(v, width);
    let (zero, one) = (lit(0, 1), lit(1, 1));
    let (in_drain, clear, drain_start, top, n_top, n_records) = (
        s.in_drain,
        s.clear,
        s.drain_start,
        s.top,
        s.n_top,
        s.n_records,
    );
    let (out_id, crefs_mem) = (f.out_id, f.crefs_mem);
    // Reference sequencer: one reference per clock in store order, walking
    // the parents (the records) and, for a grouped one, the next nodes of
    // the level below; a created one's come from `crefs`, a materialized
    // root's from the store (`ref_req` runs ahead of `ref_resp`). As in the
    // record sequencer, every buffer reads at the next values of the
    // pointers (parent, child, created reference), a clock ahead.
    let fs_d = m.reg("fs_lod", lb);
    let fs_ptr = m.reg("fs_ptr", c + 1);
    let fs_j = m.reg("fs_j", i);
    let fs_req = m.reg("fs_req", i);
    let fs_child = m.reg("fs_child", c + 1);
    let fs_cref = m.reg("fs_cref", c + 1);
    let fs_off = m.reg("fs_child_offset", i + 1);
    let fs_done = m.reg("fs_done", 1);
    let fs_d_next = m.wire("fs_lod_next", lb);
    let fs_ptr_next = m.wire("fs_ptr_next", c + 1);
    let fs_child_next = m.wire("fs_child_next", c + 1);
    let fs_cref_next = m.wire("fs_cref_next", c + 1);
    let fs_top = fs_d.eq(top);
    let fs_len = fs_top.mux(n_top, by_level(m, fs_d, n_records));
    let fs_level_last = fs_ptr.add(1, c + 1).eq(fs_len);
    let fs_busy = (in_drain & !fs_done).name("fs_busy");
    let fs_reading = drain_start | fs_busy;
    let fs_next_top = fs_d_next.eq(top);
    let fs_reads =
        |at_top: bool| move |d| reads_level(fs_reading, fs_d_next, fs_next_top, d, at_top);
    let par_addr = fs_ptr_next.slice(c - 1, 0);
    let par_top = read_ahead(w, &b.units, Buffer::ParentAtTop, par_addr, fs_reads(true));
    let par_below = read_ahead(w, &b.units, Buffer::ParentBySlot, par_addr, fs_reads(false));
    let par = parent(
        fs_top.mux(by_level(m, fs_d, &par_top), by_level(m, fs_d, &par_below)),
        i,
    );
    let p_grouped = kind_is(m, par.kind, level_out_kind::GROUPED);
    let p_created = kind_is(m, par.kind, level_out_kind::CREATED);
    let p_mat = kind_is(m, par.kind, level_out_kind::REUSED);
    // The children of level d's parents are in level d + 1, modulo 2^lod_bits
    // as the selection below reads them (level 0 only past the widest LOD,
    // whose nodes have no children).
    let child_level = fs_d_next.add(1, lb);
    let want_child = |e: usize| fs_reading & child_level.eq(lit(e as u64, lb));
    let child_addr = fs_child_next.slice(c - 1, 0);
    let children = read_ahead(w, &b.units, Buffer::Child, child_addr, want_child);
    let ch = child(by_level(m, fs_d.add(1, lb), &children), ref_w);
    let ch_index = fs_off.slice(i - 1, 0).add(ch.records, i);
    let ch_ref = ch.reused.mux(ch.refer, m.concat(&[out_id, ch_index]));
    let fs_active = fs_busy;
    let outstanding = fs_req.ne(fs_j);
    let ref_resp = Stream::input(m, "ref_resp", ref_w);
    let refs_ready = m.wire("refs_in_ready", 1);
    let source_valid = p_mat.mux(ref_resp.valid & outstanding, one);
    let refs_valid = (fs_active & source_valid).name("refs_in_valid");
    let word = p_grouped.mux(
        ch_ref,
        p_created.mux(
            crefs_mem.read_sync(fs_cref_next.slice(c - 1, 0), fs_reading),
            ref_resp.data,
        ),
    );
    let refs_out = Stream {
        valid: refs_valid,
        ready: refs_ready,
        data: refs_valid.mux(word, lit(0, ref_w)),
    };
    let fs_fire = (refs_out.valid & refs_out.ready).name("refs_fire");
    refs_out.skid_buffer("refs_skid").output("refs");
    ref_resp
        .ready
        .drive(fs_active & p_mat & outstanding & refs_ready);
    let req_valid = (fs_active & p_mat & fs_req.ne(par.count)).name("ref_req_in_valid");
    let req_index = par.first.add(fs_req, i);
    let ref_req = Stream {
        valid: req_valid,
        ready: m.wire("ref_req_in_ready", 1),
        data: req_valid.mux(m.concat(&[par.hier, req_index]), lit(0, ref_w)),
    };
    let req_fire = ref_req.valid & ref_req.ready;
    ref_req.skid_buffer("ref_req_skid").output("ref_req");
    let parent_last = fs_fire & fs_j.add(1, i).eq(par.count);
    // (fs_lod, fs_ptr) always names a parent with references left.
    let (fs_more, fs_next_lod) = next_level_with_records(m, fs_d, n_records);
    let fs_level_done = parent_last & fs_level_last;
    let fs_step_level = fs_level_done & fs_more;
    let fs_finish = fs_level_done & !fs_more;
    let zc = lit(0, c + 1);
    let zi = lit(0, i);
    fs_d_next.drive(drain_start.mux(top, fs_step_level.mux(fs_next_lod, fs_d)));
    fs_ptr_next.drive(
        (drain_start | fs_step_level).mux(zc, parent_last.mux(fs_ptr.add(1, c + 1), fs_ptr)),
    );
    fs_d.next(fs_d_next);
    fs_ptr.next(fs_ptr_next);
    fs_j.next((drain_start | parent_last).mux(zi, fs_fire.mux(fs_j.add(1, i), fs_j)));
    fs_req.next((drain_start | parent_last).mux(zi, req_fire.mux(fs_req.add(1, i), fs_req)));
    fs_child_next.drive((drain_start | fs_step_level).mux(
        zc,
        (fs_fire & p_grouped).mux(fs_child.add(1, c + 1), fs_child),
    ));
    fs_child.next(fs_child_next);
    fs_cref_next.drive(drain_start.mux(
        zc,
        (fs_fire & p_created).mux(fs_cref.add(1, c + 1), fs_cref),
    ));
    fs_cref.next(fs_cref_next);
    // off(t + 1) = the top's node count; stepping from level d to the next
    // level e with records (those between have none), off(e + 1) = off(d +
    // 1) + level e's records.
    let next_len = by_level(m, fs_next_lod, n_records).zext(i + 1);
    fs_off.next(drain_start.mux(
        n_top.zext(i + 1),
        fs_step_level.mux(fs_off.add(next_len, i + 1), fs_off),
    ));
    fs_done.next(clear.mux(zero, fs_done | fs_finish));

    (fs_busy, fs_done)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A memory declaration of the emitted Verilog,
    /// `reg [W-1:0] name [0:DEPTH-1];`, as a buffer.
    fn declared_memory(line: &str) -> Option<WriterBuffer> {
        let rest = line.trim().strip_prefix("reg [")?;
        let (hi, rest) = rest.split_once(":0] ")?;
        let (name, rest) = rest.split_once(" [0:")?;
        let (last, _) = rest.split_once("];")?;
        Some(WriterBuffer {
            name: name.trim().to_string(),
            width: hi.parse::<u32>().ok()? + 1,
            depth: last.parse::<u32>().ok()? + 1,
        })
    }

    /// The memories `text` (one module's Verilog) declares, each named
    /// `<prefix><name>`.
    fn declared_memories(text: &str, prefix: &str) -> Vec<WriterBuffer> {
        text.lines()
            .filter_map(declared_memory)
            .map(|b| WriterBuffer {
                name: format!("{prefix}{}", b.name),
                ..b
            })
            .collect()
    }

    /// The instances `text` (one module's Verilog) makes of `module`:
    /// `<module> <instance> (`.
    fn instances_of<'t>(text: &'t str, module: &str) -> Vec<&'t str> {
        text.lines()
            .filter_map(|l| l.trim().strip_prefix(module)?.strip_prefix(' '))
            .filter_map(|l| l.split_once(" (").map(|(inst, _)| inst))
            .collect()
    }

    /// The writer builds with no warning (no unread logic); and
    /// `record_writer_buffers` names exactly the memories the generator
    /// declares, in the writer and in each instance of its level modules
    /// (what a synthesis test counts macros from), `5D + 4` of them, and
    /// none is read asynchronously (no `assign x = mem[a]`).
    #[test]
    fn the_buffer_list_is_the_emitted_memories_all_read_synchronously() {
        let configs = [
            (Params::default(), 10),
            (Params::new(31, 16, 32, 8).unwrap(), 4),
            (Params::new(5, 2, 3, 2).unwrap(), 2),
        ];
        for (p, c) in configs {
            let m = record_writer_unit(&p, c).unwrap();
            let warnings = m.validate_design().expect("valid");
            assert!(warnings.is_empty(), "D = {}: {warnings:?}", p.max_lod);
            let files = crate::emit_design(&m).unwrap();
            let text_of = |module: &str| -> &str {
                let file = format!("{module}.v");
                &files.iter().find(|f| f.0 == file).expect("emitted").1
            };
            let top = text_of(&m.name());
            let mut emitted = declared_memories(top, "");
            for by_slot in [false, true] {
                let level = record_writer_level_name(&p, c, by_slot);
                let insts = instances_of(top, &level);
                assert_eq!(insts.len(), if by_slot { p.max_lod as usize } else { 1 });
                for inst in insts {
                    emitted.extend(declared_memories(text_of(&level), &format!("{inst}.")));
                }
            }
            assert_eq!(files.len(), 3, "the writer and its two level modules");
            let mut listed = record_writer_buffers(&p, c).unwrap();
            emitted.sort_by(|a, b| a.name.cmp(&b.name));
            listed.sort_by(|a, b| a.name.cmp(&b.name));
            assert_eq!(emitted, listed, "D = {}", p.max_lod);
            assert_eq!(listed.len(), 5 * p.max_lod as usize + 4);
            for (file, text) in &files {
                for mem in declared_memories(text, "") {
                    let async_read = format!("= {}[", mem.name);
                    assert!(
                        !text.lines().any(
                            |l| l.trim_start().starts_with("assign") && l.contains(&async_read)
                        ),
                        "{file}: {} is read asynchronously",
                        mem.name
                    );
                    assert!(
                        text.contains(&format!("<= {}[", mem.name)),
                        "{file}: {} has no registered read",
                        mem.name
                    );
                }
            }
        }
    }
}
