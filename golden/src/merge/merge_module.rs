//! The merging module as one unit (SPEC.md section 8.10): the beat formats of
//! its ports and its transaction, one merge, whose expected outputs come from
//! the golden stage functions ([`crate::merge::level_choice::choose_level`],
//! [`crate::merge::level_choice::unit::overlap_transaction`], [`crate::merge::merge_level::unit::level_transaction`]),
//! never from a second model.
//!
//! A merge on the unit's ports:
//! 1. `cfg`: one beat `(lo, hi)`, the candidate levels (8.2; the fetcher
//!    reads them off the inputs' headers).
//! 2. Overlap mode only, the **count pass**: for every candidate LOD `lo..=hi`
//!    in turn, each of the `k` input streams carries that input's translated
//!    nodes at the LOD in Morton order ([`input_stream`]) then `End`; the unit
//!    reports `(lod, shared, union, above, overflow)` per level.
//! 3. The **choice**: one `report` beat with `chosen` set: the merging level,
//!    or an error code ([`choice_err`]), after which the merge ends.
//! 4. The **merge pass**: each input stream carries its nodes at the chosen
//!    level, each voxel's inner node(s), leaf, then the inner nodes' child
//!    references, then `End`; `out` carries S614's base beats
//!    ([`crate::merge::merge_level::unit::BaseBeat`]) and `End`.
//!
//! Inside, a k-way merge by `(Morton code, phase, rank)` (phase: inner 0,
//! leaf 1, child reference 2) turns the `k` input streams into S614's
//! delivery order ([`crate::merge::merge_level::unit::level_stream`]), which is what makes the
//! per-input streams enough: a child reference's key is its parent's voxel.

use crate::bits::Bits;
use crate::layout::{Field, Layout, LayoutError};
use crate::merge::error::MergeError;
use crate::merge::fetcher::walk::{children, PlacedNode};
use crate::merge::level_choice::unit::{overlap_transaction, OverlapResult};
use crate::merge::level_choice::{choose_level, LevelOverlap};
use crate::merge::merge_level::unit::{
    level_transaction, random_level_case_at, BaseBeat, LevelBeat, LevelCase,
};
use crate::merge::MergeMode;
use crate::params::Params;
use crate::store::Hierarchy;
use crate::translate::stimulus::SplitMix64;

/// Error codes of a `report` beat with `chosen` set.
pub mod choice_err {
    /// The level is chosen.
    pub const NONE: u64 = 0;
    /// `Fixed(l)` outside `[lo, hi]`, or `BelowTop(k)` with `lo + k > hi`.
    pub const NOT_CANDIDATE: u64 = 1;
    /// A level's `union` reached `2^I` (the overlap counter's flag).
    pub const COUNT_OVERFLOW: u64 = 2;
    /// The `cfg` beat had `lo > hi` or `hi > D`.
    pub const BAD_RANGE: u64 = 3;
}

/// Bit layouts of the unit's `cfg` and `report` beats. The input streams
/// carry S614 input beats and `out` S614 output beats
/// ([`crate::merge::merge_level::unit::BeatLayout`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TopLayout {
    /// The `cfg` beat, from bit 0: `lo`, `hi` (`lod_bits` each).
    pub cfg: Layout,
    /// `cfg`: `lo` (`lod_bits`), the shallowest candidate level.
    pub lo: Field,
    /// `cfg`: `hi` (`lod_bits`), the deepest candidate level.
    pub hi: Field,
    /// The `report` beat, from bit 0: `lod`, `shared`, `union` (I each),
    /// `above`, `overflow`, `chosen` (1 each), `err` (2).
    pub report: Layout,
    /// `report`: `lod` (`lod_bits`), the counted or chosen level.
    pub lod: Field,
    /// `report`: `shared` (I bits), a counted level's shared voxels.
    pub shared: Field,
    /// `report`: `union` (I bits), a counted level's occupied voxels.
    pub union: Field,
    /// `report`: `above`, the counted level is above the threshold.
    pub above: Field,
    /// `report`: `overflow`, the counted level's `union` reached `2^I`.
    pub overflow: Field,
    /// `report`: `chosen`, set on the choice beat.
    pub chosen: Field,
    /// `report`: `err` (2 bits), the choice's [`choice_err`] code.
    pub err: Field,
}

