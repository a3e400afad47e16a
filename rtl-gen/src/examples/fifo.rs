//! The library FIFO ([`Stream::fifo`]) as a module of its own.

use crate::{Module, Stream};

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
