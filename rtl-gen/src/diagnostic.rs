//! Errors and warnings about a design, each naming a signal and the
//! generator source line that made it.

use std::fmt;
use std::panic::Location;

/// A source location in the generator (the Rust code that built the design).
pub type Loc = &'static Location<'static>;

/// How bad a finding is: errors stop emission and simulation, warnings do not.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Severity {
    /// The design is wrong; nothing is emitted.
    Error,
    /// The design is legal but probably not what was meant.
    Warning,
}

/// What kind of problem a [`Diagnostic`] reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum DiagKind {
    /// Operand or port widths that do not fit together.
    Width,
    /// A signal, bit range or constant used in a way the construct forbids
    /// (driving an input, slicing out of range, mixing modules, ...).
    Misuse,
    /// An illegal, reserved or duplicate name.
    Name,
    /// A wire, output, register or instance input that nothing drives.
    Undriven,
    /// A wire or register driven more than once.
    MultipleDrivers,
    /// Combinational logic that feeds back on itself.
    CombLoop,
    /// Logic, or bits of it, that nothing reads (a warning).
    Unused,
}

impl DiagKind {
    fn tag(self) -> &'static str {
        match self {
            DiagKind::Width => "width",
            DiagKind::Misuse => "misuse",
            DiagKind::Name => "name",
            DiagKind::Undriven => "undriven",
            DiagKind::MultipleDrivers => "multiple-drivers",
            DiagKind::CombLoop => "comb-loop",
            DiagKind::Unused => "unused",
        }
    }
}

/// One finding: where (generator source line), what signal, and why.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Diagnostic {
    /// Error or warning.
    pub severity: Severity,
    /// The kind of problem.
    pub kind: DiagKind,
    /// The module the finding is in.
    pub module: String,
    /// The signal concerned, when there is one.
    pub signal: Option<String>,
    /// The generator line that made the signal or called the faulty construct.
    pub location: Loc,
    /// What is wrong and what was expected.
    pub message: String,
    /// Other places involved (the second driver, the signals of a loop).
    pub related: Vec<(String, Loc)>,
}

impl fmt::Display for Diagnostic {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let sev = match self.severity {
            Severity::Error => "error",
            Severity::Warning => "warning",
        };
        write!(
            f,
            "{}:{}: {}[{}] in module {}",
            self.location.file(),
            self.location.line(),
            sev,
            self.kind.tag(),
            self.module
        )?;
        if let Some(s) = &self.signal {
            write!(f, ", signal `{s}`")?;
        }
        write!(f, ": {}", self.message)?;
        for (what, loc) in &self.related {
            write!(f, "\n    {what} ({}:{})", loc.file(), loc.line())?;
        }
        Ok(())
    }
}

/// Every error found in a design (never empty when returned as an error),
/// followed by the warnings.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Diagnostics(pub Vec<Diagnostic>);

impl Diagnostics {
    /// The findings of the given kind.
    pub fn of_kind(&self, kind: DiagKind) -> impl Iterator<Item = &Diagnostic> {
        self.0.iter().filter(move |d| d.kind == kind)
    }

    /// True when some finding has the given kind.
    pub fn has(&self, kind: DiagKind) -> bool {
        self.of_kind(kind).next().is_some()
    }

    /// The errors only.
    pub fn errors(&self) -> impl Iterator<Item = &Diagnostic> {
        self.0.iter().filter(|d| d.severity == Severity::Error)
    }
}

impl fmt::Display for Diagnostics {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, d) in self.0.iter().enumerate() {
            if i > 0 {
                writeln!(f)?;
            }
            write!(f, "{d}")?;
        }
        Ok(())
    }
}

impl std::error::Error for Diagnostics {}
