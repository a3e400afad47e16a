//! `verilog/` holds exactly what the generators emit for the default
//! configurations; each file lints clean and synthesizes (to Yosys' coarse
//! netlist) with no latch, its memories mapped onto the RAM library of
//! rtl-gen/yosys (SPEC.md 11);
//! the record writer's buffers all become RAM macros (SPEC.md 8.12).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use rtl_gen::merge::{
    record_writer_buffers, record_writer_level_name, record_writer_name, MergeConfig, MergerConfig,
};

fn verilog_files(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "v"))
        .map(|p| {
            (
                p.file_name().unwrap().to_string_lossy().into_owned(),
                std::fs::read(&p).unwrap(),
            )
        })
        .collect()
}

fn repo() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

#[test]
fn verilog_folder_is_current() {
    let fresh = tempfile::tempdir().unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_hiermerge"))
        .args(["gen", "--defaults", "--out"])
        .arg(fresh.path())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let want = verilog_files(fresh.path());
    let have = verilog_files(&repo().join("verilog"));
    assert!(!want.is_empty());
    let names = |m: &BTreeMap<String, Vec<u8>>| m.keys().cloned().collect::<Vec<_>>();
    assert_eq!(names(&have), names(&want), "verilog/ has other files than the generators emit; regenerate: cargo run --release -- gen --defaults --out verilog");
    for (name, bytes) in &want {
        assert!(have[name] == *bytes, "verilog/{name} is stale; regenerate: cargo run --release -- gen --defaults --out verilog");
    }
}

/// A missing tool fails under CI=true; locally it says how to install it.
fn tool(name: &str) -> bool {
    let ok = Command::new(name)
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success())
        || Command::new(name)
            .arg("-V")
            .output()
            .is_ok_and(|o| o.status.success());
    if !ok {
        assert!(
            std::env::var("CI").as_deref() != Ok("true"),
            "{name} is missing (CI=true): apt-get install verilator yosys"
        );
        eprintln!("{name} missing: skipping; install with apt-get install verilator yosys");
    }
    ok
}

/// The RAM library an RTL engineer maps the buffers with (SPEC.md 11).
fn ram_library() -> PathBuf {
    repo().join("rtl-gen").join("yosys")
}

/// The macro the library maps a memory of 1024 words or more onto, and its
/// data bits (`hiermerge_sdp_ram_<words>x<bits>` in sdp_rams_macros.v).
const DEEP_MACRO: &str = "hiermerge_sdp_ram_1024x32";
const DEEP_CELL: &str = "$__HIERMERGE_SDP_1024X32_";
const DEEP_WORDS: u32 = 1024;
const MACRO_BITS: u32 = 32;

/// Yosys' generic `synth` of `top` up to its fine step, with the memories
/// mapped onto the RAM library (SPEC.md 11's flow, which then runs
/// `synth -run fine:`). Latches, memory inference and the RAM mapping are
/// all decided by here; the fine step (gate mapping and ABC, most of the
/// time on the large modules) is what `hiermerge synth` measures.
fn synth_with_rams(top: &str, flatten: bool) -> String {
    let lib = ram_library();
    let flatten = if flatten { " -flatten" } else { "" };
    format!(
        "read_verilog {macros}; synth -top {top}{flatten} -run begin:fine; memory_libmap -lib {rams}; techmap -map {map}",
        macros = lib.join("sdp_rams_macros.v").display(),
        rams = lib.join("sdp_rams.txt").display(),
        map = lib.join("sdp_rams_map.v").display(),
    )
}

const NO_LATCH: &str = "check -assert; select -assert-none t:$dlatch t:$_DLATCH_*";

/// Runs a Yosys script, its log into a file; returns the log.
fn yosys(script: &str, what: &str) -> String {
    let dir = tempfile::tempdir().unwrap();
    let log_file = dir.path().join("yosys.log");
    let out = Command::new("yosys")
        .arg("-q")
        .arg("-l")
        .arg(&log_file)
        .arg("-p")
        .arg(script)
        .output()
        .unwrap();
    let log = std::fs::read_to_string(&log_file).unwrap_or_default();
    let err = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.status.success(), "yosys on {what}:\n{err}");
    assert!(
        !log.contains("Latch inferred") && !err.contains("Latch inferred"),
        "yosys inferred a latch in {what}:\n{err}"
    );
    log
}

