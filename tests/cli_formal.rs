//! `hiermerge formal` (SPEC 11.1): every proof of the default set passes,
//! split over a few tests so nextest runs them side by side, the larger
//! units' handshake proofs and every check of the small fetchers and writer;
//! a skid buffer that drops a beat, a FIFO that reads at its tail, a
//! priority merge whose grant is not held, a merging module whose refusal
//! ends without `done`, a fetcher whose phase is not reset, one that takes
//! a command while busy, one whose `End`s never leave, a writer that takes
//! every `cfg` and a merger top idle while a merge runs (the emitted
//! Verilog patched through `HIERMERGE_FORMAL_PATCH_FROM`/`_TO`) fail the
//! check that should catch them, naming the property and the step; the
//! record writer is not determined without each part of the upper
//! builder's contract. Under CI=true missing formal tools fail.

mod common;

use std::process::Output;

use serde_json::Value;

const PATCH_FROM: &str = "HIERMERGE_FORMAL_PATCH_FROM";
const PATCH_TO: &str = "HIERMERGE_FORMAL_PATCH_TO";

/// True when scripts/setup's formal tools are there; under CI=true their
/// absence fails the test.
fn tools_present() -> bool {
    match cosim::formal::formal_tools() {
        Ok(_) => true,
        Err(e) if cosim::tools::ci_mode() => {
            panic!("CI=true and the formal tools are missing: {e}")
        }
        Err(e) => {
            eprintln!("SKIPPING: {e}");
            false
        }
    }
}

/// `hiermerge formal --json` on `units` (and `extra` arguments), with
/// `env`, its files in `out`.
fn formal(
    out: &tempfile::TempDir,
    units: &[&str],
    extra: &[&str],
    env: &[(&str, &str)],
) -> (Output, Value) {
    let mut args = vec!["formal", "--json", "--out", out.path().to_str().unwrap()];
    for u in units {
        args.extend(["--unit", u]);
    }
    args.extend(extra);
    let o = common::hiermerge(&args, env);
    let r = common::json_of(&o);
    eprintln!("{r}");
    (o, r)
}

