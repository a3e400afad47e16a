//! golden: the bit-accurate reference model of hiermerge, and a library for
//! software that builds, stores, translates, merges and traces hierarchies.
//!
//! SPEC.md at the repository root is the specification these modules
//! implement; `golden/README.md` and `golden/examples/` show the library's
//! use. The main entry points: [`build::build`] (a mesh into a hierarchy),
//! [`check::check_built`] (the checker), [`trace::TraceScene`] and
//! [`trace::TraceContext`] (closest hits and shadow rays),
//! [`world::World`] (placing and merging), [`saved`] (hierarchies in files).
//!
//! ```
//! use glam::Vec3;
//! use golden::build::{build, GridMap};
//! use golden::check::check_built;
//! use golden::geom::Ray;
//! use golden::scenes::sphere;
//! use golden::trace::{Instance, TraceContext, TraceScene, TraceStats};
//! use golden::Params;
//!
//! // A mesh (here generated; `golden::mesh::Mesh::load` reads OBJ and PLY).
//! let mesh = sphere(Vec3::ZERO, 1.0, 16, 32);
//! // D = 16 levels, Q = 8 bits per box bound, 24-bit indices, 4-bit ids.
//! let params = Params::new(16, 8, 24, 4).unwrap();
//! let (lo, hi) = mesh.bounds();
//! let grid = GridMap::fit(lo, hi, &params);
//! let hierarchy = build(&mesh, &grid, &params, 0).unwrap();
//! let report = check_built(&hierarchy, &grid.mesh_to_grid(&mesh, &params).unwrap()).unwrap();
//! assert_eq!(report.nodes, hierarchy.nodes.len());
//!
//! let scene = TraceScene::new(grid, &[Instance::new(&hierarchy, &mesh)]).unwrap();
//! let mut ctx = TraceContext::new();
//! let mut stats = TraceStats::default();
//! let ray = Ray::unbounded(Vec3::new(0.0, 0.0, -3.0), Vec3::Z);
//! let hit = ctx.closest_hit(&ray, &scene, &mut stats).unwrap();
//! assert!((hit.t - 2.0).abs() < 0.01);
//! assert!(stats.node_tests > 0);
//! ```

#![warn(missing_docs)]

pub mod bits;
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
pub mod seed;
pub mod store;
pub mod study;
pub mod trace;
pub mod translate;
pub mod vectors;
pub mod world;

pub use grid::VoxelAddr;
pub use params::Params;
