//! S406-S408: leaves from sorted entries, the upper levels by grouping on the
//! parent voxel, the top rule, and the store layout (SPEC.md sections 4.5-4.7).

use super::leaves::{LeafEntry, LeafKey};
use super::quantize::child_cells_in_parent;
use super::BuildError;
use crate::grid::VoxelAddr;
use crate::params::Params;
use crate::store::{Hierarchy, NodeRecord, Reference};

/// A node while its level is being built. A *base* node is given by the
/// caller (the builder: every leaf; the merger: the nodes of S610-S614) and
/// its `first`/`count` mean what the caller says (the builder: the sorted
/// entries = `prims`); a grouped node (`base = false`, made by
/// [`group_by_parent`]) has `first`/`count` indexing the level below.
#[derive(Clone, Copy, Debug)]
pub(crate) struct LevelNode {
    pub(crate) morton: u128,
    pub(crate) x: u32,
    pub(crate) y: u32,
    pub(crate) z: u32,
    pub(crate) leaf: bool,
    pub(crate) base: bool,
    pub(crate) lo: [u16; 3],
    pub(crate) hi: [u16; 3],
    pub(crate) first: u32,
    pub(crate) count: u32,
}

/// Inverse of the 21-bit spread: gathers bits `3i` into bit `i`.
fn compact21(v: u64) -> u32 {
    let mut x = v & 0x1249_2492_4924_9249;
    x = (x ^ (x >> 2)) & 0x10c3_0c30_c30c_30c3;
    x = (x ^ (x >> 4)) & 0x100f_00f0_0f00_f00f;
    x = (x ^ (x >> 8)) & 0x001f_0000_ff00_00ff;
    x = (x ^ (x >> 16)) & 0x001f_0000_0000_ffff;
    x = (x ^ (x >> 32)) & 0x1f_ffff;
    x as u32
}

/// The coordinate at bit offset `axis` of a Morton code.
fn morton_coord(m: u128, axis: u32) -> u32 {
    let m = m >> axis;
    compact21(m as u64 & ((1u64 << 63) - 1)) | compact21((m >> 63) as u64) << 21
}

/// The entries of each LOD (index = LOD) as a range of the sorted entries:
/// the key's high bits are the LOD, so each LOD's entries are contiguous.
pub(super) fn entry_ranges_by_lod<K: LeafKey>(
    entries: &[LeafEntry<K>],
    p: &Params,
) -> Vec<std::ops::Range<usize>> {
    let shift = 3 * p.max_lod as u32;
    (0..=p.max_lod as u128)
        .map(|lod| {
            let start = entries.partition_point(|e| e.key.to_u128() >> shift < lod);
            let end = entries.partition_point(|e| e.key.to_u128() >> shift <= lod);
            start..end
        })
        .collect()
}

/// Groups the sorted entries `entries[range]` (all of one LOD) into one leaf
/// per voxel, in Morton order, into `out` (cleared first). A leaf's `first`
/// indexes the whole entry array.
#[allow(clippy::needless_range_loop)] // per-axis loops over parallel arrays
pub(super) fn leaves_of_lod_into<K: LeafKey>(
    entries: &[LeafEntry<K>],
    range: std::ops::Range<usize>,
    p: &Params,
    out: &mut Vec<LevelNode>,
) {
    out.clear();
    let shift = 3 * p.max_lod as u32;
    let mut i = range.start;
    while i < range.end {
        let key = entries[i].key;
        let mut lo = entries[i].lo;
        let mut hi = entries[i].hi;
        let mut j = i + 1;
        while j < range.end && entries[j].key == key {
            for a in 0..3 {
                lo[a] = lo[a].min(entries[j].lo[a]);
                hi[a] = hi[a].max(entries[j].hi[a]);
            }
            j += 1;
        }
        let morton = key.to_u128() & ((1u128 << shift) - 1);
        out.push(LevelNode {
            morton,
            x: morton_coord(morton, 0),
            y: morton_coord(morton, 1),
            z: morton_coord(morton, 2),
            leaf: true,
            base: true,
            lo,
            hi,
            first: i as u32,
            count: (j - i) as u32,
        });
        i = j;
    }
}