/// Every check of `units` (those of `extra` arguments such as `--check`)
/// proven, each in the mode and to the depth its proof states, and nothing
/// else in the report.
fn assert_all_proven(units: &[&str], extra: &[&str], expected: &[(&str, &str, &str, u64)]) {
    if !tools_present() {
        return;
    }
    let out = tempfile::tempdir().unwrap();
    let (o, r) = formal(&out, units, extra, &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let results = r["results"].as_array().unwrap();
    assert_eq!(results.len(), expected.len(), "{r}");
    for (got, (unit, check, mode, depth)) in results.iter().zip(expected) {
        assert_eq!(got["unit"], *unit, "{got}");
        assert_eq!(got["check"], *check, "{got}");
        assert_eq!(got["status"], "PASS", "{got}");
        assert_eq!(got["mode"], *mode, "{got}");
        assert_eq!(got["depth"], *depth, "{got}");
        assert!(got["failed"].as_array().unwrap().is_empty(), "{got}");
        assert!(got["seconds"].as_f64().unwrap() > 0.0, "{got}");
    }
    assert_eq!(r["failed"], 0, "{r}");
}

const K: &str = "k-induction";

#[test]
fn the_stream_primitives_are_proven() {
    assert_all_proven(
        &[
            "pipeline_reg",
            "skid_buffer",
            "fifo",
            "drop_fifo",
            "merge_priority",
        ],
        &[],
        &[
            ("pipeline_reg", "handshake", K, 6),
            ("pipeline_reg", "flow", K, 6),
            ("pipeline_reg", "determined", K, 6),
            ("skid_buffer", "handshake", K, 8),
            ("skid_buffer", "flow", K, 8),
            ("skid_buffer", "determined", K, 8),
            ("fifo", "handshake", K, 10),
            ("fifo", "flow", "bmc", 10),
            ("fifo", "determined", "bmc", 10),
            ("drop_fifo", "handshake", K, 10),
            ("drop_fifo", "flow", "bmc", 10),
            ("drop_fifo", "determined", "bmc", 10),
            ("merge_priority", "handshake", K, 6),
            ("merge_priority", "flow", K, 6),
            ("merge_priority", "determined", K, 6),
        ],
    );
}

#[test]
fn the_merge_stages_are_proven() {
    assert_all_proven(
        &[
            "overlap_counter",
            "merge_level",
            "upper_level",
            "per_node_decider",
        ],
        &[],
        &[
            ("overlap_counter", "handshake", K, 4),
            ("overlap_counter", "flow", K, 4),
            ("overlap_counter", "determined", K, 4),
            ("merge_level", "handshake", K, 6),
            ("merge_level", "flow", "bmc", 12),
            ("merge_level", "determined", K, 6),
            ("upper_level", "handshake", K, 6),
            ("upper_level", "determined", K, 6),
            ("per_node_decider", "handshake", K, 4),
            ("per_node_decider", "determined", K, 4),
        ],
    );
}

#[test]
fn the_merge_network_is_proven() {
    assert_all_proven(
        &["morton_merge"],
        &[],
        &[
            ("morton_merge", "handshake", K, 4),
            ("morton_merge", "determined", K, 4),
        ],
    );
}

#[test]
fn the_translation_unit_is_proven() {
    assert_all_proven(
        &["translate"],
        &[],
        &[
            ("translate", "handshake", K, 4),
            ("translate", "flow", "bmc", 12),
            ("translate", "determined", "bmc", 4),
            ("translate", "status", "bmc", 12),
        ],
    );
}

#[test]
fn the_larger_units_hold_their_handshakes() {
    // Their other checks (`formal --large`, README) take minutes: CI runs
    // the handshake proofs only.
    assert_all_proven(
        &[
            "per_node_network",
            "merge_module_overlap",
            "merge_module_per_node",
            "upper_builder",
            "fetcher",
            "hierarchy_merger",
            "store_port",
        ],
        &["--check", "handshake"],
        &[
            ("per_node_network", "handshake", K, 4),
            ("merge_module_overlap", "handshake", K, 4),
            ("merge_module_per_node", "handshake", K, 4),
            ("upper_builder", "handshake", K, 4),
            ("fetcher", "handshake", K, 4),
            ("hierarchy_merger", "handshake", K, 4),
            ("store_port", "handshake", "bmc", 14),
        ],
    );
}

// Flow, determined and status at the small configurations (SPEC 11.1):
// each check takes seconds, so CI runs them all, one test per unit so that
// nextest runs them side by side.

#[test]
fn the_small_fetcher_is_proven() {
    assert_all_proven(
        &["fetcher_small"],
        &[],
        &[
            ("fetcher_small", "handshake", K, 4),
            ("fetcher_small", "flow", "bmc", 16),
            ("fetcher_small", "determined", "bmc", 12),
            ("fetcher_small", "status", "bmc", 16),
        ],
    );
}

#[test]
fn the_small_per_node_fetcher_is_proven() {
    assert_all_proven(
        &["fetcher_per_node_small"],
        &[],
        &[
            ("fetcher_per_node_small", "handshake", K, 4),
            ("fetcher_per_node_small", "flow", "bmc", 16),
            ("fetcher_per_node_small", "determined", "bmc", 12),
            ("fetcher_per_node_small", "status", "bmc", 16),
        ],
    );
}

#[test]
fn the_small_record_writer_is_proven() {
    assert_all_proven(
        &["record_writer_small"],
        &[],
        &[
            ("record_writer_small", "handshake", K, 4),
            ("record_writer_small", "flow", "bmc", 16),
            ("record_writer_small", "determined", "bmc", 8),
            ("record_writer_small", "status", "bmc", 16),
        ],
    );
}

/// `unit`'s `check` with the emitted line `assign <port> = ...;` replaced
/// by `to`: it must fail from reset (a counterexample at a step), naming
/// only properties or invariants whose label contains `part`.
fn assert_broken_fails(unit: &str, line: &str, to: &str, check: &str, part: &str) {
    if !tools_present() {
        return;
    }
    let out = tempfile::tempdir().unwrap();
    let (o, r) = formal(
        &out,
        &[unit],
        &["--check", check],
        &[(PATCH_FROM, line), (PATCH_TO, to)],
    );
    assert!(!o.status.success(), "a broken {unit} passed: {r}");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("1 of 1 checks not proven"), "{err}");
    let res = &r["results"][0];
    assert_eq!(res["check"], check, "{res}");
    assert_eq!(res["status"], "FAIL", "{res}");
    let failed: Vec<&str> = res["failed"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f.as_str().unwrap())
        .collect();
    assert!(
        !failed.is_empty() && failed.iter().all(|f| f.contains(part)),
        "{res}"
    );
    assert!(
        res["step"].as_u64().is_some(),
        "a counterexample from reset: {res}"
    );
    assert!(
        std::path::Path::new(res["log"].as_str().unwrap()).is_file(),
        "{res}"
    );
}

