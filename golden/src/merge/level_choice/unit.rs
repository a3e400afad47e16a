//! S608, the overlap counter (unit 508): its beats, its transaction from
//! golden's [`overlap_counts`] and [`above_threshold`], and its stimulus.

use crate::bits::Bits;
use crate::grid::VoxelAddr;
use crate::layout::{Field, Layout, LayoutError};
use crate::merge::level_choice::{above_threshold, overlap_counts, LevelOverlap};
use crate::merge::stimulus::random_coord;
use crate::params::{bits_to_hold, Params};
use crate::translate::stimulus::SplitMix64;

/// Bit layout of an overlap-counter input beat, from bit 0: `x`, `y`, `z`
/// (D bits each), `rank` (`bits_to_hold(k - 1)`), `end` (1); and of its
/// output beat: `shared`, `union` (I bits each), `above` (1), `overflow` (1).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct OverlapLayout {
    /// The input beat: `x`, `y`, `z`, `rank`, `end`.
    pub input: Layout,
    /// In beat: `x`, `y`, `z` of the translated voxel (D bits each), from bit 0.
    pub coord: [Field; 3],
    /// In beat: the rank of the input holding the voxel ([`rank_bits`]`(k)` bits).
    pub rank: Field,
    /// In beat: 1 on the `End` beat closing the level.
    pub end: Field,
    /// The output beat: `shared`, `union`, `above`, `overflow`.
    pub output: Layout,
    /// Out beat: `shared` (I bits, from bit 0), voxels held by two or more inputs.
    pub shared: Field,
    /// Out beat: `union` (I bits), voxels held by any input.
    pub union: Field,
    /// Out beat: `above` (1 bit), `shared * den > num * union`.
    pub above: Field,
    /// Out beat: `overflow` (1 bit), `union` reached `2^I`; the other fields are then 0.
    pub overflow: Field,
}

impl OverlapLayout {
    /// The layouts for `p` and `k` inputs (`k >= 1`).
    pub fn new(p: &Params, k: usize) -> OverlapLayout {
        let d = p.coord_bits();
        let i = p.index_bits as u32;
        let mut input = Layout::new("overlap counter input");
        let coord = ["x", "y", "z"].map(|n| input.push(n, d));
        let rank = input.push("rank", rank_bits(k));
        let end = input.push("end", 1);
        let mut output = Layout::new("overlap counter output");
        let shared = output.push("shared", i);
        let union = output.push("union", i);
        let above = output.push("above", 1);
        let overflow = output.push("overflow", 1);
        OverlapLayout {
            input,
            coord,
            rank,
            end,
            output,
            shared,
            union,
            above,
            overflow,
        }
    }
}

/// Bits of an input rank for `k` inputs.
pub fn rank_bits(k: usize) -> u32 {
    bits_to_hold(k.saturating_sub(1) as u64)
}

/// One beat into the overlap counter: a voxel of the level and the rank of
/// the input occupying it, or the end of the level.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OverlapBeat {
    /// A voxel of the level held by input `rank`.
    Voxel {
        /// The translated voxel.
        voxel: VoxelAddr,
        /// The input's rank, `0..k`.
        rank: u16,
    },
    /// The end of the level (`end` = 1).
    End,
}

/// The overlap counter's single output beat of a level.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OverlapResult {
    /// `shared`, `union` and `above` are 0 when `overflow` (a count reached `2^I`).
    pub shared: u64,
    /// Voxels held by at least one input (`union(l)`).
    pub union: u64,
    /// `shared * den > num * union` (strict, exact).
    pub above: bool,
    /// `union` reached `2^I`, the width of the count fields.
    pub overflow: bool,
}

impl OverlapBeat {
    /// The packed beat.
    pub fn pack(&self, l: &OverlapLayout) -> Result<Bits, LayoutError> {
        let mut b = l.input.zero();
        match self {
            OverlapBeat::Voxel { voxel, rank } => {
                for (f, c) in l.coord.iter().zip([voxel.x, voxel.y, voxel.z]) {
                    b.set(f, c as u64)?;
                }
                b.set(&l.rank, *rank as u64)?;
            }
            OverlapBeat::End => b.set(&l.end, 1)?,
        }
        Ok(b)
    }
}

