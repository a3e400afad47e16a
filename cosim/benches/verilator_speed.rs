//! Verilator simulation speed on the fixtures, printed (never asserted).
//!
//! `cargo bench -p cosim --bench verilator_speed`
//! Measures: raw `step()` rate on the counter, the full stream testbench
//! (driver, monitor, scoreboard) on the skid buffer, the cost of a cache hit,
//! and, for comparison, the same testbench on Icarus Verilog.

use cosim::tb::{run_stream_bench, BenchConfig, Prng, StreamNames, Vector};
use cosim::verilator::{VerilatorEngine, VerilatorOptions};
use cosim::{Bits, Design, Engine, PortSpec};
use std::path::PathBuf;
use std::time::Instant;

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name)
}

fn counter() -> cosim::Result<Design> {
    Design::new(
        "counter",
        vec![fixture("counter.v")],
        vec![
            PortSpec::input("clk", 1),
            PortSpec::input("rst", 1),
            PortSpec::input("en", 1),
            PortSpec::output("count", 8),
        ],
        Some("clk"),
        Some("rst"),
    )
}

fn skid() -> cosim::Result<Design> {
    Design::new(
        "skid",
        vec![fixture("skid.v")],
        vec![
            PortSpec::input("clk", 1),
            PortSpec::input("rst", 1),
            PortSpec::input("in_valid", 1),
            PortSpec::output("in_ready", 1),
            PortSpec::input("in_data", 16),
            PortSpec::output("out_valid", 1),
            PortSpec::input("out_ready", 1),
            PortSpec::output("out_data", 16),
        ],
        Some("clk"),
        Some("rst"),
    )
}

fn main() -> cosim::Result<()> {
    let options = VerilatorOptions::default();
    let design = counter()?;
    let t = Instant::now();
    let mut e = VerilatorEngine::new(&design, &options)?;
    println!(
        "counter: first load {:?} (built: {})",
        t.elapsed(),
        e.build_info().built
    );
    let t = Instant::now();
    let again = VerilatorEngine::new(&design, &options)?;
    println!("counter: cache hit {:?}", t.elapsed());
    drop(again);

    e.reset(1)?;
    let en = e.port_id("en")?;
    e.poke_u64(en, 1)?;
    let cycles = 2_000_000u64;
    let t = Instant::now();
    for _ in 0..cycles {
        e.step()?;
    }
    let s = t.elapsed().as_secs_f64();
    println!(
        "counter: raw step {cycles} cycles in {s:.3} s = {:.0} cycles/s",
        cycles as f64 / s
    );

    let design = skid()?;
    let mut rng = Prng::new(5);
    let vectors: Vec<Vector> = (0..200_000)
        .map(|_| {
            let x = rng.below(1 << 16);
            Vector {
                input: vec![Bits::from_u64(x, 16).expect("16 bits")],
                outputs: vec![vec![Bits::from_u64((x + 1) & 0xffff, 16).expect("16 bits")]],
            }
        })
        .collect();
    let names = StreamNames::single("data");
    for stall in [0.0, 0.5] {
        let mut e = VerilatorEngine::new(&design, &options)?;
        let config = BenchConfig {
            in_stall: cosim::tb::Stalls::Coin(stall),
            out_stall: cosim::tb::Stalls::Coin(stall),
            ..BenchConfig::default()
        };
        let r = run_stream_bench(&mut e, &names, &vectors, None, &config, None)?;
        println!(
            "skid stream testbench, stall {stall}: {} cycles, {} transactions, {:.3} s = {:.0} cycles/s, {:.3} transactions/cycle, passed {}",
            r.cycles,
            r.inputs_sent,
            r.wall.as_secs_f64(),
            r.cycles as f64 / r.wall.as_secs_f64(),
            r.inputs_per_cycle(),
            r.passed()
        );
    }
    // Icarus for comparison: every eval/step is a pipe round trip.
    let mut e = cosim::icarus::IcarusEngine::new(&design)?;
    let config = BenchConfig {
        in_stall: cosim::tb::Stalls::Coin(0.5),
        out_stall: cosim::tb::Stalls::Coin(0.5),
        ..BenchConfig::default()
    };
    let r = run_stream_bench(&mut e, &names, &vectors[..5000], None, &config, None)?;
    println!(
        "skid stream testbench on iverilog, stall 0.5: {} cycles in {:.3} s = {:.0} cycles/s, passed {}",
        r.cycles,
        r.wall.as_secs_f64(),
        r.cycles as f64 / r.wall.as_secs_f64(),
        r.passed()
    );
    Ok(())
}
