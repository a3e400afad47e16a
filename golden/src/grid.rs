//! The voxel grid: addresses, parents and Morton order.
//!
//! A voxel is `(d, x, y, z)` with `0 <= x, y, z < 2^d`. Its parent is
//! `(d-1, x>>1, y>>1, z>>1)`. Within one LOD, voxels are ordered by their
//! Morton code (bit `i` of x, y, z goes to bits `3i`, `3i+1`, `3i+2`), which
//! puts the eight children of a voxel next to each other: grouping a sorted
//! stream by parent is then a one-pass group-by-prefix.

use serde::{Deserialize, Serialize};

use crate::params::Params;

/// The address of a voxel of the octree.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct VoxelAddr {
    /// Level of detail `d`, `0..=D`; 0 is the whole scene.
    pub lod: u8,
    /// Voxel x coordinate, `< 2^lod`, in voxels of edge `2^(D - lod)` grid units.
    pub x: u32,
    /// Voxel y coordinate, `< 2^lod`.
    pub y: u32,
    /// Voxel z coordinate, `< 2^lod`.
    pub z: u32,
}

impl VoxelAddr {
    /// The single LOD-0 voxel: the whole scene cube.
    pub const ROOT: VoxelAddr = VoxelAddr {
        lod: 0,
        x: 0,
        y: 0,
        z: 0,
    };

    /// The voxel `(lod, x, y, z)`, unchecked; see [`VoxelAddr::is_valid`].
    pub fn new(lod: u8, x: u32, y: u32, z: u32) -> VoxelAddr {
        VoxelAddr { lod, x, y, z }
    }

    /// True when the address lies inside a grid of the given parameters.
    pub fn is_valid(&self, p: &Params) -> bool {
        if self.lod > p.max_lod {
            return false;
        }
        let n = 1u64 << self.lod;
        (self.x as u64) < n && (self.y as u64) < n && (self.z as u64) < n
    }

    /// The voxel one LOD up that contains this one; `None` at LOD 0.
    pub fn parent(&self) -> Option<VoxelAddr> {
        if self.lod == 0 {
            return None;
        }
        Some(VoxelAddr::new(
            self.lod - 1,
            self.x >> 1,
            self.y >> 1,
            self.z >> 1,
        ))
    }

    /// The ancestor at LOD `lod <= self.lod`.
    pub fn ancestor(&self, lod: u8) -> VoxelAddr {
        assert!(
            lod <= self.lod,
            "ancestor LOD {lod} below voxel LOD {}",
            self.lod
        );
        let s = self.lod - lod;
        VoxelAddr::new(lod, self.x >> s, self.y >> s, self.z >> s)
    }

    /// Which of its parent's eight children this voxel is: `x0 | y0<<1 | z0<<2`.
    pub fn octant(&self) -> u8 {
        ((self.x & 1) | ((self.y & 1) << 1) | ((self.z & 1) << 2)) as u8
    }

    /// Morton code of the coordinates (3 x 31 bits fit in a u128).
    pub fn morton(&self) -> u128 {
        morton3(self.x, self.y, self.z)
    }

    /// The voxel's minimum corner in grid units.
    pub fn min_corner(&self, p: &Params) -> [u64; 3] {
        let e = p.voxel_edge(self.lod);
        [self.x as u64 * e, self.y as u64 * e, self.z as u64 * e]
    }
}

/// Spreads the low 32 bits of `v` so that bit `i` lands at bit `3i`.
pub fn spread3(v: u32) -> u128 {
    // Bit-by-bit is clear and fast enough for the golden model; the builder's
    // hot path uses the same function, and D <= 31 bounds the loop.
    let mut out = 0u128;
    let mut v = v;
    let mut i = 0;
    while v != 0 {
        out |= ((v & 1) as u128) << (3 * i);
        v >>= 1;
        i += 1;
    }
    out
}

/// Interleaves x, y, z: bit `i` of x at `3i`, of y at `3i+1`, of z at `3i+2`.
pub fn morton3(x: u32, y: u32, z: u32) -> u128 {
    spread3(x) | (spread3(y) << 1) | (spread3(z) << 2)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn morton_interleaves() {
        assert_eq!(morton3(1, 0, 0), 0b001);
        assert_eq!(morton3(0, 1, 0), 0b010);
        assert_eq!(morton3(0, 0, 1), 0b100);
        assert_eq!(morton3(3, 0, 0), 0b001_001);
        let m = (1u32 << 31) - 1;
        assert_eq!(morton3(m, m, m), (1u128 << 93) - 1);
    }

    #[test]
    fn siblings_are_adjacent_in_morton_order() {
        let v = VoxelAddr::new(5, 9, 17, 30);
        for c in 0..8u32 {
            let child = VoxelAddr::new(
                6,
                v.x * 2 + (c & 1),
                v.y * 2 + ((c >> 1) & 1),
                v.z * 2 + (c >> 2),
            );
            assert_eq!(child.parent(), Some(v));
            assert_eq!(child.morton() >> 3, v.morton());
            assert_eq!(child.octant() as u32, c);
        }
    }

    #[test]
    fn validity_and_ancestor() {
        let p = Params::new(4, 0, 8, 2).unwrap();
        assert!(VoxelAddr::new(4, 15, 15, 15).is_valid(&p));
        assert!(!VoxelAddr::new(4, 16, 0, 0).is_valid(&p));
        assert!(!VoxelAddr::new(5, 0, 0, 0).is_valid(&p));
        assert_eq!(
            VoxelAddr::new(4, 15, 8, 1).ancestor(1),
            VoxelAddr::new(1, 1, 1, 0)
        );
        assert_eq!(VoxelAddr::ROOT.parent(), None);
    }
}