impl TopLayout {
    /// The layouts for `p`.
    pub fn new(p: &Params) -> TopLayout {
        let lb = p.lod_bits();
        let i = p.index_bits as u32;
        let mut cfg = Layout::new("merging module cfg");
        let lo = cfg.push("lo", lb);
        let hi = cfg.push("hi", lb);
        let mut report = Layout::new("merging module report");
        let lod = report.push("lod", lb);
        let shared = report.push("shared", i);
        let union = report.push("union", i);
        let above = report.push("above", 1);
        let overflow = report.push("overflow", 1);
        let chosen = report.push("chosen", 1);
        let err = report.push("err", 2);
        TopLayout {
            cfg,
            lo,
            hi,
            report,
            lod,
            shared,
            union,
            above,
            overflow,
            chosen,
            err,
        }
    }

    /// The packed `cfg` beat.
    pub fn pack_cfg(&self, lo: u8, hi: u8) -> Result<Bits, LayoutError> {
        self.cfg.pack(&[("lo", lo as u64), ("hi", hi as u64)])
    }
}

/// One beat of the `report` stream.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Report {
    /// The overlap counter's result of one candidate level (count pass).
    Counted {
        /// The counted level.
        lod: u8,
        /// The overlap counter's out beat for that level.
        result: OverlapResult,
    },
    /// The merging level (`lod` 0 when `err` is not [`choice_err::NONE`]).
    Chosen {
        /// The merging level; 0 when refused.
        lod: u8,
        /// A [`choice_err`] code.
        err: u64,
    },
}

impl Report {
    /// The packed beat.
    pub fn pack(&self, l: &TopLayout) -> Result<Bits, LayoutError> {
        let mut b = l.report.zero();
        match self {
            Report::Counted { lod, result } => {
                b.set(&l.lod, *lod as u64)?;
                b.set(&l.shared, result.shared)?;
                b.set(&l.union, result.union)?;
                b.set(&l.above, result.above as u64)?;
                b.set(&l.overflow, result.overflow as u64)?;
            }
            Report::Chosen { lod, err } => {
                b.set(&l.lod, *lod as u64)?;
                b.set(&l.chosen, 1)?;
                b.set(&l.err, *err)?;
            }
        }
        Ok(b)
    }
}

/// One merge through the unit: the `cfg` beat, each input stream's beats
/// (count pass, then merge pass), the expected `report` and `out` beats.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TopTransaction {
    /// `cfg`: `lo`, the shallowest candidate level.
    pub lo: u8,
    /// `cfg`: `hi`, the deepest candidate level.
    pub hi: u8,
    /// `inputs[r]`: input `r`'s beats, the count pass's levels (overlap mode)
    /// then the chosen level's, each level ending in `End`.
    pub inputs: Vec<Vec<LevelBeat>>,
    /// The expected `report` beats: one per counted level, then the choice.
    pub reports: Vec<Report>,
    /// The expected `out` beats at the chosen level, `End` last; empty when refused.
    pub out: Vec<BaseBeat>,
}

