//! `hiermerge cosim --unit merger` against a deliberately broken hierarchy
//! merger (a small one: D = 8, Q = 0, I = 12, H = 3, k = 2, writer buffers
//! of 4, leaf FIFOs of 8, so the builds stay short): the emitted Verilog
//! patched through the test hook (`HIERMERGE_COSIM_PATCH_FROM` / `_TO`).
//! A flipped bit of every `nodes` beat is caught on Verilator and Icarus at
//! the same cycle, decoded with `NodeLayout`'s fields (only `leaf` differs),
//! with a VCD that exists; a `cfg` never accepted hangs, caught with its
//! VCD; a flipped expectation (`HIERMERGE_COSIM_FLIP_EXPECTED`: the
//! `header` beat of one merge) is caught with the header's fields decoded.
//! Under CI=true a missing Verilator or Icarus fails.

mod common;

use std::path::Path;
use std::process::Output;

use common::{
    assert_fails, assert_one_field_differs, assert_vcd, emitted_assign, field_names, hiermerge,
    json_of, tool_present, FLIP, PATCH_FROM, PATCH_TO,
};
use golden::layout::NodeLayout;
use golden::merge::merge_module::MergeDesign;
use golden::params::Params;
use rtl_gen::merge::MergerConfig;
use serde_json::Value;

/// Merges per run: few, the failures come in the first.
const MERGES: &str = "6";

/// The small merger's CLI flags and its configuration (the same one).
const SMALL: [&str; 14] = [
    "--max-lod",
    "8",
    "--quant-bits",
    "0",
    "--index-bits",
    "12",
    "--hier-bits",
    "3",
    "--inputs",
    "2",
    "--capacity-bits",
    "2",
    "--leaf-bits",
    "3",
];

fn small() -> MergerConfig {
    let d = MergeDesign {
        params: Params::new(8, 0, 12, 3).unwrap(),
        inputs: 2,
        ..MergeDesign::default()
    };
    let mut c = MergerConfig::new(d);
    c.sizes.capacity_bits = 2;
    c.sizes.leaf_bits = 3;
    c
}

/// The small merger's emitted line `assign <port> = <rhs>;`.
fn merger_assign(port: &str) -> (String, String) {
    let module = rtl_gen::merge::hierarchy_merger_unit(&small()).unwrap();
    emitted_assign(&module, port)
}

/// `hiermerge cosim --unit merger --json` on the small merger (seed 7,
/// stall 0.3) on `engine` with `env` set, VCDs into `vcd_dir`; its JSON.
fn run_merger(engine: &str, env: &[(&str, &str)], vcd_dir: &Path) -> (Output, Value) {
    let vcd = vcd_dir.to_str().unwrap();
    let mut args = vec![
        "cosim", "--unit", "merger", "--engine", engine, "--count", MERGES, "--seed", "7",
    ];
    args.extend(["--stall", "0.3", "--json", "--vcd-dir", vcd]);
    args.extend(SMALL);
    let o = hiermerge(&args, env);
    let r = json_of(&o);
    eprintln!(
        "{engine} {env:?}: {} merges, {} beats in, {} out, {} cycles, {} mismatches, {:.2} s",
        r["transactions"],
        r["merger"]["beats_in"],
        r["merger"]["beats_out"],
        r["cycles"],
        r["mismatches"],
        r["wall_seconds"].as_f64().unwrap_or(0.0)
    );
    (o, r)
}

#[test]
fn a_flipped_nodes_bit_is_caught_decoded_with_a_vcd_on_both_engines() {
    if !tool_present("verilator") || !tool_present("iverilog") {
        return;
    }
    let (line, rhs) = merger_assign("nodes_data");
    let width = NodeLayout::new(&small().design.params).width();
    // Bit 0 (`leaf`) of every `nodes` beat flipped.
    let broken = format!("assign nodes_data = {rhs} ^ {width}'d1;");
    let env = [(PATCH_FROM, line.as_str()), (PATCH_TO, broken.as_str())];
    let mut seen = Vec::new();
    for engine in ["verilator", "iverilog"] {
        let vcd_dir = tempfile::tempdir().unwrap();
        let (o, r) = run_merger(engine, &env, vcd_dir.path());
        assert_fails(&o, &r, PATCH_FROM);
        let m = &r["first_mismatch"];
        assert_eq!(m["stream"], "nodes", "{m}");
        assert_eq!(m["beat"], 0, "the first record written is wrong: {m}");
        assert_one_field_differs(m, "leaf");
        let names = field_names(m);
        let layout = NodeLayout::new(&small().design.params);
        let expected: Vec<&str> = layout.fields().map(|f| f.name).collect();
        assert_eq!(names, expected, "NodeLayout's fields in bit order: {m}");
        // Every `nodes` beat differs, no other stream's.
        let records = r["nodes"].as_u64().unwrap();
        assert!(records > 0, "{r}");
        assert_eq!(r["mismatches"], records, "{r}");
        assert_vcd(&r, vcd_dir.path());
        seen.push((
            m["cycle"].clone(),
            m["transaction"].clone(),
            r["mismatches"].clone(),
        ));
    }
    assert_eq!(
        seen[0], seen[1],
        "same stall draws, same failure on both engines"
    );
}

#[test]
fn a_cfg_never_accepted_hangs_with_a_vcd() {
    if !tool_present("iverilog") {
        return;
    }
    let (line, _) = merger_assign("cfg_ready");
    let env = [
        (PATCH_FROM, line.as_str()),
        (PATCH_TO, "assign cfg_ready = 1'b0;"),
    ];
    let vcd_dir = tempfile::tempdir().unwrap();
    let (o, r) = run_merger("iverilog", &env, vcd_dir.path());
    assert_fails(&o, &r, PATCH_TO);
    assert_eq!(
        r["merger"]["beats_out"], 0,
        "nothing comes out without a cfg: {r}"
    );
    assert_eq!(r["merger"]["done_pulses"], 0, "{r}");
    let what = r["first_mismatch"]["what"].as_str().unwrap();
    assert!(what.contains("no handshake for"), "{r}");
    assert!(
        what.contains("`header` beats"),
        "the missing headers named: {r}"
    );
    assert_vcd(&r, vcd_dir.path());
}

/// The hook flips bit 0 of merge 3's expected `header` beat (its
/// `out_id`): the run fails there and only there, the header decoded
/// (the writer's header, then the merger's flags); without the hook the
/// same run passes.
#[test]
fn a_flipped_expectation_is_caught_with_the_header_decoded() {
    let vcd_dir = tempfile::tempdir().unwrap();
    let (o, r) = run_merger("ir", &[(FLIP, "3")], vcd_dir.path());
    assert_fails(&o, &r, &format!("{FLIP}=3"));
    assert_eq!(r["mismatches"], 1, "{r}");
    let m = &r["first_mismatch"];
    assert_eq!(m["stream"], "header", "{m}");
    assert_eq!(m["transaction"], 3, "{m}");
    assert_eq!(m["beat"], 3, "one header per merge: {m}");
    assert_one_field_differs(m, "out_id");
    let names = field_names(m);
    assert_eq!(
        names,
        [
            "out_id",
            "top",
            "roots",
            "nodes",
            "refs",
            "err",
            "leaf_overflow",
            "count_overflow",
            "fetch_err",
            "fetch_rank"
        ],
        "{m}"
    );
    let (o, r) = run_merger("ir", &[], vcd_dir.path());
    assert!(o.status.success() && r["passed"] == true, "{r}");
}
