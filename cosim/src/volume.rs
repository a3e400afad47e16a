//! The regression volume: how many transactions a co-simulation test runs.
//!
//! Volume pays on the fast engine and depth on the others: CI runs every
//! configuration, mode and hard case, with the long random Verilator runs
//! cut to a tenth (never below 2,000 transactions, so the rare cases a run
//! must meet still come up); `HIERMERGE_VOLUME=full` (`scripts/regress`)
//! runs them as written.
//! A test wraps only its volume counts in [`volume`], never its hard cases.

/// The environment variable that selects the volume: `full`, or `ci`
/// (the default, also for any other value but an empty one).
pub const VOLUME_VAR: &str = "HIERMERGE_VOLUME";

/// What CI runs of a volume count: one in this many...
pub const CI_FRACTION: usize = 10;

/// ...but never fewer than this many (or the full count, when smaller).
pub const CI_FLOOR: usize = 2_000;

/// True when `HIERMERGE_VOLUME=full`.
pub fn full_volume() -> bool {
    std::env::var(VOLUME_VAR).is_ok_and(|v| v == "full")
}

/// `full` transactions at full volume; in CI a tenth of them (rounded up),
/// at least [`CI_FLOOR`] or `full` when that is smaller.
pub fn volume(full: usize) -> usize {
    if full_volume() {
        full
    } else {
        full.div_ceil(CI_FRACTION).max(full.min(CI_FLOOR))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ci_runs_a_tenth_rounded_up() {
        // The variable is not set in the test environment unless asked for.
        if full_volume() {
            assert_eq!(volume(100_000), 100_000);
        } else {
            assert_eq!(volume(100_000), 10_000);
            assert_eq!(volume(5_000), 2_000);
            assert_eq!(volume(500), 500);
        }
    }
}
