//! A three-stage pipelined datapath: saturated absolute difference.

use crate::{Module, Stream};

/// Streams `in` (`{a, b}`, two signed `width`-bit numbers, `a` high) to
/// `out` = `min(|a - b|, limit)` (`width + 1` bits) through three pipeline
/// registers: subtract, absolute value, saturate.
///
/// ```
/// use rtl_gen::{examples::abs_diff_pipeline, Sim};
/// let m = abs_diff_pipeline(8, 100);
/// let mut sim = Sim::new(&m).unwrap();
/// sim.reset();
/// sim.poke("out_ready", 1u64).unwrap();
/// sim.poke("in_valid", 1u64).unwrap();
/// sim.poke("in_data", (3u64 << 8) | 250).unwrap(); // a = 3, b = -6
/// sim.step_n(3);
/// assert_eq!(sim.peek("out_data").unwrap().to_u64(), Some(9));
/// ```
pub fn abs_diff_pipeline(width: u32, limit: u128) -> Module {
    let m = Module::new(&format!("abs_diff_w{width}"));
    let w = width + 1;
    let diff = Stream::input(&m, "in", 2 * width)
        .map(|d| {
            let (a, b) = (
                d.slice(2 * width - 1, width).as_signed(),
                d.slice(width - 1, 0).as_signed(),
            );
            a.sub(b, w).name("diff")
        })
        .pipeline_reg("s1");
    let abs = diff
        .map(|d| {
            d.as_signed()
                .lt(0)
                .mux(m.lit(0, w).sub(d, w), d)
                .name("abs")
        })
        .pipeline_reg("s2");
    abs.map(|d| {
        d.gt(m.lit(limit, w))
            .mux(m.lit(limit, w), d)
            .name("clamped")
    })
    .pipeline_reg("s3")
    .output("out");
    m
}
