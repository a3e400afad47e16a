//! The hierarchy store (SPEC.md section 3): node records, child references,
//! primitive indices and a header per hierarchy, addressed by hierarchy id.
//!
//! Records are kept unpacked ([`NodeRecord`], [`Reference`]) for speed; their
//! packed form, bit for bit what the hardware stores, comes from
//! [`NodeRecord::pack`] / [`Reference::pack`] with the layouts of
//! [`crate::layout`].

use std::collections::BTreeMap;
use std::fmt;

use crate::bits::Bits;
use crate::grid::VoxelAddr;
use crate::layout::{LayoutError, NodeLayout, RefLayout};
use crate::params::Params;

/// One node: a voxel, a box quantized inside it, and a range of children
/// (`refs`, inner node) or primitives (`prims`, leaf).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct NodeRecord {
    /// True: `first..first+count` indexes `prims`; false: it indexes `refs`.
    pub leaf: bool,
    /// The node's voxel.
    pub voxel: VoxelAddr,
    /// Box minimum cell per axis, `0..2^Q`, relative to the voxel.
    pub lo: [u16; 3],
    /// Box maximum cell (inclusive) per axis, `lo..2^Q`.
    pub hi: [u16; 3],
    /// First index into `refs` (inner) or `prims` (leaf).
    pub first: u32,
    /// Number of children or primitives; at least 1.
    pub count: u32,
}

/// A child reference: node `node` of hierarchy `hier`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Reference {
    /// Id of the hierarchy holding the child, below `2^H`.
    pub hier: u8,
    /// Index of the child in that hierarchy's `nodes`.
    pub node: u32,
}

/// A node record that is well formed bit-wise but not as a node.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RecordError {
    /// The field at fault, as SPEC 3 names it (`lod`, `x`, `lo_y`, `count`, ...).
    pub field: &'static str,
    /// The field's value.
    pub value: u64,
    /// What the field must be, e.g. `0..=16` or `below 2^Q = 256`.
    pub expected: String,
}

impl fmt::Display for RecordError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "node record field `{}` = {}: expected {}",
            self.field, self.value, self.expected
        )
    }
}

impl std::error::Error for RecordError {}

const AXIS_LO: [&str; 3] = ["lo_x", "lo_y", "lo_z"];
const AXIS_HI: [&str; 3] = ["hi_x", "hi_y", "hi_z"];
const AXIS_COORD: [&str; 3] = ["x", "y", "z"];

impl NodeRecord {
    /// Packs the record into `layout`'s bits. Every field is checked against
    /// its width (an error, never truncation); meaning is checked by
    /// [`NodeRecord::validate`], not here, so corrupt records can be packed on purpose.
    #[allow(clippy::needless_range_loop)] // per-axis loops over parallel arrays
    pub fn pack(&self, layout: &NodeLayout) -> Result<Bits, LayoutError> {
        let mut b = layout.zero();
        b.set(layout.leaf(), self.leaf as u64)?;
        b.set(layout.lod(), self.voxel.lod as u64)?;
        let c = [self.voxel.x, self.voxel.y, self.voxel.z];
        for axis in 0..3 {
            b.set(layout.coord(axis), c[axis] as u64)?;
            b.set(layout.lo(axis), self.lo[axis] as u64)?;
            b.set(layout.hi(axis), self.hi[axis] as u64)?;
        }
        b.set(layout.first(), self.first as u64)?;
        b.set(layout.count(), self.count as u64)?;
        Ok(b)
    }

    /// Reads a record back from `bits`, which must have `layout`'s width.
    pub fn unpack(bits: &Bits, layout: &NodeLayout) -> Result<NodeRecord, LayoutError> {
        if bits.width() != layout.width() {
            return Err(LayoutError::WrongWidth {
                what: "node record",
                expected: layout.width(),
                found: bits.width(),
            });
        }
        // Field widths bound every value: lod <= 5 bits, coords <= 31, Q <= 16, I <= 32.
        let mut lo = [0u16; 3];
        let mut hi = [0u16; 3];
        let mut c = [0u32; 3];
        for axis in 0..3 {
            c[axis] = bits.get(layout.coord(axis))? as u32;
            lo[axis] = bits.get(layout.lo(axis))? as u16;
            hi[axis] = bits.get(layout.hi(axis))? as u16;
        }
        Ok(NodeRecord {
            leaf: bits.get(layout.leaf())? == 1,
            voxel: VoxelAddr::new(bits.get(layout.lod())? as u8, c[0], c[1], c[2]),
            lo,
            hi,
            first: bits.get(layout.first())? as u32,
            count: bits.get(layout.count())? as u32,
        })
    }

