//! The Verilog-2005 back-end: IR → syntax tree ([`ast`]) → text ([`mod@print`]).

pub mod ast;
mod lower;
pub mod print;

use crate::diagnostic::{DiagKind, Diagnostic, Diagnostics, Severity};
use crate::graph::GraphRef;
use crate::Module;
use std::path::{Path, PathBuf};
use std::rc::Rc;

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
    Ok(print::print_module(&lower::lower(&m.graph())))
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
    Ok(lower::lower(&m.graph()))
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
    top.validate_design()?;
    let mut files: Vec<(String, String)> = Vec::new();
    for g in design_modules(top) {
        let g = g.borrow();
        let text = print::print_module(&lower::lower(&g));
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
    let files = emit_design(top).map_err(DesignError::Invalid)?;
    std::fs::create_dir_all(dir).map_err(|e| DesignError::Io(dir.to_path_buf(), e))?;
    let mut out = Vec::new();
    for (name, text) in files {
        let p = dir.join(name);
        std::fs::write(&p, text).map_err(|e| DesignError::Io(p.clone(), e))?;
        out.push(p);
    }
    Ok(out)
}
