//! The merger's store front end (SPEC.md section 8.15, "The shared store
//! port"): the read streams of the fetchers and the writer arbitrated onto
//! one read port of the store.
//!
//! Requester `j` (`r{j}_req`: `{slot, hier, index}`, an entry of a
//! hierarchy's array for the merge of slot `slot`) is granted round robin
//! (`golden::merge::merger::store_port::round_robin_next`: after `j`, the first
//! requester after `j` showing a request, wrapping round), so one that keeps
//! its request up waits for at most `n - 1` other grants. The grant goes
//! into a skid buffer whose output is `store_req` (`{array, slot, hier,
//! index}`), and
//! the requester's id into a tag FIFO of `2^tag_bits` words: the reads in
//! flight, one issued per clock. `store_resp` comes back in request order;
//! the tag at the FIFO's head routes it to that requester (`r{j}_resp`):
//! in the same clock when its answer buffer (a FIFO of `2^tag_bits`) is
//! empty and it takes it, else through the buffer.
//!
//! **Why `store_resp` never waits on a unit.** A requester is granted only
//! while it has fewer than `2^tag_bits` reads in flight or answered but not
//! taken (its credit), which its answer buffer holds: an answer always
//! finds room, and `store_resp_ready` is high whenever a read is in flight.
//! So one requester alone can keep the port busy, and a unit that stalls
//! its own answer (a fetcher waiting on its `out`) stalls only itself,
//! never the answers of the others behind it in the one in-order stream,
//! which could otherwise close a wait cycle through the merging module
//! (8.15, "Why one walk cannot deadlock").

use golden::merge::merger::store_port::{StoreArray, StorePortLayout};
use golden::params::{bits_to_hold, Params};

use crate::DropFifo;
use crate::{Module, Signal, Stream};

/// A store front end: the grid parameters (index, record and reference
/// widths), the array each requester reads, and the tag FIFO's size.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct StorePortConfig {
    /// Grid parameters: `I` and the record and reference layouts.
    pub params: Params,
    /// Per requester `r{j}`: the array it reads.
    pub arrays: Vec<StoreArray>,
    /// The tag FIFO holds `2^tag_bits` reads in flight (`1..=8`).
    pub tag_bits: u32,
}

impl StorePortConfig {
    /// Refuses what the front end cannot build: fewer than 2 or more than
    /// 256 requesters, `tag_bits` outside `1..=8`, or no requester of the
    /// wider array (whose answer fills `store_resp`).
    pub fn validate(&self) -> Result<(), String> {
        let n = self.arrays.len();
        if !(2..=256).contains(&n) {
            return Err(format!("{n} requesters: expected 2..=256"));
        }
        if !(1..=8).contains(&self.tag_bits) {
            return Err(format!(
                "tag_bits = {}: expected 1..=8 (a tag FIFO of 2^tag_bits reads)",
                self.tag_bits
            ));
        }
        let l = StorePortLayout::new(&self.params);
        if !self.arrays.iter().any(|a| l.width_of(*a) == l.resp_width) {
            return Err(format!(
                "no requester reads the array whose answer is {} bits wide (store_resp)",
                l.resp_width
            ));
        }
        Ok(())
    }

    /// Width of a requester id (a tag).
    pub fn tag_width(&self) -> u32 {
        bits_to_hold(self.arrays.len() as u64 - 1)
    }
}

/// Module name of the front end for `c`: index, record and reference
/// widths, the arrays in requester order (`n`, `r`), the tag FIFO's bits.
pub fn store_port_name(c: &StorePortConfig) -> String {
    let l = StorePortLayout::new(&c.params);
    let arrays: String = c.arrays.iter().map(|a| a.letter()).collect();
    format!(
        "store_port_i{}_n{}_r{}_{arrays}_t{}",
        l.index.width, l.node_width, l.ref_width, c.tag_bits
    )
}

/// One-hot: the lowest of `cands` that is high.
fn lowest<'m>(cands: &[Signal<'m>]) -> Vec<Signal<'m>> {
    let mut out = Vec::with_capacity(cands.len());
    let mut earlier: Option<Signal<'m>> = None;
    for (j, c) in cands.iter().enumerate() {
        out.push(earlier.map_or(*c, |e| *c & !e));
        // The last candidate's OR would be read by nothing.
        if j + 1 < cands.len() {
            earlier = Some(earlier.map_or(*c, |e| e | *c));
        }
    }
    out
}

