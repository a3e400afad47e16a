//! The translation unit as the RTL sees it: one transaction per cycle,
//! ports as integers. The vector writer (`hiermerge vectors --unit
//! translate`) and the RTL generator share these definitions, and
//! [`TranslateUnit::step`] is the golden behaviour of one transaction.
//!
//! A transaction: determine a translation from a placement (format flag,
//! three encodings, level `L`, hierarchy extents at `L`), optionally write it
//! into the translation table at `write_id`, and read entry `read_id`. The
//! read sees the table as it was before this transaction's write (read-first).
//! Every error is a flag; flags are computed per axis in parallel, as the
//! hardware does, instead of stopping at the first.

use serde::{Deserialize, Serialize};

use super::determine::{round_axis, AxisFault};
use super::error::{Axis, TranslateError};
use super::extents::{axis_outside_scene, VoxelRange};
use super::float::{bit_length, Format};
use super::table::TranslationTable;
use super::translation::{encode_component, trans_max, Translation};
use crate::params::Params;

/// The unit's configuration: grid parameters and table depth (the vector
/// file header carries both).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct TranslateUnitConfig {
    /// Grid parameters (SPEC 1); they fix every port width.
    pub params: Params,
    /// Table entries, `1..=2^H`.
    pub table_depth: u32,
}

/// Input ports of one transaction.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct TranslateInputs {
    /// Format flag (1 bit): 0 binary32 (encodings in bits 31..0), 1 binary64.
    pub format: u8,
    /// Placement encodings x, y, z (64 bits each).
    pub placement: [u64; 3],
    /// Translation level `L` (`lod_bits`).
    pub lod: u8,
    /// Hierarchy extents at `L`, inclusive (`D` bits each).
    pub extents_lo: [u32; 3],
    /// Highest voxel per axis of the extents at `L`, inclusive (`D` bits each).
    pub extents_hi: [u32; 3],
    /// Table write enable (1 bit) and hierarchy id (`H` bits).
    pub write_enable: u8,
    /// Table entry to write when `write_enable` is 1 (`H` bits).
    pub write_id: u32,
    /// Table read id (`H` bits).
    pub read_id: u32,
}

/// Output ports of one transaction. Masks have bit `a` for axis `a`
/// (x = bit 0, y = bit 1, z = bit 2).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct TranslateOutputs {
    /// 1 when determine succeeded (no error flag below is set).
    pub ok: u8,
    /// `tx, ty, tz` as `D+1`-bit two's-complement codes; 0 unless `ok`.
    pub t: [u64; 3],
    /// Residual encodings in the input format; 0 unless `ok`.
    pub residual: [u64; 3],
    /// `L > D`. When set, no other determine flag is evaluated (all 0).
    pub err_lod: u8,
    /// The extents are not a range at `L` (`lo > hi` or `hi >= 2^L` on some
    /// axis). When set, `err_outside` is not evaluated (0).
    pub err_extents: u8,
    /// binary32 encoding with bits set above bit 31.
    pub err_width: u8,
    /// NaN placement.
    pub err_nan: u8,
    /// Infinite placement.
    pub err_inf: u8,
    /// Rounded translation beyond the `D+1`-bit signed field.
    pub err_range: u8,
    /// Scene-extents rule failed; evaluated only on axes with no other flag.
    pub err_outside: u8,
    /// Write enabled with `write_id >= table_depth`.
    pub err_write_id: u8,
    /// 1 when the table was written (`write_enable`, `ok`, id in range).
    pub written: u8,
    /// `read_id >= table_depth`.
    pub err_read_id: u8,
    /// The read entry's valid bit (0 when `err_read_id`).
    pub read_valid: u8,
    /// The read entry's `L` and component codes; 0 unless `read_valid`.
    pub read_lod: u8,
    /// The read entry's `tx, ty, tz` as `D+1`-bit two's-complement codes; 0 unless `read_valid`.
    pub read_t: [u64; 3],
}

/// One vector record: a transaction's inputs and the expected outputs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct TranslateRecord {
    /// The input ports.
    pub inputs: TranslateInputs,
    /// The outputs the golden model expects.
    pub outputs: TranslateOutputs,
}

/// The unit's state: its configuration and its table (reset: all invalid).
#[derive(Clone, Debug)]
pub struct TranslateUnit {
    config: TranslateUnitConfig,
    table: TranslationTable,
}

