//! The translation unit's top: the table, both paths and the status.
//!
//! Status outputs (SPEC.md 7.9): `idle` (no transaction inside either
//! path), `done` (one cycle, the first idle cycle after a busy one), and
//! the sticky `det_error_seen` / `apply_error_seen` (an output beat with
//! an error flag or code has left since reset).

use golden::vectors::translate::TranslateDesign;

use super::apply::apply_path;
use super::determine::determine_path;
use super::table::Table;
use crate::Module;

/// The Verilog module name of a configuration: `translate_unit_<tag>`.
pub fn module_name(d: &TranslateDesign) -> String {
    format!("translate_unit_{}", d.tag())
}

/// Generates the translation unit for `d` (widths from golden only).
pub fn translate_unit(d: &TranslateDesign) -> Module {
    let m = Module::new(&module_name(d));
    let table = Table::new(&m, d);
    let (det_valids, det_fire, det_error) = determine_path(&m, d, &table);
    let (app_valids, app_fire, app_error) = apply_path(&m, d, &table);
    let busy = det_valids
        .iter()
        .chain(&app_valids)
        .copied()
        .reduce(|a, b| a | b)
        .expect("both paths have registers");
    let idle = (!busy).name("idle_now");
    let was_busy = m.reg("was_busy", 1);
    was_busy.next(busy);
    m.output("idle", idle);
    m.output("done", idle & was_busy);
    let det_seen = m.reg("det_error_seen", 1);
    det_seen.next(det_seen | (det_fire & det_error));
    let app_seen = m.reg("apply_error_seen", 1);
    app_seen.next(app_seen | (app_fire & app_error));
    m.output("det_error_seen", det_seen);
    m.output("apply_error_seen", app_seen);
    m
}
