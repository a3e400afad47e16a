//! The functional-coverage bins of a passing run (SPEC 10.5): declared
//! from golden's lists (categories, codes, modes, stall patterns, input
//! counts), hit from the transactions the scoreboard matched bit for bit.
//! The streams' full and empty bins are hit by the drivers and monitors
//! (`cosim::tb`), from the DUT's `valid` and `ready`.

use cosim::fcov::{declare, hit};
use cosim::tb::Stalls;
use golden::merge::MergeMode;
use golden::vectors::translate::{TranslateDesign, TranslateTxn};

/// The stall patterns, as `--stalls` names them.
const STALLS: [&str; 4] = ["none", "coin", "bursty", "periodic"];

/// The merging modes, as `--mode` names them.
const MODES: [&str; 5] = ["overlap", "fixed", "below-top", "proportion", "per-node"];

/// The kind of a canonical `kind:parameters` spelling.
fn kind(spelled: &str) -> String {
    spelled.split(':').next().unwrap_or(spelled).to_string()
}

/// `stalls.<pattern>`: every pattern is run.
pub(super) fn stalls(s: &Stalls) {
    declare(STALLS.iter().map(|k| format!("stalls.{k}")));
    hit(&format!("stalls.{}", kind(&s.to_string())), 1);
}

/// `translate.<class>`: every hard-case category of the vectors and every
/// error and status outcome the design can produce.
pub(super) fn translate(design: &TranslateDesign, txns: &[TranslateTxn]) {
    let names = |k: &str| format!("translate.{k}");
    declare(
        golden::vectors::classes::expected_classes(design)
            .into_iter()
            .map(names),
    );
    for (k, n) in golden::vectors::classes::classes(design, txns) {
        hit(&names(k), n as u64);
    }
}

/// `merge.mode.<mode>`: the merging module in every mode; the full
/// (input) and empty (output) bins of its streams.
pub(super) fn merge_module(mode: &MergeMode, top: &str, inputs: usize, merges: u64) {
    declare(MODES.iter().map(|k| format!("merge.mode.{k}")));
    hit(&format!("merge.mode.{}", kind(&mode.to_string())), merges);
    declare((0..inputs).map(|i| format!("{top}.in{i}.full")));
    declare(["report", "out"].map(|s| format!("{top}.{s}.empty")));
}

/// `merge_level.in.full`, `.out.empty` of the S614 stage alone.
pub(super) fn merge_level(top: &str) {
    declare([format!("{top}.in.full"), format!("{top}.out.empty")]);
}

/// `merger.inputs.<n>`: merges of every input count from 1 to k;
/// `merger.<outcome>`: the merger's outcomes besides a plain merge (a
/// refused range, a fetcher error, leaves above the merging level through
/// the leaf FIFOs, a materialized root).
pub(super) fn merger(k: usize, s: &cosim::units::merger::MergeStats) {
    declare((1..=k).map(|n| format!("merger.inputs.{n}")));
    for (n, m) in &s.by_inputs {
        hit(&format!("merger.inputs.{n}"), *m as u64);
    }
    let outcomes = [
        ("refused", s.refused),
        ("fetch_err", s.fetch_errors),
        ("leaves_above", s.leaves_above),
        ("materialized", s.materialized),
    ];
    declare(outcomes.iter().map(|(o, _)| format!("merger.{o}")));
    for (o, n) in outcomes {
        hit(&format!("merger.{o}"), n as u64);
    }
}
