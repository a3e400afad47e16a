//! The functional-coverage bins of a passing run (SPEC 10.5): declared
//! from golden's lists (categories, codes, modes, stall patterns, input
//! counts), hit from the transactions the scoreboard matched bit for bit.
//! The streams' full and empty bins are hit by the drivers and monitors
//! (`cosim::tb`), from the DUT's `valid` and `ready`.

use cosim::fcov::{declare, hit};
use cosim::tb::Stalls;
use golden::merge::MergeMode;
use golden::translate::model::{TranslateDesign, TranslateTxn};

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
/// refused range, leaves above the merging level through the leaf FIFOs,
/// a leaf FIFO overflowing (`leaf_overflow`: the hard merges' leaf flood,
/// which golden expects with the leaves the FIFOs keep), a materialized
/// root); `merger.fetch_err.<code>`: every fetcher error code
/// a merge can expect bit for bit (`golden::vectors::hard_merges::CFG_ERRORS`,
/// whose doc says why the codes met mid-walk cannot be); and
/// `merger.writer_err.<code>`: the writer's header errors the stimulus
/// reaches, `capacity` being the one overflow the merger reports that a
/// merge reaches bit for bit.
///
/// No bin, because no merge golden can expect bit for bit reaches them:
/// `leaf_overflow` from a node of per-node mode's module dropped at a full
/// FIFO (its references still reach the writer, a merged hierarchy golden
/// does not model, so the hard merges leave such merges out); `count_overflow` (a created
/// node's reference count at `2^I`: `merger_transaction` refuses the merge,
/// `module_base`); the writer's `LEVEL_OVERFLOW` (with `C < I` a builder
/// overflow shows first as `CAPACITY`, so only a corrupt child box or count
/// reaches it); and the count pass's `overflow` on `report` and the
/// writer's `INDEX_OVERFLOW`, which need more than `2^I` voxels at a level
/// or records in a merge: none of the regression's merges (I = 24, or I =
/// 12 and 10 tried) comes near, and below I = 9 golden's soups do not
/// build. The leaf FIFOs' full and empty are not seen at the unit's
/// boundary: full only as `leaf_overflow`, empty not at all (the drivers
/// and monitors count full and empty on the unit's own streams).
pub(super) fn merger(k: usize, s: &cosim::units::merger::MergeStats) {
    input_counts("merger", k, &s.by_inputs);
    let outcomes = [
        ("refused", s.refused),
        ("leaves_above", s.leaves_above),
        ("leaf_overflow", s.leaf_overflows),
        ("materialized", s.materialized),
    ];
    declare(outcomes.iter().map(|(o, _)| format!("merger.{o}")));
    for (o, n) in outcomes {
        hit(&format!("merger.{o}"), n as u64);
    }
    use golden::merge::fetcher::fetch_err;
    let fetch_codes = [
        (fetch_err::ENTRY, "entry"),
        (fetch_err::ROOT_COUNT, "root_count"),
        (fetch_err::ROOT_CAPACITY, "root_capacity"),
    ];
    debug_assert!(fetch_codes
        .iter()
        .map(|c| c.0)
        .eq(golden::vectors::hard_merges::CFG_ERRORS));
    codes("merger.fetch_err", &fetch_codes, &s.fetch_codes);
    use golden::merge::record_writer::writer_err;
    let writer_codes = [
        (writer_err::NO_TOP, "no_top"),
        (writer_err::CAPACITY, "capacity"),
    ];
    codes("merger.writer_err", &writer_codes, &s.writer_errs);
}

/// `<prefix>.<name>` for every `(code, name)` of `names`, hit by the
/// merges counted per code in `counts`.
fn codes(prefix: &str, names: &[(u64, &str)], counts: &std::collections::BTreeMap<u64, usize>) {
    declare(names.iter().map(|(_, n)| format!("{prefix}.{n}")));
    for (code, n) in names {
        let m = counts.get(code).copied().unwrap_or(0);
        hit(&format!("{prefix}.{n}"), m as u64);
    }
}

/// `hierarchy.inputs.<n>`: merges of every input count from 1 to k through
/// the hierarchy unit, each with its determine commands;
/// `hierarchy.rewritten`: a determine command rewriting an entry an
/// earlier merge read (the table persists across merges);
/// `hierarchy.residual`: a determine command whose placement lies off the
/// voxel grid (rounded to the entry, the rest its residual). The random
/// merges reach no refused range and, at the regression's small
/// configuration, no leaves above the merging level in their count; the
/// merger's own bins (`merger.*`, hard merges) cover those.
pub(super) fn hierarchy(k: usize, s: &cosim::units::hierarchy_unit::HierarchyStats) {
    input_counts("hierarchy", k, &s.merges.by_inputs);
    let outcomes = [("rewritten", s.rewrites), ("residual", s.residuals)];
    declare(outcomes.iter().map(|(o, _)| format!("hierarchy.{o}")));
    for (o, n) in outcomes {
        hit(&format!("hierarchy.{o}"), n);
    }
}

/// `<prefix>.inputs.<n>` for every input count `1..=k`, hit by the merges
/// counted per input count in `by_inputs`.
fn input_counts(prefix: &str, k: usize, by_inputs: &std::collections::BTreeMap<usize, usize>) {
    declare((1..=k).map(|n| format!("{prefix}.inputs.{n}")));
    for (n, m) in by_inputs {
        hit(&format!("{prefix}.inputs.{n}"), *m as u64);
    }
}
