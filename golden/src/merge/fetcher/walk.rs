//! S610 and S612 (paragraphs 56-58): walk each input from its top down to
//! the merging level, translating every node it meets into the scene.
//!
//! The walk goes level by level (a breadth-first stream per LOD), following
//! each inner node's references. Every node reached is moved by its input's
//! translation ([`translate_node`]): the level determination (S608) needs
//! the translated voxels of every candidate level, so translation happens as
//! nodes stream past rather than as a separate pass; what S612 hands on is
//! the translated leaves above the merging level and the translated nodes at
//! it ([`collect`]).

use crate::merge::error::MergeError;
use crate::store::{Hierarchy, NodeRecord, Reference};
use crate::translate::{translate_node, Translation};

/// A node of an input, as it sits in the scene.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PlacedNode {
    /// Position of the node's input in the merge's input list: the
    /// tie-break between inputs at one voxel.
    pub rank: u16,
    /// Where the node is stored: (input id, node index).
    pub at: Reference,
    /// The stored record with its voxel translated; the box cells, `first`
    /// and `count` are the stored ones (a box is relative to its voxel).
    pub record: NodeRecord,
}

impl PlacedNode {
    /// The stream key within one LOD: Morton code of the translated voxel,
    /// then input rank, then inner before leaf.
    pub fn key(&self) -> (u128, u16, bool) {
        (morton(&self.record.voxel), self.rank, self.record.leaf)
    }
}

/// Spreads the low 21 bits of `v` so bit `i` lands at bit `3i` (magic
/// masks: the streams' sort keys are computed for every walked node).
fn spread21(v: u64) -> u64 {
    let mut x = v & 0x1f_ffff;
    x = (x | (x << 32)) & 0x001f_0000_0000_ffff;
    x = (x | (x << 16)) & 0x001f_0000_ff00_00ff;
    x = (x | (x << 8)) & 0x100f_00f0_0f00_f00f;
    x = (x | (x << 4)) & 0x10c3_0c30_c30c_30c3;
    x = (x | (x << 2)) & 0x1249_2492_4924_9249;
    x
}

/// [`crate::grid::VoxelAddr::morton`], computed 21 bits at a time.
pub fn morton(v: &crate::grid::VoxelAddr) -> u128 {
    let part = |shift: u32| {
        let (x, y, z) = (
            (v.x >> shift) as u64,
            (v.y >> shift) as u64,
            (v.z >> shift) as u64,
        );
        (spread21(x) | spread21(y) << 1 | spread21(z) << 2) as u128
    };
    part(0) | part(21) << 63
}

/// One input walked from its top down to some LOD.
#[derive(Clone, Debug)]
pub struct WalkedInput {
    /// The input's hierarchy id.
    pub id: u8,
    /// The input's position in the merge's input list.
    pub rank: u16,
    /// The input's translation `T_i` from the table, applied to every node walked.
    pub translation: Translation,
    /// The LOD of the input's roots, where the walk starts.
    pub top_lod: u8,
    /// The deepest LOD walked.
    pub down_to: u8,
    /// `by_lod[d]`: the translated nodes at LOD `d`, in walk order (empty
    /// above the top and below `down_to`).
    pub by_lod: Vec<Vec<PlacedNode>>,
}

fn bad(
    input: u8,
    node: Option<u32>,
    field: &'static str,
    expected: impl Into<String>,
    found: impl Into<String>,
) -> MergeError {
    MergeError::BadInput {
        input,
        node,
        field,
        expected: expected.into(),
        found: found.into(),
    }
}

/// The children references of inner node `at`, checked: in range, naming
/// the input itself (a merging input must be self-contained), existing.
pub fn children<'h>(
    h: &'h Hierarchy,
    at: u32,
    n: &NodeRecord,
) -> Result<&'h [Reference], MergeError> {
    let r = n.range();
    if n.count == 0 || r.end > h.refs.len() as u64 {
        return Err(bad(
            h.id,
            Some(at),
            "first/count",
            format!("a non-empty range within the {} refs", h.refs.len()),
            format!("{r:?}"),
        ));
    }
    let refs = &h.refs[r.start as usize..r.end as usize];
    for c in refs {
        if c.hier != h.id || c.node as usize >= h.nodes.len() {
            return Err(bad(
                h.id,
                Some(at),
                "reference",
                format!("a node of hierarchy {} (below {})", h.id, h.nodes.len()),
                format!("({}, {})", c.hier, c.node),
            ));
        }
    }
    Ok(refs)
}

