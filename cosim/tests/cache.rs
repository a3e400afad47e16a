//! The Verilator build cache: a hit is cheap and rebuilds nothing, keys follow
//! content (not timestamps), and two threads building the same design at
//! once leave one good entry.
mod common;

use cosim::cache::{builds_in_this_process, cache_report, clear_cache};
use cosim::verilator::{VerilatorEngine, VerilatorOptions};
use cosim::Engine;
use std::time::Instant;

fn count_to(e: &mut VerilatorEngine, n: u64) -> u64 {
    e.reset(1).unwrap();
    let en = e.port_id("en").unwrap();
    e.poke_u64(en, 1).unwrap();
    for _ in 0..n {
        e.step().unwrap();
    }
    e.peek_u64(e.port_id("count").unwrap()).unwrap()
}

#[test]
fn second_load_is_a_hit_and_builds_nothing() {
    if !common::tools_present(&["verilator", "g++"]) {
        return;
    }
    let design = common::counter();
    let options = VerilatorOptions::default();
    let mut first = VerilatorEngine::new(&design, &options).unwrap();
    assert_eq!(count_to(&mut first, 5), 5);
    let builds_before = builds_in_this_process();
    let t = Instant::now();
    let mut second = VerilatorEngine::new(&design, &options).unwrap();
    let hit = t.elapsed();
    println!(
        "cache hit: {hit:?} total (find {:?}, load {:?})",
        second.build_info().build_time,
        second.build_info().load_time
    );
    assert!(!second.build_info().built, "second load rebuilt the model");
    assert_eq!(
        builds_in_this_process(),
        builds_before,
        "a cache entry was built"
    );
    assert_eq!(second.build_info().cache_dir, first.build_info().cache_dir);
    // Two instances of one library are independent models.
    assert_eq!(count_to(&mut second, 7), 7);
    assert_eq!(first.peek_u64(first.port_id("count").unwrap()).unwrap(), 5);
}

#[test]
fn parallel_builds_into_a_fresh_cache_publish_one_entry_and_content_changes_the_key() {
    if !common::tools_present(&["verilator", "g++"]) {
        return;
    }
    let root = tempfile::tempdir().unwrap();
    let src_dir = tempfile::tempdir().unwrap();
    let src = src_dir.path().join("counter.v");
    std::fs::copy(common::fixture("counter.v"), &src).unwrap();
    let mut design = common::counter();
    design.verilog_files = vec![src.clone()];
    let options = VerilatorOptions {
        jobs: 1,
        ..VerilatorOptions::default()
    };
    let results: Vec<(bool, std::path::PathBuf, u64)> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..2)
            .map(|_| {
                s.spawn(|| {
                    let mut e =
                        VerilatorEngine::with_cache(&design, &options, root.path()).unwrap();
                    let info = e.build_info().clone();
                    (info.built, info.cache_dir, count_to(&mut e, 300))
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    assert_eq!(
        results.iter().filter(|r| r.0).count(),
        1,
        "exactly one thread built"
    );
    assert_eq!(results[0].1, results[1].1);
    assert!(results.iter().all(|r| r.2 == 300 % 256));
    let report = cache_report(root.path());
    println!("{report}");
    // One model entry and one runtime entry, nothing half-built left published.
    assert_eq!(report.entries.len(), 2, "{report}");

    // Same content, new timestamp: still a hit.
    let text = std::fs::read_to_string(&src).unwrap();
    std::fs::write(&src, &text).unwrap();
    let e = VerilatorEngine::with_cache(&design, &options, root.path()).unwrap();
    assert!(!e.build_info().built, "touching the file must not rebuild");
    drop(e);
    // Different content: a new entry.
    std::fs::write(&src, text.replace("8'd1", "8'd2")).unwrap();
    let mut e = VerilatorEngine::with_cache(&design, &options, root.path()).unwrap();
    assert!(e.build_info().built, "changed Verilog must rebuild");
    assert_eq!(count_to(&mut e, 10), 20, "the new build counts by 2");
    drop(e);
    assert_eq!(cache_report(root.path()).entries.len(), 3);
    clear_cache(root.path()).unwrap();
    assert_eq!(cache_report(root.path()).entries.len(), 0);
}