/// The store front end for `c`; an error when `c.validate()` refuses it.
///
/// Ports: `clk`, `rst`; per requester `j` the streams `r{j}_req` (in,
/// `{slot, hier, index}`, 1 + H + I bits) and `r{j}_resp` (out, the answer: a
/// node record or a reference); `store_req` (out, [`StorePortLayout`]'s
/// `{array, slot, hier, index}`),
/// `store_resp` (in, [`StorePortLayout::resp_width`]); output `idle` (no
/// read in flight, no answer buffered).
pub fn store_port_unit(c: &StorePortConfig) -> Result<Module, String> {
    c.validate()?;
    let l = StorePortLayout::new(&c.params);
    let n = c.arrays.len();
    let tw = c.tag_width();
    let m = Module::new(&store_port_name(c));
    let lit = |v: u64, w: u32| m.lit(v as u128, w);
    let reqs: Vec<Stream> = (0..n)
        .map(|j| Stream::input(&m, &format!("r{j}_req"), l.addr.width()))
        .collect();
    // A requester's reads in flight or answered and not taken: at most
    // its answer buffer's `2^tag_bits`.
    let cw = c.tag_bits + 1;
    let credits: Vec<Signal> = (0..n).map(|j| m.reg(&format!("credit{j}"), cw)).collect();
    let most = lit(1 << c.tag_bits, cw);
    let tags = DropFifo::new(&m, "tag_mem", "tag", tw, c.tag_bits);
    let last = m.reg("rr_last", tw);

    // ---- round robin: the first eligible requester after `last`, else the
    // first eligible one.
    let eligible: Vec<Signal> = (0..n)
        .map(|j| (reqs[j].valid & credits[j].lt(most)).name(&format!("eligible{j}")))
        .collect();
    let after: Vec<Signal> = (0..n)
        .map(|j| match j {
            0 => lit(0, 1),
            _ => eligible[j] & last.lt(lit(j as u64, tw)),
        })
        .collect();
    let any_after = after
        .iter()
        .fold(lit(0, 1), |a, s| a | *s)
        .name("any_after");
    let (first_after, first_any) = (lowest(&after), lowest(&eligible));
    let grant: Vec<Signal> = (0..n)
        .map(|j| {
            any_after
                .mux(first_after[j], first_any[j])
                .name(&format!("grant{j}"))
        })
        .collect();
    let any = eligible.iter().fold(lit(0, 1), |a, s| a | *s);
    let (mut beat, mut tag) = (lit(0, l.req.width()), lit(0, tw));
    for j in 0..n {
        let b = m.concat(&[lit(c.arrays[j].code(), 1), reqs[j].data]);
        beat = grant[j].mux(b, beat);
        tag = grant[j].mux(lit(j as u64, tw), tag);
    }
    let arb = Stream {
        valid: (any & !tags.full()).name("arb_valid"),
        data: beat.name("arb_data"),
        ready: m.wire("arb_ready", 1),
    };
    let issue = arb.fire().name("issue");
    for (j, r) in reqs.iter().enumerate() {
        r.ready.drive(grant[j] & arb.ready & !tags.full());
    }
    arb.skid_buffer("store_req_q").output("store_req");
    let tag = tag.name("grant_tag");
    last.next_when(issue, tag);
    tags.write(tag, issue);

    // ---- answers: in order, to the requester at the tag FIFO's head,
    // straight through when its buffer is empty and it takes the answer,
    // else into its buffer (never full: the credits).
    let store_resp = Stream::input(&m, "store_resp", l.resp_width);
    let head = tags.head().name("tag_head");
    let waiting = (!tags.empty()).name("tag_waiting");
    store_resp.ready.drive(waiting);
    let answered = store_resp.fire().name("answered");
    let mut idle = lit(1, 1);
    for (j, array) in c.arrays.iter().enumerate() {
        let w = l.width_of(*array);
        let arrive = (answered & head.eq(lit(j as u64, tw))).name(&format!("to{j}"));
        let word = store_resp.data.slice(w - 1, 0);
        let buf = DropFifo::new(
            &m,
            &format!("r{j}_ans_mem"),
            &format!("r{j}_ans"),
            w,
            c.tag_bits,
        );
        let out = Stream {
            valid: (!buf.empty() | arrive).name(&format!("r{j}_resp_valid_w")),
            data: buf.empty().mux(word, buf.head()),
            ready: m.wire(&format!("r{j}_resp_ready_w"), 1),
        };
        let taken = out.fire();
        let push = arrive & !(buf.empty() & out.ready);
        buf.write(word, push);
        buf.advance(push, taken & !buf.empty(), lit(0, 1));
        out.output(&format!("r{j}_resp"));
        let got = issue & grant[j];
        let cr = credits[j];
        let cw = cr.width();
        cr.next(got.mux(taken.mux(cr, cr.add(1, cw)), taken.mux(cr.sub(1, cw), cr)));
        idle = idle & cr.eq(lit(0, cw));
    }
    tags.advance(issue, answered, lit(0, 1));
    m.output("idle", idle.name("port_idle"));
    Ok(m)
}