#[test]
fn a_skid_buffer_that_drops_a_beat_fails_its_flow_proof() {
    // Ready while the spare register is full: the beat taken then is lost.
    let (line, _) =
        common::emitted_assign(&rtl_gen::formal::units::skid_buffer(8).module, "in_ready");
    assert_broken_fails(
        "skid_buffer",
        &line,
        "assign in_ready = 1'b1;",
        "flow",
        "_f0_",
    );
}

#[test]
fn a_fifo_that_reads_at_its_tail_fails_its_flow_proof() {
    // The word offered is the one at the write address, not the oldest.
    let (line, _) =
        common::emitted_assign(&rtl_gen::formal::units::fifo(8, 2).module, "mem_out_data");
    assert_broken_fails(
        "fifo",
        &line,
        "assign mem_out_data = mem[mem_tail];",
        "flow",
        "_f0_",
    );
}

#[test]
fn a_drop_fifo_that_keeps_a_push_while_full_fails_its_proof() {
    // Every push kept: one while full overwrites the oldest word and moves
    // the write pointer a lap ahead of the read pointer. The handshake
    // check's producer is free to push while full.
    let (line, _) =
        common::emitted_assign(&rtl_gen::formal::units::drop_fifo(8, 2).module, "q_wr_put");
    assert_broken_fails(
        "drop_fifo",
        &line,
        "assign q_wr_put = in_valid;",
        "handshake",
        "within_depth",
    );
}

#[test]
fn a_priority_merge_that_drops_its_grant_under_a_stall_fails_its_handshake_proof() {
    // The grant recomputed every cycle (no hold): a higher-priority input
    // arriving under a stall changes the beat offered.
    let module = rtl_gen::formal::units::merge_priority(8, 3).module;
    let (line, rhs) = common::emitted_assign(&module, "arb_grant");
    let free = rhs.rsplit(" : ").next().unwrap();
    assert_broken_fails(
        "merge_priority",
        &line,
        &format!("assign arb_grant = {free};"),
        "handshake",
        "p_out_data_held",
    );
}

#[test]
fn a_merging_module_whose_refusal_ends_without_done_fails_its_status_proof() {
    // `done` pulses after a merge's End only: a refused merge leaves idle
    // high again with no pulse.
    let module = rtl_gen::formal::units::merge_module_overlap().module;
    let line = common::emitted_line(&module, "done_pulse <= merge_done | ");
    assert_broken_fails(
        "merge_module_overlap",
        &line,
        "done_pulse <= merge_done;",
        "status",
        "p_done_pulse",
    );
}

#[test]
fn bad_arguments_and_a_patch_that_does_not_match_once_are_refused() {
    let o = common::hiermerge(&["formal", "--unit", "no_such_unit"], &[]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("--unit no_such_unit: expected one of pipeline_reg"),
        "{err}"
    );
    let o = common::hiermerge(&["formal", "--check", "liveness"], &[]);
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("--check liveness: expected one of handshake")
    );
    if !tools_present() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let o = common::hiermerge(
        &[
            "formal",
            "--unit",
            "skid_buffer",
            "--out",
            dir.path().to_str().unwrap(),
        ],
        &[(PATCH_FROM, "no such text"), (PATCH_TO, "x")],
    );
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("occurs 0 times"), "{err}");
}

#[test]
fn a_fetcher_whose_phase_is_not_reset_fails_its_determined_proof() {
    // The phase register left out of reset: `idle` and the `cfg`/`cmd`
    // handshakes read a value set before reset.
    let module = rtl_gen::formal::units::fetcher_small().module;
    let line = common::emitted_line(&module, "phase <= 3'd0;");
    assert_broken_fails(
        "fetcher_small",
        &line,
        "phase <= phase;",
        "determined",
        "_determined",
    );
}

#[test]
fn a_fetcher_that_takes_a_command_while_busy_fails_its_status_proof() {
    // `cmd` ready whenever an input is loaded, not only while idle or
    // reading the next command's roots (PREFETCH).
    let module = rtl_gen::formal::units::fetcher_small().module;
    let (line, _) = common::emitted_assign(&module, "cmd_ready");
    assert_broken_fails(
        "fetcher_small",
        &line,
        "assign cmd_ready = cfg_have;",
        "status",
        "p_cmd_only_when_idle",
    );
}

