//! The merger's store front end (`rtl_gen::merge::store_port_unit`, SPEC.md
//! 8.15 "The shared store port") against `golden::merge::merger::store_port`: every
//! requester's answers bit for bit, in its order, on the IR simulator,
//! Verilator and Icarus, under random and bursty stalls on every stream and
//! on the store (which answers each read from its contents after a latency,
//! `cosim::units::merger::store_port::StoreModel`); one read per clock with no
//! back-pressure; lint and synthesis with no latch.
mod merge_common;

use cosim::tb::{BenchConfig, Stalls};
use cosim::units::merger::store_port::{random_transaction, run};
use cosim::units::multi_stream::ModuleEngine;
use golden::merge::merger::store_port::{StoreAddr, StoreArray};
use golden::params::Params;
use golden::translate::stimulus::SplitMix64;
use merge_common::*;
use rtl_gen::merge::StorePortConfig;

/// The default grid with the requesters of a 2-input merger (per fetcher
/// node, root reference, child reference; then the writer's reference).
fn config(tag_bits: u32) -> StorePortConfig {
    use StoreArray::{Node, Reference};
    StorePortConfig {
        params: Params::default(),
        arrays: vec![
            Node, Reference, Reference, Node, Reference, Reference, Reference,
        ],
        tag_bits,
    }
}

fn bench(seed: u64, stall: Stalls) -> BenchConfig {
    BenchConfig {
        seed,
        in_stall: stall,
        out_stall: stall,
        reproduce: Some("cargo nextest run -p cosim --test merge_store_port".into()),
        ..BenchConfig::default()
    }
}

#[test]
fn store_port_matches_golden_on_three_engines_under_stalls() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    let c = config(2);
    let stalls = [
        Stalls::None,
        Stalls::Coin(0.5),
        Stalls::Bursty { stall: 8, go: 8 },
    ];
    for engine in [
        ModuleEngine::Ir,
        ModuleEngine::Verilator,
        ModuleEngine::Iverilog,
    ] {
        for (s, stall) in stalls.iter().enumerate() {
            let mut rng = SplitMix64(40 + s as u64);
            let (store, tx) = random_transaction(&mut rng, &c, 64, 24).unwrap();
            // Latency 1 and 6: the tag FIFO (4) short of and beyond the
            // round trip.
            let latency = [1, 6][s % 2];
            let dir = tempfile::tempdir().unwrap();
            let out = run(
                &c,
                engine,
                &store,
                &tx,
                &bench(s as u64, *stall),
                latency,
                dir.path(),
            )
            .expect("the bench runs");
            let asked: u64 = tx.requests.iter().map(|r| r.len() as u64).sum();
            eprintln!(
                "store port {engine:?} {stall:?} latency {latency}: {} reads, {} cycles",
                out.store.reads, out.report.cycles
            );
            assert!(
                out.passed(),
                "{engine:?} {stall:?}:\n{}\n{:?}",
                out.report,
                out.store
            );
            assert_eq!(out.store.reads, asked, "{engine:?} {stall:?}: reads");
        }
    }
}

/// With no back-pressure anywhere and a tag FIFO deeper than the round trip,
/// the port reads once per clock while any requester has a read left.
#[test]
fn store_port_reads_once_per_clock_without_back_pressure() {
    let c = config(3);
    let mut rng = SplitMix64(7);
    let (store, _) = random_transaction(&mut rng, &c, 64, 2).unwrap();
    // Every requester the same number of reads, so all stay busy to the end.
    let reqs: Vec<Vec<StoreAddr>> = (0..c.arrays.len())
        .map(|_| {
            (0..40)
                .map(|_| StoreAddr {
                    hier: rng.next_u64() % 3,
                    index: rng.next_u64() % 64,
                })
                .collect()
        })
        .collect();
    let tx =
        golden::merge::merger::store_port::store_port_transaction(&c.arrays, reqs, &store).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = run(
        &c,
        ModuleEngine::Ir,
        &store,
        &tx,
        &bench(1, Stalls::None),
        2,
        dir.path(),
    )
    .expect("the bench runs");
    assert!(out.passed(), "{}", out.report);
    let rate = out.store.busy_rate();
    eprintln!(
        "store port: {} reads from cycle {} to {}: {rate:.3} reads per clock",
        out.store.reads, out.store.first_read, out.store.last_read
    );
    assert!(rate >= 0.99, "{rate}");
}

#[test]
fn store_port_lints_and_synthesizes_without_latches() {
    if !tools_present(&["verilator", "yosys"]) {
        return;
    }
    let small = StorePortConfig {
        params: Params::new(4, 0, 8, 2).unwrap(),
        ..config(2)
    };
    for c in [config(2), small] {
        let m = rtl_gen::merge::store_port_unit(&c).expect("a valid port");
        let w = m.validate_design().expect("valid");
        assert!(w.is_empty(), "{w:?}");
        let dir = tempfile::tempdir().unwrap();
        lint_and_synth(&design_of(&m, dir.path()));
    }
}

fn refused(c: &StorePortConfig) -> String {
    match rtl_gen::merge::store_port_unit(c) {
        Ok(m) => panic!("{} built", m.name()),
        Err(e) => e,
    }
}

#[test]
fn store_port_refuses_bad_configurations() {
    let one = StorePortConfig {
        arrays: vec![StoreArray::Node],
        ..config(2)
    };
    let e = refused(&one);
    assert!(e.contains("1 requesters"), "{e}");
    let refs_only = StorePortConfig {
        arrays: vec![StoreArray::Reference; 3],
        ..config(2)
    };
    let e = refused(&refs_only);
    assert!(e.contains("store_resp"), "{e}");
    let e = refused(&config(9));
    assert!(e.contains("tag_bits = 9"), "{e}");
}
