//! `VerilatorEngine`: a Verilated model loaded with libloading and stepped from Rust.

use super::build::{build_model, VerilatorOptions, LIBRARY_NAME};
use super::shim::SHIM_VERSION;
use crate::cache::cache_root;
use crate::design::{Design, PortDir, PortId};
use crate::engine::Engine;
use crate::error::{CosimError, Result};
use golden::bits::Bits;
use std::ffi::{c_char, c_int, c_void, CString};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

type CreateFn = unsafe extern "C" fn() -> *mut c_void;
type DestroyFn = unsafe extern "C" fn(*mut c_void);
type SetFn = unsafe extern "C" fn(*mut c_void, u32, *const u64, u32) -> c_int;
type GetFn = unsafe extern "C" fn(*mut c_void, u32, *mut u64, u32) -> c_int;
type EvalFn = unsafe extern "C" fn(*mut c_void);
type TraceOpenFn = unsafe extern "C" fn(*mut c_void, *const c_char, *const c_char) -> c_int;
type CoverageWriteFn = unsafe extern "C" fn(*mut c_void, *const c_char) -> c_int;
type U32Fn = unsafe extern "C" fn() -> u32;
type U32ArgFn = unsafe extern "C" fn(u32) -> u32;

/// How the model was obtained.
#[derive(Clone, Debug)]
pub struct BuildInfo {
    /// The cache entry holding the library.
    pub cache_dir: PathBuf,
    /// True when this engine's construction built the model (a cache miss).
    pub built: bool,
    /// Time spent finding or building the cache entry.
    pub build_time: Duration,
    /// Time spent loading the library and creating the model.
    pub load_time: Duration,
}

/// A Verilated model of one design.
pub struct VerilatorEngine {
    design: Design,
    instance: *mut c_void,
    destroy: DestroyFn,
    set: SetFn,
    get: GetFn,
    eval_fn: EvalFn,
    trace_open: TraceOpenFn,
    trace_close: DestroyFn,
    clock: Option<PortId>,
    cycle: u64,
    info: BuildInfo,
    /// What the trace build writes (None: not a trace build).
    waves: Option<crate::waves::WaveFormat>,
    /// The Verilator scope traced (empty: all).
    scope: CString,
    coverage_write: CoverageWriteFn,
    /// Where this engine writes its coverage counts when dropped (a
    /// coverage build while [`crate::coverage::collect_into`] is in force).
    coverage_out: Option<PathBuf>,
    // Declared last so it is dropped after `instance` is destroyed.
    _library: libloading::Library,
}

impl VerilatorEngine {
    /// Build (or load from the cache at `cache_root()`) and instantiate `design`.
    pub fn new(design: &Design, options: &VerilatorOptions) -> Result<VerilatorEngine> {
        VerilatorEngine::with_cache(design, options, &cache_root())
    }

