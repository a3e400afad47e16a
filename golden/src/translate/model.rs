//! The translation unit's hardware configuration ([`TranslateDesign`]) and
//! its transaction model as the RTL sees it ([`TranslateModel`]): determine
//! transactions ([`crate::translate::unit`]) and apply transactions (a node
//! record and a hierarchy id in, the moved record, or the unchanged record
//! and an error code, out). The generator, the vector files
//! (`crate::vectors::translate`), the RTL generator (`rtl_gen::translate`)
//! and the bench (`cosim::units::translate`) all read these.

use crate::layout::NodeLayout;
use crate::params::Params;
use crate::store::NodeRecord;
use crate::translate::table::TranslationTable;
use crate::translate::{
    translate_node, Axis, TranslateError, TranslateInputs, TranslateOutputs, TranslateRecord,
    TranslateUnit, TranslateUnitConfig,
};

/// What a translation-unit hardware configuration contains: the golden
/// unit configuration (grid parameters, table depth) and whether the
/// determine path takes binary64 placements as well as binary32.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TranslateDesign {
    /// The golden unit's configuration: grid parameters and table depth.
    pub unit: TranslateUnitConfig,
    /// With `false` there is no format port, placements are 32-bit binary32
    /// encodings and residuals 32 bits.
    pub binary64: bool,
}

impl Default for TranslateDesign {
    /// Default parameters, a table for every hierarchy id, binary32 only.
    fn default() -> Self {
        let params = Params::default();
        TranslateDesign {
            unit: TranslateUnitConfig {
                params,
                table_depth: params.hier_capacity() as u32,
            },
            binary64: false,
        }
    }
}

impl TranslateDesign {
    /// The grid parameters.
    pub fn params(&self) -> &Params {
        &self.unit.params
    }

    /// Checks the parameters and `1 <= table_depth <= 2^H`.
    pub fn validate(&self) -> Result<(), TranslateError> {
        TranslateUnit::new(self.unit).map(|_| ())
    }

    /// Bits of a placement (and residual) port: 64 with binary64, else 32.
    pub fn placement_bits(&self) -> u32 {
        if self.binary64 {
            64
        } else {
            32
        }
    }

    /// A short name for files and modules: `d16_q8_i24_h4_t16_b32`.
    pub fn tag(&self) -> String {
        let p = self.params();
        format!(
            "{}_t{}_{}",
            p.tag(),
            self.unit.table_depth,
            if self.binary64 { "b64" } else { "b32" }
        )
    }
}

/// Result code of an apply transaction (3 bits on the port). When it is not
/// [`ApplyCode::Ok`] the output record is the input record, unchanged.
/// The codes follow the golden checks in order: id, entry, node, level,
/// axes x, y, z (the first failing check is the code).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ApplyCode {
    /// The node moved; the output record holds the translated voxel.
    Ok = 0,
    /// `hier >= table_depth`.
    BadId = 1,
    /// The table entry of `hier` was never written.
    EmptyEntry = 2,
    /// The record is not a voxel of the grid (`lod > D` or a coordinate `>= 2^lod`).
    BadNode = 3,
    /// `d < L`: the aligned unit cannot move a node above the translation level.
    AboveLevel = 4,
    /// The moved x coordinate falls outside `[0, 2^d)`.
    OutsideX = 5,
    /// The moved y coordinate falls outside `[0, 2^d)` (x was inside).
    OutsideY = 6,
    /// The moved z coordinate falls outside `[0, 2^d)` (x and y were inside).
    OutsideZ = 7,
}

impl ApplyCode {
    /// Every code, by value.
    pub const ALL: [ApplyCode; 8] = [
        ApplyCode::Ok,
        ApplyCode::BadId,
        ApplyCode::EmptyEntry,
        ApplyCode::BadNode,
        ApplyCode::AboveLevel,
        ApplyCode::OutsideX,
        ApplyCode::OutsideY,
        ApplyCode::OutsideZ,
    ];
    /// Width of the code port.
    pub const BITS: u32 = 3;

    /// The code of a port value (`None` above 7).
    pub fn from_bits(v: u64) -> Option<ApplyCode> {
        ApplyCode::ALL.get(v as usize).copied()
    }

    fn outside(axis: Axis) -> ApplyCode {
        match axis {
            Axis::X => ApplyCode::OutsideX,
            Axis::Y => ApplyCode::OutsideY,
            Axis::Z => ApplyCode::OutsideZ,
        }
    }
}

/// Inputs of an apply transaction: the node record (as the golden layout
/// packs it) and the id of the hierarchy whose table entry moves it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ApplyInputs {
    /// Id of the hierarchy whose table entry moves the node (`H` bits).
    pub hier: u32,
    /// The node record to move; every field must fit its width in the layout.
    pub node: NodeRecord,
}

