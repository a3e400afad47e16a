//! The translation unit's generated RTL (Verilator, or the IR engine), driven with the
//! frame's placements and compared bit for bit with the golden unit model
//! (`golden::translate::model::TranslateModel`), which is itself compared
//! with the translations the world determined. Built the first time a frame
//! needs it (cosim's content-addressed cache makes later runs load it), and
//! kept across frames like the hardware's translation table.

use cosim::{Engine, PortId};
use golden::store::Hierarchy;
use golden::translate::model::{
    ApplyInputs, TranslateDesign, TranslateModel, TranslateTxn, TxnInputs,
};
use golden::translate::TranslateUnitConfig;
use golden::translate::{TranslateInputs, Translation, VoxelRange};
use golden::Params;
use rtl_gen::translate::ports::{pack_apply_in, pack_apply_out, pack_det_in, pack_det_out};
use rtl_gen::translate::translate_unit;
use rtl_gen::Bits;

use super::engine::RunEngine;

/// Cycles a transaction may take before the run calls the unit stuck.
const WATCHDOG_CYCLES: u64 = 10_000;

/// One object's placement this frame, as the unit sees it.
pub struct Placed<'a> {
    pub id: u8,
    pub hierarchy: &'a Hierarchy,
    /// The placement in grid units (binary64 encodings go on the port).
    pub grid_units: [f64; 3],
    /// What the world's determine gave.
    pub translation: Translation,
}

/// What one frame's RTL run did.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct RtlFrame {
    pub determine: u64,
    pub apply: u64,
    pub cycles: u64,
    /// Outputs of the RTL that differ from golden, plus golden unit
    /// translations that differ from the world's.
    pub mismatches: u64,
    /// The first mismatch, described.
    pub first_mismatch: Option<String>,
    pub seconds: f64,
}

/// The built unit and its golden twin.
pub struct TranslateRtl {
    design: TranslateDesign,
    model: TranslateModel,
    engine: Box<dyn Engine>,
    ports: Ports,
    /// Seconds spent generating and building (or loading) the model.
    pub build_seconds: f64,
}

struct Ports {
    det_in_valid: PortId,
    det_in_data: PortId,
    det_in_ready: PortId,
    det_out_valid: PortId,
    det_out_data: PortId,
    det_out_ready: PortId,
    apply_in_valid: PortId,
    apply_in_data: PortId,
    apply_in_ready: PortId,
    apply_out_valid: PortId,
    apply_out_data: PortId,
    apply_out_ready: PortId,
}

/// The unit's configuration for a scene: its grid parameters, a table
/// entry per hierarchy id, binary64 placements (what the world uses).
pub fn design_for(params: &Params) -> TranslateDesign {
    TranslateDesign {
        unit: TranslateUnitConfig {
            params: *params,
            table_depth: params.hier_capacity() as u32,
        },
        binary64: true,
    }
}

impl TranslateRtl {
    /// Generates the unit for `params`, builds it for `engine` and resets it.
    pub fn build(params: &Params, engine: RunEngine) -> Result<TranslateRtl, String> {
        let start = std::time::Instant::now();
        let design = design_for(params);
        let mut engine = engine.open(&translate_unit(&design), "translation unit RTL")?;
        let id = |n: &str| {
            engine
                .port_id(n)
                .map_err(|e| format!("translation unit RTL: port {n}: {e}"))
        };
        let ports = Ports {
            det_in_valid: id("det_in_valid")?,
            det_in_data: id("det_in_data")?,
            det_in_ready: id("det_in_ready")?,
            det_out_valid: id("det_out_valid")?,
            det_out_data: id("det_out_data")?,
            det_out_ready: id("det_out_ready")?,
            apply_in_valid: id("apply_in_valid")?,
            apply_in_data: id("apply_in_data")?,
            apply_in_ready: id("apply_in_ready")?,
            apply_out_valid: id("apply_out_valid")?,
            apply_out_data: id("apply_out_data")?,
            apply_out_ready: id("apply_out_ready")?,
        };
        let model = TranslateModel::new(design).map_err(|e| e.to_string())?;
        let sim = |e: cosim::CosimError| format!("translation unit RTL: {e}");
        for p in [
            ports.det_in_valid,
            ports.apply_in_valid,
            ports.det_out_ready,
            ports.apply_out_ready,
        ] {
            engine.poke_u64(p, 0).map_err(sim)?;
        }
        engine.reset(2).map_err(sim)?;
        Ok(TranslateRtl {
            design,
            model,
            engine,
            ports,
            build_seconds: start.elapsed().as_secs_f64(),
        })
    }

