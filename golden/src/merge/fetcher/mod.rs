//! The fetcher (S610 + S612 in hardware, SPEC.md section 8.13): one input
//! hierarchy walked from the store and translated, producing the merging
//! module's per-input stream (8.10's `in<i>`, [`crate::merge::merge_module::input_stream`]'s
//! order) and the leaves above the walked level for the upper builder.
//!
//! The beat layouts of the fetcher's ports are in [`beats`]; its
//! transaction, in [`transaction`]: a store image of one input, its `cfg` beat and a list of
//! commands give the expected memory requests (node and reference read
//! ports), the responses the memory answers with, the `out` beats and the
//! `leaves` beats. Every value comes from golden's walk functions
//! ([`crate::merge::fetcher::walk::place_node`] validates and translates, [`crate::merge::fetcher::walk::children`]
//! checks reference ranges, [`crate::merge::merge_level::sort_stream`] orders the
//! roots); the model adds only the visiting order the hardware promises (a
//! breadth-first walk from the sorted roots, one read at a time), and the
//! tests check that on well-formed inputs its streams equal
//! [`crate::merge::fetcher::walk::walk_input`] + [`crate::merge::fetcher::walk::collect`] +
//! [`crate::merge::merge_module::input_stream`].

pub mod beats;
pub mod root_sorter;
pub mod transaction;
pub mod walk;

#[cfg(test)]
mod tests;

pub use beats::*;
pub use transaction::*;