/// One inner node per parent voxel of `level` (sorted by Morton, so the
/// children of a parent are a contiguous run); the parent's box is the union
/// of its children's boxes rounded outward into its own cells.
pub(crate) fn group_by_parent(level: &[LevelNode], quant_bits: u8) -> Vec<LevelNode> {
    let mut out = Vec::with_capacity(level.len() / 2 + 1);
    group_by_parent_into(level, quant_bits, &mut out);
    out
}

/// [`group_by_parent`] into `out` (cleared first), reusing its storage.
#[allow(clippy::needless_range_loop)] // per-axis loops over parallel arrays
pub(super) fn group_by_parent_into(level: &[LevelNode], quant_bits: u8, out: &mut Vec<LevelNode>) {
    out.clear();
    let mut i = 0;
    while i < level.len() {
        let pm = level[i].morton >> 3;
        let mut node = LevelNode {
            morton: pm,
            x: level[i].x >> 1,
            y: level[i].y >> 1,
            z: level[i].z >> 1,
            leaf: false,
            base: false,
            lo: [u16::MAX; 3],
            hi: [0; 3],
            first: i as u32,
            count: 0,
        };
        let mut j = i;
        while j < level.len() && level[j].morton >> 3 == pm {
            let c = &level[j];
            let odd = [c.x & 1 == 1, c.y & 1 == 1, c.z & 1 == 1];
            for a in 0..3 {
                let (l, h) = child_cells_in_parent(c.lo[a], c.hi[a], odd[a], quant_bits);
                node.lo[a] = node.lo[a].min(l);
                node.hi[a] = node.hi[a].max(h);
            }
            j += 1;
        }
        node.count = (j - i) as u32;
        out.push(node);
        i = j;
    }
}

/// [`merge_level`] into `out` (cleared first), reusing its storage.
pub(super) fn merge_level_into(
    inner: &[LevelNode],
    leaves: &[LevelNode],
    out: &mut Vec<LevelNode>,
) {
    out.clear();
    out.reserve(inner.len() + leaves.len());
    let (mut a, mut b) = (0, 0);
    while a < inner.len() && b < leaves.len() {
        if inner[a].morton <= leaves[b].morton {
            out.push(inner[a]);
            a += 1;
        } else {
            out.push(leaves[b]);
            b += 1;
        }
    }
    out.extend_from_slice(&inner[a..]);
    out.extend_from_slice(&leaves[b..]);
}

/// Merges the inner nodes and the leaves of one LOD, both in Morton order;
/// at the same voxel the inner node comes first.
fn merge_level(inner: Vec<LevelNode>, leaves: Vec<LevelNode>) -> Vec<LevelNode> {
    if leaves.is_empty() {
        return inner;
    }
    let mut out = Vec::with_capacity(inner.len() + leaves.len());
    let (mut a, mut b) = (inner.into_iter().peekable(), leaves.into_iter().peekable());
    loop {
        let take_inner = match (a.peek(), b.peek()) {
            (Some(i), Some(l)) => i.morton <= l.morton,
            (Some(_), None) => true,
            (None, Some(_)) => false,
            (None, None) => break,
        };
        out.push(if take_inner { a.next() } else { b.next() }.expect("peeked"));
    }
    out
}

/// The top rule's exception: a single inner LOD-0 node whose box covers more
/// than half the scene, `(hx-lx+1)(hy-ly+1)(hz-lz+1) * 2 > 2^(3Q)`, exactly.
pub(crate) fn covers_most_of_scene(n: &LevelNode, quant_bits: u8) -> bool {
    let cells: u64 = (0..3).map(|a| (n.hi[a] - n.lo[a]) as u64 + 1).product();
    cells * 2 > 1u64 << (3 * quant_bits as u32)
}

