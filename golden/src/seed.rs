//! The seeds of seeded random tests. Every test that draws its stimulus
//! from a hand-rolled seeded generator passes its own fixed seeds through
//! [`seeded`]: one environment variable, [`SEED_VAR`], moves every such
//! seed of a run by the same amount (to run the tests on other random
//! draws), and the amount is printed once per test process (the test
//! harness shows it with a failure), so a failure is repeated by setting
//! the variable to the printed value. Unset, or 0, a test draws what it
//! always drew. proptest tests keep proptest's own seeds and regression
//! files.

use std::sync::OnceLock;

/// The environment variable that moves every seeded test's seeds: a
/// decimal number or `0x` and hex digits.
pub const SEED_VAR: &str = "HIERMERGE_SEED";

/// `text` as a value of [`SEED_VAR`]; `Err` says what was expected.
pub fn parse_seed(text: &str) -> Result<u64, String> {
    let t = text.trim();
    let parsed = match t.strip_prefix("0x").or_else(|| t.strip_prefix("0X")) {
        Some(hex) => u64::from_str_radix(hex, 16),
        None => t.parse(),
    };
    parsed.map_err(|_| {
        format!(
            "{SEED_VAR}={text}: expected an unsigned 64-bit seed (decimal, or 0x and hex digits)"
        )
    })
}

/// The amount [`SEED_VAR`] moves seeds by in this process (0 when unset),
/// read and printed on stderr once. For tests: a malformed value panics
/// with [`parse_seed`]'s message.
pub fn seed_base() -> u64 {
    static BASE: OnceLock<u64> = OnceLock::new();
    *BASE.get_or_init(|| {
        let base = match std::env::var(SEED_VAR) {
            Ok(v) => parse_seed(&v).unwrap_or_else(|e| panic!("{e}")),
            Err(_) => 0,
        };
        eprintln!("seeds moved by {SEED_VAR}={base:#x} (set it to repeat this run's random draws)");
        base
    })
}

/// A test's fixed seed `literal`, moved by [`seed_base`] (wrapping).
pub fn seeded(literal: u64) -> u64 {
    literal.wrapping_add(seed_base())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seeds_are_read_in_decimal_and_hex_and_a_bad_one_is_named() {
        assert_eq!(parse_seed("0x1f"), Ok(31));
        assert_eq!(parse_seed(" 42 "), Ok(42));
        let e = parse_seed("-3").unwrap_err();
        assert!(
            e.contains("HIERMERGE_SEED=-3") && e.contains("unsigned"),
            "{e}"
        );
        assert!(parse_seed("18446744073709551616").is_err());
    }
}
