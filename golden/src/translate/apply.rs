//! Apply (the aligned unit): move a node at LOD `d >= L` by
//! `t << (d - L)` voxels per axis, exactly. Out-of-scene results are errors,
//! never wrapped; nodes above the translation level (`d < L`) are refused
//! (moving them needs the expanding variant, [`super::expand`]).
//!
//! The node's quantized box is stored relative to its voxel (SPEC section 3),
//! so an aligned move changes `x, y, z` and nothing else.

use super::error::{Axis, TranslateError};
use super::translation::Translation;
use crate::grid::VoxelAddr;
use crate::params::Params;

/// `x + (t << s)` as a signed value: `|t| < 2^31`, `s <= 31`, `x < 2^31`,
/// so the sum is below `2^63` in magnitude (the hardware adder is
/// `D + 1 + (D - L) + 1` bits wide). For validated inputs only.
pub(crate) fn shift_add(x: u32, t: i64, s: u32) -> i64 {
    x as i64 + (t << s)
}

/// Checks `0 <= v < 2^lod` and narrows `v` to a coordinate.
pub fn coord_in_scene(axis: Axis, v: i64, lod: u8) -> Result<u32, TranslateError> {
    if v < 0 || v >= 1i64 << lod {
        return Err(TranslateError::NodeOutsideScene {
            axis,
            value: v,
            lod,
        });
    }
    Ok(v as u32)
}

/// Checks that `addr` is a voxel of the grid.
pub fn check_node(addr: &VoxelAddr, p: &Params) -> Result<(), TranslateError> {
    if addr.is_valid(p) {
        Ok(())
    } else {
        Err(TranslateError::InvalidNode {
            lod: addr.lod,
            x: addr.x,
            y: addr.y,
            z: addr.z,
        })
    }
}

/// Moves a node by a voxel-aligned translation: for `d >= L`,
/// `x' = x + tx 2^(d-L)` (same for y, z). Errors: the node or the
/// translation invalid; `d < L` ([`TranslateError::AboveTranslationLevel`]);
/// a result outside `[0, 2^d)` ([`TranslateError::NodeOutsideScene`],
/// axes checked x, y, z in order).
pub fn translate_node(
    addr: VoxelAddr,
    t: &Translation,
    p: &Params,
) -> Result<VoxelAddr, TranslateError> {
    check_node(&addr, p)?;
    t.validate(p)?;
    if addr.lod < t.lod {
        return Err(TranslateError::AboveTranslationLevel {
            node_lod: addr.lod,
            translation_lod: t.lod,
        });
    }
    let s = (addr.lod - t.lod) as u32;
    let c = [addr.x, addr.y, addr.z];
    let mut out = [0u32; 3];
    for axis in Axis::ALL {
        let a = axis.index();
        out[a] = coord_in_scene(axis, shift_add(c[a], t.t[a], s), addr.lod)?;
    }
    Ok(VoxelAddr::new(addr.lod, out[0], out[1], out[2]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn moves_by_shifted_translation() {
        let p = Params::new(8, 4, 16, 2).unwrap();
        let t = Translation {
            lod: 2,
            t: [1, -1, 0],
        };
        // At d = 5 one LOD-2 voxel is 8 LOD-5 voxels.
        assert_eq!(
            translate_node(VoxelAddr::new(5, 3, 9, 31), &t, &p),
            Ok(VoxelAddr::new(5, 11, 1, 31))
        );
        assert_eq!(
            translate_node(VoxelAddr::new(5, 3, 7, 31), &t, &p),
            Err(TranslateError::NodeOutsideScene {
                axis: Axis::Y,
                value: -1,
                lod: 5
            })
        );
        assert_eq!(
            translate_node(VoxelAddr::new(1, 0, 0, 0), &t, &p),
            Err(TranslateError::AboveTranslationLevel {
                node_lod: 1,
                translation_lod: 2
            })
        );
    }
}
