//! The command line that runs a `hiermerge cosim` run again: printed with a
//! failure, and kept as a ledger entry's `args`.

use super::{merge_stage, verilog_patch, Args, MergeStage, Unit, DEFAULT_COUNT};
use super::{FLIP_EXPECTED_VAR, PATCH_FROM_VAR, PATCH_TO_VAR};
use cosim::units::merger::Merges;

/// The one command line that runs this again, the same way: the test hooks'
/// variables, then `hiermerge cosim` and [`run_args`], quoted for a shell.
pub(super) fn reproduce(a: &Args, flip: Option<usize>) -> Result<String, String> {
    let mut s = String::new();
    if let Some(n) = flip {
        s += &format!("{FLIP_EXPECTED_VAR}={n} ");
    }
    if let Some(p) = verilog_patch()? {
        s += &format!(
            "{PATCH_FROM_VAR}={} {PATCH_TO_VAR}={} ",
            shell_quoted(&p.from),
            shell_quoted(&p.to)
        );
    }
    s += "hiermerge cosim";
    for arg in run_args(a)? {
        s += " ";
        s += &shell_quoted(&arg);
    }
    Ok(s)
}

/// `text` as one shell word: as it is when it holds only characters no shell
/// treats specially, else in single quotes.
fn shell_quoted(text: &str) -> String {
    let plain = |c: char| c.is_ascii_alphanumeric() || "-_.,:/=+@%".contains(c);
    if !text.is_empty() && text.chars().all(plain) {
        text.to_string()
    } else {
        format!("'{}'", text.replace('\'', "'\\''"))
    }
}

/// The arguments of `hiermerge cosim` that run this again, every value
/// spelled out (defaults too) and the mode in its canonical form, so that a
/// ledger entry's `args` name the run whatever the defaults become.
pub(super) fn run_args(a: &Args) -> Result<Vec<String>, String> {
    let mut v: Vec<String> = Vec::new();
    let mut push = |flag: &str, value: String| v.extend([flag.to_string(), value]);
    push("--unit", a.unit.name().into());
    if a.unit == Unit::MergeModule && merge_stage(a)? == MergeStage::MergeLevel {
        push("--stage", "merge-level".into());
    }
    push("--engine", a.engine.name().into());
    match &a.vectors {
        Some(p) => {
            push("--vectors", p.display().to_string());
            push("--seed", a.seed.to_string());
        }
        None => {
            push("--seed", a.seed.to_string());
            push("--count", a.count.unwrap_or(DEFAULT_COUNT).to_string());
        }
    }
    // A coin is written as it always was, so a ledger entry's args keep
    // their form; another pattern by its canonical name.
    match super::stalls(a)? {
        cosim::tb::Stalls::Coin(p) => push("--stall", p.to_string()),
        other => push("--stalls", other.to_string()),
    }
    for (stream, stalls) in super::stream_stalls(a)?.iter() {
        push("--stall-stream", format!("{stream}={stalls}"));
    }
    let g = &a.design.grid;
    push("--max-lod", g.max_lod.to_string());
    push("--quant-bits", g.quant_bits.to_string());
    push("--index-bits", g.index_bits.to_string());
    push("--hier-bits", g.hier_bits.to_string());
    match a.unit {
        Unit::Translate => {
            if let Some(t) = a.design.table_depth {
                push("--table-depth", t.to_string());
            }
            if a.design.binary64 {
                v.push("--binary64".into());
            }
        }
        Unit::MergeModule | Unit::Merger | Unit::Hierarchy => {
            let mode = crate::cmd::merge::parse_mode(a.design.mode())?;
            push("--inputs", a.design.inputs().to_string());
            push("--mode", mode.to_string());
            if a.unit == Unit::Hierarchy {
                for (flag, v) in [
                    ("--capacity-bits", a.capacity_bits),
                    ("--leaf-bits", a.leaf_bits),
                    ("--table-depth", a.design.table_depth),
                ] {
                    if let Some(v) = v {
                        push(flag, v.to_string());
                    }
                }
            }
            if a.unit == Unit::Merger {
                if let Some(c) = a.capacity_bits {
                    push("--capacity-bits", c.to_string());
                }
                if let Some(l) = a.leaf_bits {
                    push("--leaf-bits", l.to_string());
                }
                // Only when shared, so per-unit entries keep their form.
                if let Some(golden::merge::merger::store_port::StorePort::Shared { tag_bits }) =
                    a.store_port
                {
                    push("--store-port", format!("shared:{tag_bits}"));
                }
                if let Some(l) = a.store_latency {
                    push("--store-latency", l.to_string());
                }
            }
            // Only when not the default, so the ledger's entries of
            // random merges keep their form.
            let hard = a.vectors.is_none() && super::merger::merges_of(a) == Merges::Hard;
            if a.unit != Unit::MergeModule && hard {
                push("--merges", "hard".into());
            }
        }
    }
    Ok(v)
}
