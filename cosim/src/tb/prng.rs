//! A tiny seeded PRNG (SplitMix64) so every stall pattern is reproducible from a seed.

use golden::bits::Bits;

/// SplitMix64: fast, full-period, good enough for stall patterns and payloads.
#[derive(Clone, Debug)]
pub struct Prng {
    state: u64,
}

impl Prng {
    /// A generator seeded with `seed`.
    pub fn new(seed: u64) -> Prng {
        Prng { state: seed }
    }

    /// A generator for a sub-stream (driver, monitor, ...) derived from one seed.
    pub fn derived(seed: u64, stream: u64) -> Prng {
        let mut p = Prng::new(seed ^ stream.wrapping_mul(0xA076_1D64_78BD_642F));
        p.next_u64();
        p
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        golden::scenes::splitmix64_next(&mut self.state)
    }

    /// Uniform in [0, 1) with 53 bits of precision.
    pub fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// True with probability `p` (p <= 0: never, p >= 1: always).
    pub fn chance(&mut self, p: f64) -> bool {
        self.next_f64() < p
    }

    /// Uniform in [0, n); 0 when n == 0.
    pub fn below(&mut self, n: u64) -> u64 {
        if n == 0 {
            return 0;
        }
        // Multiply-shift keeps the bias far below anything a test could see.
        ((self.next_u64() as u128 * n as u128) >> 64) as u64
    }

    /// A uniformly random `width`-bit vector.
    pub fn bits(&mut self, width: u32) -> Bits {
        let words: Vec<u64> = (0..width.div_ceil(64)).map(|_| self.next_u64()).collect();
        let mut v = Bits::zero(width);
        for i in 0..width {
            if words[(i / 64) as usize] >> (i % 64) & 1 == 1 {
                // Cannot fail: i < width.
                let _ = v.set_bit(i, true);
            }
        }
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_seed_same_stream_and_rates_are_plausible() {
        let mut a = Prng::new(7);
        let mut b = Prng::new(7);
        assert_eq!(a.next_u64(), b.next_u64());
        let hits = (0..10_000).filter(|_| a.chance(0.3)).count();
        assert!((2700..3300).contains(&hits), "{hits}");
        assert!((0..1000).all(|_| a.below(10) < 10));
        assert!(!(0..1000).any(|_| a.chance(0.0)));
        assert_ne!(
            Prng::derived(1, 0).next_u64(),
            Prng::derived(1, 1).next_u64()
        );
        assert_eq!(a.bits(300).width(), 300);
    }
}