#[test]
fn a_fetcher_that_loses_its_level_ends_fails_its_flow_proof() {
    // Every token beat sent with kind 0: the command's `End`s never leave.
    let module = rtl_gen::formal::units::fetcher_small().module;
    let (line, rhs) = common::emitted_assign(&module, "out_core_data");
    let kind = rtl_gen::formal::units::small_fetch_out_kind();
    let w = common::port_width(&module, "out_data");
    let mask = ((1u128 << kind.width) - 1) << kind.offset;
    assert_broken_fails(
        "fetcher_small",
        &line,
        &format!("assign out_core_data = ({rhs}) & ~{w}'h{mask:x};"),
        "flow",
        "p_command_ends_",
    );
}

#[test]
fn a_writer_that_takes_every_cfg_fails_its_flow_proof() {
    // `cfg` always ready: merges asked without a header to answer them.
    let module = rtl_gen::formal::units::record_writer_small().module;
    let (line, _) = common::emitted_assign(&module, "cfg_ready");
    assert_broken_fails(
        "record_writer_small",
        &line,
        "assign cfg_ready = 1'b1;",
        "flow",
        "p_header_per_cfg_",
    );
}

#[test]
fn the_writer_is_not_determined_without_each_promise_of_the_builder() {
    // Each part of the upper builder's contract left out in turn: a merge
    // that breaks it makes the drain read a buffer word no beat wrote since
    // reset, and the two copies disagree on what they write.
    if !tools_present() {
        return;
    }
    let tools = cosim::formal::formal_tools().unwrap();
    let parts = [
        "_index_counts_nodes",
        "_records_count_records",
        "top_has_nodes",
        "_grouped_counts_",
        "crefs_are_created_counts",
    ];
    for a in &rtl_gen::formal::units::record_writer_small().assumptions {
        assert!(
            parts.iter().any(|p| a.label.contains(p)),
            "{} is in no part",
            a.label
        );
    }
    // Each counterexample ends by step 6: BMC 7 finds it in seconds (the
    // proof's depth, 8, spends most of its time in its last step).
    let depth = Some(7);
    for part in parts {
        let mut p = rtl_gen::formal::units::record_writer_small();
        let before = p.assumptions.len();
        p.assumptions.retain(|a| !a.label.contains(part));
        assert!(p.assumptions.len() < before, "{part}");
        let out = tempfile::tempdir().unwrap();
        let folder = cosim::formal::prepare(&p, out.path(), depth, 300, None).unwrap();
        let r = cosim::formal::run_check(
            &tools,
            "record_writer_small",
            &p,
            &folder,
            rtl_gen::formal::Check::Determined,
            depth,
            300,
        )
        .unwrap();
        eprintln!("without {part}: {r:?}");
        assert_eq!(r.status, "FAIL", "without {part}: {r:?}");
        assert!(
            !r.failed.is_empty() && r.failed.iter().all(|f| f.ends_with("_determined")),
            "without {part}: {r:?}"
        );
        assert!(r.step.is_some(), "a counterexample from reset: {r:?}");
    }
}

#[test]
fn a_merger_top_idle_while_a_merge_runs_fails_its_status_proof() {
    // `idle` without `!busy`: high while a merge is in flight.
    let module = rtl_gen::formal::units::hierarchy_merger_small().module;
    let (line, rhs) = common::emitted_assign(&module, "merger_idle");
    assert!(rhs.contains("busy_not"), "`!busy` in {rhs}");
    let without_busy = rhs.replacen("busy_not", "1'b1", 1);
    assert_broken_fails(
        "hierarchy_merger_small",
        &line,
        &format!("assign merger_idle = {without_busy};"),
        "status",
        "p_idle_means_empty",
    );
}

#[test]
fn a_hierarchy_unit_whose_table_is_always_settled_fails_its_status_proof() {
    // The translation unit's `idle` held high: a merge command may then be
    // taken while a determine command is still inside, and `idle` says
    // nothing is outstanding while one is.
    assert_broken_fails(
        "hierarchy_unit_small",
        "assign idle = idle_now;",
        "assign idle = 1'b1;",
        "status",
        "p_idle_means_empty",
    );
}
