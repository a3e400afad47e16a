//! An enabled wrapping counter.

use crate::Module;

/// A `width`-bit counter that counts up when `en` is high and resets to zero.
///
/// ```
/// use rtl_gen::{examples::counter, Sim};
/// let m = counter(4);
/// let mut sim = Sim::new(&m).unwrap();
/// sim.reset();
/// sim.poke("en", 1u64).unwrap();
/// sim.step_n(20);
/// assert_eq!(sim.peek("count").unwrap().to_u64(), Some(20 % 16));
/// ```
pub fn counter(width: u32) -> Module {
    let m = Module::new(&format!("counter_w{width}"));
    let en = m.input("en", 1);
    let count = m.reg("count", width);
    count.next_when(en, count.add(1, width));
    m.output("count", count);
    m
}
