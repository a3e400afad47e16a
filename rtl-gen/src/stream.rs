//! [`Stream`]: a ready/valid handshake bundle and its usual pieces.
//!
//! A transfer happens on a clock edge where `valid` and `ready` are both
//! high. The producer drives `valid` and `data` and must hold them until
//! the transfer; the consumer drives `ready`.

use crate::{Module, Signal};

/// A skid buffer ([`Stream::skid_buffer_loads`]): its output stream, and
/// `next`, the word its output register takes at the edge where `load` is
/// high (it keeps its word otherwise).
#[derive(Clone, Copy, Debug)]
pub struct SkidBuffer<'m> {
    /// The buffered stream.
    pub stream: Stream<'m>,
    /// High when the output register loads at the next edge.
    pub load: Signal<'m>,
    /// The word it loads then.
    pub next: Signal<'m>,
}

/// A ready/valid stream: `valid` and `data` from the producer, `ready` from
/// the consumer. Helpers that make a stream leave its `ready` as a wire the
/// consumer drives (with [`Signal::drive`] or another helper).
///
/// ```
/// use rtl_gen::{Module, Stream};
/// let m = Module::new("pipe2");
/// let input = Stream::input(&m, "in", 16);
/// let out = input.pipeline_reg("stage1").map(|d| d ^ 0x00ff).skid_buffer("stage2");
/// out.output("out");
/// assert!(m.validate().is_ok());
/// ```
#[derive(Clone, Copy, Debug)]
pub struct Stream<'m> {
    /// High when `data` holds a word to transfer.
    pub valid: Signal<'m>,
    /// High when the consumer takes the word this cycle.
    pub ready: Signal<'m>,
    /// The payload.
    pub data: Signal<'m>,
}

impl<'m> Stream<'m> {
    /// Input ports `<name>_valid`, `<name>_data` and output port `<name>_ready`
    /// (driven by whatever consumes the returned stream).
    #[track_caller]
    pub fn input(m: &'m Module, name: &str, width: u32) -> Stream<'m> {
        Stream {
            valid: m.input(&format!("{name}_valid"), 1),
            data: m.input(&format!("{name}_data"), width),
            ready: m.output_wire(&format!("{name}_ready"), 1),
        }
    }

    /// Three wires `<name>_valid`, `<name>_ready`, `<name>_data`, all to be driven.
    #[track_caller]
    pub fn wires(m: &'m Module, name: &str, width: u32) -> Stream<'m> {
        Stream {
            valid: m.wire(&format!("{name}_valid"), 1),
            data: m.wire(&format!("{name}_data"), width),
            ready: m.wire(&format!("{name}_ready"), 1),
        }
    }

    /// Output ports `<name>_valid`, `<name>_data` and input port
    /// `<name>_ready`, which drives this stream's `ready`.
    #[track_caller]
    pub fn output(self, name: &str) {
        let m = self.valid.module();
        m.output(&format!("{name}_valid"), self.valid);
        m.output(&format!("{name}_data"), self.data);
        self.ready.drive(m.input(&format!("{name}_ready"), 1));
    }

    /// One bit: a transfer happens at the next edge.
    ///
    /// ```
    /// # use rtl_gen::{Module, Stream};
    /// let m = Module::new("m");
    /// let s = Stream::input(&m, "in", 8);
    /// let n = m.reg("n", 32);
    /// n.next_when(s.fire(), n.add(1, 32));
    /// s.map(|d| !d).output("out");
    /// # m.output("count", n);
    /// # assert!(m.validate().unwrap().is_empty());
    /// ```
    #[track_caller]
    pub fn fire(self) -> Signal<'m> {
        self.valid & self.ready
    }

    /// The same handshake with the data transformed combinationally.
    pub fn map(self, f: impl FnOnce(Signal<'m>) -> Signal<'m>) -> Stream<'m> {
        Stream {
            data: f(self.data),
            ..self
        }
    }

    /// A pipeline register: `valid`/`data` registered, full throughput,
    /// `ready` passes through combinationally (`ready_in = !valid_q | ready_out`).
    ///
    /// ```
    /// # use rtl_gen::{Module, Stream};
    /// let m = Module::new("m");
    /// Stream::input(&m, "in", 8).pipeline_reg("p").output("out");
    /// # assert!(m.validate().is_ok());
    /// ```
    #[track_caller]
    pub fn pipeline_reg(self, name: &str) -> Stream<'m> {
        let m = self.valid.module();
        let valid = m.reg(&format!("{name}_valid"), 1);
        let data = m.reg(&format!("{name}_data"), self.data.width());
        let ready = m.wire(&format!("{name}_ready"), 1);
        let take = (!valid | ready).name(&format!("{name}_take"));
        self.ready.drive(take);
        valid.next_when(take, self.valid);
        data.next_when(take & self.valid, self.data);
        Stream { valid, ready, data }
    }

