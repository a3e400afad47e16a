//! The hierarchy unit (docs/hardware.md 8.16): the translation unit and the
//! hierarchy merger top behind one in-order command stream, so that the
//! translation unit writes the table and the merger's fetchers are placed
//! by it, and the candidate range comes from the inputs' headers.
//!
//! The front end is combinational: a determine command goes straight to
//! the translation unit's `det_in`; a merge command waits at the head of
//! `cmd` until the translation unit is idle (every determine before it has
//! written the table), then is the merger's `cfg` beat, each input's
//! translation read from the table by one lookup port per input and
//! `(lo, hi)` computed from the headers. No command passes another, so a
//! merge sees every table write before it and none after it.
//!
//! Golden: `golden::merge::hierarchy_unit`.

use golden::merge::hierarchy_unit::{CmdLayout, KIND_MERGE};
use golden::merge::merger::MergerLayout;
use golden::translate::model::TranslateDesign;
use golden::translate::TranslateUnitConfig;

use super::hierarchy_merger_unit;
use super::merger::{hierarchy_merger_name, pass_stream, MergerConfig};
use crate::translate::{lookup_unit_name, ports::det_in_layout, translate_lookup_unit};
use crate::{Direction, Module, Signal, Stream};

/// The hierarchy unit's configuration: the merger top's, and the
/// translation unit's (its parameters must be the merger's).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct HierarchyUnitConfig {
    /// The merger top.
    pub merger: MergerConfig,
    /// The translation unit: table depth and whether placements may be
    /// binary64.
    pub table: TranslateDesign,
}

impl HierarchyUnitConfig {
    /// `merger` with a translation unit of a table entry per hierarchy id
    /// and binary64 placements (a scene's placements are binary64).
    pub fn new(merger: MergerConfig) -> HierarchyUnitConfig {
        let params = merger.design.params;
        HierarchyUnitConfig {
            merger,
            table: TranslateDesign {
                unit: TranslateUnitConfig {
                    params,
                    table_depth: params.hier_capacity() as u32,
                },
                binary64: true,
            },
        }
    }

    /// Refuses what either unit refuses, and a translation unit of other
    /// parameters than the merger's.
    pub fn validate(&self) -> Result<(), String> {
        self.merger.validate()?;
        self.table
            .validate()
            .map_err(|e| format!("translation unit: {e:?}"))?;
        if *self.table.params() != self.merger.design.params {
            return Err(format!(
                "translation unit parameters {} differ from the merger's {}: expected the same",
                self.table.params().tag(),
                self.merger.design.params.tag()
            ));
        }
        Ok(())
    }

    /// The `cmd` beat's layout.
    pub fn cmd_layout(&self) -> CmdLayout {
        CmdLayout::new(
            &self.merger.design.params,
            self.merger.design.inputs,
            det_in_layout(&self.table).width(),
        )
    }
}

/// Module name: `hierarchy_unit_<the merger's name after
/// hierarchy_merger_>_t<table depth>_<b32|b64>`.
pub fn hierarchy_unit_name(c: &HierarchyUnitConfig) -> String {
    let merger = hierarchy_merger_name(&c.merger);
    let rest = merger.strip_prefix("hierarchy_merger_").unwrap_or(&merger);
    let b = if c.table.binary64 { "b64" } else { "b32" };
    format!("hierarchy_unit_{rest}_t{}_{b}", c.table.unit.table_depth)
}

