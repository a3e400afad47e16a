//! The main job as a library (SPEC.md section 12): a scene run frame by
//! frame, what `hiermerge run` does, callable from Rust.
//!
//! Per frame: bring the world to the frame (`golden::frames::Frames::step`:
//! static hierarchies reused, dynamic ones rebuilt or re-translated, the
//! merge redone only when an input changed), check the merged hierarchy,
//! run the translation unit's and the merging module's RTL on what changed,
//! and the hierarchy merger top on every merge redone (fetchers, merging
//! module, upper builder, record writer on the store's real contents,
//! through one shared store read port by default: `Options::merger_store`), its
//! written records compared bit for bit with the merged hierarchy), when
//! the scene uses them and `Options::rtl` asks for RTL, trace the ray
//! kinds the scene asks for through the merged hierarchy, compare node tests
//! per ray with the separate hierarchies and a full rebuild on a subsample,
//! and write the image and the heat map. A frame where nothing changed
//! reuses the last frame's results and says so.
//!
//! ```no_run
//! use hiermerge::run::{preflight, run, MergerStore, Options, RunEngine};
//! use golden::scene::Scene;
//!
//! let scene = Scene::load("scenes/default.json".as_ref())?;
//! preflight::check(&scene, "scenes/default.json")?;
//! let out = std::path::PathBuf::from("out/lib-run");
//! std::fs::create_dir_all(&out)?;
//! let options = Options {
//!     out: out.clone(),
//!     write_to: out,
//!     rtl: false, // golden model only; true builds the units with `engine`
//!     engine: RunEngine::Verilator,
//!     progress: false,
//!     narrate: false,
//!     verify: true,
//!     images: true,
//!     merger_store: MergerStore::default(), // one shared store read port
//! };
//! let report = run(&scene, &options)?;
//! assert_eq!(report.mismatches, 0);
//! println!("{}", hiermerge::run::closing_table(&report));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod compare;
mod engine;
mod merge_rtl;
mod merger_rtl;
mod merges;
mod pipeline;
pub mod preflight;
mod render;
mod rtl;
mod table;

pub use compare::{Comparison, SUBSAMPLE};
pub use engine::RunEngine;
pub use merge_rtl::MergeRtlFrame;
pub use merger_rtl::{
    FrameMerge, FrameRun, MergerGroup, MergerRtlFrame, MergerStore, PATCH_FROM_VAR, PATCH_TO_VAR,
};
pub use merges::GroupOut;
pub use pipeline::{
    run, EffectsInfo, FrameOut, ImageSummary, ObjectInfo, Options, RtlInfo, Run, RunReport,
    StageSeconds,
};
pub use render::RayCounts;
pub use rtl::RtlFrame;
pub use table::closing_table;
