//! The translation unit (SPEC.md section 7, issue 5): a generator of
//! Verilog for the determine path (IEEE-754 placement to voxel-aligned
//! translation, round half to even, extents rule, table write/read) and
//! the apply path (node records moved by shift-and-add), sharing the
//! translation table, with ready/valid streams and status outputs.
//!
//! Every width comes from golden (`Params`, `NodeLayout`, `trans_bits`,
//! the binary formats); [`ports`] says where each field sits in the stream
//! payloads and packs golden transactions into port values.
//!
//! ```
//! use golden::translate::model::TranslateDesign;
//! let m = rtl_gen::translate::translate_unit(&TranslateDesign::default());
//! assert!(m.validate().is_ok());
//! ```

mod apply;
mod bundle;
mod determine;
mod float;
pub mod ports;
mod table;
mod unit;

use std::path::{Path, PathBuf};

use golden::params::Params;
use golden::translate::model::TranslateDesign;
use golden::translate::TranslateUnitConfig;

pub use unit::{lookup_unit_name, module_name, translate_lookup_unit, translate_unit};

/// Writes the Verilog of `d`'s unit into `dir` (created if needed);
/// returns the files written (one: `<module_name>.v`).
pub fn emit(d: &TranslateDesign, dir: &Path) -> Result<Vec<PathBuf>, String> {
    d.validate()
        .map_err(|e| format!("translate unit configuration: {e:?}"))?;
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    crate::write_design(&translate_unit(d), dir).map_err(|e| e.to_string())
}

/// The configurations the project ships and tests: the default, and
/// `D = 31` with binary64, `Q = 0` with a table depth that is not a power
/// of two, binary64 at the default grid, and the smallest grid.
pub fn reference_designs() -> Vec<TranslateDesign> {
    let design = |d, q, i, h, depth, binary64| TranslateDesign {
        unit: TranslateUnitConfig {
            params: Params::new(d, q, i, h).expect("valid reference parameters"),
            table_depth: depth,
        },
        binary64,
    };
    vec![
        TranslateDesign::default(),
        design(31, 16, 32, 8, 24, true),
        design(10, 0, 12, 3, 5, false),
        design(16, 8, 24, 4, 16, true),
        design(1, 0, 1, 1, 1, true),
    ]
}

/// [`emit`] of the default configuration ([`TranslateDesign::default`]).
pub fn emit_default(dir: &Path) -> Result<Vec<PathBuf>, String> {
    emit(&TranslateDesign::default(), dir)
}
