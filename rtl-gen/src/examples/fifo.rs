//! A synchronous FIFO on a register file.

use crate::{Module, Stream};

/// A FIFO of `2^addr_bits` words of `width` bits with ready/valid streams
/// `in` and `out`. Pointers carry one extra wrap bit so full and empty differ.
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
    let input = Stream::input(&m, "in", width);
    let out_ready = m.input("out_ready", 1);
    let mem = m.memory("mem", width, 1 << addr_bits);
    let wr = m.reg("wr_ptr", addr_bits + 1);
    let rd = m.reg("rd_ptr", addr_bits + 1);
    let (wr_addr, rd_addr) = (wr.slice(addr_bits - 1, 0), rd.slice(addr_bits - 1, 0));
    let empty = wr.eq(rd).name("empty");
    let full = (wr.msb().ne(rd.msb()) & wr_addr.eq(rd_addr)).name("full");
    let push = (input.valid & !full).name("push");
    let pop = (!empty & out_ready).name("pop");
    input.ready.drive(!full);
    mem.write(wr_addr, input.data, push);
    wr.next_when(push, wr.add(1, addr_bits + 1));
    rd.next_when(pop, rd.add(1, addr_bits + 1));
    m.output("out_valid", !empty);
    m.output("out_data", mem.read(rd_addr));
    m
}