/// Input `rank`'s stream of one level: its nodes in (Morton, leaf) order
/// (stable from `at_level`, as S614's sort), per voxel the inner node(s),
/// the leaf, then (with `refs`) the inner nodes' child references; `End`.
pub fn input_stream(
    at_level: &[PlacedNode],
    inputs: &[&Hierarchy],
    rank: u16,
    refs: bool,
) -> Result<Vec<LevelBeat>, MergeError> {
    let mut mine: Vec<PlacedNode> = at_level
        .iter()
        .filter(|n| n.rank == rank)
        .copied()
        .collect();
    mine.sort_by_key(|n| (n.record.voxel.morton(), n.record.leaf));
    let mut out = Vec::new();
    let mut i = 0;
    while i < mine.len() {
        let v = mine[i].record.voxel;
        let j = i + mine[i..].iter().take_while(|n| n.record.voxel == v).count();
        let group = &mine[i..j];
        for n in group {
            out.push(LevelBeat::of_node(n));
        }
        if refs {
            for n in group.iter().filter(|n| !n.record.leaf) {
                let h = inputs[rank as usize];
                let rs = children(h, n.at.node, &h.nodes[n.at.node as usize])?;
                out.extend(rs.iter().map(|r| LevelBeat::ChildRef(*r)));
            }
        }
        i = j;
    }
    out.push(LevelBeat::End);
    Ok(out)
}

/// The unit's choice over `[lo, hi]` (after `counted`, the count pass's
/// results in LOD order, in overlap mode): golden [`choose_level`] behind the
/// unit's own refusals (a bad range, a count overflow).
pub fn choose(mode: &MergeMode, p: &Params, lo: u8, hi: u8, counted: &[OverlapResult]) -> Report {
    let refuse = |err| Report::Chosen { lod: 0, err };
    if lo > hi || hi > p.max_lod {
        return refuse(choice_err::BAD_RANGE);
    }
    if counted.iter().any(|r| r.overflow) {
        return refuse(choice_err::COUNT_OVERFLOW);
    }
    let overlap: Vec<LevelOverlap> = counted
        .iter()
        .zip(lo..)
        .map(|(r, lod)| LevelOverlap {
            lod,
            shared: r.shared,
            union: r.union,
        })
        .collect();
    match choose_level(mode, lo, hi, &overlap) {
        Ok(Some(lod)) => Report::Chosen {
            lod,
            err: choice_err::NONE,
        },
        _ => refuse(choice_err::NOT_CANDIDATE),
    }
}

/// The merge of `levels` (the candidate levels' nodes, `lo..=hi` in order;
/// only the chosen level is read outside overlap mode, so the others may be
/// absent: `levels[l - lo]` must exist for the chosen `l`). `count_refs`:
/// the count pass's streams carry child references too (the unit drops
/// them). Refuses [`MergeMode::PerNode`]: its merges go in LOD passes
/// ([`crate::merge::per_node::unit::per_node_transaction`]).
pub fn top_transaction(
    mode: &MergeMode,
    p: &Params,
    k: usize,
    lo: u8,
    hi: u8,
    levels: &[Option<LevelCase>],
    count_refs: bool,
) -> Result<TopTransaction, MergeError> {
    let overlap_mode = match *mode {
        MergeMode::Overlap { .. } => true,
        MergeMode::PerNode { .. } => {
            return Err(MergeError::Unsupported {
                what: "a per-node merge is per_node::unit::per_node_transaction's (SPEC 8.14)",
            })
        }
        _ => false,
    };
    let mut tx = TopTransaction {
        lo,
        hi,
        inputs: vec![Vec::new(); k],
        reports: Vec::new(),
        out: Vec::new(),
    };
    let range_ok = lo <= hi && hi <= p.max_lod;
    let mut counted = Vec::new();
    if overlap_mode && range_ok {
        let MergeMode::Overlap { num, den } = *mode else {
            unreachable!("overlap mode")
        };
        for (lod, case) in (lo..=hi).zip(levels) {
            let case = case.as_ref().ok_or(MergeError::Unsupported {
                what: "overlap mode needs every candidate level",
            })?;
            let hs: Vec<&Hierarchy> = case.hierarchies.iter().collect();
            let mut voxels = vec![Vec::new(); k];
            for n in &case.at_level {
                voxels[n.rank as usize].push(n.record.voxel);
            }
            for (r, stream) in tx.inputs.iter_mut().enumerate() {
                stream.extend(input_stream(&case.at_level, &hs, r as u16, count_refs)?);
            }
            let (_, result) = overlap_transaction(&voxels, p, num, den);
            counted.push(result);
            tx.reports.push(Report::Counted { lod, result });
        }
    }
    let choice = choose(mode, p, lo, hi, &counted);
    tx.reports.push(choice);
    if let Report::Chosen {
        lod,
        err: choice_err::NONE,
    } = choice
    {
        let case = levels
            .get((lod - lo) as usize)
            .and_then(|c| c.as_ref())
            .ok_or(MergeError::Unsupported {
                what: "no nodes given at the chosen level",
            })?;
        let hs: Vec<&Hierarchy> = case.hierarchies.iter().collect();
        for (r, stream) in tx.inputs.iter_mut().enumerate() {
            stream.extend(input_stream(&case.at_level, &hs, r as u16, true)?);
        }
        tx.out = level_transaction(&case.at_level, &hs, p)?.outputs;
    }
    Ok(tx)
}

