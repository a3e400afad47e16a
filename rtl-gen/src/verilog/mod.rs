//! The Verilog-2005 back-end: IR → syntax tree ([`ast`]) → text ([`mod@print`]).

pub mod ast;
mod enables;
mod lower;
pub mod print;
mod share;

use crate::diagnostic::{DiagKind, Diagnostic, Diagnostics, Severity};
use crate::graph::GraphRef;
use crate::Module;
use std::path::{Path, PathBuf};
use std::rc::Rc;

/// How registers are written in the `always` block.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum RegisterStyle {
    /// A register whose next value is a mux with the register itself on an
    /// arm is written as the enable idiom, `if (en) r <= d;`, registers
    /// testing one select grouped under one `if` (SPEC 11). The default.
    #[default]
    Enables,
    /// Every register loads its next value every cycle, `r <= r_next;`,
    /// with `r_next` a continuous mux (the emission before the enable
    /// idiom; for comparing the two, e.g. by a Yosys equivalence check).
    NextWires,
}

/// The Verilog text of one module (one file, named `<module>.v`), after
/// [`Module::validate`]; the same design always gives the same bytes.
///
/// ```
/// use rtl_gen::{emit_verilog, Module};
/// let m = Module::new("inc");
/// let a = m.input("a", 8);
/// m.output("y", a.add(1, 8));
/// let v = emit_verilog(&m).unwrap();
/// assert!(v.contains("assign y = a + 8'd1;"));
/// assert_eq!(v, emit_verilog(&m).unwrap());
/// ```
pub fn emit_verilog(m: &Module) -> Result<String, Diagnostics> {
    m.validate()?;
    Ok(print::print_module(&lower::lower(
        &m.graph(),
        RegisterStyle::Enables,
    )))
}

/// The syntax tree of one module (for tools that want to inspect or extend it).
///
/// ```
/// use rtl_gen::{verilog::{ast::Item, print::print_module, verilog_ast}, Module};
/// let m = Module::new("m");
/// m.output("y", !m.input("a", 2));
/// let tree = verilog_ast(&m).unwrap();
/// assert!(tree.items.iter().any(|i| matches!(i, Item::Assign(lhs, _) if lhs == "y")));
/// assert_eq!(print_module(&tree), rtl_gen::emit_verilog(&m).unwrap());
/// ```
pub fn verilog_ast(m: &Module) -> Result<ast::VModule, Diagnostics> {
    m.validate()?;
    Ok(lower::lower(&m.graph(), RegisterStyle::Enables))
}

/// Every module of a design, children before parents, each once.
pub(crate) fn design_modules(top: &Module) -> Vec<GraphRef> {
    fn visit(g: &GraphRef, seen: &mut Vec<GraphRef>, depth: u32) {
        if depth > 64 || seen.iter().any(|s| Rc::ptr_eq(s, g)) {
            return;
        }
        let children: Vec<GraphRef> = match g.try_borrow() {
            Ok(b) => b.insts.iter().map(|i| Rc::clone(&i.child)).collect(),
            Err(_) => vec![],
        };
        for c in &children {
            visit(c, seen, depth + 1);
        }
        if !seen.iter().any(|s| Rc::ptr_eq(s, g)) {
            seen.push(Rc::clone(g));
        }
    }
    let mut seen = Vec::new();
    visit(&top.g, &mut seen, 0);
    seen
}

/// The syntax tree of every module of the design, children first, each
/// once (the property harnesses of [`crate::formal`] read the names and
/// widths of the nets they observe from it).
pub(crate) fn design_asts(top: &Module) -> Result<Vec<ast::VModule>, Diagnostics> {
    top.validate_design()?;
    let mut out: Vec<ast::VModule> = Vec::new();
    for g in design_modules(top) {
        let v = lower::lower(&g.borrow(), RegisterStyle::Enables);
        if !out.iter().any(|m| m.name == v.name) {
            out.push(v);
        }
    }
    Ok(out)
}

/// Why a design could not be written.
#[derive(Debug)]
pub enum DesignError {
    /// Validation failed.
    Invalid(Diagnostics),
    /// Writing a file failed.
    Io(PathBuf, std::io::Error),
    /// The configuration asks for something the generator does not build.
    Config(String),
}

