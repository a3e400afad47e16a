//! golden: the bit-accurate reference model of hiermerge, and a library for
//! software that builds, stores, translates, merges and traces hierarchies.
//!
//! SPEC.md at the repository root is the specification these modules implement.

#![warn(missing_docs)]

pub mod build;
pub mod camera;
pub mod check;
pub mod frames;
pub mod geom;
pub mod grid;
pub mod input;
pub mod json;
pub mod layout;
pub mod merge;
pub mod mesh;
pub mod oracle;
pub mod output;
pub mod params;
pub mod saved;
pub mod scene;
pub mod scenes;
pub mod store;
pub mod study;
pub mod trace;
pub mod translate;
pub mod vectors;
pub mod world;

pub use grid::VoxelAddr;
pub use params::Params;