    /// Determines (and writes into the table) every placement of `placed`,
    /// then moves each one's root nodes (apply), in the RTL and in golden.
    pub fn run_frame(&mut self, placed: &[Placed]) -> Result<RtlFrame, String> {
        let start = std::time::Instant::now();
        let c0 = self.engine.cycle();
        let mut out = RtlFrame::default();
        let p = *self.design.params();
        for o in placed {
            let h = o.hierarchy;
            let tops: Vec<_> = h.roots().iter().map(|n| n.voxel).collect();
            let ext = VoxelRange::of_nodes(&tops, h.top_lod, &p).map_err(|e| e.to_string())?;
            let inputs = TranslateInputs {
                format: 1,
                placement: o.grid_units.map(f64::to_bits),
                lod: h.top_lod,
                extents_lo: ext.lo,
                extents_hi: ext.hi,
                write_enable: 1,
                write_id: o.id as u32,
                read_id: o.id as u32,
            };
            let txn = self
                .model
                .run(&TxnInputs::Determine(inputs))
                .map_err(|e| format!("object {}: golden translation unit: {e}", o.id))?;
            let TranslateTxn::Determine(r) = txn else {
                unreachable!("a determine input gives a determine record")
            };
            let golden_t = self.model.table().get(o.id as u32).ok().flatten();
            if golden_t != Some(o.translation) {
                note(
                    &mut out,
                    format!(
                        "object {}: golden unit translation {golden_t:?}, world determined {:?}",
                        o.id, o.translation
                    ),
                );
            }
            let sent = pack_det_in(&self.design, &r.inputs)?;
            let expected = pack_det_out(&self.design, &r.outputs)?;
            let got = self.transact(true, &sent)?;
            if got != expected {
                note(
                    &mut out,
                    format!("object {}: determine output differs from golden", o.id),
                );
            }
            out.determine += 1;
        }
        for o in placed {
            for node in o.hierarchy.roots() {
                let inputs = ApplyInputs {
                    hier: o.id as u32,
                    node: *node,
                };
                let TranslateTxn::Apply(r) = self
                    .model
                    .run(&TxnInputs::Apply(inputs))
                    .map_err(|e| format!("object {}: golden apply: {e}", o.id))?
                else {
                    unreachable!("an apply input gives an apply record")
                };
                let sent = pack_apply_in(&self.design, &r.inputs)?;
                let expected = pack_apply_out(&self.design, &r.outputs)?;
                let got = self.transact(false, &sent)?;
                if got != expected {
                    note(
                        &mut out,
                        format!("object {}: apply output differs from golden", o.id),
                    );
                }
                out.apply += 1;
            }
        }
        out.cycles = self.engine.cycle() - c0;
        out.seconds = start.elapsed().as_secs_f64();
        Ok(out)
    }

    /// One transaction on the determine (`det`) or apply stream: the input
    /// beat is offered until accepted, then the output beat is taken.
    fn transact(&mut self, det: bool, data: &Bits) -> Result<Bits, String> {
        let p = &self.ports;
        let (iv, id, ir, ov, od, or) = if det {
            (
                p.det_in_valid,
                p.det_in_data,
                p.det_in_ready,
                p.det_out_valid,
                p.det_out_data,
                p.det_out_ready,
            )
        } else {
            (
                p.apply_in_valid,
                p.apply_in_data,
                p.apply_in_ready,
                p.apply_out_valid,
                p.apply_out_data,
                p.apply_out_ready,
            )
        };
        let sim = |e: cosim::CosimError| format!("translation unit RTL: {e}");
        let e = &mut self.engine;
        e.poke(id, data).map_err(sim)?;
        e.poke_u64(iv, 1).map_err(sim)?;
        e.poke_u64(or, 1).map_err(sim)?;
        let start = e.cycle();
        let mut accepted = false;
        loop {
            e.eval().map_err(sim)?;
            if !accepted && e.peek_bool(ir).map_err(sim)? {
                accepted = true;
            }
            let valid = e.peek_bool(ov).map_err(sim)?;
            let value = if valid {
                Some(e.peek(od).map_err(sim)?)
            } else {
                None
            };
            e.step().map_err(sim)?;
            if accepted {
                e.poke_u64(iv, 0).map_err(sim)?;
            }
            if let Some(v) = value {
                e.poke_u64(or, 0).map_err(sim)?;
                e.poke_u64(iv, 0).map_err(sim)?;
                e.eval().map_err(sim)?;
                return Ok(v);
            }
            if e.cycle() - start > WATCHDOG_CYCLES {
                return Err(format!(
                    "translation unit RTL: no output within {WATCHDOG_CYCLES} cycles"
                ));
            }
        }
    }
}

fn note(out: &mut RtlFrame, what: String) {
    out.mismatches += 1;
    out.first_mismatch.get_or_insert(what);
}
