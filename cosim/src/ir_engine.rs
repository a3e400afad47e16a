//! `IrEngine`: rtl-gen's own IR simulator (`rtl_gen::Sim`) behind the
//! [`Engine`] trait, so one Rust testbench runs unchanged on Verilator,
//! Icarus Verilog and the IR the Verilog was emitted from.
//!
//! The simulator is two-state and cycle based, exactly like the cycle model
//! of the trait: pokes are sampled at the next `step`, outputs are read
//! after `eval` and `step`. rtl-gen's clock is implicit (`Sim::step` is the
//! rising edge), so the clock port exists in the `Design` but cannot be poked.

use crate::design::{Design, PortDir, PortId};
use crate::engine::Engine;
use crate::error::{io_err, CosimError, Result};
use rtl_gen::sim::Handle;
use rtl_gen::{Bits, Direction, Module, Sim};
use std::cell::RefCell;
use std::io::{BufWriter, Write};
use std::path::Path;
use std::rc::Rc;

/// The IR simulator of one `rtl_gen::Module`, described by the same
/// [`Design`] the Verilog engines build (see [`crate::from_rtl`]).
pub struct IrEngine {
    design: Design,
    sim: Sim,
    /// One handle per design port, in `Design::ports` order.
    handles: Vec<Handle>,
    /// Inputs as last poked, outputs as of the last `eval`/`step`.
    values: Vec<Bits>,
    clock: Option<PortId>,
    cycle: u64,
    trace: Option<SharedVcdFile>,
}

impl IrEngine {
    /// Simulates `module`; `design` must list exactly the module's ports by
    /// name, each with its width and direction, as
    /// `from_rtl::design_from_module` does.
    pub fn new(module: &Module, design: &Design) -> Result<IrEngine> {
        design.validate()?;
        check_ports_agree(module, design)?;
        let sim = Sim::new(module).map_err(|d| CosimError::Design {
            what: format!("rtl-gen refused to simulate {}: {d}", module.name()),
        })?;
        let handles = design
            .ports
            .iter()
            .map(|p| {
                sim.handle(&p.name).map_err(|e| CosimError::PortMismatch {
                    port: p.name.clone(),
                    what: format!("the IR simulator has no such port: {e}"),
                })
            })
            .collect::<Result<Vec<_>>>()?;
        let values = design.ports.iter().map(|p| Bits::zero(p.width)).collect();
        let clock = match &design.clock {
            Some(name) => Some(design.port_id(name)?),
            None => None,
        };
        let mut engine = IrEngine {
            design: design.clone(),
            sim,
            handles,
            values,
            clock,
            cycle: 0,
            trace: None,
        };
        engine.refresh_outputs()?;
        Ok(engine)
    }

    /// Copies every output of the settled simulator into `values`.
    fn refresh_outputs(&mut self) -> Result<()> {
        for (i, port) in self.design.ports.iter().enumerate() {
            if port.dir == PortDir::Output {
                let words = self.sim.get_words(self.handles[i]);
                self.values[i] = Bits::from_words(words, port.width)?;
            }
        }
        Ok(())
    }
}

/// The design's port list must be the module's, so that a test cannot
/// compare the IR of one design with the Verilog of another.
fn check_ports_agree(module: &Module, design: &Design) -> Result<()> {
    let ports = module.ports();
    for (i, spec) in design.ports.iter().enumerate() {
        let Some(p) = ports.iter().find(|p| p.name == spec.name) else {
            return Err(CosimError::PortMismatch {
                port: spec.name.clone(),
                what: format!("module {} has no such port", module.name()),
            });
        };
        let dir = match p.direction {
            Direction::Input => PortDir::Input,
            Direction::Output => PortDir::Output,
        };
        if p.width != spec.width || dir != spec.dir {
            return Err(CosimError::PortMismatch {
                port: spec.name.clone(),
                what: format!(
                    "port {i} is {:?} {} bits in the design, {dir:?} {} bits in module {}",
                    spec.dir,
                    spec.width,
                    p.width,
                    module.name()
                ),
            });
        }
    }
    if let Some(extra) = ports
        .iter()
        .find(|p| !design.ports.iter().any(|s| s.name == p.name))
    {
        return Err(CosimError::PortMismatch {
            port: extra.name.clone(),
            what: format!("module {} has it, the design does not", module.name()),
        });
    }
    Ok(())
}

