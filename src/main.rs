//! The hiermerge command-line program.
fn main() {
    println!("hiermerge: under construction");
}