/// A random merge for `mode` with `k` inputs: candidate ranges of one to four
/// levels anywhere in `0..=D` (sometimes a bad range), levels of 1 to
/// `most_voxels` voxels with every kind of overlap ([`random_level_case_at`]).
pub fn random_top_transaction(
    rng: &mut SplitMix64,
    p: &Params,
    k: usize,
    mode: &MergeMode,
    most_voxels: usize,
) -> Result<TopTransaction, MergeError> {
    let d = p.max_lod;
    let lod_cap = (1u64 << p.lod_bits()) - 1;
    let (lo, hi) = if rng.below(32) == 0 {
        // The unit's refusal: lo > hi, or hi beyond D when the field holds it.
        let lo = 1 + rng.below(d as u64) as u8;
        if lod_cap > d as u64 && rng.below(2) == 0 {
            (
                lo.min(d),
                (d as u64 + 1 + rng.below(lod_cap - d as u64)) as u8,
            )
        } else {
            (lo, lo - 1)
        }
    } else {
        let lo = match (*mode, rng.below(4)) {
            // Ranges near the built-in level, so that it is chosen and refused.
            (MergeMode::Fixed(l), 0 | 1) => l.min(d).saturating_sub(rng.below(3) as u8),
            (_, 0) => 0,
            (_, 1) => d,
            _ => rng.below(d as u64 + 1) as u8,
        };
        let spread = match *mode {
            MergeMode::BelowTop(k) => 2 * k as u64 + 3,
            _ => 4,
        };
        let hi = (lo as u64 + rng.below(spread)).min(d as u64) as u8;
        (lo, hi)
    };
    let make = |lod: u8, rng: &mut SplitMix64| {
        let voxels = 1 + rng.below(most_voxels.max(1) as u64) as usize;
        Some(random_level_case_at(rng, p, k, voxels, lod))
    };
    let levels: Vec<Option<LevelCase>> = if lo > hi || hi > d {
        Vec::new()
    } else if matches!(*mode, MergeMode::Overlap { .. }) {
        (lo..=hi).map(|l| make(l, rng)).collect()
    } else {
        match choose(mode, p, lo, hi, &[]) {
            Report::Chosen { lod, err: 0 } => (lo..=hi)
                .map(|l| if l == lod { make(l, rng) } else { None })
                .collect(),
            _ => Vec::new(),
        }
    };
    let count_refs = rng.below(2) == 0;
    top_transaction(mode, p, k, lo, hi, &levels, count_refs)
}

/// A configuration of the merging hardware (the merging module, and the
/// merger top and the hierarchy unit built around it): what the generators,
/// the vectors and the benches are for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MergeDesign {
    /// Grid and record parameters (SPEC 1); they fix every beat's layout.
    pub params: Params,
    /// Inputs `k` of the overlap counter (and of the S614 stimulus).
    pub inputs: usize,
    /// How the merging module chooses the merging level: the only mode its
    /// hardware builds ([`Self::validate`]).
    pub mode: MergeMode,
    /// Root sorter capacity.
    pub roots: usize,
}