impl Engine for IrEngine {
    fn name(&self) -> &'static str {
        "ir"
    }

    fn design(&self) -> &Design {
        &self.design
    }

    fn poke(&mut self, port: PortId, value: &Bits) -> Result<()> {
        let spec = self.design.check_poke(port, value)?;
        if Some(port) == self.clock {
            return Err(CosimError::Unsupported {
                what: format!(
                    "poking the clock `{}`: the IR simulator's clock is implicit, use step()",
                    spec.name
                ),
            });
        }
        self.sim
            .set(self.handles[port.0], value)
            .map_err(|e| CosimError::Protocol {
                what: format!("IR simulator refused `{}`: {e}", spec.name),
            })?;
        self.values[port.0] = value.clone();
        Ok(())
    }

    fn peek(&self, port: PortId) -> Result<Bits> {
        self.design.port(port)?;
        Ok(self.values[port.0].clone())
    }

    fn eval(&mut self) -> Result<()> {
        self.refresh_outputs()
    }

    fn step(&mut self) -> Result<()> {
        self.sim.step();
        self.cycle += 1;
        self.refresh_outputs()?;
        match &self.trace {
            Some(t) if t.failed() => Err(CosimError::Io {
                path: t.path.clone(),
                source: std::io::Error::other("writing the IR simulator's VCD failed"),
            }),
            _ => Ok(()),
        }
    }

    fn cycle(&self) -> u64 {
        self.cycle
    }

    fn trace_start(&mut self, path: &Path) -> Result<()> {
        crate::waves::check_engine_writes(
            Some(crate::waves::WaveFormat::Vcd),
            path,
            "the IR simulator",
        )?;
        self.trace_stop()?;
        let file = std::fs::File::create(path).map_err(io_err(path))?;
        let shared = SharedVcdFile::new(path, file);
        self.sim
            .trace_vcd(Box::new(shared.clone()))
            .map_err(io_err(path))?;
        self.trace = Some(shared);
        Ok(())
    }

    fn trace_stop(&mut self) -> Result<()> {
        match self.trace.take() {
            Some(t) => t.close(),
            None => Ok(()),
        }
    }
}

/// The VCD file the simulator writes through. `Sim` has no "stop tracing"
/// call but drops its writer on the first write error, so closing the file
/// here (later writes then fail) is how `trace_stop` ends a trace.
#[derive(Clone)]
struct SharedVcdFile {
    path: std::path::PathBuf,
    state: Rc<RefCell<VcdState>>,
}

struct VcdState {
    file: Option<BufWriter<std::fs::File>>,
    /// Set by a real write error (not by writes after `close`).
    failed: bool,
}

impl SharedVcdFile {
    fn new(path: &Path, file: std::fs::File) -> SharedVcdFile {
        SharedVcdFile {
            path: path.to_path_buf(),
            state: Rc::new(RefCell::new(VcdState {
                file: Some(BufWriter::new(file)),
                failed: false,
            })),
        }
    }

    fn failed(&self) -> bool {
        self.state.borrow().failed
    }

    fn close(&self) -> Result<()> {
        let mut state = self.state.borrow_mut();
        let failed = state.failed;
        if let Some(mut f) = state.file.take() {
            f.flush().map_err(io_err(&self.path))?;
        }
        if failed {
            return Err(CosimError::Io {
                path: self.path.clone(),
                source: std::io::Error::other("writing the IR simulator's VCD failed"),
            });
        }
        Ok(())
    }
}

impl Write for SharedVcdFile {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let mut state = self.state.borrow_mut();
        let result = match state.file.as_mut() {
            Some(f) => f.write(buf),
            None => return Err(std::io::Error::other("VCD trace stopped")),
        };
        state.failed |= result.is_err();
        result
    }

    fn flush(&mut self) -> std::io::Result<()> {
        let mut state = self.state.borrow_mut();
        match state.file.as_mut() {
            Some(f) => {
                let result = f.flush();
                state.failed |= result.is_err();
                result
            }
            None => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::from_rtl::design_from_module;
    use rtl_gen::examples::counter;

    #[test]
    fn counts_like_the_module_says_and_refuses_the_clock() {
        let dir = tempfile::tempdir().unwrap();
        let m = counter(4);
        let design = design_from_module(&m, dir.path()).unwrap();
        let mut e = IrEngine::new(&m, &design).unwrap();
        let en = e.port_id("en").unwrap();
        let count = e.port_id("count").unwrap();
        e.poke_u64(en, 1).unwrap();
        e.reset(2).unwrap();
        assert_eq!(e.peek_u64(count).unwrap(), 0);
        for k in 1..=20u64 {
            e.step().unwrap();
            assert_eq!(e.peek_u64(count).unwrap(), k % 16);
        }
        assert_eq!(e.cycle(), 22);
        let clk = e.port_id("clk").unwrap();
        assert!(matches!(
            e.poke_u64(clk, 1),
            Err(CosimError::Unsupported { .. })
        ));
        assert!(e.poke(en, &Bits::zero(2)).is_err());
        assert!(e.poke_u64(count, 1).is_err());
    }

    #[test]
    fn a_design_that_is_not_the_module_is_refused_by_port_name() {
        let dir = tempfile::tempdir().unwrap();
        let design = design_from_module(&counter(4), dir.path()).unwrap();
        let err = IrEngine::new(&counter(5), &design).err().unwrap();
        assert!(err.to_string().contains("count"), "{err}");
    }

    #[test]
    fn traces_between_start_and_stop() {
        let dir = tempfile::tempdir().unwrap();
        let m = counter(4);
        let design = design_from_module(&m, dir.path()).unwrap();
        let mut e = IrEngine::new(&m, &design).unwrap();
        let vcd = dir.path().join("ir.vcd");
        e.poke_u64(e.port_id("en").unwrap(), 1).unwrap();
        e.reset(1).unwrap();
        e.trace_start(&vcd).unwrap();
        e.step().unwrap();
        e.step().unwrap();
        e.trace_stop().unwrap();
        let len = std::fs::metadata(&vcd).unwrap().len();
        e.step().unwrap();
        e.step().unwrap();
        let text = std::fs::read_to_string(&vcd).unwrap();
        assert_eq!(text.len() as u64, len, "nothing written after stop");
        assert!(
            text.contains("$enddefinitions") && text.contains("b0010 "),
            "{text}"
        );
    }
}
