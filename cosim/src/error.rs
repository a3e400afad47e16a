//! The one error type of the co-simulation harness.
//!
//! Every variant names what was being done (the file, the port, the cycle) so a
//! failing test or CLI run can be acted on without a debugger.

use std::fmt;
use std::path::PathBuf;

/// Anything that can go wrong while building, loading or stepping a design.
#[derive(Debug)]
pub enum CosimError {
    /// The design description itself is inconsistent (duplicate port, bad name, ...).
    Design { what: String },
    /// A port name was looked up that the design does not have.
    UnknownPort { name: String },
    /// A port index out of range for the design.
    BadPortId { index: usize, count: usize },
    /// A value does not fit the port it was poked into (never silently truncated).
    Width {
        port: String,
        width: usize,
        value_bits: usize,
    },
    /// Poke on an output port.
    NotAnInput { port: String },
    /// A required external tool is missing or failed to start.
    ToolMissing { tool: String, hint: String },
    /// An external tool ran and failed; `log` holds its output.
    ToolFailed {
        tool: String,
        command: String,
        log: String,
    },
    /// The compiled model disagrees with the port description.
    PortMismatch { port: String, what: String },
    /// An I/O error with the path it concerns.
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    /// Loading the shared library or a symbol failed.
    Load { path: PathBuf, what: String },
    /// The simulator process broke the pipe protocol or exited.
    Protocol { what: String },
    /// A 4-state simulator produced X or Z on an output after reset.
    UnknownOutput {
        port: String,
        cycle: u64,
        value: String,
    },
    /// A text value could not be parsed as a bit vector.
    Parse { text: String, what: String },
    /// The feature asked for is not available in this engine or build.
    Unsupported { what: String },
}

impl fmt::Display for CosimError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CosimError::Design { what } => write!(f, "design description: {what}"),
            CosimError::UnknownPort { name } => write!(f, "the design has no port named `{name}`"),
            CosimError::BadPortId { index, count } => {
                write!(
                    f,
                    "port id {index} out of range (the design has {count} ports)"
                )
            }
            CosimError::Width {
                port,
                width,
                value_bits,
            } => write!(
                f,
                "value for port `{port}` needs {value_bits} bits but the port is {width} bits wide"
            ),
            CosimError::NotAnInput { port } => write!(f, "port `{port}` is not an input"),
            CosimError::ToolMissing { tool, hint } => write!(f, "`{tool}` not usable: {hint}"),
            CosimError::ToolFailed { tool, command, log } => {
                write!(f, "`{tool}` failed\ncommand: {command}\n{log}")
            }
            CosimError::PortMismatch { port, what } => write!(f, "port `{port}`: {what}"),
            CosimError::Io { path, source } => write!(f, "{}: {source}", path.display()),
            CosimError::Load { path, what } => write!(f, "loading {}: {what}", path.display()),
            CosimError::Protocol { what } => write!(f, "simulator pipe protocol: {what}"),
            CosimError::UnknownOutput { port, cycle, value } => write!(
                f,
                "output `{port}` is X/Z after reset at cycle {cycle} (value {value})"
            ),
            CosimError::Parse { text, what } => write!(f, "cannot parse `{text}`: {what}"),
            CosimError::Unsupported { what } => write!(f, "unsupported: {what}"),
        }
    }
}

impl std::error::Error for CosimError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            CosimError::Io { source, .. } => Some(source),
            _ => None,
        }
    }
}

/// Shorthand used across the crate.
pub type Result<T> = std::result::Result<T, CosimError>;

/// Attach a path to an I/O error.
pub(crate) fn io_err(path: impl Into<PathBuf>) -> impl FnOnce(std::io::Error) -> CosimError {
    let path = path.into();
    move |source| CosimError::Io { path, source }
}
