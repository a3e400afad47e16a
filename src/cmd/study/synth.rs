//! Area and clock from synthesis (SPEC 13.4). `hiermerge synth` (SPEC 14,
//! `cosim::synth`) measures them, but the study does not yet read its
//! cache: every lookup answers `None`, and the study prints "not measured"
//! for area, Fmax and ns per merge, never a guess. (The study must only
//! read cached figures: one synthesis of a merger top takes 18-60 minutes
//! per Yosys step on this project's 2-core machines.)

use rtl_gen::merge::MergerConfig;
use serde::Serialize;

/// What synthesis measured for one unit configuration.
#[derive(Serialize, Clone, Debug, PartialEq)]
pub struct SynthFigures {
    /// Area of the hierarchy merger top (cells, or um^2 of the flow named).
    pub area: f64,
    /// What `area` counts.
    pub area_unit: String,
    /// Highest clock frequency, MHz.
    pub fmax_mhz: f64,
    /// The flow that measured it (tool, target).
    pub flow: String,
}

/// The one lookup of synthesis figures: the cached `hiermerge synth`
/// result for the hierarchy merger `unit` (the configuration whose cycles
/// the study measures, `rtl::merger_config`), or `None` when nothing
/// measured it. Not wired to `cosim::synth`'s cache yet: always `None`.
pub fn synth_figures(_unit: &MergerConfig) -> Option<SynthFigures> {
    None
}

/// Nanoseconds per merge, cycles / Fmax, when both are measured.
pub fn ns_per_merge(cycles_per_merge: Option<f64>, s: Option<&SynthFigures>) -> Option<f64> {
    Some(cycles_per_merge? * 1e3 / s?.fmax_mhz)
}
