//! [`Scope`]: a name prefix for the signals a part of a generator makes
//! (SpinalHDL's `Area`), so a stage's nets read `visit_go`, `range_idx`
//! while the stage's code says `go`, `idx`.

use crate::Module;

/// While it lives, every register, wire, memory and `.name()` the module
/// makes is named `<scope>_<name>` (scopes nest: `<outer>_<inner>_<name>`);
/// ports, instances, [`crate::Signal::named_after`] (already after a
/// prefixed name) and state constants ([`Module::states`]) keep their
/// names. Dropping it closes it and every scope opened inside it.
///
/// ```
/// use rtl_gen::{emit_verilog, Module, Stream};
/// let m = Module::new("m");
/// let input = Stream::input(&m, "in", 8);
/// let out = {
///     let _stage = m.scope("stage1");
///     input.pipeline_reg("pipe")
/// };
/// out.output("out");
/// let v = emit_verilog(&m).unwrap();
/// assert!(v.contains("reg [7:0] stage1_pipe_data;"), "{v}");
/// ```
#[must_use = "a scope closes when dropped"]
pub struct Scope<'m> {
    m: &'m Module,
    depth: usize,
}

impl Module {
    /// Opens a [`Scope`] named `name` inside the scopes open now.
    pub fn scope(&self, name: &str) -> Scope<'_> {
        let mut g = self.graph_mut();
        let depth = g.scopes.len();
        g.scopes.push(name.to_string());
        Scope { m: self, depth }
    }

    /// `name` inside the open scopes.
    pub(crate) fn scoped(&self, name: &str) -> String {
        let g = self.graph();
        if g.scopes.is_empty() {
            return name.to_string();
        }
        format!("{}_{name}", g.scopes.join("_"))
    }
}

impl Drop for Scope<'_> {
    fn drop(&mut self) {
        self.m.graph_mut().scopes.truncate(self.depth);
    }
}
