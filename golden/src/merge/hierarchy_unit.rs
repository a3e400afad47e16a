//! The hierarchy unit (docs/hardware.md 8.16): the translation unit (7.9)
//! and the hierarchy merger top (8.15) as one block behind one in-order
//! command stream, so that the merger's inputs are placed by the table the
//! translation unit wrote, and nothing of the translation or the candidate
//! range passes through software.
//!
//! A `cmd` beat is a **determine** command (the translation unit's
//! `det_in` beat: a placement that writes the table) or a **merge** command
//! (the inputs' ids and headers, the input count and the output id). The
//! unit reads each input's translation from the table and computes the
//! candidate range `(lo, hi)` from the headers' `top` and `deep`
//! ([`header_range`], SPEC 8.2), then starts the merger. Commands take
//! effect in order: a merge waits until every determine before it has left
//! the translation unit, so it sees their table writes.

use crate::bits::Bits;
use crate::layout::{Field, Layout, LayoutError};
use crate::params::{bits_to_hold, Params};
use crate::store::{Hierarchy, HierarchyStore};
use crate::translate::TranslationTable;

use super::{MergeError, MergeMode};
use crate::merge::level_choice::deep_lod;
use crate::merge::merger::{merger_transaction_in_range, MergerSizes, MergerTransaction};

/// `kind` of a determine command.
pub const KIND_DETERMINE: u64 = 0;
/// `kind` of a merge command.
pub const KIND_MERGE: u64 = 1;

/// What a merge command says of one input: its id and its header, as the
/// store keeps them beside the hierarchy.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct InputHeader {
    /// The input's hierarchy id: its table entry and its store arrays.
    pub hier: u8,
    /// `root_count`.
    pub roots: u32,
    /// The LOD of the roots.
    pub top: u8,
    /// The deepest LOD of an inner node; `top` when there is none
    /// ([`deep_lod`]).
    pub deep: u8,
    /// The length of the `nodes` array.
    pub nodes: u32,
    /// The length of the `refs` array.
    pub refs: u32,
}

impl InputHeader {
    /// The header of `h`.
    pub fn of(h: &Hierarchy) -> InputHeader {
        InputHeader {
            hier: h.id,
            roots: h.root_count,
            top: h.top_lod,
            deep: deep_lod(h),
            nodes: h.nodes.len() as u32,
            refs: h.refs.len() as u32,
        }
    }
}

/// A merge command: the used inputs in rank order, and the merged
/// hierarchy's id.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MergeCmd {
    /// The inputs, rank order (`1..=k` of them).
    pub inputs: Vec<InputHeader>,
    /// The merged hierarchy's id.
    pub out_id: u8,
}

/// The candidate range as the hardware computes it from the headers:
/// `lo = max top`, `hi = max(lo, min deep)`, SPEC 8.2's range over the
/// inputs' node arrays when the headers are theirs. Over no inputs, `lo = 0`
/// and `hi` is the largest `lod_bits` value (a range the merging module
/// refuses when it is past `D`).
pub fn header_range(inputs: &[InputHeader], p: &Params) -> (u8, u8) {
    let lo = inputs.iter().map(|h| h.top).max().unwrap_or(0);
    let none = ((1u32 << p.lod_bits()) - 1) as u8;
    let deep = inputs.iter().map(|h| h.deep).min().unwrap_or(none);
    (lo, deep.max(lo))
}

/// The fields of one input's header in a merge command, from the input's
/// first bit: `hier` (H), `roots` (I), `top`, `deep` (`lod_bits` each),
/// `nodes`, `refs` (I each).
/// A [`Layout`] (through `Deref`) with an accessor per field.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct InputFields {
    /// The input's hierarchy id.
    pub hier: Field,
    /// `root_count`.
    pub roots: Field,
    /// The roots' LOD.
    pub top: Field,
    /// The deepest inner node's LOD.
    pub deep: Field,
    /// The `nodes` array's length.
    pub nodes: Field,
    /// The `refs` array's length.
    pub refs: Field,
    layout: Layout,
}

impl std::ops::Deref for InputFields {
    type Target = Layout;
    fn deref(&self) -> &Layout {
        &self.layout
    }
}

impl InputFields {
    fn new(p: &Params) -> InputFields {
        let (h, i, lb) = (p.hier_bits as u32, p.index_bits as u32, p.lod_bits());
        let mut layout = Layout::new("merge command input");
        let hier = layout.push("hier", h);
        let roots = layout.push("roots", i);
        let top = layout.push("top", lb);
        let deep = layout.push("deep", lb);
        let nodes = layout.push("nodes", i);
        let refs = layout.push("refs", i);
        InputFields {
            hier,
            roots,
            top,
            deep,
            nodes,
            refs,
            layout,
        }
    }
}

