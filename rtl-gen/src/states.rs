//! The named states of a state machine: each state's code is a constant
//! with the state's name, emitted as a `localparam`, so the Verilog reads
//! `state == DRAIN` where it would read `state == 2'd1`.

use crate::diagnostic::DiagKind;
use crate::{Module, Signal};
use std::panic::Location;

/// The states of one state machine: names and codes of one width.
///
/// ```
/// use rtl_gen::{emit_verilog, Module};
/// let m = Module::new("fsm");
/// let go = m.input("go", 1);
/// let s = m.states(2, &[("IDLE", 0), ("RUN", 1)]);
/// let st = m.reg("state", 2);
/// st.next(go.mux(s.code(1), s.code(0)));
/// m.output("running", s.is(st, 1));
/// let v = emit_verilog(&m).unwrap();
/// assert!(v.contains("localparam [1:0] RUN = 2'd1;"));
/// assert!(v.contains("(state == RUN)") || v.contains("state == RUN;"));
/// ```
pub struct States<'m> {
    m: &'m Module,
    width: u32,
    names: Vec<(String, u64)>,
}

impl Module {
    /// The states `(name, code)` of a state machine whose state register is
    /// `width` bits wide.
    pub fn states(&self, width: u32, states: &[(&str, u64)]) -> States<'_> {
        States {
            m: self,
            width,
            names: states.iter().map(|(n, c)| (n.to_string(), *c)).collect(),
        }
    }
}

impl<'m> States<'m> {
    /// The code of the state whose code is `value`, as a constant named
    /// after the state; an error (reported by validation) for a code no
    /// state has.
    #[track_caller]
    pub fn code(&self, value: u64) -> Signal<'m> {
        let loc = Location::caller();
        match self.names.iter().find(|s| s.1 == value) {
            // One constant per state in the module, whatever scope uses it.
            Some((name, _)) => self
                .m
                .lit(value.into(), self.width)
                .name_unscoped(name, loc),
            None => self.m.fail(
                DiagKind::Misuse,
                None,
                loc,
                format!(
                    "{value} is no state's code; the states are {}",
                    self.names
                        .iter()
                        .map(|(n, c)| format!("{n} = {c}"))
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
                self.width,
            ),
        }
    }

    /// Whether `state` holds the state whose code is `value`.
    #[track_caller]
    pub fn is(&self, state: Signal<'m>, value: u64) -> Signal<'m> {
        state.eq(self.code(value))
    }
}