/// The hierarchy unit for `c`; an error when `c.validate()` refuses it.
///
/// Ports: `clk`, `rst`; streams `cmd` (in, [`CmdLayout::width`]), `det_out`
/// (out, the translation unit's), and every stream of the merger top but
/// its `cfg`, under the merger's names; outputs `idle` (neither unit holds
/// a command), `done` (the merger's: one clock after a merge's header
/// left), the merger's other status outputs under their names, and the
/// translation unit's `det_error_seen` and `done` (as `translate_done`).
pub fn hierarchy_unit(c: &HierarchyUnitConfig) -> Result<Module, String> {
    c.validate()?;
    let k = c.merger.design.inputs;
    let cl = c.cmd_layout();
    let p = c.merger.design.params;
    let ml = MergerLayout::new(&p, k, c.merger.sizes.capacity_bits).map_err(|e| e.to_string())?;
    let merger_mod = hierarchy_merger_unit(&c.merger)?;
    let table_mod = translate_lookup_unit(&c.table, k);
    debug_assert_eq!(table_mod.name(), lookup_unit_name(&c.table, k));

    let m = Module::new(&hierarchy_unit_name(c));
    let table = m.instance("u_translate", &table_mod);
    let merger = m.instance("u_merger", &merger_mod);
    let cmd = Stream::input(&m, "cmd", cl.width);
    let kind = cmd.data.view(&cl.kind);
    let is_merge = kind.eq(m.lit(KIND_MERGE as u128, 1)).name("cmd_is_merge");

    // Determine commands: the translation unit's det_in, as they come.
    table.connect("det_in_valid", cmd.valid & !is_merge);
    table.connect("det_in_data", cmd.data.slice(cl.det_width - 1, 0));
    let det_out_width = table_mod
        .ports()
        .iter()
        .find(|q| q.name == "det_out_data")
        .map_or(0, |q| q.width);
    pass_stream(
        &m,
        table,
        "det_out",
        "det_out",
        Direction::Output,
        det_out_width,
    );

    // A merge command: once the table holds every write before it.
    let table_settled = table.output("idle").name("table_settled");
    let merge_valid = (cmd.valid & is_merge & table_settled).name("merge_valid");
    let cfg = merger_cfg(&m, &cl, &ml, cmd.data, |i, hier| {
        table.connect(&format!("lookup{i}_id"), hier);
        table.output(&format!("lookup{i}_entry"))
    });
    merger.connect("cfg_valid", merge_valid);
    merger.connect("cfg_data", cfg);
    let merge_ready = merger.output("cfg_ready") & table_settled;
    cmd.ready
        .drive(is_merge.mux(merge_ready, table.output("det_in_ready")));

    pass_merger_ports(&m, merger, &merger_mod);
    m.output("idle", merger.output("idle") & table_settled);
    m.output("det_error_seen", table.output("det_error_seen"));
    m.output("translate_done", table.output("done"));
    Ok(m)
}

/// The merger's `cfg` beat of the merge command `data`: each input's
/// fetcher `cfg` from its header and the entry `lookup(i, hier)` reads,
/// unused inputs 0; the count and the output id; `(lo, hi)` from the
/// used inputs' `top` and `deep` (golden's `header_range`).
fn merger_cfg<'m>(
    m: &'m Module,
    cl: &CmdLayout,
    ml: &MergerLayout,
    data: Signal<'m>,
    mut lookup: impl FnMut(usize, Signal<'m>) -> Signal<'m>,
) -> Signal<'m> {
    let fl = &ml.fetch;
    let lb = ml.lo.width;
    let count = data.view(&cl.count).name("count");
    let get = |i: usize, f| data.view(&cl.input_field(i, f));
    let mut inputs = Vec::new();
    let (mut lo, mut deep) = (m.lit(0, lb), m.lit((1u128 << lb) - 1, lb));
    for i in 0..cl.k {
        let used = count
            .gt(m.lit(i as u128, count.width()))
            .name(&format!("used{i}"));
        let hier = get(i, &cl.input.hier);
        let entry = lookup(i, hier);
        let beat = m.lit(0, fl.cfg.width()).with_fields(&[
            (fl.hier, hier),
            (fl.roots, get(i, &cl.input.roots)),
            (fl.top, get(i, &cl.input.top)),
            (fl.nodes, get(i, &cl.input.nodes)),
            (fl.refs, get(i, &cl.input.refs)),
            (fl.entry, entry),
        ]);
        inputs.push(used.mux(beat, m.lit(0, fl.cfg.width())));
        let top = get(i, &cl.input.top);
        let d = get(i, &cl.input.deep);
        lo = (used & top.gt(lo))
            .mux(top, lo)
            .name(&format!("lo_upto{i}"));
        deep = (used & d.lt(deep))
            .mux(d, deep)
            .name(&format!("deep_upto{i}"));
    }
    let lo = lo.name("range_lo");
    let hi = deep.gt(lo).mux(deep, lo).name("range_hi");
    let mut parts = vec![data.view(&cl.out_id), hi, lo, count];
    parts.extend(inputs.into_iter().rev());
    let beat = m.concat(&parts).name("merger_cfg");
    debug_assert_eq!(beat.width(), ml.cfg.width());
    beat
}

/// Every port of the merger but `cfg`, `idle` and its clock and reset,
/// under its own name.
fn pass_merger_ports<'m>(m: &'m Module, merger: crate::Instance<'m>, merger_mod: &Module) {
    let ports = merger_mod.ports();
    let width = |name: &str| ports.iter().find(|q| q.name == name).map_or(0, |q| q.width);
    for q in &ports {
        if let Some(stream) = q.name.strip_suffix("_valid") {
            if stream == "cfg" {
                continue;
            }
            let w = width(&format!("{stream}_data"));
            pass_stream(m, merger, stream, stream, q.direction, w);
        } else if q.direction == Direction::Output
            && q.name != "idle"
            && !q.name.ends_with("_ready")
            && !q.name.ends_with("_data")
        {
            m.output(&q.name, merger.output(&q.name));
        }
    }
}
