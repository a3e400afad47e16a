//! The translation unit's top: the table, both paths and the status.
//!
//! Status outputs (SPEC.md 7.9): `idle` (no transaction inside either
//! path), `done` (one cycle, the first idle cycle after a busy one), and
//! the sticky `det_error_seen` / `apply_error_seen` (an output beat with
//! an error flag or code has left since reset).

use golden::translate::model::TranslateDesign;

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
    unit_body(Module::new(&module_name(d)), d, Shape::Standalone)
}

/// The Verilog module name of [`translate_lookup_unit`]:
/// `translate_unit_<tag>_lookup<n>`.
pub fn lookup_unit_name(d: &TranslateDesign, lookups: usize) -> String {
    format!("{}_lookup{lookups}", module_name(d))
}

/// The translation unit as the hierarchy unit holds it (docs/hardware.md
/// 8.16): the determine path and the table with `lookups` read ports
/// `lookup{j}_id` (in, H) / `lookup{j}_entry` (out, the packed entry of
/// 7.5: `valid` at bit 0, then `L`, `tx`, `ty`, `tz`; zeros when invalid),
/// asynchronous like the determine path's read. No apply path: the
/// merger's fetchers move the nodes themselves.
pub fn translate_lookup_unit(d: &TranslateDesign, lookups: usize) -> Module {
    let m = Module::new(&lookup_unit_name(d, lookups));
    unit_body(m, d, Shape::Lookups(lookups))
}

/// Which paths a translation unit has besides determine and the table.
#[derive(Clone, Copy)]
enum Shape {
    /// The apply path (7.9).
    Standalone,
    /// Read ports for the hierarchy unit, no apply path.
    Lookups(usize),
}

fn unit_body(m: Module, d: &TranslateDesign, shape: Shape) -> Module {
    let table = Table::new(&m, d);
    let (det_valids, det_fire, det_error) = determine_path(&m, d, &table);
    let mut valids = det_valids;
    let mut apply = None;
    match shape {
        Shape::Standalone => {
            let (app_valids, app_fire, app_error) = apply_path(&m, d, &table);
            valids.extend(app_valids);
            apply = Some((app_fire, app_error));
        }
        Shape::Lookups(n) => {
            let hb = d.params().hier_bits as u32;
            for j in 0..n {
                let id = m.input(&format!("lookup{j}_id"), hb);
                let e = table.read(id, &format!("lookup{j}"));
                let entry = m.concat(&[
                    e.t[2].as_unsigned(),
                    e.t[1].as_unsigned(),
                    e.t[0].as_unsigned(),
                    e.lod,
                    e.valid,
                ]);
                m.output(&format!("lookup{j}_entry"), entry);
            }
        }
    }
    let busy = valids
        .iter()
        .copied()
        .reduce(|a, b| a | b)
        .expect("the determine path has registers");
    let idle = (!busy).name("idle_now");
    let was_busy = m.reg("was_busy", 1);
    was_busy.next(busy);
    m.output("idle", idle);
    m.output("done", idle & was_busy);
    let det_seen = m.reg("det_error_seen", 1);
    det_seen.next(det_seen | (det_fire & det_error));
    let app_seen = apply.map(|(app_fire, app_error)| {
        let app_seen = m.reg("apply_error_seen", 1);
        app_seen.next(app_seen | (app_fire & app_error));
        app_seen
    });
    m.output("det_error_seen", det_seen);
    if let Some(app_seen) = app_seen {
        m.output("apply_error_seen", app_seen);
    }
    m
}
