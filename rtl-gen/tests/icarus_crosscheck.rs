//! The emitted Verilog, run in Icarus Verilog (`iverilog -g2005`), agrees bit
//! for bit with the IR simulator on the combinational operator suites. (The
//! cosim crate runs the full three-engine suite; this keeps the emitter and
//! the simulator honest inside rtl-gen.)

mod common;

use common::{require_tool, Rng};
use rtl_gen::optest::op_suite;
use rtl_gen::{Bits, Direction, Module, Sim};
use std::fmt::Write;
use std::process::Command;

/// Random and edge stimulus: all zeros, all ones, then random words.
fn vectors(m: &Module, n: usize, rng: &mut Rng) -> Vec<Vec<Bits>> {
    let inputs: Vec<u32> = m
        .ports()
        .iter()
        .filter(|p| p.direction == Direction::Input)
        .map(|p| p.width)
        .collect();
    (0..n)
        .map(|k| {
            inputs
                .iter()
                .map(|&w| match k {
                    0 => Bits::zero(w),
                    1 => Bits::ones(w),
                    _ => Bits::from_bools(&rng.bits(w)),
                })
                .collect()
        })
        .collect()
}

/// A testbench applying each vector, waiting, and printing every output in hex.
fn testbench(m: &Module, vecs: &[Vec<Bits>]) -> String {
    let ports = m.ports();
    let mut tb = String::from("`timescale 1ns/1ns\nmodule tb;\n");
    for p in &ports {
        let kind = if p.direction == Direction::Input {
            "reg"
        } else {
            "wire"
        };
        let _ = writeln!(tb, "    {kind} [{}:0] {};", p.width - 1, p.name);
    }
    let conns: Vec<String> = ports.iter().map(|p| format!(".{0}({0})", p.name)).collect();
    let _ = writeln!(tb, "    {} dut ({});", m.name(), conns.join(", "));
    tb.push_str("    initial begin\n");
    let ins: Vec<_> = ports
        .iter()
        .filter(|p| p.direction == Direction::Input)
        .collect();
    let outs: Vec<_> = ports
        .iter()
        .filter(|p| p.direction == Direction::Output)
        .collect();
    for v in vecs {
        for (p, b) in ins.iter().zip(v) {
            let _ = writeln!(tb, "        {} = {};", p.name, b);
        }
        let fmt = vec!["%h"; outs.len()].join(" ");
        let names: Vec<&str> = outs.iter().map(|p| p.name.as_str()).collect();
        let _ = writeln!(tb, "        #1 $display(\"{fmt}\", {});", names.join(", "));
    }
    tb.push_str("        $finish;\n    end\nendmodule\n");
    tb
}

fn parse_hex(s: &str, width: u32) -> Bits {
    let bits: Vec<bool> = (0..width)
        .map(|i| {
            let digit = s.as_bytes()[s.len() - 1 - (i / 4) as usize] as char;
            let v = digit
                .to_digit(16)
                .unwrap_or_else(|| panic!("non-binary value `{s}`"));
            (v >> (i % 4)) & 1 == 1
        })
        .collect();
    Bits::from_bools(&bits)
}

fn crosscheck(m: &Module, seed: u64) {
    let dir = tempfile::tempdir().expect("temp dir");
    let files = rtl_gen::write_design(m, dir.path()).expect("valid design");
    let mut rng = Rng(seed);
    let vecs = vectors(m, 24, &mut rng);
    let tb = dir.path().join("tb.v");
    std::fs::write(&tb, testbench(m, &vecs)).expect("write tb");
    let exe = dir.path().join("sim.vvp");
    let out = Command::new("iverilog")
        .args(["-g2005", "-Wall", "-o"])
        .arg(&exe)
        .arg(&tb)
        .args(&files)
        .output()
        .expect("run iverilog");
    let msg = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success(),
        "iverilog failed on {}:\n{msg}",
        m.name()
    );
    // -Wall may only mention the testbench's timescale, never the design.
    for line in msg.lines() {
        assert!(
            !line.contains("warning") || line.contains("timescale"),
            "iverilog warning: {line}"
        );
    }
    let run = Command::new("vvp").arg(&exe).output().expect("run vvp");
    let text = String::from_utf8_lossy(&run.stdout);
    let lines: Vec<&str> = text
        .lines()
        .filter(|l| !l.starts_with("VCD") && !l.contains("$finish"))
        .collect();
    assert_eq!(lines.len(), vecs.len(), "{text}");
    let mut sim = Sim::new(m).expect("sim");
    let ports = m.ports();
    let ins: Vec<_> = ports
        .iter()
        .filter(|p| p.direction == Direction::Input)
        .collect();
    let outs: Vec<_> = ports
        .iter()
        .filter(|p| p.direction == Direction::Output)
        .collect();
    for (v, line) in vecs.iter().zip(lines) {
        for (p, b) in ins.iter().zip(v) {
            sim.poke(&p.name, b).expect("poke");
        }
        for (p, word) in outs.iter().zip(line.split_whitespace()) {
            let got = parse_hex(word, p.width);
            let want = sim.peek(&p.name).expect("peek");
            assert_eq!(got, want, "{} output {}", m.name(), p.name);
        }
    }
}

#[test]
fn icarus_agrees_with_the_ir_simulator_on_operator_suites() {
    if !require_tool("iverilog") {
        return;
    }
    for (w, signed) in [
        (1, false),
        (7, true),
        (33, false),
        (64, true),
        (65, true),
        (129, false),
        (300, true),
    ] {
        crosscheck(&op_suite(w, signed, false), w as u64);
    }
}
