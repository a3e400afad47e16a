//! Why a merge was refused. Every variant names the input (hierarchy id),
//! the node or field at fault, and what was expected.

use std::fmt;

use crate::params::Params;
use crate::store::StoreError;
use crate::translate::TranslateError;

/// A merge that cannot be done. Merging never panics on bad input.
#[derive(Clone, Debug, PartialEq)]
pub enum MergeError {
    /// The list of inputs is empty.
    NoInputs,
    /// An input id is listed twice.
    DuplicateInput(u8),
    /// An input id names no hierarchy in the store.
    UnknownInput(u8),
    /// The output id is already in the store (an input or another hierarchy).
    OutIdInUse(u8),
    /// The output id does not fit in `H` bits.
    OutIdOutOfRange {
        /// The output id asked for.
        id: u8,
        /// `H`: ids run `0..2^H`.
        hier_bits: u8,
    },
    /// An input's parameters differ from the first input's.
    ParamsMismatch {
        /// The input whose parameters differ.
        input: u8,
        /// The first input's parameters.
        expected: Params,
        /// This input's parameters.
        found: Params,
    },
    /// The translation table has no usable entry for an input.
    Translation {
        /// The input's id.
        input: u8,
        /// The table's error, e.g. `EmptyEntry` for an entry never written.
        error: TranslateError,
    },
    /// S612: moving a node of an input failed (outside the scene, or above
    /// the translation level `L`).
    TranslateNode {
        /// The input's id.
        input: u8,
        /// Index of the node in the input's `nodes`.
        node: u32,
        /// The `translate_node` error, e.g. `NodeOutsideScene` or `AboveTranslationLevel`.
        error: TranslateError,
    },
    /// An input is not a well-formed, self-contained hierarchy.
    BadInput {
        /// The input's id.
        input: u8,
        /// The node at fault; `None` when the fault is not one node's (e.g. `root_count`).
        node: Option<u32>,
        /// The field or property at fault, e.g. `"first/count"` or `"reference"`.
        field: &'static str,
        /// What it had to be.
        expected: String,
        /// What it was.
        found: String,
    },
    /// A ratio `num / den` outside `0 <= num <= den`, `den >= 1`.
    BadRatio {
        /// The mode the ratio belongs to: `"Overlap"`, `"Proportion"` or `"PerNode"`.
        mode: &'static str,
        /// The numerator given.
        num: u32,
        /// The denominator given.
        den: u32,
    },
    /// `Fixed(level)` outside the candidate levels `[lo, hi]`.
    LevelNotCandidate {
        /// The merging LOD asked for.
        level: u8,
        /// The shallowest candidate level, the deepest input top LOD (SPEC 8.2).
        lo: u8,
        /// The deepest candidate level (SPEC 8.2).
        hi: u8,
    },
    /// `BelowTop(k)`: `lo + k` is deeper than `hi`.
    BelowTopTooDeep {
        /// The levels below the top asked for.
        k: u8,
        /// The shallowest candidate level, the deepest input top LOD (SPEC 8.2).
        lo: u8,
        /// The deepest candidate level (SPEC 8.2).
        hi: u8,
    },
    /// The top of the merged hierarchy would be an input's leaf at LOD 0,
    /// which a merged record cannot stand for (its primitives index the
    /// input's triangles).
    InputLeafAtTop {
        /// The input holding the leaf.
        input: u8,
        /// Index of the leaf in that input's `nodes`.
        node: u32,
    },
    /// A node count, reference count or `count` field exceeds `I` bits.
    IndexOverflow {
        /// What overflowed, e.g. `"node count - 1"` or `"count"`.
        what: &'static str,
        /// Its value, at or above `2^index_bits`.
        value: u64,
        /// The bits it had to fit: `I`, or 16 for the input count.
        index_bits: u8,
    },
    /// Storing the merged hierarchy failed (S618).
    Store(StoreError),
    /// Asked of the merging module's hardware, which does not build it
    /// (e.g. per-node merging).
    Unsupported {
        /// What was asked and why it cannot be done.
        what: &'static str,
    },
}

impl fmt::Display for MergeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use MergeError::*;
        match self {
            NoInputs => write!(f, "merge: no input hierarchies given"),
            DuplicateInput(id) => write!(f, "merge: input hierarchy {id} is listed twice"),
            UnknownInput(id) => write!(f, "merge: input hierarchy {id} is not in the store"),
            OutIdInUse(id) => write!(
                f,
                "merge: output id {id} is already in the store: expected a free id"
            ),
            OutIdOutOfRange { id, hier_bits } => write!(
                f,
                "merge: output id {id} does not fit in H = {hier_bits} bits"
            ),
            ParamsMismatch {
                input,
                expected,
                found,
            } => write!(
                f,
                "merge: input {input} has parameters {found:?}, expected {expected:?} (the first input's)"
            ),
            Translation { input, error } => {
                write!(f, "merge: translation table entry of input {input}: {error}")
            }
            TranslateNode { input, node, error } => {
                write!(f, "merge: S612 translating input {input} node {node}: {error}")
            }
            BadInput {
                input,
                node,
                field,
                expected,
                found,
            } => {
                write!(f, "merge: input {input}")?;
                if let Some(n) = node {
                    write!(f, " node {n}")?;
                }
                write!(f, " field `{field}`: expected {expected}, found {found}")
            }
            BadRatio { mode, num, den } => write!(
                f,
                "merge: mode {mode} ratio {num}/{den}: expected 0 <= num <= den and den >= 1"
            ),
            LevelNotCandidate { level, lo, hi } => write!(
                f,
                "merge: fixed merging level {level} is not a candidate level: expected {lo}..={hi}"
            ),
            BelowTopTooDeep { k, lo, hi } => write!(
                f,
                "merge: {k} levels below the top ({lo}) is deeper than the deepest candidate level {hi}"
            ),
            InputLeafAtTop { input, node } => write!(
                f,
                "merge: input {input} leaf {node} would be a root at LOD 0 of the merged hierarchy: expected an inner node"
            ),
            IndexOverflow {
                what,
                value,
                index_bits,
            } => write!(
                f,
                "merge: {what} = {value} does not fit in I = {index_bits} index bits"
            ),
            Store(e) => write!(f, "merge: S618 storing the merged hierarchy: {e}"),
            Unsupported { what } => write!(f, "merge: {what}"),
        }
    }
}

impl std::error::Error for MergeError {}