impl Default for MergeDesign {
    fn default() -> Self {
        MergeDesign {
            params: Params::default(),
            inputs: 4,
            mode: MergeMode::default(),
            roots: 16,
        }
    }
}

impl MergeDesign {
    /// The overlap counter's threshold `num / den`, in overlap mode (the
    /// only mode that counts).
    pub fn threshold(&self) -> Option<(u32, u32)> {
        match self.mode {
            MergeMode::Overlap { num, den } => Some((num, den)),
            _ => None,
        }
    }

    /// Refuses what the hardware cannot build: fewer than 2 or more than
    /// `2^H` inputs, a bad ratio, no root capacity.
    pub fn validate(&self) -> Result<(), String> {
        let cap = self.params.hier_capacity();
        if self.inputs < 2 || self.inputs as u64 > cap {
            return Err(format!(
                "inputs = {}: expected 2..={cap} (2^hier_bits)",
                self.inputs
            ));
        }
        if self.roots == 0 {
            return Err("roots = 0: expected a root sorter capacity of at least 1".into());
        }
        match self.mode {
            MergeMode::Overlap { num, den }
            | MergeMode::Proportion { num, den }
            | MergeMode::PerNode { num, den }
                if den == 0 || num > den =>
            {
                Err(format!(
                    "mode {}: expected N/D with 0 <= N <= D, D >= 1",
                    self.mode
                ))
            }
            MergeMode::Fixed(l) if l > self.params.max_lod => Err(format!(
                "mode {}: expected a level at most max_lod = {}",
                self.mode, self.params.max_lod
            )),
            _ => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::merge::merge_level::unit::{level_kind, level_stream};

    /// The per-input streams merged by `(Morton, kind, rank)` (a child
    /// reference keyed by its input's last node) are S614's delivery order:
    /// the rule the RTL merge network implements.
    #[test]
    fn merging_input_streams_by_key_gives_delivery_order() {
        let p = Params::default();
        let mut rng = SplitMix64(7);
        for _ in 0..300 {
            let k = 2 + rng.below(3) as usize;
            let lod = rng.below(p.max_lod as u64 + 1) as u8;
            let voxels = 1 + rng.below(20) as usize;
            let case = random_level_case_at(&mut rng, &p, k, voxels, lod);
            let hs: Vec<&Hierarchy> = case.hierarchies.iter().collect();
            let mut streams: Vec<std::collections::VecDeque<LevelBeat>> = (0..k)
                .map(|r| {
                    input_stream(&case.at_level, &hs, r as u16, true)
                        .unwrap()
                        .into()
                })
                .collect();
            let mut last = vec![0u128; k];
            let mut merged = Vec::new();
            loop {
                let key = |r: usize, b: &LevelBeat| match b {
                    LevelBeat::Inner { record, .. } => {
                        (0, record.voxel.morton(), level_kind::INNER, r)
                    }
                    LevelBeat::Leaf { record, .. } => {
                        (0, record.voxel.morton(), level_kind::LEAF, r)
                    }
                    LevelBeat::ChildRef(_) => (0, last[r], level_kind::CHILD_REF, r),
                    LevelBeat::End => (1, 0, level_kind::END, r),
                };
                let (r, b) = streams
                    .iter()
                    .enumerate()
                    .map(|(r, s)| (r, *s.front().expect("a stream ends with End")))
                    .min_by_key(|(r, b)| key(*r, b))
                    .unwrap();
                if b == LevelBeat::End {
                    merged.push(b);
                    break;
                }
                if let LevelBeat::Inner { record, .. } | LevelBeat::Leaf { record, .. } = b {
                    last[r] = record.voxel.morton();
                }
                streams[r].pop_front();
                merged.push(b);
            }
            let mut want: Vec<LevelBeat> = level_stream(&case.at_level, &hs)
                .unwrap()
                .into_iter()
                .flat_map(|(_, beats)| beats)
                .collect();
            want.push(LevelBeat::End);
            assert_eq!(merged, want);
        }
    }

    #[test]
    fn choices_follow_the_mode_and_refuse_bad_ranges() {
        let p = Params::default();
        let r = |shared, union| OverlapResult {
            shared,
            union,
            above: false,
            overflow: false,
        };
        let ov = MergeMode::Overlap { num: 1, den: 2 };
        // Deepest above 1/2: LOD 4 (3 of 4 shared), not 5 (1 of 4).
        let counted = [r(2, 2), r(3, 4), r(1, 4)];
        assert_eq!(
            choose(&ov, &p, 3, 5, &counted),
            Report::Chosen {
                lod: 4,
                err: choice_err::NONE
            }
        );
        assert_eq!(
            choose(&ov, &p, 3, 5, &[r(0, 1), r(1, 2), r(0, 0)]),
            Report::Chosen { lod: 3, err: 0 }
        );
        let mut o = r(0, 0);
        o.overflow = true;
        assert_eq!(
            choose(&ov, &p, 3, 3, &[o]).clone(),
            Report::Chosen {
                lod: 0,
                err: choice_err::COUNT_OVERFLOW
            }
        );
        assert_eq!(
            choose(&ov, &p, 5, 4, &[]),
            Report::Chosen {
                lod: 0,
                err: choice_err::BAD_RANGE
            }
        );
        assert_eq!(
            choose(&ov, &p, 3, 17, &[]),
            Report::Chosen {
                lod: 0,
                err: choice_err::BAD_RANGE
            }
        );
        assert_eq!(
            choose(&MergeMode::Fixed(6), &p, 3, 5, &[]),
            Report::Chosen {
                lod: 0,
                err: choice_err::NOT_CANDIDATE
            }
        );
        assert_eq!(
            choose(&MergeMode::BelowTop(2), &p, 3, 5, &[]),
            Report::Chosen { lod: 5, err: 0 }
        );
        assert_eq!(
            choose(&MergeMode::Proportion { num: 1, den: 3 }, &p, 2, 9, &[]),
            Report::Chosen { lod: 4, err: 0 }
        );
        assert!(top_transaction(
            &MergeMode::PerNode { num: 1, den: 2 },
            &p,
            2,
            0,
            0,
            &[],
            false
        )
        .is_err());
    }

    /// Every random merge is well formed: each input stream ends every pass
    /// with `End`, a refused choice has no merge pass, `out` ends with `End`.
    #[test]
    fn random_merges_are_well_formed() {
        let p = Params::new(8, 2, 10, 3).unwrap();
        let mut rng = SplitMix64(11);
        let mut refused = 0;
        for mode in [
            MergeMode::Overlap { num: 1, den: 2 },
            MergeMode::Fixed(3),
            MergeMode::BelowTop(1),
            MergeMode::Proportion { num: 2, den: 3 },
        ] {
            for _ in 0..200 {
                let tx = random_top_transaction(&mut rng, &p, 3, &mode, 12).unwrap();
                let passes = match tx.reports.last() {
                    Some(Report::Chosen { err: 0, .. }) => {
                        assert_eq!(tx.out.last(), Some(&BaseBeat::End));
                        1
                    }
                    Some(Report::Chosen { .. }) => {
                        refused += 1;
                        assert!(tx.out.is_empty());
                        0
                    }
                    other => panic!("the last report is the choice: {other:?}"),
                } + tx.reports.len()
                    - 1;
                for s in &tx.inputs {
                    assert_eq!(s.iter().filter(|b| **b == LevelBeat::End).count(), passes);
                }
            }
        }
        assert!(refused > 20, "refusals are exercised: {refused}");
    }
}