/// The default configuration's record writer (`record_writer_name`) and
/// its level modules.
fn default_writer() -> (String, [String; 2]) {
    let c = MergerConfig::new(MergeConfig::default());
    let (p, cap) = (c.design.params, c.sizes.capacity_bits);
    let levels = [false, true].map(|by_slot| record_writer_level_name(&p, cap, by_slot));
    (record_writer_name(&p, cap), levels)
}

/// The record writer's default configuration whose module is `top`,
/// flattened with its level modules: its buffers (the writer's own list,
/// named as the flattened writer names them) each map onto `DEEP_MACRO`s,
/// none is left to flip-flops, and exactly the macros they need appear.
/// The Yosys command asserting the count, and the check of the log.
fn writer_macros_and_check(top: &str) -> (String, impl Fn(&str)) {
    let c = MergerConfig::new(MergeConfig::default());
    let p = c.design.params;
    let cap = c.sizes.capacity_bits;
    let buffers = record_writer_buffers(&p, cap).expect("the default capacity is valid");
    let macros: u32 = buffers
        .iter()
        .map(|b| {
            assert!(
                b.depth >= DEEP_WORDS,
                "{}: {} words map onto the shallow macro",
                b.name,
                b.depth
            );
            b.width.div_ceil(MACRO_BITS) * b.depth.div_ceil(DEEP_WORDS)
        })
        .sum();
    let script = format!("select -assert-count {macros} t:{DEEP_MACRO}");
    let top = top.to_string();
    let check = move |log: &str| {
        for b in &buffers {
            let mapped = format!("mapping memory {top}.{} via {DEEP_CELL}", b.name);
            assert!(
                log.contains(&mapped),
                "{top}: buffer {} is not a RAM macro",
                b.name
            );
        }
        let to_flops = format!("using FF mapping for memory {top}.");
        assert!(
            !log.contains(&to_flops),
            "{top}: a memory left to flip-flops"
        );
        println!(
            "{top}: {} buffers on {macros} {DEEP_MACRO} macros",
            buffers.len()
        );
    };
    (script, check)
}

#[test]
fn verilog_folder_lints_clean_and_synthesizes_without_latches() {
    if !tool("verilator") || !tool("yosys") {
        return;
    }
    let dir = repo().join("verilog");
    // Every file is read with each top: a module may instantiate others
    // (the merging module its network, counter and S614).
    let all: Vec<std::path::PathBuf> = verilog_files(&dir).keys().map(|n| dir.join(n)).collect();
    let all_text = all
        .iter()
        .map(|f| f.display().to_string())
        .collect::<Vec<_>>()
        .join(" ");
    for name in verilog_files(&dir).keys() {
        let top = name.trim_end_matches(".v");
        let lint = Command::new("verilator")
            .args(["--lint-only", "-Wall", "--top-module", top])
            .args(&all)
            .output()
            .unwrap();
        let text = format!(
            "{}{}",
            String::from_utf8_lossy(&lint.stdout),
            String::from_utf8_lossy(&lint.stderr)
        );
        assert!(
            lint.status.success() && text.trim().is_empty(),
            "verilator -Wall on {name}:\n{text}"
        );
        // Every module is a file of verilog/ and a top of this loop: the
        // modules a top instantiates are black boxes here (their ports
        // checked), so each module's logic is synthesized once (the record
        // writer's level modules twice: alone, and flat in the writer, so
        // that the buffers of every level are counted). Every top takes the
        // RAM flow of SPEC 11: the writer's buffers and the fetcher's
        // frontier FIFO become macros, small memories stay flip-flops.
        let t = Instant::now();
        let (writer, writer_levels) = default_writer();
        let is_writer = top == writer;
        let others: Vec<String> = verilog_files(&dir)
            .keys()
            .map(|n| n.trim_end_matches(".v").to_string())
            .filter(|n| n != top && !(is_writer && writer_levels.contains(n)))
            .collect();
        let head = format!(
            "read_verilog {all_text}; blackbox {}; hierarchy -check -top {top}; {}; {NO_LATCH}",
            others.join(" "),
            synth_with_rams(top, is_writer)
        );
        if is_writer {
            let (macros, check) = writer_macros_and_check(top);
            check(&yosys(&format!("{head}; {macros}"), name));
        } else if top.starts_with("hierarchy_merger_") {
            // The writer is in it (synthesized with its RAMs above).
            yosys(&format!("{head}; select -assert-count 1 t:{writer}"), name);
        } else {
            yosys(&head, name);
        }
        println!("yosys {top}: {:.1?}", t.elapsed());
    }
}