    /// Checks that the record means a node under `p`: voxel inside the grid,
    /// `lo <= hi < 2^Q` per axis, `count >= 1`, indices and count within `I` bits.
    pub fn validate(&self, p: &Params) -> Result<(), RecordError> {
        let v = self.voxel;
        if v.lod > p.max_lod {
            return Err(RecordError {
                field: "lod",
                value: v.lod as u64,
                expected: format!("0..={}", p.max_lod),
            });
        }
        let c = [v.x, v.y, v.z];
        for axis in 0..3 {
            if (c[axis] as u64) >> v.lod != 0 {
                return Err(RecordError {
                    field: AXIS_COORD[axis],
                    value: c[axis] as u64,
                    expected: format!("below 2^{} at LOD {}", v.lod, v.lod),
                });
            }
            let cells = p.quant_cells() as u64;
            if self.hi[axis] as u64 >= cells {
                return Err(RecordError {
                    field: AXIS_HI[axis],
                    value: self.hi[axis] as u64,
                    expected: format!("below 2^Q = {cells}"),
                });
            }
            if self.lo[axis] > self.hi[axis] {
                return Err(RecordError {
                    field: AXIS_LO[axis],
                    value: self.lo[axis] as u64,
                    expected: format!("<= {} = {}", AXIS_HI[axis], self.hi[axis]),
                });
            }
        }
        let cap = p.index_capacity();
        if self.count == 0 || self.count as u64 >= cap {
            return Err(RecordError {
                field: "count",
                value: self.count as u64,
                expected: format!("1..2^I = 1..{cap}"),
            });
        }
        if self.first as u64 >= cap {
            return Err(RecordError {
                field: "first",
                value: self.first as u64,
                expected: format!("below 2^I = {cap}"),
            });
        }
        Ok(())
    }

    /// The index range this node's `first`/`count` covers (as u64, no overflow).
    pub fn range(&self) -> std::ops::Range<u64> {
        self.first as u64..self.first as u64 + self.count as u64
    }
}

impl Reference {
    /// Packs `node` into bits `[0, I)` and `hier` into `[I, I + H)`.
    pub fn pack(&self, layout: &RefLayout) -> Result<Bits, LayoutError> {
        let mut b = layout.zero();
        b.set(layout.node(), self.node as u64)?;
        b.set(layout.hier(), self.hier as u64)?;
        Ok(b)
    }

    /// Reads a reference back; `bits` must have `layout`'s width.
    pub fn unpack(bits: &Bits, layout: &RefLayout) -> Result<Reference, LayoutError> {
        if bits.width() != layout.width() {
            return Err(LayoutError::WrongWidth {
                what: "reference",
                expected: layout.width(),
                found: bits.width(),
            });
        }
        Ok(Reference {
            node: bits.get(layout.node())? as u32,
            hier: bits.get(layout.hier())? as u8,
        })
    }
}

/// The exact box of `n` in fine units (grid units times `2^Q`), per axis
/// `[(x << Q) e + lo e, (x << Q) e + (hi + 1) e]` with `e = 2^(D - d)`
/// (SPEC.md section 3). Returns `(min, max)`; both ends are inclusive as a
/// closed box. Exact: `D + Q <= 47` bits.
pub fn node_box_fine(n: &NodeRecord, p: &Params) -> ([u64; 3], [u64; 3]) {
    let e = p.voxel_edge(n.voxel.lod);
    let q = p.quant_bits as u32;
    let c = [n.voxel.x, n.voxel.y, n.voxel.z];
    let mut lo = [0u64; 3];
    let mut hi = [0u64; 3];
    for axis in 0..3 {
        let v0 = ((c[axis] as u64) << q) * e;
        lo[axis] = v0 + n.lo[axis] as u64 * e;
        hi[axis] = v0 + (n.hi[axis] as u64 + 1) * e;
    }
    (lo, hi)
}

/// The box of `n` in grid units as binary64: the fine-unit box divided by
/// `2^Q`, exact (integers below `2^47` scaled by a power of two).
pub fn node_box_grid(n: &NodeRecord, p: &Params) -> ([f64; 3], [f64; 3]) {
    let (lo, hi) = node_box_fine(n, p);
    let s = 1.0 / (1u64 << p.quant_bits) as f64;
    (lo.map(|v| v as f64 * s), hi.map(|v| v as f64 * s))
}