/// Outputs of an apply transaction: the code, the hierarchy id (passed
/// through) and the moved record, or the input record when `code != Ok`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ApplyOutputs {
    /// The result; any code but `Ok` means `node` is the input record.
    pub code: ApplyCode,
    /// The input's `hier`, passed through.
    pub hier: u32,
    /// The moved record, or the input record when `code` is not `Ok`.
    pub node: NodeRecord,
}

/// One apply transaction and its expected outputs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ApplyRecord {
    /// The transaction's inputs.
    pub inputs: ApplyInputs,
    /// The outputs the golden model expects.
    pub outputs: ApplyOutputs,
}

/// One transaction of the translation unit, in file order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TranslateTxn {
    /// A determine transaction, with its table write and read (SPEC 7.8).
    Determine(TranslateRecord),
    /// An apply transaction on one node record (SPEC 7.9).
    Apply(ApplyRecord),
}

/// The golden translation unit with both paths: determine (with the table
/// write and read of [`TranslateUnit::step`]) and apply, sharing one table.
#[derive(Clone, Debug)]
pub struct TranslateModel {
    design: TranslateDesign,
    unit: TranslateUnit,
}

impl TranslateModel {
    /// The unit after reset (every table entry invalid).
    pub fn new(design: TranslateDesign) -> Result<TranslateModel, TranslateError> {
        Ok(TranslateModel {
            design,
            unit: TranslateUnit::new(design.unit)?,
        })
    }

    /// The table as the transactions so far left it.
    pub fn table(&self) -> &TranslationTable {
        self.unit.table()
    }

    /// One determine transaction. Inputs no port of this design carries are
    /// refused: without binary64, `format` must be 0 and placements 32 bits.
    pub fn determine(&mut self, inp: &TranslateInputs) -> Result<TranslateOutputs, TranslateError> {
        if !self.design.binary64 {
            if inp.format != 0 {
                return Err(TranslateError::PackedTooWide {
                    what: "format flag (no binary64 in this design)",
                    width: 0,
                });
            }
            if inp.placement.iter().any(|b| b >> 32 != 0) {
                return Err(TranslateError::PackedTooWide {
                    what: "placement (binary32 only)",
                    width: 32,
                });
            }
        }
        self.unit.step(inp)
    }

    /// One apply transaction (SPEC 7.9). Inputs wider than their ports are
    /// refused; everything else is a code.
    pub fn apply(&self, inp: &ApplyInputs) -> Result<ApplyOutputs, TranslateError> {
        let p = self.design.params();
        check_apply_widths(inp, p)?;
        let fail = |code| ApplyOutputs {
            code,
            hier: inp.hier,
            node: inp.node,
        };
        let table = self.unit.table();
        if inp.hier as usize >= table.depth() {
            return Ok(fail(ApplyCode::BadId));
        }
        let Some(t) = table.get(inp.hier)? else {
            return Ok(fail(ApplyCode::EmptyEntry));
        };
        match translate_node(inp.node.voxel, &t, p) {
            Ok(voxel) => Ok(ApplyOutputs {
                code: ApplyCode::Ok,
                hier: inp.hier,
                node: NodeRecord { voxel, ..inp.node },
            }),
            Err(TranslateError::InvalidNode { .. }) => Ok(fail(ApplyCode::BadNode)),
            Err(TranslateError::AboveTranslationLevel { .. }) => Ok(fail(ApplyCode::AboveLevel)),
            Err(TranslateError::NodeOutsideScene { axis, .. }) => {
                Ok(fail(ApplyCode::outside(axis)))
            }
            Err(e) => Err(e),
        }
    }

    /// Runs a transaction's inputs, giving the transaction with the
    /// expected outputs.
    pub fn run(&mut self, txn: &TxnInputs) -> Result<TranslateTxn, TranslateError> {
        Ok(match txn {
            TxnInputs::Determine(i) => TranslateTxn::Determine(TranslateRecord {
                inputs: *i,
                outputs: self.determine(i)?,
            }),
            TxnInputs::Apply(i) => TranslateTxn::Apply(ApplyRecord {
                inputs: *i,
                outputs: self.apply(i)?,
            }),
        })
    }
}

/// The inputs of either kind of transaction.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TxnInputs {
    /// Inputs of a determine transaction.
    Determine(TranslateInputs),
    /// Inputs of an apply transaction.
    Apply(ApplyInputs),
}

fn check_apply_widths(inp: &ApplyInputs, p: &Params) -> Result<(), TranslateError> {
    if inp.hier as u64 >= p.hier_capacity() {
        return Err(TranslateError::PackedTooWide {
            what: "apply hier",
            width: p.hier_bits as u32,
        });
    }
    let layout = NodeLayout::new(p);
    inp.node
        .pack(&layout)
        .map(|_| ())
        .map_err(|_| TranslateError::PackedTooWide {
            what: "apply node record",
            width: layout.width(),
        })
}