    /// Same as `new` with an explicit cache root.
    pub fn with_cache(
        design: &Design,
        options: &VerilatorOptions,
        cache_root: &Path,
    ) -> Result<VerilatorEngine> {
        let t0 = Instant::now();
        let entry = build_model(design, options, cache_root)?;
        let build_time = t0.elapsed();
        let t1 = Instant::now();
        let path = entry.dir.join(LIBRARY_NAME);
        // SAFETY: the library is one this crate generated and built; its
        // initializers are Verilator's and the shim's static tables.
        let library = unsafe { libloading::Library::new(&path) }.map_err(|e| CosimError::Load {
            path: path.clone(),
            what: e.to_string(),
        })?;
        let sym = |name: &str| -> Result<*mut c_void> {
            // SAFETY: only the address is taken; the signature is asserted by
            // the shim generator of the same SHIM_VERSION, checked below.
            unsafe { library.get::<*mut c_void>(name.as_bytes()) }
                .map(|s| *s)
                .map_err(|e| CosimError::Load {
                    path: path.clone(),
                    what: format!("symbol {name}: {e}"),
                })
        };
        // SAFETY: every symbol below is defined by the generated shim with
        // exactly these C signatures (see shim.rs).
        let (
            version,
            count,
            width,
            is_output,
            create,
            destroy,
            set,
            get,
            eval_fn,
            trace_open,
            trace_close,
            coverage_write,
        ) = unsafe {
            (
                std::mem::transmute::<*mut c_void, U32Fn>(sym("hm_shim_version")?),
                std::mem::transmute::<*mut c_void, U32Fn>(sym("hm_port_count")?),
                std::mem::transmute::<*mut c_void, U32ArgFn>(sym("hm_port_width")?),
                std::mem::transmute::<*mut c_void, U32ArgFn>(sym("hm_port_is_output")?),
                std::mem::transmute::<*mut c_void, CreateFn>(sym("hm_create")?),
                std::mem::transmute::<*mut c_void, DestroyFn>(sym("hm_destroy")?),
                std::mem::transmute::<*mut c_void, SetFn>(sym("hm_set_port")?),
                std::mem::transmute::<*mut c_void, GetFn>(sym("hm_get_port")?),
                std::mem::transmute::<*mut c_void, EvalFn>(sym("hm_eval")?),
                std::mem::transmute::<*mut c_void, TraceOpenFn>(sym("hm_trace_open")?),
                std::mem::transmute::<*mut c_void, DestroyFn>(sym("hm_trace_close")?),
                std::mem::transmute::<*mut c_void, CoverageWriteFn>(sym("hm_coverage_write")?),
            )
        };
        // SAFETY: argument-free / index-taking pure functions of the shim.
        unsafe {
            if version() != SHIM_VERSION {
                return Err(CosimError::Load {
                    path,
                    what: format!("shim version {} != {SHIM_VERSION}", version()),
                });
            }
            if count() as usize != design.ports.len() {
                return Err(CosimError::Load {
                    path,
                    what: format!(
                        "{} ports in the model, {} described",
                        count(),
                        design.ports.len()
                    ),
                });
            }
            for (i, p) in design.ports.iter().enumerate() {
                let out = p.dir == PortDir::Output;
                if width(i as u32) != p.width || (is_output(i as u32) == 1) != out {
                    return Err(CosimError::PortMismatch {
                        port: p.name.clone(),
                        what: format!("the loaded model disagrees ({path:?})"),
                    });
                }
            }
        }
        let coverage_out = match options.coverage {
            true => crate::coverage::raw_path_for(design)?,
            false => None,
        };
        // SAFETY: hm_create allocates a fresh model; it is destroyed in Drop.
        let instance = unsafe { create() };
        let clock = design
            .clock
            .as_deref()
            .map(|c| design.port_id(c))
            .transpose()?;
        let info = BuildInfo {
            cache_dir: entry.dir,
            built: entry.built,
            build_time,
            load_time: t1.elapsed(),
        };
        Ok(VerilatorEngine {
            design: design.clone(),
            instance,
            destroy,
            set,
            get,
            eval_fn,
            trace_open,
            trace_close,
            clock,
            cycle: 0,
            info,
            waves: options.trace.then_some(if options.fst {
                crate::waves::WaveFormat::Fst
            } else {
                crate::waves::WaveFormat::Vcd
            }),
            scope: CString::default(),
            coverage_write,
            coverage_out,
            _library: library,
        })
    }

    /// Traces only the instance `scope` of the design's top (a path of
    /// instance names, `u_a.u_b`) and everything below it; set before the
    /// first trace.
    pub fn set_trace_scope(&mut self, scope: &str) -> Result<()> {
        let full = format!("TOP.{}.{scope}", self.design.top);
        self.scope = CString::new(full).map_err(|_| CosimError::Unsupported {
            what: format!("trace scope `{scope}`: NUL in the name"),
        })?;
        Ok(())
    }

    /// Where the model came from and what it cost.
    pub fn build_info(&self) -> &BuildInfo {
        &self.info
    }