/// Bit layout of the `cmd` beat: from bit 0 either the translation unit's
/// `det_in` beat (`det_width` bits, 7.9) or a merge command, `input0` ..
/// `input{k-1}` ([`InputFields`]), `count` (`bits_to_hold(k)`), `out_id`
/// (H); then `kind` (1 bit, [`KIND_DETERMINE`] or [`KIND_MERGE`]) above the
/// wider of the two. The two commands are two [`Layout`]s of one width,
/// [`Self::determine`] and [`Self::merge`], that agree on `kind`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CmdLayout {
    /// Inputs the merger has.
    pub k: usize,
    /// One input's header fields, relative to [`Self::input_offset`].
    pub input: InputFields,
    /// A determine command: `det` (the `det_in` beat), `kind`.
    pub determine: Layout,
    /// A merge command: `input<i>.hier` .. `input<i>.refs` per input,
    /// `count`, `out_id`, `kind`.
    pub merge: Layout,
    /// Inputs used, `1..=k`.
    pub count: Field,
    /// The merged hierarchy's id.
    pub out_id: Field,
    /// Bits of a merge command.
    pub merge_width: u32,
    /// Bits of a determine command (the translation unit's `det_in` beat).
    pub det_width: u32,
    /// Which command.
    pub kind: Field,
    /// Bits of the beat.
    pub width: u32,
    inputs: Vec<Field>,
}

impl CmdLayout {
    /// The layout for `p`, `k` inputs and a `det_in` beat of `det_width`
    /// bits (the translation unit's, which its generator lays out).
    pub fn new(p: &Params, k: usize, det_width: u32) -> CmdLayout {
        let input = InputFields::new(p);
        let mut merge = Layout::new("merge command");
        let inputs = (0..k)
            .map(|i| merge.nest(&format!("input{i}"), &input))
            .collect();
        let count = merge.push("count", bits_to_hold(k as u64));
        let out_id = merge.push("out_id", p.hier_bits as u32);
        let merge_width = merge.width();
        let kind = merge.push_at("kind", merge_width.max(det_width), 1);
        let mut determine = Layout::new("determine command");
        determine.push("det", det_width);
        determine.push_at("kind", kind.offset, 1);
        CmdLayout {
            k,
            input,
            determine,
            merge,
            count,
            out_id,
            merge_width,
            det_width,
            kind,
            width: kind.end(),
            inputs,
        }
    }

    /// Where `input<i>` starts.
    pub fn input_offset(&self, i: usize) -> u32 {
        self.inputs[i].offset
    }

    /// Field `f` of [`InputFields`] moved to input `i`.
    pub fn input_field(&self, i: usize, f: &Field) -> Field {
        Field::new(f.name, self.input_offset(i) + f.offset, f.width)
    }

    /// A determine command carrying the `det_in` beat `det`.
    pub fn pack_determine(&self, det: &Bits) -> Result<Bits, LayoutError> {
        if det.width() != self.det_width {
            return Err(LayoutError::WrongWidth {
                what: "determine command's det_in beat",
                expected: self.det_width,
                found: det.width(),
            });
        }
        // `det` may be wider than the 64 bits `Layout::pack` takes per field.
        let mut b = self.determine.zero();
        b.put(0, det)?;
        b.set(&self.kind, KIND_DETERMINE)?;
        Ok(b)
    }

    /// A merge command (unused inputs' fields 0); an error when more inputs
    /// than `k` or a value does not fit its field.
    pub fn pack_merge(&self, cmd: &MergeCmd) -> Result<Bits, LayoutError> {
        if cmd.inputs.len() > self.k {
            return Err(LayoutError::DoesNotFit {
                field: "count",
                value: cmd.inputs.len() as u64,
                width: self.count.width,
            });
        }
        let mut values = Vec::new();
        for i in 0..self.k {
            let header = cmd.inputs.get(i).map_or([0; 6], |h| {
                let (hier, top, deep) = (h.hier as u64, h.top as u64, h.deep as u64);
                [
                    hier,
                    h.roots as u64,
                    top,
                    deep,
                    h.nodes as u64,
                    h.refs as u64,
                ]
            });
            for (f, v) in self.input.fields().zip(header) {
                values.push((format!("input{i}.{}", f.name), v));
            }
        }
        values.push(("count".into(), cmd.inputs.len() as u64));
        values.push(("out_id".into(), cmd.out_id as u64));
        values.push(("kind".into(), KIND_MERGE));
        self.merge.pack(&values)
    }
}

/// The merge command of inputs `ids` (rank order) of `store` into `out_id`.
pub fn merge_cmd(store: &HierarchyStore, ids: &[u8], out_id: u8) -> Result<MergeCmd, MergeError> {
    let inputs = ids
        .iter()
        .map(|&id| {
            store
                .get(id)
                .map(InputHeader::of)
                .ok_or(MergeError::UnknownInput(id))
        })
        .collect::<Result<_, _>>()?;
    Ok(MergeCmd { inputs, out_id })
}