impl TranslateUnit {
    /// A unit after reset.
    pub fn new(config: TranslateUnitConfig) -> Result<TranslateUnit, TranslateError> {
        config
            .params
            .validate()
            .map_err(TranslateError::BadParams)?;
        let table = TranslationTable::new(config.table_depth as usize, &config.params)?;
        Ok(TranslateUnit { config, table })
    }

    /// The configuration.
    pub fn config(&self) -> &TranslateUnitConfig {
        &self.config
    }

    /// The table (as software reads it).
    pub fn table(&self) -> &TranslationTable {
        &self.table
    }

    /// Runs one transaction. Errors only for inputs that do not fit their
    /// ports (values no RTL port could carry); everything else is a flag.
    pub fn step(&mut self, inp: &TranslateInputs) -> Result<TranslateOutputs, TranslateError> {
        let p = self.config.params;
        check_port_widths(inp, &p)?;
        let mut out = TranslateOutputs::default();
        let translation = determine_flags(inp, &p, &mut out);

        out.err_read_id = (inp.read_id as usize >= self.table.depth()) as u8;
        if out.err_read_id == 0 {
            if let Some(e) = self.table.get(inp.read_id)? {
                out.read_valid = 1;
                out.read_lod = e.lod;
                out.read_t = e.t.map(|v| encode_component(v, &p));
            }
        }

        if inp.write_enable == 1 {
            out.err_write_id = (inp.write_id as usize >= self.table.depth()) as u8;
            if let (Some(t), 0) = (translation, out.err_write_id) {
                self.table.write(inp.write_id, t)?;
                out.written = 1;
            }
        }
        Ok(out)
    }
}

/// Refuses input values wider than their ports.
fn check_port_widths(inp: &TranslateInputs, p: &Params) -> Result<(), TranslateError> {
    let too_wide = |what, width| Err(TranslateError::PackedTooWide { what, width });
    if inp.format > 1 {
        return too_wide("format flag", 1);
    }
    if inp.write_enable > 1 {
        return too_wide("write_enable", 1);
    }
    if bit_length(inp.lod as u64) > p.lod_bits() {
        return too_wide("lod", p.lod_bits());
    }
    for v in inp.extents_lo.iter().chain(inp.extents_hi.iter()) {
        if bit_length(*v as u64) > p.coord_bits() {
            return too_wide("extents", p.coord_bits());
        }
    }
    if bit_length(inp.write_id as u64) > p.hier_bits as u32 {
        return too_wide("write_id", p.hier_bits as u32);
    }
    if bit_length(inp.read_id as u64) > p.hier_bits as u32 {
        return too_wide("read_id", p.hier_bits as u32);
    }
    Ok(())
}

/// Determine with every flag evaluated; fills `out` and returns the
/// translation when `ok`.
fn determine_flags(
    inp: &TranslateInputs,
    p: &Params,
    out: &mut TranslateOutputs,
) -> Option<Translation> {
    if inp.lod > p.max_lod {
        out.err_lod = 1;
        return None;
    }
    let range = VoxelRange {
        lod: inp.lod,
        lo: inp.extents_lo,
        hi: inp.extents_hi,
    };
    out.err_extents = range.validate(p).is_err() as u8;
    let format = if inp.format == 0 {
        Format::Binary32
    } else {
        Format::Binary64
    };
    let fmt = format.layout();
    let k = (p.max_lod - inp.lod) as u32;
    let max_bits = bit_length(trans_max(p) as u64);
    let mut t = Translation::zero(inp.lod);
    let mut residual = [0u64; 3];
    for axis in Axis::ALL {
        let a = axis.index();
        let bit = 1u8 << a;
        let bits = inp.placement[a];
        if !fmt.fits(bits) {
            out.err_width |= bit;
            continue;
        }
        match round_axis(fmt, bits, k, max_bits) {
            Err(AxisFault::NotANumber) => out.err_nan |= bit,
            Err(AxisFault::Infinite { .. }) => out.err_inf |= bit,
            Err(AxisFault::TooLarge) => out.err_range |= bit,
            Ok(r) => {
                t.t[a] = r.t;
                residual[a] = r.residual_bits;
                if out.err_extents == 0 && axis_outside_scene(&range, &t, axis).is_some() {
                    out.err_outside |= bit;
                }
            }
        }
    }
    let any = out.err_extents
        | out.err_width
        | out.err_nan
        | out.err_inf
        | out.err_range
        | out.err_outside;
    if any != 0 {
        return None;
    }
    out.ok = 1;
    out.t = t.t.map(|v| encode_component(v, p));
    out.residual = residual;
    Some(t)
}
