//! The example designs, emitted and run in Icarus Verilog, agree cycle by
//! cycle with the IR simulator under random stimulus (random valid, data and
//! ready every cycle, reset first). Outputs Icarus reports as unknown (`x`,
//! e.g. data read from a never-written FIFO slot while `out_valid` is low)
//! are the only ones not compared; after the reset edge, handshake outputs
//! must never be unknown.

mod common;

use common::{require_tool, Rng};
use rtl_gen::{examples, Bits, Direction, Module, Sim};
use std::fmt::Write;
use std::process::Command;

fn run(m: &Module, cycles: usize, seed: u64) {
    let ports = m.ports();
    let ins: Vec<_> = ports
        .iter()
        .filter(|p| p.direction == Direction::Input && p.name != "clk")
        .collect();
    let outs: Vec<_> = ports
        .iter()
        .filter(|p| p.direction == Direction::Output)
        .collect();
    let mut rng = Rng(seed);
    let stimulus: Vec<Vec<Bits>> = (0..cycles)
        .map(|c| {
            ins.iter()
                .map(|p| match p.name.as_str() {
                    "rst" => Bits::from_bools(&[c < 2]),
                    _ => Bits::from_bools(&rng.bits(p.width)),
                })
                .collect()
        })
        .collect();

    let mut tb = String::from("`timescale 1ns/1ns\nmodule tb;\n    reg clk = 1'b0;\n");
    for p in &ports {
        if p.name == "clk" {
            continue;
        }
        let kind = if p.direction == Direction::Input {
            "reg"
        } else {
            "wire"
        };
        let _ = writeln!(tb, "    {kind} [{}:0] {};", p.width - 1, p.name);
    }
    let conns: Vec<String> = ports.iter().map(|p| format!(".{0}({0})", p.name)).collect();
    let _ = writeln!(
        tb,
        "    {} dut ({});\n    initial begin",
        m.name(),
        conns.join(", ")
    );
    let fmt = vec!["%h"; outs.len()].join(" ");
    let names: Vec<&str> = outs.iter().map(|p| p.name.as_str()).collect();
    for v in &stimulus {
        for (p, b) in ins.iter().zip(v) {
            let _ = writeln!(tb, "        {} = {};", p.name, b);
        }
        let _ = writeln!(tb, "        #1 $display(\"{fmt}\", {});", names.join(", "));
        tb.push_str("        clk = 1'b1; #1 clk = 1'b0;\n");
    }
    tb.push_str("        $finish;\n    end\nendmodule\n");

    let dir = tempfile::tempdir().expect("temp dir");
    let files = rtl_gen::write_design(m, dir.path()).expect("valid design");
    let tb_path = dir.path().join("tb.v");
    std::fs::write(&tb_path, tb).expect("write tb");
    let exe = dir.path().join("sim.vvp");
    let out = Command::new("iverilog")
        .args(["-g2005", "-o"])
        .arg(&exe)
        .arg(&tb_path)
        .args(&files)
        .output()
        .expect("run iverilog");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let run = Command::new("vvp").arg(&exe).output().expect("run vvp");
    let text = String::from_utf8_lossy(&run.stdout);
    let lines: Vec<&str> = text.lines().filter(|l| !l.contains("$finish")).collect();
    assert_eq!(lines.len(), cycles, "{text}");

    let mut sim = Sim::new(m).expect("sim");
    let mut compared = 0;
    for (cycle, (v, line)) in stimulus.iter().zip(lines).enumerate() {
        for (p, b) in ins.iter().zip(v) {
            sim.poke(&p.name, b).expect("poke");
        }
        for (p, word) in outs.iter().zip(line.split_whitespace()) {
            let unknown = word.contains(['x', 'X', 'z', 'Z']);
            if unknown {
                // Before the first (reset) edge every register is unknown;
                // after it only data words may be.
                assert!(
                    cycle == 0 || p.width > 1,
                    "{} cycle {cycle}: {} is unknown",
                    m.name(),
                    p.name
                );
                continue;
            }
            let want = sim.peek(&p.name).expect("peek");
            let got = Bits::from_u128(u128::from_str_radix(word, 16).expect("hex"), p.width)
                .expect("fits");
            assert_eq!(got, want, "{} cycle {cycle}: output {}", m.name(), p.name);
            compared += 1;
        }
        sim.step();
    }
    assert!(
        2 * compared >= (cycles - 1) * outs.len(),
        "compared only {compared} values"
    );
}

#[test]
fn examples_agree_with_icarus_cycle_by_cycle() {
    if !require_tool("iverilog") {
        return;
    }
    run(&examples::counter(8), 300, 1);
    run(&examples::fifo(8, 2), 600, 2);
    run(&examples::skid_buffer(16), 600, 3);
    run(&examples::abs_diff_pipeline(8, 100), 600, 4);
}