/// S612 for one node: node `i` of input `h`, validated and moved by `t`.
pub fn place_node(
    h: &Hierarchy,
    rank: u16,
    t: &Translation,
    i: u32,
) -> Result<PlacedNode, MergeError> {
    let n = h.nodes.get(i as usize).ok_or_else(|| {
        bad(
            h.id,
            Some(i),
            "node index",
            format!("below {}", h.nodes.len()),
            i.to_string(),
        )
    })?;
    n.validate(&h.params)
        .map_err(|e| bad(h.id, Some(i), e.field, e.expected, e.value.to_string()))?;
    let voxel =
        translate_node(n.voxel, t, &h.params).map_err(|error| MergeError::TranslateNode {
            input: h.id,
            node: i,
            error,
        })?;
    Ok(PlacedNode {
        rank,
        at: Reference {
            hier: h.id,
            node: i,
        },
        record: NodeRecord { voxel, ..*n },
    })
}

/// Walks input `h` (rank `rank`, translation `t`) from its roots down to
/// LOD `down_to` inclusive, translating every node (S612). Errors: a
/// malformed input (roots, ranges, references, a child not one LOD below
/// its parent) or a node that cannot be translated.
pub fn walk_input(
    h: &Hierarchy,
    rank: u16,
    t: &Translation,
    down_to: u8,
) -> Result<WalkedInput, MergeError> {
    let p = &h.params;
    if h.root_count == 0 || h.root_count as usize > h.nodes.len() {
        return Err(bad(
            h.id,
            None,
            "root_count",
            format!("1..={}", h.nodes.len()),
            h.root_count.to_string(),
        ));
    }
    let mut by_lod = vec![Vec::new(); p.max_lod as usize + 1];
    let mut level: Vec<u32> = (0..h.root_count).collect();
    let mut lod = h.top_lod;
    loop {
        let mut next = Vec::new();
        for &i in &level {
            let n = &h.nodes[i as usize];
            if n.voxel.lod != lod {
                return Err(bad(
                    h.id,
                    Some(i),
                    "lod",
                    format!("{lod} (its parent's plus one, or top_lod for a root)"),
                    n.voxel.lod.to_string(),
                ));
            }
            let placed = place_node(h, rank, t, i)?;
            by_lod[lod as usize].push(placed);
            if !n.leaf && lod < down_to {
                next.extend(children(h, i, n)?.iter().map(|c| c.node));
            }
        }
        if next.is_empty() || lod >= down_to {
            break;
        }
        level = next;
        lod += 1;
    }
    Ok(WalkedInput {
        id: h.id,
        rank,
        translation: *t,
        top_lod: h.top_lod,
        down_to,
        by_lod,
    })
}

/// S610's result for merging level `m`: the leaves above `m` (they go into
/// the merged hierarchy as they are) and every node at `m`, of all inputs.
pub fn collect(walked: &[WalkedInput], m: u8) -> (Vec<PlacedNode>, Vec<PlacedNode>) {
    let mut above = Vec::new();
    let mut at = Vec::new();
    for w in walked {
        for lod in w.top_lod..m.min(w.down_to + 1) {
            above.extend(w.by_lod[lod as usize].iter().filter(|n| n.record.leaf));
        }
        if let Some(level) = w.by_lod.get(m as usize) {
            at.extend_from_slice(level);
        }
    }
    (above, at)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::VoxelAddr;
    use crate::scenes::SplitMix64;

    #[test]
    fn fast_morton_is_the_grid_morton() {
        let mut r = SplitMix64::new(9);
        let m = (1u64 << 31) - 1;
        for k in 0..20_000 {
            let pick = |r: &mut SplitMix64| match k % 4 {
                0 => (r.next_u64() & m) as u32,
                1 => m as u32,
                2 => (r.next_u64() & 0xff) as u32,
                _ => 1u32 << (r.next_u64() % 31),
            };
            let v = VoxelAddr::new(31, pick(&mut r), pick(&mut r), pick(&mut r));
            assert_eq!(morton(&v), v.morton(), "{v:?}");
        }
    }
}