/// The voxel of `v` in fine units: `(min, max)` corners, per axis
/// `[x e 2^Q, (x + 1) e 2^Q]`.
pub fn voxel_box_fine(v: &VoxelAddr, p: &Params) -> ([u64; 3], [u64; 3]) {
    let e = p.voxel_edge(v.lod) << p.quant_bits;
    let c = [v.x as u64, v.y as u64, v.z as u64];
    (c.map(|c| c * e), c.map(|c| (c + 1) * e))
}

/// One hierarchy in the store.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Hierarchy {
    /// This hierarchy's id (below `2^H`).
    pub id: u8,
    /// The parameters its records are laid out with.
    pub params: Params,
    /// Node records; the roots are `nodes[0..root_count]`.
    pub nodes: Vec<NodeRecord>,
    /// Child references of inner nodes.
    pub refs: Vec<Reference>,
    /// Primitive (triangle) indices of leaves.
    pub prims: Vec<u32>,
    /// Number of roots at the front of `nodes`.
    pub root_count: u32,
    /// The LOD of every root.
    pub top_lod: u8,
}

impl Hierarchy {
    /// The root nodes.
    pub fn roots(&self) -> &[NodeRecord] {
        &self.nodes[..(self.root_count as usize).min(self.nodes.len())]
    }

    /// The child references of inner node `n` (empty for a leaf or a bad range).
    pub fn children_of(&self, n: &NodeRecord) -> &[Reference] {
        if n.leaf {
            return &[];
        }
        let r = n.range();
        self.refs
            .get(r.start as usize..r.end as usize)
            .unwrap_or(&[])
    }

    /// The primitive indices of leaf `n` (empty for an inner node or a bad range).
    pub fn prims_of(&self, n: &NodeRecord) -> &[u32] {
        if !n.leaf {
            return &[];
        }
        let r = n.range();
        self.prims
            .get(r.start as usize..r.end as usize)
            .unwrap_or(&[])
    }

    /// Every node record packed with `params`' node layout.
    pub fn pack_nodes(&self) -> Result<Vec<Bits>, LayoutError> {
        let l = NodeLayout::new(&self.params);
        self.nodes.iter().map(|n| n.pack(&l)).collect()
    }

    /// Every reference packed with `params`' reference layout.
    pub fn pack_refs(&self) -> Result<Vec<Bits>, LayoutError> {
        let l = RefLayout::new(&self.params);
        self.refs.iter().map(|r| r.pack(&l)).collect()
    }
}

/// A store refusing an insertion.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum StoreError {
    /// The id is already taken.
    IdInUse(u8),
    /// The id does not fit in `H` bits.
    IdOutOfRange {
        /// The refused id.
        id: u8,
        /// `H` of the hierarchy's parameters; ids must be below `2^H`.
        hier_bits: u8,
    },
}

impl fmt::Display for StoreError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            StoreError::IdInUse(id) => write!(f, "hierarchy id {id} is already in the store"),
            StoreError::IdOutOfRange { id, hier_bits } => {
                write!(f, "hierarchy id {id} does not fit in H = {hier_bits} bits")
            }
        }
    }
}

impl std::error::Error for StoreError {}

/// The hierarchy store: hierarchies by id. Adding one (e.g. a merged
/// hierarchy) never touches the others, so inputs stay valid for the next
/// frame (paragraph 66).
#[derive(Clone, Debug, Default)]
pub struct HierarchyStore {
    hierarchies: BTreeMap<u8, Hierarchy>,
}

impl HierarchyStore {
    /// An empty store.
    pub fn new() -> HierarchyStore {
        HierarchyStore::default()
    }

    /// Adds `h` under `h.id`; an error if the id is taken or exceeds `H` bits.
    pub fn insert(&mut self, h: Hierarchy) -> Result<(), StoreError> {
        if (h.id as u64) >= h.params.hier_capacity() {
            return Err(StoreError::IdOutOfRange {
                id: h.id,
                hier_bits: h.params.hier_bits,
            });
        }
        if self.hierarchies.contains_key(&h.id) {
            return Err(StoreError::IdInUse(h.id));
        }
        self.hierarchies.insert(h.id, h);
        Ok(())
    }

    /// Replaces (or adds) hierarchy `h.id`, returning the old one: a rebuilt
    /// dynamic hierarchy for a new frame.
    pub fn replace(&mut self, h: Hierarchy) -> Result<Option<Hierarchy>, StoreError> {
        if (h.id as u64) >= h.params.hier_capacity() {
            return Err(StoreError::IdOutOfRange {
                id: h.id,
                hier_bits: h.params.hier_bits,
            });
        }
        Ok(self.hierarchies.insert(h.id, h))
    }