    fn set_raw(&mut self, port: PortId, value: &Bits) -> Result<()> {
        let words = value.words();
        // SAFETY: `instance` is live; `words` has ceil(width/64) entries, the
        // count the shim checks before reading.
        let rc = unsafe {
            (self.set)(
                self.instance,
                port.0 as u32,
                words.as_ptr(),
                words.len() as u32,
            )
        };
        if rc != 0 {
            return Err(CosimError::Protocol {
                what: format!(
                    "shim refused a value for port {}",
                    self.design.ports[port.0].name
                ),
            });
        }
        Ok(())
    }
}

impl Engine for VerilatorEngine {
    fn name(&self) -> &'static str {
        "verilator"
    }

    fn design(&self) -> &Design {
        &self.design
    }

    fn poke(&mut self, port: PortId, value: &Bits) -> Result<()> {
        self.design.check_poke(port, value)?;
        self.set_raw(port, value)
    }

    fn peek(&self, port: PortId) -> Result<Bits> {
        let width = self.design.port(port)?.width;
        let mut words = vec![0u64; width.div_ceil(64) as usize];
        // SAFETY: `instance` is live and `words` holds the count the shim checks.
        let rc = unsafe {
            (self.get)(
                self.instance,
                port.0 as u32,
                words.as_mut_ptr(),
                words.len() as u32,
            )
        };
        if rc != 0 {
            return Err(CosimError::Protocol {
                what: format!(
                    "shim refused to read port {}",
                    self.design.ports[port.0].name
                ),
            });
        }
        Ok(Bits::from_words(&words, width)?)
    }

    fn eval(&mut self) -> Result<()> {
        // SAFETY: `instance` is live.
        unsafe { (self.eval_fn)(self.instance) };
        Ok(())
    }

    fn step(&mut self) -> Result<()> {
        if let Some(clk) = self.clock {
            self.set_raw(clk, &Bits::zero(1))?;
            self.eval()?;
            self.set_raw(clk, &Bits::ones(1))?;
        }
        self.eval()?;
        self.cycle += 1;
        Ok(())
    }

    fn cycle(&self) -> u64 {
        self.cycle
    }

    fn trace_start(&mut self, path: &Path) -> Result<()> {
        crate::waves::check_engine_writes(self.waves, path, "this Verilator model")?;
        let c_path =
            CString::new(path.to_string_lossy().as_bytes()).map_err(|_| CosimError::Io {
                path: path.to_path_buf(),
                source: std::io::Error::new(std::io::ErrorKind::InvalidInput, "NUL in path"),
            })?;
        // SAFETY: `instance` is live and `c_path` outlives the call.
        match unsafe { (self.trace_open)(self.instance, c_path.as_ptr(), self.scope.as_ptr()) } {
            0 => Ok(()),
            -1 => Err(CosimError::Unsupported {
                what: "VCD tracing needs a Verilator model built with VerilatorOptions { trace: true }"
                    .to_string(),
            }),
            _ => Err(CosimError::Io {
                path: path.to_path_buf(),
                source: std::io::Error::other("Verilator could not open the VCD file"),
            }),
        }
    }

    fn trace_stop(&mut self) -> Result<()> {
        // SAFETY: `instance` is live.
        unsafe { (self.trace_close)(self.instance) };
        Ok(())
    }
}

impl Drop for VerilatorEngine {
    fn drop(&mut self) {
        if let Some(path) = self.coverage_out.take() {
            let written = CString::new(path.to_string_lossy().as_bytes())
                .ok()
                // SAFETY: `instance` is live and the path outlives the call.
                .map(|c| unsafe { (self.coverage_write)(self.instance, c.as_ptr()) });
            if written != Some(0) || !path.is_file() {
                crate::coverage::record_error(format!(
                    "{}: the Verilator model of {} wrote no coverage counts",
                    path.display(),
                    self.design.top
                ));
            }
        }
        // SAFETY: created by hm_create, destroyed exactly once, before the library unloads.
        unsafe { (self.destroy)(self.instance) };
    }
}
