//! The translation table (S1504, paragraph 81, claims 9 and 18): one entry
//! per hierarchy id, read by the merging module and by traversal.
//!
//! An entry is `(valid, L, tx, ty, tz)`. Its packed form, from bit 0 up:
//! `valid` (1 bit), `L` (`lod_bits`), `tx`, `ty`, `tz` (`trans_bits = D+1`
//! each, two's complement): `1 + lod_bits + 3 (D+1)` bits, 102 at D = 31.

use super::error::{Axis, TranslateError};
use super::translation::{decode_component, encode_component, trans_bits, Translation};
use crate::params::Params;

/// A table of translations indexed by hierarchy id `0..depth`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TranslationTable {
    params: Params,
    entries: Vec<Option<Translation>>,
}

impl TranslationTable {
    /// An empty table (every entry invalid) of `depth` entries;
    /// `1 <= depth <= 2^H` since ids are `H` bits.
    pub fn new(depth: usize, p: &Params) -> Result<TranslationTable, TranslateError> {
        if depth == 0 || depth as u64 > p.hier_capacity() {
            return Err(TranslateError::BadTableDepth {
                depth,
                max: p.hier_capacity(),
            });
        }
        Ok(TranslationTable {
            params: *p,
            entries: vec![None; depth],
        })
    }

    /// Number of entries.
    pub fn depth(&self) -> usize {
        self.entries.len()
    }

    fn slot(&self, id: u32) -> Result<usize, TranslateError> {
        if (id as usize) < self.entries.len() {
            Ok(id as usize)
        } else {
            Err(TranslateError::IdOutOfRange {
                id,
                depth: self.entries.len(),
            })
        }
    }

    /// Stores `t` for hierarchy `id` (the entry becomes valid). The
    /// translation must pass [`Translation::validate`].
    pub fn write(&mut self, id: u32, t: Translation) -> Result<(), TranslateError> {
        let i = self.slot(id)?;
        t.validate(&self.params)?;
        self.entries[i] = Some(t);
        Ok(())
    }

    /// Marks the entry of `id` invalid.
    pub fn invalidate(&mut self, id: u32) -> Result<(), TranslateError> {
        let i = self.slot(id)?;
        self.entries[i] = None;
        Ok(())
    }

    /// The translation of hierarchy `id`. Reading an invalid entry is an
    /// error ([`TranslateError::EmptyEntry`]): a hierarchy used without a
    /// placement is a bug of the caller, not a zero translation.
    pub fn read(&self, id: u32) -> Result<Translation, TranslateError> {
        self.get(id)?.ok_or(TranslateError::EmptyEntry { id })
    }

    /// The entry of `id`: `None` when invalid. Out-of-range ids are errors.
    pub fn get(&self, id: u32) -> Result<Option<Translation>, TranslateError> {
        Ok(self.entries[self.slot(id)?])
    }

    /// The packed entry of `id` as the hardware table holds it.
    pub fn packed(&self, id: u32) -> Result<u128, TranslateError> {
        Ok(pack_entry(self.get(id)?.as_ref(), &self.params))
    }
}

/// Width of a packed entry: `1 + lod_bits + 3 trans_bits`.
pub fn entry_bits(p: &Params) -> u32 {
    1 + p.lod_bits() + 3 * trans_bits(p)
}

/// Packs an entry; `None` packs as all zeros (valid = 0). The translation
/// is assumed valid (table writes check it).
pub fn pack_entry(t: Option<&Translation>, p: &Params) -> u128 {
    let Some(t) = t else { return 0 };
    let w = trans_bits(p);
    let mut v = 1u128 | ((t.lod as u128) << 1);
    let mut at = 1 + p.lod_bits();
    for axis in Axis::ALL {
        v |= (encode_component(t.t[axis.index()], p) as u128) << at;
        at += w;
    }
    v
}

/// Unpacks an entry: `None` when `valid = 0` (the other bits are then not
/// read: an invalid entry carries no translation); errors for bits above the width, `L > D` or a component code
/// outside the field.
pub fn unpack_entry(v: u128, p: &Params) -> Result<Option<Translation>, TranslateError> {
    let w = trans_bits(p);
    let width = entry_bits(p);
    if v >> width != 0 {
        return Err(TranslateError::PackedTooWide {
            what: "translation table entry",
            width,
        });
    }
    if v & 1 == 0 {
        return Ok(None);
    }
    let lod = ((v >> 1) & ((1u128 << p.lod_bits()) - 1)) as u8;
    let mut t = [0i64; 3];
    let mut at = 1 + p.lod_bits();
    for axis in Axis::ALL {
        let code = ((v >> at) & ((1u128 << w) - 1)) as u64;
        t[axis.index()] = decode_component(axis, code, p)?;
        at += w;
    }
    let tr = Translation { lod, t };
    tr.validate(p)?;
    Ok(Some(tr))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn write_read_invalidate_and_bounds() {
        let p = Params::new(10, 4, 16, 3).unwrap();
        assert!(TranslationTable::new(9, &p).is_err());
        assert!(TranslationTable::new(0, &p).is_err());
        let mut tab = TranslationTable::new(8, &p).unwrap();
        assert_eq!(tab.read(3), Err(TranslateError::EmptyEntry { id: 3 }));
        assert_eq!(tab.get(3), Ok(None));
        let t = Translation {
            lod: 4,
            t: [-3, 0, 1023],
        };
        tab.write(3, t).unwrap();
        assert_eq!(tab.read(3), Ok(t));
        assert_eq!(
            tab.write(8, t),
            Err(TranslateError::IdOutOfRange { id: 8, depth: 8 })
        );
        assert!(tab
            .write(
                2,
                Translation {
                    lod: 4,
                    t: [1024, 0, 0]
                }
            )
            .is_err());
        assert!(tab
            .write(
                2,
                Translation {
                    lod: 11,
                    t: [0, 0, 0]
                }
            )
            .is_err());
        tab.invalidate(3).unwrap();
        assert_eq!(tab.get(3), Ok(None));
    }

    #[test]
    fn entries_pack_and_unpack() {
        let p = Params::new(31, 16, 32, 8).unwrap();
        assert_eq!(entry_bits(&p), 102);
        let t = Translation {
            lod: 31,
            t: [-(1 << 31) + 1, (1 << 31) - 1, -1],
        };
        let v = pack_entry(Some(&t), &p);
        assert!(v < 1u128 << 102);
        assert_eq!(unpack_entry(v, &p), Ok(Some(t)));
        assert_eq!(unpack_entry(0, &p), Ok(None));
        assert!(unpack_entry(1u128 << 102, &p).is_err());
        // L = 20 fits the 5-bit LOD field but does not exist at D = 16.
        let p16 = Params::new(16, 8, 24, 4).unwrap();
        assert!(matches!(
            unpack_entry(1 | (20u128 << 1), &p16),
            Err(TranslateError::LodAboveMax {
                lod: 20,
                max_lod: 16
            })
        ));
    }
}