impl std::fmt::Display for DesignError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            DesignError::Invalid(d) => write!(f, "{d}"),
            DesignError::Io(p, e) => write!(f, "{}: {e}", p.display()),
            DesignError::Config(why) => write!(f, "configuration: {why}"),
        }
    }
}

impl std::error::Error for DesignError {}

/// The text of every module of the design as `(file name, text)`, children
/// first and the top last. Two different modules with one name are an error.
///
/// ```
/// use rtl_gen::{emit_design, Module};
/// let leaf = Module::new("leaf");
/// leaf.output("y", leaf.input("a", 1));
/// let top = Module::new("top");
/// let u = top.instance("u", &leaf);
/// u.connect("a", top.input("a", 1));
/// top.output("y", u.output("y"));
/// let files = emit_design(&top).unwrap();
/// let names: Vec<&str> = files.iter().map(|f| f.0.as_str()).collect();
/// assert_eq!(names, ["leaf.v", "top.v"]);
/// ```
pub fn emit_design(top: &Module) -> Result<Vec<(String, String)>, Diagnostics> {
    emit_design_with_style(top, RegisterStyle::Enables)
}

/// [`emit_design`] with registers written in `style`.
///
/// ```
/// use rtl_gen::{verilog::{emit_design_with_style, RegisterStyle}, Module};
/// let m = Module::new("m");
/// let (en, d) = (m.input("en", 1), m.input("d", 4));
/// let q = m.reg("q", 4);
/// q.next_when(en, d);
/// m.output("y", q);
/// let old = emit_design_with_style(&m, RegisterStyle::NextWires).unwrap();
/// assert!(old[0].1.contains("q <= q_next;"));
/// let new = emit_design_with_style(&m, RegisterStyle::Enables).unwrap();
/// assert!(new[0].1.contains("if (en) begin") && !new[0].1.contains("q_next"));
/// ```
pub fn emit_design_with_style(
    top: &Module,
    style: RegisterStyle,
) -> Result<Vec<(String, String)>, Diagnostics> {
    top.validate_design()?;
    let mut files: Vec<(String, String)> = Vec::new();
    for g in design_modules(top) {
        let g = g.borrow();
        let text = print::print_module(&lower::lower(&g, style));
        let file = format!("{}.v", g.name);
        match files.iter().find(|f| f.0 == file) {
            Some(f) if f.1 == text => continue,
            Some(_) => {
                return Err(Diagnostics(vec![Diagnostic {
                    severity: Severity::Error,
                    kind: DiagKind::Name,
                    module: g.name.clone(),
                    signal: None,
                    location: g.loc,
                    message: "two different modules of the design share this name; put the parameters in the name".into(),
                    related: vec![],
                }]))
            }
            None => files.push((file, text)),
        }
    }
    Ok(files)
}

/// Writes every module of the design to `dir/<module>.v`; returns the paths,
/// children first, top last.
///
/// ```
/// # use rtl_gen::{write_design, Module};
/// let m = Module::new("top");
/// m.output("y", m.input("a", 1));
/// let dir = std::env::temp_dir().join("rtl_gen_doc_write_design");
/// let files = write_design(&m, &dir).unwrap();
/// assert!(files[0].ends_with("top.v"));
/// ```
pub fn write_design(top: &Module, dir: &Path) -> Result<Vec<PathBuf>, DesignError> {
    write_design_with_style(top, dir, RegisterStyle::Enables)
}

/// [`write_design`] with registers written in `style`.
pub fn write_design_with_style(
    top: &Module,
    dir: &Path,
    style: RegisterStyle,
) -> Result<Vec<PathBuf>, DesignError> {
    let files = emit_design_with_style(top, style).map_err(DesignError::Invalid)?;
    std::fs::create_dir_all(dir).map_err(|e| DesignError::Io(dir.to_path_buf(), e))?;
    let mut out = Vec::new();
    for (name, text) in files {
        let p = dir.join(name);
        // Atomic, so an interrupted `gen` never leaves half a module behind
        // (SPEC 15.3).
        golden::output::write_atomic(&p, text.as_bytes())
            .map_err(|e| DesignError::Io(p.clone(), std::io::Error::other(e)))?;
        out.push(p);
    }
    Ok(out)
}
