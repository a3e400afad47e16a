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
    Design {
        /// What is inconsistent.
        what: String,
    },
    /// A port name was looked up that the design does not have.
    UnknownPort {
        /// The name looked up.
        name: String,
    },
    /// A port index out of range for the design.
    BadPortId {
        /// The index given.
        index: usize,
        /// The design's number of ports.
        count: usize,
    },
    /// A value does not fit the port it was poked into (never silently truncated).
    Width {
        /// The port.
        port: String,
        /// The port's width in bits.
        width: u32,
        /// Bits the value needs.
        value_bits: u32,
    },
    /// Poke on an output port.
    NotAnInput {
        /// The port.
        port: String,
    },
    /// A required external tool is missing or failed to start.
    ToolMissing {
        /// The tool (`verilator`, `iverilog`, `vvp`, `g++`, ...).
        tool: String,
        /// Why it is not usable, and how to install it.
        hint: String,
    },
    /// An external tool ran and failed; `log` holds its output.
    ToolFailed {
        /// The tool.
        tool: String,
        /// The command line it ran with.
        command: String,
        /// Its output (stdout and stderr).
        log: String,
    },
    /// The compiled model disagrees with the port description.
    PortMismatch {
        /// The port.
        port: String,
        /// How they disagree.
        what: String,
    },
    /// An I/O error with the path it concerns.
    Io {
        /// The file or folder.
        path: PathBuf,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// Loading the shared library or a symbol failed.
    Load {
        /// The shared library.
        path: PathBuf,
        /// What failed (the loader's message, or the missing symbol).
        what: String,
    },
    /// The simulator process broke the pipe protocol or exited.
    Protocol {
        /// What it sent or did instead.
        what: String,
    },
    /// A 4-state simulator produced X or Z on an output after reset.
    UnknownOutput {
        /// The output port.
        port: String,
        /// The cycle it was seen in.
        cycle: u64,
        /// The value as the simulator printed it (with `x`/`z` digits).
        value: String,
    },
    /// A text value could not be parsed as a bit vector.
    Parse {
        /// The text (or the file it came from).
        text: String,
        /// What was expected.
        what: String,
    },
    /// A bit vector could not be built, read or written (a value wider than
    /// its width, a bit range past it, text that is not hex).
    Bits(golden::bits::BitsError),
    /// The bench was asked for something the design cannot give it (a
    /// stall pattern for a stream it does not have).
    Bench {
        /// What was asked, and what the design has.
        what: String,
    },
    /// The feature asked for is not available in this engine or build.
    Unsupported {
        /// The feature.
        what: String,
    },
}

impl fmt::Display for CosimError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CosimError::Design { what } => write!(f, "design description: {what}"),
            CosimError::Bench { what } => write!(f, "bench: {what}"),
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
            CosimError::Bits(e) => write!(f, "{e}"),
            CosimError::Unsupported { what } => write!(f, "unsupported: {what}"),
        }
    }
}

impl std::error::Error for CosimError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            CosimError::Io { source, .. } => Some(source),
            CosimError::Bits(e) => Some(e),
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

impl From<golden::bits::BitsError> for CosimError {
    fn from(e: golden::bits::BitsError) -> CosimError {
        CosimError::Bits(e)
    }
}
