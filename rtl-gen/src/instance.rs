//! [`Instance`]: a module used inside another.

use crate::diagnostic::DiagKind;
use crate::{IntoSignal, Module, Signal};
use std::panic::Location;

/// An instance made by [`Module::instance`].
#[derive(Clone, Copy)]
pub struct Instance<'m> {
    pub(crate) m: &'m Module,
    pub(crate) idx: usize,
}

impl<'m> Instance<'m> {
    fn name(&self) -> String {
        self.m.graph().insts[self.idx].name.clone()
    }

    /// Drives the child's input port `port` with `value` (same width).
    ///
    /// ```
    /// # use rtl_gen::Module;
    /// let child = Module::new("child");
    /// let a = child.input("a", 2);
    /// child.output("y", a);
    /// let top = Module::new("top");
    /// let u = top.instance("u", &child);
    /// u.connect("a", top.input("x", 2));
    /// top.output("y", u.output("y"));
    /// assert!(top.validate().is_ok());
    /// ```
    #[track_caller]
    pub fn connect(&self, port: &str, value: impl IntoSignal<'m>) {
        let loc = Location::caller();
        let slot = self.m.graph().insts[self.idx]
            .inputs
            .iter()
            .position(|i| i.port == port);
        let Some(slot) = slot else {
            let msg = format!("instance `{}` has no input port `{port}`", self.name());
            self.m
                .graph_mut()
                .error(DiagKind::Misuse, Some(port.into()), loc, msg);
            return;
        };
        let width = self.m.graph().insts[self.idx].inputs[slot].width;
        let v = value.into_signal_like(self.m.lit(0, width), loc);
        if v.width() != width {
            let msg = format!(
                "port `{port}` of `{}` is {width} bits, connected to {} bits",
                self.name(),
                v.width()
            );
            self.m
                .graph_mut()
                .error(DiagKind::Width, Some(port.into()), loc, msg);
            return;
        }
        self.m.graph_mut().insts[self.idx].inputs[slot]
            .drivers
            .push((v.id, loc));
    }

    /// The child's output port `port`, as a signal of this module.
    #[track_caller]
    pub fn output(&self, port: &str) -> Signal<'m> {
        let loc = Location::caller();
        let found = self.m.graph().insts[self.idx]
            .outputs
            .iter()
            .find(|o| o.0 == port)
            .map(|o| o.1);
        match found {
            Some(id) => self.m.sig(id, false),
            None => {
                let msg = format!("instance `{}` has no output port `{port}`", self.name());
                self.m
                    .fail(DiagKind::Misuse, Some(port.into()), loc, msg, 1)
            }
        }
    }
}