pub(super) fn check_index(what: &'static str, value: u64, p: &Params) -> Result<(), BuildError> {
    if value >= p.index_capacity() {
        return Err(BuildError::IndexOverflow {
            what,
            value,
            index_bits: p.index_bits,
        });
    }
    Ok(())
}

/// The levels of a hierarchy over `base` (index = LOD, each list in Morton
/// order): from the deepest base level up, each level is the grouping of the
/// one below merged with that LOD's base nodes, until the top rule stops it
/// (SPEC.md section 4). Returns the levels (`levels[d]` for `d <= deepest`,
/// empty above the top) and the top LOD; `None` when `base` is empty. Shared
/// by the builder (S408) and the merger (S616).
pub(crate) fn build_levels(
    mut base: Vec<Vec<LevelNode>>,
    p: &Params,
) -> Option<(Vec<Vec<LevelNode>>, usize)> {
    let deepest = base.iter().rposition(|l| !l.is_empty())?;
    let shallowest_base = base.iter().position(|l| !l.is_empty())?;

    // levels[d]: the nodes of LOD d, in store order.
    let mut levels: Vec<Vec<LevelNode>> = vec![Vec::new(); deepest + 1];
    let mut d = deepest;
    levels[d] = std::mem::take(&mut base[d]);
    while !(d == 0 || (levels[d].len() == 1 && d <= shallowest_base)) {
        let parents = group_by_parent(&levels[d], p.quant_bits);
        levels[d - 1] = merge_level(parents, std::mem::take(&mut base[d - 1]));
        d -= 1;
    }
    let mut top = d;
    // Only a grouped root can give way to its children: they are level 1.
    if top == 0
        && levels[0].len() == 1
        && !levels[0][0].base
        && covers_most_of_scene(&levels[0][0], p.quant_bits)
    {
        top = 1;
    }
    Some((levels, top))
}

/// Builds the hierarchy from entries sorted by key (then primitive index).
///
/// The same levels and top as [`build_levels`], streamed: each level is
/// written out as node records as soon as the one above it has been grouped,
/// so only two levels of [`LevelNode`]s are alive at a time (not all of them:
/// a sparse scene has several nodes per primitive). Each level's records are
/// appended reversed, deepest level first, so that reversing the whole array
/// at the end gives store order (top level first, each level in order).
///
/// References need no per-child loop: the inner nodes of a level, in order,
/// have as children every node of the next level exactly once, in order, so
/// in store order `refs[k]` names node `root_count + k`, and an inner node's
/// `first` is its first child's store index minus `root_count`.
pub(super) fn assemble<K: LeafKey>(
    entries: &[LeafEntry<K>],
    p: &Params,
    id: u8,
) -> Result<Hierarchy, BuildError> {
    // Leaves are made one LOD at a time, when the build reaches it.
    let ranges = entry_ranges_by_lod(entries, p);
    let deepest = ranges
        .iter()
        .rposition(|r| !r.is_empty())
        .ok_or(BuildError::EmptyMesh)?;
    let shallowest_base = ranges
        .iter()
        .position(|r| !r.is_empty())
        .ok_or(BuildError::EmptyMesh)?;

    // Records, deepest level first; inner nodes' `first` is still the index
    // of the first child within the level below. Room for the leaves (one
    // per distinct key) and as many inner nodes, more than the scenes have;
    // room for one per entry, as before, held several times the nodes
    // where triangles share voxels (more entries than voxels).
    let leaf_count = 1 + entries.windows(2).filter(|w| w[0].key != w[1].key).count();
    let mut nodes: Vec<NodeRecord> = Vec::with_capacity(2 * leaf_count + 64);
    let mut level_len = vec![0usize; deepest + 1];
    let mut d = deepest;
    let mut level = Vec::new();
    leaves_of_lod_into(entries, ranges[d].clone(), p, &mut level);
    // Grouping, leaves and merging reuse three buffers from level to level.
    let mut parents = Vec::with_capacity(level.len() / 2 + 1);
    let mut leaves = Vec::new();
    while !(d == 0 || (level.len() == 1 && d <= shallowest_base)) {
        push_records(&mut nodes, &level, d);
        level_len[d] = level.len();
        group_by_parent_into(&level, p.quant_bits, &mut parents);
        leaves_of_lod_into(entries, ranges[d - 1].clone(), p, &mut leaves);
        if leaves.is_empty() {
            std::mem::swap(&mut level, &mut parents);
        } else {
            merge_level_into(&parents, &leaves, &mut level);
        }
        d -= 1;
    }
    // Only a grouped root can give way to its children: they are level 1.
    let top = if d == 0
        && level.len() == 1
        && !level[0].base
        && covers_most_of_scene(&level[0], p.quant_bits)
    {
        1
    } else {
        push_records(&mut nodes, &level, d);
        level_len[d] = level.len();
        d
    };
    drop(level);

    nodes.reverse();
    let mut offset = vec![0u64; deepest + 2];
    for lod in top..=deepest {
        offset[lod + 1] = offset[lod] + level_len[lod] as u64;
    }
    let total_nodes = offset[deepest + 1];
    let root_count = level_len[top] as u64;
    check_index("node count - 1", total_nodes.saturating_sub(1), p)?;
    check_index(
        "prims length - 1",
        (entries.len() as u64).saturating_sub(1),
        p,
    )?;
    for lod in top..=deepest {
        for n in &mut nodes[offset[lod] as usize..offset[lod + 1] as usize] {
            check_index("count", n.count as u64, p)?;
            if !n.leaf {
                n.first = (offset[lod + 1] + n.first as u64 - root_count) as u32;
            }
        }
    }
    let prims = entries.iter().map(|e| e.prim).collect();
    finish(nodes, prims, root_count, top, p, id)
}

