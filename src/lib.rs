//! hiermerge as a library: the scene run of `hiermerge run` ([`run`]) and
//! the images it writes ([`image`]). The golden model, the RTL generators
//! and the co-simulation harness are the workspace's crates `golden`,
//! `rtl_gen` and `cosim`; this crate puts them together.

pub mod image;
pub mod run;