/// The merger's units (`clients`: instances, their modules and the bits
/// the front end's request has above the unit's own: the slot of the merge
/// the unit serves and, for a unit whose requests are bare indices, the
/// hierarchy it reads, a fetcher's input's from the held `cfg`), in
/// requester order, on one store front end of `c`'s tag FIFO, and its
/// `store_req` / `store_resp` as the top's streams. Every read stream of a
/// unit (`<name>_req` out, `<name>_resp` in) is one requester; the array it
/// reads is told by its answer's width (a node record or a reference).
pub(super) fn connect_shared<'m>(
    m: &'m Module,
    c: &super::MergerConfig,
    clients: &[(crate::Instance<'m>, &Module, Signal<'m>)],
) {
    let p = c.design.params;
    let l = StorePortLayout::new(&p);
    let tag_bits = match c.sizes.store_port {
        golden::merge::merger::store_port::StorePort::Shared { tag_bits } => tag_bits,
        golden::merge::merger::store_port::StorePort::PerUnit => return,
    };
    let mut reqs = Vec::new();
    for (inst, module, above) in clients {
        for (name, dir, w) in super::store_streams(module) {
            if let (crate::Direction::Input, Some(base)) = (dir, name.strip_suffix("_resp")) {
                let array = if w == l.node_width {
                    StoreArray::Node
                } else {
                    StoreArray::Reference
                };
                reqs.push((*inst, base.to_string(), array, *above));
            }
        }
    }
    let sc = StorePortConfig {
        params: p,
        arrays: reqs.iter().map(|r| r.2).collect(),
        tag_bits,
    };
    // `MergerConfig::validate` checked `tag_bits`; every merger has a
    // fetcher's node reader, the wider answer.
    let port_mod = store_port_unit(&sc).expect("a merger's store port is valid");
    let port = m.instance("u_store_port", &port_mod);
    for (j, (inst, base, _, above)) in reqs.iter().enumerate() {
        let (r, q) = (format!("r{j}"), format!("{base}_req"));
        let data = inst.output(&format!("{q}_data"));
        // A bare index gets its unit's hierarchy above it; the writer's
        // request is already `{hier, index}` (a reference).
        let addr = m.concat(&[*above, data]);
        port.connect(
            &format!("{r}_req_valid"),
            inst.output(&format!("{q}_valid")),
        );
        port.connect(&format!("{r}_req_data"), addr);
        inst.connect(
            &format!("{q}_ready"),
            port.output(&format!("{r}_req_ready")),
        );
        let a = format!("{base}_resp");
        inst.connect(
            &format!("{a}_valid"),
            port.output(&format!("{r}_resp_valid")),
        );
        inst.connect(&format!("{a}_data"), port.output(&format!("{r}_resp_data")));
        port.connect(
            &format!("{r}_resp_ready"),
            inst.output(&format!("{a}_ready")),
        );
    }
    let req = Stream {
        valid: port.output("store_req_valid"),
        data: port.output("store_req_data"),
        ready: m.wire("store_req_ready_w", 1),
    };
    port.connect("store_req_ready", req.ready);
    req.output("store_req");
    let resp = Stream::input(m, "store_resp", l.resp_width);
    port.connect("store_resp_valid", resp.valid);
    port.connect("store_resp_data", resp.data);
    resp.ready.drive(port.output("store_resp_ready"));
    m.output("store_idle", port.output("idle"));
}