    /// A skid buffer: every output and `ready_in` come straight from
    /// registers, full throughput; a second register holds the word that
    /// arrives in the cycle the consumer stalls.
    ///
    /// ```
    /// # use rtl_gen::{Module, Stream};
    /// let m = Module::new("m");
    /// Stream::input(&m, "in", 8).skid_buffer("skid").output("out");
    /// # assert!(m.validate().is_ok());
    /// ```
    #[track_caller]
    pub fn skid_buffer(self, name: &str) -> Stream<'m> {
        self.skid_buffer_loads(name).stream
    }

    /// [`Stream::skid_buffer`], also returning when its output register
    /// loads and the word it loads then, for a consumer that works a clock
    /// ahead on the word its output will hold.
    ///
    /// ```
    /// # use rtl_gen::{Module, Stream};
    /// let m = Module::new("m");
    /// let skid = Stream::input(&m, "in", 8).skid_buffer_loads("skid");
    /// let seen = m.reg("seen", 8);
    /// seen.next_when(skid.load, skid.next);
    /// skid.stream.output("out");
    /// # m.output("s", seen);
    /// # assert!(m.validate().is_ok());
    /// ```
    #[track_caller]
    pub fn skid_buffer_loads(self, name: &str) -> SkidBuffer<'m> {
        let m = self.valid.module();
        let w = self.data.width();
        let out_valid = m.reg(&format!("{name}_valid"), 1);
        let out_data = m.reg(&format!("{name}_data"), w);
        let spare_valid = m.reg(&format!("{name}_spare_valid"), 1);
        let spare_data = m.reg(&format!("{name}_spare_data"), w);
        let ready = m.wire(&format!("{name}_ready"), 1);
        let room = (!spare_valid).name(&format!("{name}_room"));
        self.ready.drive(room);
        // The output register moves when it is empty or being taken.
        let drain = (ready | !out_valid).name(&format!("{name}_drain"));
        let take = (self.valid & room).name(&format!("{name}_take"));
        out_valid.next(drain.mux(spare_valid | self.valid, out_valid));
        let next = spare_valid.mux(spare_data, self.data);
        out_data.next_when(drain, next);
        spare_valid.next(drain.mux(m.lit(0, 1), spare_valid | take));
        spare_data.next_when(!drain & take, self.data);
        SkidBuffer {
            stream: Stream {
                valid: out_valid,
                ready,
                data: out_data,
            },
            load: drain,
            next,
        }
    }

    /// A FIFO of `depth` words (a power of two) on a memory, in order:
    /// this stream's `ready` is driven here (room left), the returned
    /// stream's `ready` by its consumer. A word pushed is readable from the
    /// next clock; a push and a pop may share a clock, so a depth of 2 runs
    /// one word a clock. Registers `<name>_head`, `<name>_tail` (read and
    /// write addresses) and `<name>_count` (the words held, so full and
    /// empty are one compare each); the output's data is zero while it is
    /// empty, never an unwritten (X in 4-state simulators) word.
    ///
    /// ```
    /// # use rtl_gen::{Module, Stream};
    /// let m = Module::new("m");
    /// Stream::input(&m, "in", 8).fifo("q", 4).output("out");
    /// # assert!(m.validate().is_ok());
    /// ```
    #[track_caller]
    pub fn fifo(self, name: &str, depth: u32) -> Stream<'m> {
        let m = self.valid.module();
        let width = self.data.width();
        // The memory reports a depth that is not a power of two >= 2.
        let aw = depth.max(2).next_power_of_two().trailing_zeros();
        let cb = golden::params::bits_to_hold(depth as u64);
        let mem = m.memory(name, width, depth);
        let head = m.reg(&format!("{name}_head"), aw);
        let tail = m.reg(&format!("{name}_tail"), aw);
        let count = m.reg(&format!("{name}_count"), cb);
        let out = Stream::wires(m, &format!("{name}_out"), width);
        self.ready.drive(count.ne(m.lit(depth as u128, cb)));
        let nonempty = count.ne(0);
        out.valid.drive(nonempty);
        out.data
            .drive(nonempty.mux(mem.read(head), m.lit(0, width)));
        let push = self.fire();
        let pop = out.fire();
        mem.write(tail, self.data, push);
        head.next(pop.mux(head.add(1, aw), head));
        tail.next(push.mux(tail.add(1, aw), tail));
        count.next(push.mux(
            pop.mux(count, count.add(1, cb)),
            pop.mux(count.sub(1, cb), count),
        ));
        out
    }

    /// Merges streams of equal width into one by fixed priority: the
    /// lowest-numbered valid input wins and is the only one told `ready`.
    /// While the output is stalled (valid, not ready) the grant is held to
    /// the next clock, so the output keeps its beat as a producer must (a
    /// lower-numbered input that becomes valid meanwhile waits); otherwise
    /// the choice is combinational.
    ///
    /// ```
    /// # use rtl_gen::{Module, Stream};
    /// let m = Module::new("m");
    /// let a = Stream::input(&m, "a", 8);
    /// let b = Stream::input(&m, "b", 8);
    /// Stream::merge_priority(&m, "arb", &[a, b]).output("out");
    /// # assert!(m.validate().is_ok());
    /// ```
    #[track_caller]
    pub fn merge_priority(m: &'m Module, name: &str, inputs: &[Stream<'m>]) -> Stream<'m> {
        let ready = m.wire(&format!("{name}_ready"), 1);
        let Some(last) = inputs.last() else {
            let none = m.concat(&[]);
            return Stream {
                valid: none,
                ready,
                data: none,
            };
        };
        // The one-hot choice by priority, then the choice held under a stall.
        let mut free = Vec::with_capacity(inputs.len());
        let mut earlier_valid: Option<Signal<'m>> = None;
        for s in inputs {
            free.push(match earlier_valid {
                None => s.valid,
                Some(e) => s.valid & !e,
            });
            earlier_valid = Some(match earlier_valid {
                None => s.valid,
                Some(e) => e | s.valid,
            });
        }
        let free_vec = m
            .concat(&free.iter().rev().copied().collect::<Vec<_>>())
            .name(&format!("{name}_free"));
        let n = inputs.len() as u32;
        let stalled = m.reg(&format!("{name}_stalled"), 1);
        let held = m.reg(&format!("{name}_held"), n);
        let grant = stalled.mux(held, free_vec).name(&format!("{name}_grant"));
        let valid = earlier_valid.unwrap_or(last.valid);
        stalled.next(valid & !ready);
        held.next(grant);
        let mut data = last.data;
        for (i, s) in inputs.iter().enumerate().rev().skip(1) {
            data = grant.bit(i as u32).mux(s.data, data);
        }
        for (i, s) in inputs.iter().enumerate() {
            s.ready.drive(ready & grant.bit(i as u32));
        }
        Stream {
            valid: valid.name(&format!("{name}_valid")),
            ready,
            data: data.name(&format!("{name}_data")),
        }
    }
}