/// The hierarchy of the node array `nodes` (store order, `first`s final)
/// and the primitives `prims`: its references, `refs[k]` naming node
/// `root_count + k` (see [`assemble`]), their count checked.
pub(super) fn finish(
    nodes: Vec<NodeRecord>,
    prims: Vec<u32>,
    root_count: u64,
    top: usize,
    p: &Params,
    id: u8,
) -> Result<Hierarchy, BuildError> {
    let total_nodes = nodes.len() as u64;
    let refs_len = total_nodes - root_count;
    check_index("refs length - 1", refs_len.saturating_sub(1), p)?;
    let refs = (root_count..total_nodes)
        .map(|node| Reference {
            hier: id,
            node: node as u32,
        })
        .collect();
    Ok(Hierarchy {
        id,
        params: *p,
        nodes,
        refs,
        prims,
        root_count: root_count as u32,
        top_lod: top as u8,
    })
}

/// Appends the records of one level (LOD `lod`) in reverse order, so that
/// reversing the whole array later puts them back in order.
fn push_records(nodes: &mut Vec<NodeRecord>, level: &[LevelNode], lod: usize) {
    nodes.extend(level.iter().rev().map(|n| record_of(n, lod)));
}

/// The record of node `n` of LOD `lod`, its `first` as the level gave it.
pub(super) fn record_of(n: &LevelNode, lod: usize) -> NodeRecord {
    NodeRecord {
        leaf: n.leaf,
        voxel: VoxelAddr::new(lod as u8, n.x, n.y, n.z),
        lo: n.lo,
        hi: n.hi,
        first: n.first,
        count: n.count,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::morton3;

    #[test]
    fn morton_coordinates_decode() {
        for (x, y, z) in [
            (0, 0, 0),
            (1, 2, 3),
            ((1 << 31) - 1, 5, (1 << 30) + 7),
            (123456, 7654321, 2),
        ] {
            let m = morton3(x, y, z);
            assert_eq!(
                (morton_coord(m, 0), morton_coord(m, 1), morton_coord(m, 2)),
                (x, y, z)
            );
        }
    }
}
