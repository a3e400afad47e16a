//! [`Module::first_of`]: a priority select, the chain of 2-way muxes a
//! generator would otherwise nest by hand.

use crate::{Module, Signal};
use std::panic::Location;

impl Module {
    /// The value of the first arm whose condition (one bit) is high, else
    /// `default`; values and `default` of one width. Emitted as the nested
    /// `c0 ? v0 : c1 ? v1 : ... : default`, first arm outermost.
    ///
    /// ```
    /// # use rtl_gen::{Module, Sim};
    /// let m = Module::new("m");
    /// let (a, b) = (m.input("a", 1), m.input("b", 1));
    /// let code = m.first_of(&[(a, m.lit(1, 2)), (b, m.lit(2, 2))], m.lit(0, 2));
    /// m.output("code", code);
    /// let mut sim = Sim::new(&m).unwrap();
    /// sim.poke("a", 1u64).unwrap();
    /// sim.poke("b", 1u64).unwrap();
    /// assert_eq!(sim.peek("code").unwrap().to_u64(), Some(1));
    /// sim.poke("a", 0u64).unwrap();
    /// assert_eq!(sim.peek("code").unwrap().to_u64(), Some(2));
    /// ```
    #[track_caller]
    pub fn first_of<'m>(
        &'m self,
        arms: &[(Signal<'m>, Signal<'m>)],
        default: Signal<'m>,
    ) -> Signal<'m> {
        let loc = Location::caller();
        arms.iter().rev().fold(default, |rest, &(cond, value)| {
            cond.mux_at(value, rest, loc)
        })
    }
}
