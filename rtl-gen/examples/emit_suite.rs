//! Writes the operator suite for one width: `emit_suite <width> <s|u> <comb|reg> <dir>`.
use rtl_gen::{optest::op_suite, write_design};
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let width: u32 = args.get(1).and_then(|w| w.parse().ok()).unwrap_or(8);
    let signed = args.get(2).map(|s| s == "s").unwrap_or(false);
    let reg = args.get(3).map(|s| s == "reg").unwrap_or(false);
    let dir = args.get(4).cloned().unwrap_or_else(|| "suite-out".into());
    match write_design(&op_suite(width, signed, reg), std::path::Path::new(&dir)) {
        Ok(files) => println!("{}", files.len()),
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(1);
        }
    }
}
