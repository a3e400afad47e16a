//! Writes the example designs' Verilog to a directory (default `rtl-gen-out/`).
//!
//! `cargo run -p rtl-gen --example emit_examples -- <dir>`

use rtl_gen::{examples, write_design};
use std::path::PathBuf;

fn main() {
    let dir = PathBuf::from(
        std::env::args()
            .nth(1)
            .unwrap_or_else(|| "rtl-gen-out".into()),
    );
    let designs = [
        examples::counter(8),
        examples::fifo(8, 3),
        examples::skid_buffer(16),
        examples::abs_diff_pipeline(8, 100),
    ];
    for m in &designs {
        match write_design(m, &dir) {
            Ok(files) => files.iter().for_each(|f| println!("{}", f.display())),
            Err(e) => {
                eprintln!("{e}");
                std::process::exit(1);
            }
        }
    }
}
