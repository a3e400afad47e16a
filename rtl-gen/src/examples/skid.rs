//! A skid buffer module around [`Stream::skid_buffer`].

use crate::{Module, Stream};

/// A fully registered ready/valid stage of `width` bits: streams `in` and `out`.
///
/// ```
/// use rtl_gen::{examples::skid_buffer, emit_verilog};
/// assert!(emit_verilog(&skid_buffer(32)).is_ok());
/// ```
pub fn skid_buffer(width: u32) -> Module {
    let m = Module::new(&format!("skid_buffer_w{width}"));
    Stream::input(&m, "in", width)
        .skid_buffer("skid")
        .output("out");
    m
}
