//! Small complete designs written in the DSL: each a plain Rust function
//! that takes its parameters and returns a finished [`crate::Module`].
//! They are emitted, linted, synthesized and simulated by the crate's tests.

mod counter;
mod datapath;
mod fifo;
mod skid;

pub use counter::counter;
pub use datapath::abs_diff_pipeline;
pub use fifo::{drop_fifo, fifo};
pub use skid::skid_buffer;