/// The merge `cmd` through the hierarchy unit: the merger's transaction
/// over `store`, placed by `table` as the determine commands before it
/// left it, with the candidate range of the headers ([`header_range`]).
/// An error when a header is not its hierarchy's in `store` (the hardware
/// trusts the headers; golden models only true ones), or as
/// [`merger_transaction_in_range`] refuses.
pub fn hierarchy_merge(
    store: &HierarchyStore,
    table: &TranslationTable,
    cmd: &MergeCmd,
    mode: MergeMode,
    k: usize,
    sizes: MergerSizes,
) -> Result<MergerTransaction, MergeError> {
    let ids: Vec<u8> = cmd.inputs.iter().map(|h| h.hier).collect();
    let truth = merge_cmd(store, &ids, cmd.out_id)?;
    if let Some((said, real)) = cmd.inputs.iter().zip(&truth.inputs).find(|(a, b)| a != b) {
        return Err(MergeError::BadInput {
            input: said.hier,
            node: None,
            field: "header",
            expected: format!("{real:?} (the store's)"),
            found: format!("{said:?}"),
        });
    }
    let p = match cmd.inputs.first().and_then(|h| store.get(h.hier)) {
        Some(h) => h.params,
        None => return Err(MergeError::NoInputs),
    };
    let range = header_range(&cmd.inputs, &p);
    merger_transaction_in_range(store, table, &ids, mode, cmd.out_id, k, sizes, Some(range))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::merge::level_choice::candidate_range;
    use crate::merge::stimulus::soup;
    use crate::translate::stimulus::SplitMix64;

    /// 1..=4 random soups of different sizes (so tops and depths differ),
    /// ids 1.., in one store.
    fn random_store(seed: u64) -> (HierarchyStore, Vec<u8>) {
        let p = Params::default();
        let mut rng = SplitMix64(seed);
        let mut store = HierarchyStore::new();
        let n = 1 + rng.below(4) as u8;
        for id in 1..=n {
            let tris = 1 + rng.below(12) as usize;
            let size = 0.01 + rng.below(40) as f32 / 100.0;
            store
                .insert(soup(&p, id, tris, size, rng.next_u64()))
                .unwrap();
        }
        (store, (1..=n).collect())
    }

    /// The range off the headers is SPEC 8.2's range off the node arrays,
    /// which `candidate_range` computes by scanning them.
    #[test]
    fn header_range_is_the_node_arrays_range() {
        let mut deeps_differ = 0;
        for seed in 0..40u64 {
            let (store, ids) = random_store(seed);
            let hs: Vec<&Hierarchy> = ids.iter().map(|&id| store.get(id).unwrap()).collect();
            let cmd = merge_cmd(&store, &ids, 0).unwrap();
            let p = hs[0].params;
            assert_eq!(
                header_range(&cmd.inputs, &p),
                candidate_range(&hs),
                "seed {seed}"
            );
            let deep = cmd.inputs.iter().map(|h| h.deep);
            deeps_differ += (deep.clone().min() != deep.max()) as usize;
        }
        // Else the min over `deep` would go untested.
        assert!(
            deeps_differ > 5,
            "only {deeps_differ} stores of differing depths"
        );
    }

    #[test]
    fn a_wrong_header_is_refused_by_name() {
        let (store, ids) = random_store(7);
        let mut cmd = merge_cmd(&store, &ids, 0).unwrap();
        cmd.inputs[0].deep ^= 1;
        let table = TranslationTable::new(16, &store.get(ids[0]).unwrap().params).unwrap();
        let sizes = MergerSizes::new(&store.get(ids[0]).unwrap().params);
        let e = hierarchy_merge(&store, &table, &cmd, MergeMode::default(), 4, sizes).unwrap_err();
        assert!(e.to_string().contains("header"), "{e}");
    }

    #[test]
    fn commands_pack_kind_above_the_wider_payload() {
        let p = Params::default();
        let l = CmdLayout::new(&p, 4, 300);
        assert_eq!(l.kind.offset, 300.max(l.merge_width));
        let det = Bits::zero(300);
        let b = l.pack_determine(&det).unwrap();
        assert_eq!(b.get(&l.kind).unwrap(), KIND_DETERMINE);
        assert!(l.pack_determine(&Bits::zero(299)).is_err());
        assert_eq!(l.determine.width(), l.merge.width());
        assert_eq!(l.merge.get("kind").unwrap(), &l.kind);
        assert_eq!(l.merge.get("input2.roots").unwrap(), &{
            let f = l.input_field(2, &l.input.roots);
            Field::new("input2.roots", f.offset, f.width)
        });
        let h = InputHeader {
            hier: 3,
            roots: 2,
            top: 5,
            deep: 9,
            nodes: 40,
            refs: 7,
        };
        let cmd = MergeCmd {
            inputs: vec![h, h],
            out_id: 15,
        };
        let b = l.pack_merge(&cmd).unwrap();
        assert_eq!(b.get(&l.kind).unwrap(), KIND_MERGE);
        assert_eq!(b.get(&l.count).unwrap(), 2);
        assert_eq!(b.get(&l.input_field(1, &l.input.deep)).unwrap(), 9);
        assert_eq!(b.get(&l.input_field(2, &l.input.hier)).unwrap(), 0);
        let five = MergeCmd {
            inputs: vec![h; 5],
            out_id: 0,
        };
        assert!(l.pack_merge(&five).is_err());
    }
}
