//! The library FIFOs ([`Stream::fifo`], [`crate::DropFifo`]) as modules of
//! their own.

use crate::{DropFifo, Module, Stream};

/// A FIFO of `2^addr_bits` words of `width` bits with ready/valid streams
/// `in` and `out`: [`Stream::fifo`] named `mem`.
///
/// ```
/// use rtl_gen::{examples::fifo, Sim};
/// let m = fifo(8, 2);
/// let mut sim = Sim::new(&m).unwrap();
/// sim.reset();
/// sim.poke("in_valid", 1u64).unwrap();
/// sim.poke("in_data", 42u64).unwrap();
/// sim.step();
/// assert_eq!(sim.peek("out_valid").unwrap().to_u64(), Some(1));
/// assert_eq!(sim.peek("out_data").unwrap().to_u64(), Some(42));
/// ```
pub fn fifo(width: u32, addr_bits: u32) -> Module {
    let m = Module::new(&format!("fifo_w{width}_a{addr_bits}"));
    Stream::input(&m, "in", width)
        .fifo("mem", 1 << addr_bits)
        .output("out");
    m
}

/// The library's [`crate::DropFifo`] of `2^cb` words of `width` bits behind
/// streams `in` and `out`: `in` is always taken (`in_ready` high), a beat
/// that finds the FIFO full is dropped and flagged on `dropped`, and
/// `clear` empties it.
///
/// ```
/// use rtl_gen::{examples::drop_fifo, Sim};
/// let m = drop_fifo(8, 1);
/// let mut sim = Sim::new(&m).unwrap();
/// sim.reset();
/// sim.poke("in_valid", 1u64).unwrap();
/// for w in [5u64, 6] {
///     sim.poke("in_data", w).unwrap();
///     sim.step();
/// }
/// assert_eq!(sim.peek("dropped").unwrap().to_u64(), Some(1));
/// assert_eq!(sim.peek("out_data").unwrap().to_u64(), Some(5));
/// ```
pub fn drop_fifo(width: u32, cb: u32) -> Module {
    let m = Module::new(&format!("drop_fifo_w{width}_c{cb}"));
    let input = Stream::input(&m, "in", width);
    let clear = m.input("clear", 1);
    let q = DropFifo::new(&m, "q_mem", "q", width, cb);
    input.ready.drive(m.lit(1, 1));
    let out = Stream::wires(&m, "q_out", width);
    out.valid.drive(!q.empty());
    out.data.drive(q.head());
    q.write(input.data, input.valid);
    q.advance(input.valid, out.fire(), clear);
    m.output("dropped", input.valid & q.full());
    out.output("out");
    m
}
