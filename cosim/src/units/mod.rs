//! Complete testbenches of hiermerge's generated units, over any
//! [`crate::Engine`], returning what they measured or the first mismatch
//! (never panicking): the translation unit ([`translate`]) and the merging
//! module's S614 merge-level stage ([`merge`]). `hiermerge cosim` runs them.

pub mod chunked;
pub mod merge;
pub mod merge_module;
pub mod merger;
pub mod translate;

use crate::engine::Engine;
use crate::error::Result;

/// Makes an engine for one run; `true` asks for one that can trace (a VCD).
pub type EngineFactory<'a> = dyn FnMut(bool) -> Result<Box<dyn Engine>> + 'a;

/// Progress callback: (transactions whose outputs all arrived, cycle).
pub type ProgressFn<'a> = dyn FnMut(u64, u64) + 'a;

/// The stall probability a driver or monitor uses, checked: `0 <= p < 1`
/// (at 1 nothing would ever move).
pub fn check_stall(stall: f64) -> std::result::Result<f64, String> {
    if (0.0..1.0).contains(&stall) {
        Ok(stall)
    } else {
        Err(format!("stall probability {stall}: expected 0 <= P < 1"))
    }
}
