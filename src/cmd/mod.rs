//! One module per subcommand.

pub mod build;
pub mod common;
pub mod merge;
pub mod run;
pub mod trace;