impl OverlapResult {
    /// The packed beat.
    pub fn pack(&self, l: &OverlapLayout) -> Result<Bits, LayoutError> {
        let mut b = l.output.zero();
        b.set(&l.shared, self.shared)?;
        b.set(&l.union, self.union)?;
        b.set(&l.above, self.above as u64)?;
        b.set(&l.overflow, self.overflow as u64)?;
        Ok(b)
    }
}

/// S608 for one level as a stream transaction: `voxels[r]` is the
/// (unsorted) voxel list of input rank `r`; the beats are their union in
/// (Morton, rank) order then `End`; the result comes from the golden
/// [`overlap_counts`] and [`above_threshold`].
pub fn overlap_transaction(
    voxels: &[Vec<VoxelAddr>],
    p: &Params,
    num: u32,
    den: u32,
) -> (Vec<OverlapBeat>, OverlapResult) {
    let mut beats: Vec<(u128, u16, VoxelAddr)> = voxels
        .iter()
        .enumerate()
        .flat_map(|(r, vs)| vs.iter().map(move |v| (v.morton(), r as u16, *v)))
        .collect();
    beats.sort_by_key(|b| (b.0, b.1));
    let streams = voxels
        .iter()
        .map(|vs| {
            let mut m: Vec<u128> = vs.iter().map(|v| v.morton()).collect();
            m.sort_unstable();
            m.into_iter()
        })
        .collect();
    let (shared, union) = overlap_counts(streams);
    let o = LevelOverlap {
        lod: 0,
        shared,
        union,
    };
    let overflow = union >= p.index_capacity();
    let result = if overflow {
        OverlapResult {
            shared: 0,
            union: 0,
            above: false,
            overflow,
        }
    } else {
        OverlapResult {
            shared,
            union,
            above: above_threshold(&o, num, den),
            overflow,
        }
    };
    let mut out: Vec<OverlapBeat> = beats
        .into_iter()
        .map(|(_, rank, voxel)| OverlapBeat::Voxel { voxel, rank })
        .collect();
    out.push(OverlapBeat::End);
    (out, result)
}

/// A random level for the overlap counter: `k` inputs, about `voxels`
/// voxels each drawn from a shared pool (so overlap ranges from none to
/// full), repeats allowed within an input (an inner node and a leaf).
pub fn random_overlap_case(
    rng: &mut SplitMix64,
    p: &Params,
    k: usize,
    voxels: usize,
) -> Vec<Vec<VoxelAddr>> {
    let lod = match rng.below(5) {
        0 => 0,
        1 => p.max_lod,
        _ => rng.below(p.max_lod as u64 + 1) as u8,
    };
    let pool_size = 1 + rng.below(voxels as u64 + 1) as usize;
    let pool: Vec<VoxelAddr> = (0..pool_size)
        .map(|_| {
            VoxelAddr::new(
                lod,
                random_coord(rng, lod),
                random_coord(rng, lod),
                random_coord(rng, lod),
            )
        })
        .collect();
    (0..k)
        .map(|_| {
            let n = rng.below(voxels as u64 + 1) as usize;
            (0..n)
                .map(|_| pool[rng.below(pool.len() as u64) as usize])
                .collect()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overlap_transaction_counts_distinct_inputs() {
        let p = Params::new(4, 0, 8, 2).unwrap();
        let v = |x| VoxelAddr::new(2, x, 0, 0);
        let (beats, r) = overlap_transaction(&[vec![v(1), v(3), v(3)], vec![v(3), v(2)]], &p, 1, 2);
        assert_eq!(beats.len(), 6);
        assert_eq!((r.shared, r.union, r.above), (1, 3, false));
        let (_, r) = overlap_transaction(&[vec![v(1), v(3)], vec![v(3), v(1)]], &p, 1, 2);
        assert_eq!((r.shared, r.union, r.above), (2, 2, true));
    }
}
