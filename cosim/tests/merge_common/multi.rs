//! The multi-stream bench runs shared by the merging-module tests whose
//! units have several input and output streams (fetcher, record writer,
//! builder, per-node and merging module): one stall setting for every
//! stream, the report printed, a failed run a panic naming the run.

use cosim::tb::{BenchConfig, MultiReport, StreamBeats};
use cosim::units::multi_stream::{run_multi, MultiSim};

/// Every stream stalls with probability `stall`, drawn from `seed`.
pub fn stalled(seed: u64, stall: f64) -> BenchConfig {
    BenchConfig {
        seed,
        in_stall: cosim::tb::Stalls::Coin(stall),
        out_stall: cosim::tb::Stalls::Coin(stall),
        ..BenchConfig::default()
    }
}

/// One run of `ins` -> `outs` on `engine`, counting the cycles each of
/// `pulses` (1-bit outputs) is high; printed, and a panic when it fails.
pub fn multi_bench_watching(
    engine: &mut dyn cosim::Engine,
    ins: &[StreamBeats],
    outs: &[StreamBeats],
    seed: u64,
    stall: f64,
    what: &str,
    pulses: &[&str],
) -> (MultiReport, Vec<(String, u64)>) {
    let sim = MultiSim::Stepped(engine);
    let (r, counts) =
        run_multi(sim, ins, outs, &stalled(seed, stall), pulses).expect("the bench runs");
    check_passed(&r, stall, what);
    (r, counts)
}

/// `r` printed; a panic naming the run when it failed.
pub fn check_passed(r: &MultiReport, stall: f64, what: &str) {
    eprint!("{what}: stall {stall:.2}: {r}");
    assert!(r.passed(), "{what} stall {stall}:\n{r}");
}

/// One run of a merging module: as [`multi_bench_watching`], and its `done` output
/// pulses once per merge, i.e. once per beat of the first input (`cfg`).
pub fn multi_bench_done_per_merge(
    engine: &mut dyn cosim::Engine,
    ins: &[StreamBeats],
    outs: &[StreamBeats],
    seed: u64,
    stall: f64,
    what: &str,
) -> MultiReport {
    let (r, pulses) = multi_bench_watching(engine, ins, outs, seed, stall, what, &["done"]);
    assert_eq!(
        pulses[0].1,
        ins[0].beats.len() as u64,
        "{what}: one done pulse per merge"
    );
    r
}

/// The same run inside one Icarus `vvp` (`cosim::icarus::IcarusMultiBatch`):
/// every stream its own driver and back-pressure in the testbench.
pub fn multi_batch_bench(
    design: &cosim::Design,
    ins: &[StreamBeats],
    outs: &[StreamBeats],
    seed: u64,
    stall: f64,
    what: &str,
) -> MultiReport {
    let sim = MultiSim::Batch(design);
    let (r, _) = run_multi(sim, ins, outs, &stalled(seed, stall), &[]).expect("the batch runs");
    check_passed(&r, stall, what);
    r
}

/// Where a run goes: the stepped engine kept across a test's runs, or,
/// without one, Icarus's multi-stream batch of `design`.
pub fn sim_of<'a>(
    engine: &'a mut Option<Box<dyn cosim::Engine>>,
    design: &'a cosim::Design,
) -> MultiSim<'a> {
    match engine {
        Some(e) => MultiSim::Stepped(e.as_mut()),
        None => MultiSim::Batch(design),
    }
}
