//! The scene-extents rule (paragraph 84, claim 7): a translated hierarchy
//! stays inside the scene.
//!
//! A hierarchy's extent at the translation level `L` is the bounding box of
//! the LOD-`L` voxels its nodes occupy, as an inclusive voxel range
//! `[lo, hi]` per axis. Translating by `t` (in LOD-`L` voxels) keeps the
//! hierarchy in the scene exactly when `0 <= lo + t` and `hi + t <= 2^L - 1`
//! on every axis. A node at LOD `d >= L` has its LOD-`L` ancestor inside
//! `[lo, hi]`, and its translated coordinate `x + t 2^(d-L)` lies in
//! `[0, 2^d)` exactly when the ancestor's `a + t` lies in `[0, 2^L)`; so the
//! rule passing means every aligned node move succeeds.

use serde::{Deserialize, Serialize};

use super::error::{Axis, TranslateError};
use super::translation::Translation;
use crate::grid::VoxelAddr;
use crate::params::Params;

/// An inclusive range of voxels at one LOD: `lo[a] ..= hi[a]` on axis `a`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct VoxelRange {
    /// The LOD `L` whose voxels the range counts.
    pub lod: u8,
    /// Lowest voxel coordinate per axis (x, y, z).
    pub lo: [u32; 3],
    /// Highest voxel coordinate per axis, inclusive; valid when `lo <= hi < 2^lod`.
    pub hi: [u32; 3],
}

impl VoxelRange {
    /// Checks `lod <= D` and `lo <= hi < 2^lod` on every axis.
    pub fn validate(&self, p: &Params) -> Result<(), TranslateError> {
        if self.lod > p.max_lod {
            return Err(TranslateError::LodAboveMax {
                lod: self.lod,
                max_lod: p.max_lod,
            });
        }
        for axis in Axis::ALL {
            let (lo, hi) = (self.lo[axis.index()], self.hi[axis.index()]);
            if lo > hi || hi as u64 >= 1u64 << self.lod {
                return Err(TranslateError::BadExtents {
                    axis,
                    lo,
                    hi,
                    lod: self.lod,
                });
            }
        }
        Ok(())
    }

    /// The range of LOD-`lod` voxels covered by `nodes` (normally a
    /// hierarchy's top nodes). A node at `d >= lod` contributes its ancestor
    /// at `lod` (`x >> (d - lod)`); a node at `d < lod` contributes every
    /// LOD-`lod` voxel inside it (`x << (lod - d)` to `((x+1) << (lod - d)) - 1`).
    pub fn of_nodes(
        nodes: &[VoxelAddr],
        lod: u8,
        p: &Params,
    ) -> Result<VoxelRange, TranslateError> {
        if lod > p.max_lod {
            return Err(TranslateError::LodAboveMax {
                lod,
                max_lod: p.max_lod,
            });
        }
        let mut range: Option<VoxelRange> = None;
        for n in nodes {
            if !n.is_valid(p) {
                return Err(TranslateError::InvalidNode {
                    lod: n.lod,
                    x: n.x,
                    y: n.y,
                    z: n.z,
                });
            }
            let (lo, hi) = node_span_at(n, lod);
            range = Some(match range {
                None => VoxelRange { lod, lo, hi },
                Some(r) => VoxelRange {
                    lod,
                    lo: [0, 1, 2].map(|a| r.lo[a].min(lo[a])),
                    hi: [0, 1, 2].map(|a| r.hi[a].max(hi[a])),
                },
            });
        }
        range.ok_or(TranslateError::NoNodes)
    }
}

/// The inclusive LOD-`lod` voxel span of one node on each axis.
fn node_span_at(n: &VoxelAddr, lod: u8) -> ([u32; 3], [u32; 3]) {
    let c = [n.x, n.y, n.z];
    if n.lod >= lod {
        let s = n.lod - lod;
        let a = c.map(|v| v >> s);
        (a, a)
    } else {
        let s = lod - n.lod;
        // (x+1) << s - 1 is below 2^lod <= 2^31: fits u32 through u64.
        (
            c.map(|v| v << s),
            c.map(|v| (((v as u64 + 1) << s) - 1) as u32),
        )
    }
}

/// The scene-extents rule: `0 <= lo + t` and `hi + t <= 2^L - 1` on every
/// axis, checked x, y, z in order; the first failing axis is the error.
/// The range and the translation are validated first, and `range.lod` must
/// equal `t.lod`.
pub fn check_scene_extents(
    range: &VoxelRange,
    t: &Translation,
    p: &Params,
) -> Result<(), TranslateError> {
    range.validate(p)?;
    t.validate(p)?;
    if range.lod != t.lod {
        return Err(TranslateError::ExtentsLodMismatch {
            extents_lod: range.lod,
            lod: t.lod,
        });
    }
    for axis in Axis::ALL {
        if let Some(e) = axis_outside_scene(range, t, axis) {
            return Err(e);
        }
    }
    Ok(())
}

/// The extents rule on one axis; `Some(OutsideScene)` when it fails. For
/// validated inputs only (`lod <= 31`, `|t| < 2^31`: no overflow).
pub(crate) fn axis_outside_scene(
    range: &VoxelRange,
    t: &Translation,
    axis: Axis,
) -> Option<TranslateError> {
    let a = axis.index();
    let lo = range.lo[a] as i64 + t.t[a];
    let hi = range.hi[a] as i64 + t.t[a];
    let top = (1i64 << range.lod) - 1;
    if lo < 0 || hi > top {
        Some(TranslateError::OutsideScene {
            axis,
            lo,
            hi,
            lod: range.lod,
        })
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn extents_of_nodes_above_and_below_the_level() {
        let p = Params::new(8, 0, 16, 2).unwrap();
        let nodes = [VoxelAddr::new(3, 1, 2, 3), VoxelAddr::new(5, 20, 3, 31)];
        let r = VoxelRange::of_nodes(&nodes, 4, &p).unwrap();
        // (3,1,2,3) covers 2..=3, 4..=5, 6..=7 at LOD 4; (5,20,3,31) sits in (4,10,1,15).
        assert_eq!(r.lo, [2, 1, 6]);
        assert_eq!(r.hi, [10, 5, 15]);
        assert_eq!(
            VoxelRange::of_nodes(&[], 4, &p),
            Err(TranslateError::NoNodes)
        );
    }

    #[test]
    fn rule_admits_the_edges_and_names_the_failing_axis() {
        let p = Params::new(8, 0, 16, 2).unwrap();
        let r = VoxelRange {
            lod: 3,
            lo: [2, 0, 5],
            hi: [4, 7, 5],
        };
        assert_eq!(
            check_scene_extents(
                &r,
                &Translation {
                    lod: 3,
                    t: [-2, 0, 2]
                },
                &p
            ),
            Ok(())
        );
        assert_eq!(
            check_scene_extents(
                &r,
                &Translation {
                    lod: 3,
                    t: [0, 1, 0]
                },
                &p
            ),
            Err(TranslateError::OutsideScene {
                axis: Axis::Y,
                lo: 1,
                hi: 8,
                lod: 3
            })
        );
        assert!(matches!(
            check_scene_extents(
                &r,
                &Translation {
                    lod: 3,
                    t: [-3, 0, 0]
                },
                &p
            ),
            Err(TranslateError::OutsideScene {
                axis: Axis::X,
                lo: -1,
                ..
            })
        ));
    }
}
