//! The values of `hiermerge merge --translate` and `--mode` (also read by
//! `gen`, `cosim` and the ledger's plans). Self-contained, so that the fuzz
//! targets (`tests/fuzz.rs`) include this file and drive it directly.

use glam::DVec3;
use golden::merge::MergeMode;

/// Parses `--translate x,y,z`: three finite numbers.
pub fn parse_vec3(s: &str) -> Result<DVec3, String> {
    let parts: Vec<&str> = s.split(',').collect();
    if parts.len() != 3 {
        return Err(format!(
            "`{s}`: expected x,y,z (three numbers separated by commas)"
        ));
    }
    let mut v = [0.0; 3];
    for (i, p) in parts.iter().enumerate() {
        v[i] = p.trim().parse::<f64>().map_err(|e| {
            format!(
                "`{s}`: component {} `{p}`: {e}",
                "xyz".as_bytes()[i] as char
            )
        })?;
        if !v[i].is_finite() {
            return Err(format!(
                "`{s}`: component {} is not finite",
                "xyz".as_bytes()[i] as char
            ));
        }
    }
    Ok(DVec3::from_array(v))
}

/// Parses a ratio `N/D` with `D >= 1`.
pub fn parse_ratio(s: &str) -> Result<(u32, u32), String> {
    let (n, d) = s
        .split_once('/')
        .ok_or_else(|| format!("`{s}`: expected a ratio N/D"))?;
    let n: u32 = n
        .trim()
        .parse()
        .map_err(|e| format!("`{s}`: numerator: {e}"))?;
    let d: u32 = d
        .trim()
        .parse()
        .map_err(|e| format!("`{s}`: denominator: {e}"))?;
    if d == 0 {
        return Err(format!("`{s}`: the denominator must not be 0"));
    }
    Ok((n, d))
}

/// Parses a merging mode (paragraphs 53-55).
pub fn parse_mode(s: &str) -> Result<MergeMode, String> {
    let (name, arg) = match s.split_once(':') {
        Some((n, a)) => (n, Some(a)),
        None => (s, None),
    };
    let level = |a: Option<&str>| -> Result<u8, String> {
        a.ok_or_else(|| format!("`{s}`: expected {name}:LEVEL"))?
            .parse::<u8>()
            .map_err(|e| format!("`{s}`: {e}"))
    };
    match name {
        "overlap" => {
            let (num, den) = arg.map(parse_ratio).transpose()?.unwrap_or((1, 2));
            Ok(MergeMode::Overlap { num, den })
        }
        "per-node" => {
            let (num, den) = arg.map(parse_ratio).transpose()?.unwrap_or((1, 2));
            Ok(MergeMode::PerNode { num, den })
        }
        "fixed" => Ok(MergeMode::Fixed(level(arg)?)),
        "below-top" => Ok(MergeMode::BelowTop(level(arg)?)),
        "proportion" => {
            let (num, den) = parse_ratio(arg.ok_or_else(|| format!("`{s}`: expected proportion:N/D"))?)?;
            Ok(MergeMode::Proportion { num, den })
        }
        _ => Err(format!("`{s}`: unknown mode; expected overlap[:N/D], fixed:L, below-top:K, proportion:N/D or per-node[:N/D]")),
    }
}