    /// Removes hierarchy `id`.
    pub fn remove(&mut self, id: u8) -> Option<Hierarchy> {
        self.hierarchies.remove(&id)
    }

    /// Hierarchy `id`, if stored.
    pub fn get(&self, id: u8) -> Option<&Hierarchy> {
        self.hierarchies.get(&id)
    }

    /// The stored ids, ascending.
    pub fn ids(&self) -> impl Iterator<Item = u8> + '_ {
        self.hierarchies.keys().copied()
    }

    /// Number of stored hierarchies.
    pub fn len(&self) -> usize {
        self.hierarchies.len()
    }

    /// True when nothing is stored.
    pub fn is_empty(&self) -> bool {
        self.hierarchies.is_empty()
    }

    /// The node `r` points at, if both the hierarchy and the node exist.
    pub fn node(&self, r: Reference) -> Option<&NodeRecord> {
        self.get(r.hier)?.nodes.get(r.node as usize)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rec(lod: u8, x: u32, y: u32, z: u32, lo: [u16; 3], hi: [u16; 3]) -> NodeRecord {
        NodeRecord {
            leaf: false,
            voxel: VoxelAddr::new(lod, x, y, z),
            lo,
            hi,
            first: 0,
            count: 1,
        }
    }

    #[test]
    fn fine_box_matches_the_spec_formula() {
        let p = Params::new(4, 2, 8, 2).unwrap();
        // LOD 2 voxel (1, 2, 3): edge 4 grid units = 16 fine units, cells of 4 fine units.
        let n = rec(2, 1, 2, 3, [0, 1, 3], [3, 2, 3]);
        let (lo, hi) = node_box_fine(&n, &p);
        assert_eq!(lo, [16, 32 + 4, 48 + 12]);
        assert_eq!(hi, [32, 32 + 12, 64]);
        let (glo, ghi) = node_box_grid(&n, &p);
        assert_eq!(glo, [4.0, 9.0, 15.0]);
        assert_eq!(ghi, [8.0, 11.0, 16.0]);
        assert_eq!(voxel_box_fine(&n.voxel, &p), ([16, 32, 48], [32, 48, 64]));
    }

    #[test]
    fn q0_box_is_the_voxel() {
        let p = Params::new(5, 0, 8, 2).unwrap();
        let n = rec(3, 7, 0, 5, [0; 3], [0; 3]);
        assert_eq!(node_box_fine(&n, &p), voxel_box_fine(&n.voxel, &p));
    }

    #[test]
    fn validate_names_the_bad_field() {
        let p = Params::new(4, 2, 8, 2).unwrap();
        let good = rec(2, 3, 0, 1, [0, 0, 0], [3, 3, 3]);
        assert!(good.validate(&p).is_ok());
        assert_eq!(
            rec(2, 4, 0, 0, [0; 3], [0; 3])
                .validate(&p)
                .unwrap_err()
                .field,
            "x"
        );
        assert_eq!(
            rec(5, 0, 0, 0, [0; 3], [0; 3])
                .validate(&p)
                .unwrap_err()
                .field,
            "lod"
        );
        assert_eq!(
            rec(2, 0, 0, 0, [0; 3], [0, 4, 0])
                .validate(&p)
                .unwrap_err()
                .field,
            "hi_y"
        );
        assert_eq!(
            rec(2, 0, 0, 0, [0, 0, 2], [0, 0, 1])
                .validate(&p)
                .unwrap_err()
                .field,
            "lo_z"
        );
        let mut c = good;
        c.count = 0;
        assert_eq!(c.validate(&p).unwrap_err().field, "count");
    }

    #[test]
    fn store_keeps_inputs_and_refuses_reuse() {
        let p = Params::new(4, 2, 8, 2).unwrap();
        let h = |id| Hierarchy {
            id,
            params: p,
            nodes: vec![],
            refs: vec![],
            prims: vec![],
            root_count: 0,
            top_lod: 0,
        };
        let mut s = HierarchyStore::new();
        s.insert(h(1)).unwrap();
        assert_eq!(s.insert(h(1)), Err(StoreError::IdInUse(1)));
        assert_eq!(
            s.insert(h(4)),
            Err(StoreError::IdOutOfRange {
                id: 4,
                hier_bits: 2
            })
        );
        s.insert(h(3)).unwrap();
        assert_eq!(s.ids().collect::<Vec<_>>(), vec![1, 3]);
        assert!(s.get(1).is_some());
    }
}
