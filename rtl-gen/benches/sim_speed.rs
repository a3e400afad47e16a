//! IR simulator speed: clock edges per second on the example designs.
//! `cargo bench -p rtl-gen --bench sim_speed`

use rtl_gen::{examples, optest, Sim};
use std::time::Instant;

fn bench(name: &str, m: &rtl_gen::Module, cycles: u64, inputs: &[&str]) {
    let mut sim = match Sim::new(m) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("{name}: {e}");
            return;
        }
    };
    let handles: Vec<_> = inputs.iter().filter_map(|p| sim.handle(p).ok()).collect();
    let mut x = 0x1234_5678_9abc_def0u64;
    let start = Instant::now();
    for _ in 0..cycles {
        for &h in &handles {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            if sim.set_u64(h, x & 1).is_err() {
                return;
            }
        }
        sim.step();
    }
    let secs = start.elapsed().as_secs_f64();
    println!(
        "{name:<32} {cycles:>8} edges  {:>10.0} edges/s  {:>7.2} us/edge",
        cycles as f64 / secs,
        secs * 1e6 / cycles as f64
    );
}

fn main() {
    println!("rtl-gen IR simulator speed (random 1-bit stimulus on the listed inputs)");
    bench("counter_w32", &examples::counter(32), 1_000_000, &["en"]);
    bench(
        "fifo_w32_a4",
        &examples::fifo(32, 4),
        300_000,
        &["in_valid", "out_ready", "in_data"],
    );
    bench(
        "skid_buffer_w64",
        &examples::skid_buffer(64),
        300_000,
        &["in_valid", "out_ready", "in_data"],
    );
    bench(
        "abs_diff_w16",
        &examples::abs_diff_pipeline(16, 1000),
        300_000,
        &["in_valid", "out_ready", "in_data"],
    );
    bench(
        "op_suite_w64_s_reg",
        &optest::op_suite(64, true, true),
        100_000,
        &["add_a", "add_b", "lt_a"],
    );
    bench(
        "op_suite_w300_s_reg",
        &optest::op_suite(300, true, true),
        20_000,
        &["add_a", "add_b", "lt_a"],
    );
}
