//! The hierarchy merger with one shared store port (`StorePort::Shared`,
//! SPEC.md 8.15 "The shared store port"): every output stream (`report`,
//! `nodes`, `refs`, `header`) bit for bit against golden while a store
//! model answers `store_req` from the store's contents
//! (`cosim::units::merger::run`), every read one golden's units make and as
//! many per merge; on the IR simulator, Verilator and Icarus under random
//! stalls, on Verilator under bursty stalls with a slow store; a flipped
//! expected beat is caught; the per-unit configuration keeps its module
//! name; the shared top lints clean.
mod merge_common;

use cosim::tb::Stalls;
use cosim::units::merger::{self, MergerEngine, Merges, ModuleRunConfig, RunConfig};
use golden::merge::merge_module::MergeDesign;
use golden::merge::merger::store_port::StorePort;
use golden::merge::merger::MergerSizes;
use golden::merge::MergeMode;
use golden::params::Params;
use merge_common::*;
use rtl_gen::merge::MergerConfig;

/// D = 8, Q = 0, k = 3 (the merger tests' `q0`) with a shared port of
/// `2^tag_bits` reads in flight: small enough for Icarus stepped from Rust.
fn q0(tag_bits: u32) -> MergerConfig {
    let params = Params::new(8, 0, 12, 3).unwrap();
    MergerConfig {
        sizes: MergerSizes {
            capacity_bits: 7,
            leaf_bits: 6,
            store_port: StorePort::Shared { tag_bits },
            ..MergerSizes::new(&params)
        },
        design: MergeDesign {
            params,
            inputs: 3,
            mode: MergeMode::Proportion { num: 1, den: 1 },
            roots: 16,
        },
    }
}

fn run(
    c: &MergerConfig,
    engine: MergerEngine,
    count: usize,
    stall: Stalls,
    latency: u64,
    flip: Option<usize>,
) -> merger::Outcome {
    let dir = tempfile::tempdir().unwrap();
    let config = RunConfig {
        bench: ModuleRunConfig {
            seed: 11,
            stall,
            ..ModuleRunConfig::default()
        },
        count,
        merges: Merges::Random,
        flip_expected: flip,
        store_latency: latency,
    };
    merger::run(c, engine, &config, dir.path(), &mut |_, _| {}).expect("the bench runs")
}

#[test]
fn shared_port_merger_matches_golden_on_three_engines() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    let c = q0(2);
    for (engine, count) in [
        (MergerEngine::Ir, 6),
        (MergerEngine::Verilator, 40),
        (MergerEngine::Iverilog, 4),
    ] {
        let t = std::time::Instant::now();
        let o = run(&c, engine, count, Stalls::Coin(0.3), 3, None);
        let st = o.store.as_ref().expect("a shared port's store outcome");
        eprintln!(
            "{engine:?}: {count} merges, {} cycles, {} reads, {:.1?}",
            o.totals.cycles,
            st.stats.reads,
            t.elapsed()
        );
        assert!(o.passed(), "{engine:?}: {:?}\n{:?}", o.totals, st.failure);
        assert_eq!(o.totals.merges, count);
        assert!(st.stats.reads > 0 && st.stats.reads == st.expected_reads);
        assert!(o.totals.beats_out > count as u64, "{:?}", o.totals);
    }
    let o = run(
        &c,
        MergerEngine::Verilator,
        40,
        Stalls::Bursty { stall: 8, go: 8 },
        7,
        None,
    );
    assert!(o.passed(), "bursty: {:?}", o.totals);
}

#[test]
fn shared_port_bench_catches_a_wrong_expected_beat() {
    let o = run(&q0(2), MergerEngine::Ir, 6, Stalls::None, 1, Some(4));
    assert!(!o.passed());
    let m = o.totals.first_mismatch.as_ref().expect("the flipped beat");
    assert_eq!((m.stream.as_str(), m.merge), ("header", 4), "{m:?}");
}

/// The fetchers reading under the other merge's slot (their reads then
/// for no merge in flight, or counted to the older merge) fail the run:
/// the store model attributes every read by its slot.
#[test]
fn shared_port_bench_catches_a_read_of_the_wrong_merge() {
    if !tools_present(&["iverilog"]) {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let config = RunConfig {
        bench: ModuleRunConfig {
            seed: 11,
            stall: Stalls::None,
            verilog_patch: Some(merger::VerilogPatch {
                from: "assign fetch_slot = ~slot_next;".into(),
                to: "assign fetch_slot = slot_next;".into(),
            }),
            ..ModuleRunConfig::default()
        },
        count: 4,
        merges: Merges::Random,
        flip_expected: None,
        store_latency: 1,
    };
    let o = merger::run(
        &q0(2),
        MergerEngine::Iverilog,
        &config,
        dir.path(),
        &mut |_, _| {},
    )
    .expect("the bench runs");
    let st = o.store.as_ref().expect("a shared port's store outcome");
    assert!(!o.passed(), "{:?}", o.totals);
    let why = st.failure.as_ref().expect("the store's reads fail");
    assert!(why.contains("no merge in flight"), "{why}");
}

#[test]
fn per_unit_keeps_its_name_and_the_shared_top_lints_clean() {
    let per_unit = MergerConfig {
        sizes: MergerSizes {
            store_port: StorePort::PerUnit,
            ..q0(2).sizes
        },
        ..q0(2)
    };
    let name = rtl_gen::merge::hierarchy_merger_name(&per_unit);
    assert!(name.ends_with("_l6"), "{name}");
    assert_eq!(
        rtl_gen::merge::hierarchy_merger_name(&q0(3)),
        format!("{name}_sp3")
    );
    let bad = rtl_gen::merge::hierarchy_merger_unit(&q0(9))
        .err()
        .expect("refused");
    assert!(bad.contains("tag_bits = 9"), "{bad}");
    if !tools_present(&["verilator"]) {
        return;
    }
    let m = rtl_gen::merge::hierarchy_merger_unit(&q0(3)).expect("a valid merger");
    assert!(m.validate_design().expect("valid").is_empty());
    let ports: Vec<String> = m.ports().iter().map(|p| p.name.clone()).collect();
    assert!(ports.iter().any(|p| p == "store_req_valid"));
    assert!(!ports
        .iter()
        .any(|p| p.starts_with("f0_") || p.starts_with("w_ref")));
    let dir = tempfile::tempdir().unwrap();
    lint_only(&design_of(&m, dir.path()));
}
