//! Complete testbenches of hiermerge's generated units, over any
//! [`crate::Engine`], returning what they measured or the first mismatch
//! (never panicking). One module per unit, named as its golden model
//! (`golden::merge::<unit>`) and its generator (`rtl_gen::merge`): the
//! translation unit ([`translate`]), the merging module's S614 stage
//! ([`merge_level`]), the merging module as one unit ([`merge_module`]),
//! the hierarchy merger top ([`merger`], with its store front end
//! [`merger::store_port`]) and the hierarchy unit ([`hierarchy_unit`]); the
//! multi-stream ones run in chunks of a long run ([`chunked`]).
//! `hiermerge cosim` runs them. The fetcher ([`fetcher`], with its root
//! sorter [`fetcher::root_sorter`]), the upper builder ([`upper_builder`],
//! one level [`upper_builder::level`]) and the record writer
//! ([`record_writer`]) are run by the integration tests.

pub mod chunked;
pub mod fetcher;
pub mod hierarchy_unit;
pub mod merge_level;
pub mod merge_module;
pub mod merger;
pub mod multi_stream;
pub mod record_writer;
pub mod translate;
pub mod upper_builder;

use crate::engine::Engine;
use crate::error::Result;
use crate::tb::{run_stream_bench, BenchConfig, BenchReport, StreamNames, Vector};

/// Makes an engine for one run; `true` asks for one that can trace (a VCD).
pub type EngineFactory<'a> = dyn FnMut(bool) -> Result<Box<dyn Engine>> + 'a;

/// Progress callback: (transactions whose outputs all arrived, cycle).
pub type ProgressFn<'a> = dyn FnMut(u64, u64) + 'a;

/// The stall pattern a driver or monitor uses, checked as they check it
/// ([`crate::tb::Stalls::check`]), so that a command refuses a bad value
/// before it builds anything.
pub fn check_stalls(stalls: crate::tb::Stalls) -> std::result::Result<crate::tb::Stalls, String> {
    stalls.check().map(|_| stalls)
}

/// Where one run of a single-stream unit goes (the root sorter, one upper
/// level, the S614 stage: one `data` stream in, one out).
pub enum StreamSim<'a> {
    /// An engine stepped from Rust (the IR simulator, Verilator, Icarus's
    /// pipe engine).
    Stepped(&'a mut dyn Engine),
    /// Icarus's batch ([`crate::icarus::IcarusBatch`]), built once for the
    /// unit and reused by every run.
    Batch(&'a crate::icarus::IcarusBatch),
}

/// One run of `vectors` on `sim` with the stalls of `config`: every output
/// compared bit for bit with its vector's, in order. The report says
/// whether it passed; an `Err` is a bench that could not run.
pub fn run_vectors(
    sim: StreamSim,
    vectors: &[Vector],
    config: &BenchConfig,
) -> Result<BenchReport> {
    match sim {
        StreamSim::Stepped(e) => {
            run_stream_bench(e, &StreamNames::single("data"), vectors, None, config, None)
        }
        StreamSim::Batch(b) => b.run_stream(vectors, None, config),
    }
}
