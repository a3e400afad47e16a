//! A cycle-based simulator of the IR: [`Sim`].
//!
//! The design is flattened, combinational nodes are levelized once, and all
//! values live in one word arena laid out so that every operand of a node
//! sits before it; a step allocates nothing.

pub(crate) mod flatten;
mod vcd;

use crate::graph::{BinOp, CmpOp, Direction, RedOp, ShiftKind};
use crate::{Bits, BitsError, Diagnostics, Module, Signal};
use flatten::{comb_order, flatten, FOp, F};
use golden::bits::words::{self, words_for};
use std::collections::BTreeMap;
use std::fmt;
use std::rc::Rc;

/// A problem with a simulator call (never a panic).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SimError {
    /// No port or named signal has this name.
    UnknownName(String),
    /// Only top-level input ports can be poked.
    NotAnInput(String),
    /// The clock is implicit: advance it with [`Sim::step`].
    ClockIsImplicit,
    /// The value does not fit the port.
    DoesNotFit(String, BitsError),
    /// The signal belongs to another module than the simulated top.
    ForeignSignal,
}

impl fmt::Display for SimError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SimError::UnknownName(n) => write!(f, "no port or named signal `{n}`"),
            SimError::NotAnInput(n) => write!(f, "`{n}` is not a top-level input port"),
            SimError::ClockIsImplicit => write!(f, "the clock is implicit: call step()"),
            SimError::DoesNotFit(n, e) => write!(f, "poke `{n}`: {e}"),
            SimError::ForeignSignal => write!(f, "signal does not belong to the simulated module"),
        }
    }
}

impl std::error::Error for SimError {}

/// A value that can be poked: integers (which must fit the port), `bool`, [`Bits`].
pub trait SimValue {
    /// The value as `width` bits, or why it does not fit.
    fn to_bits(&self, width: u32) -> Result<Bits, BitsError>;
}

macro_rules! unsigned_value {
    ($($t:ty),*) => {$(
        impl SimValue for $t {
            fn to_bits(&self, width: u32) -> Result<Bits, BitsError> {
                Bits::from_u128(*self as u128, width)
            }
        }
    )*};
}
unsigned_value!(u8, u16, u32, u64, u128, bool);

impl SimValue for i64 {
    /// Two's complement; must fit `width` bits as a signed number.
    fn to_bits(&self, width: u32) -> Result<Bits, BitsError> {
        Bits::from_i128(*self as i128, width)
    }
}

impl SimValue for Bits {
    fn to_bits(&self, width: u32) -> Result<Bits, BitsError> {
        if self.width() == width {
            return Ok(self.clone());
        }
        self.to_u128()
            .ok_or(BitsError::DoesNotFit {
                value: self.to_string(),
                width,
            })
            .and_then(|v| Bits::from_u128(v, width))
    }
}

impl SimValue for &Bits {
    fn to_bits(&self, width: u32) -> Result<Bits, BitsError> {
        (*self).to_bits(width)
    }
}

/// A register: its node, its next-value node, and its reset value with the reset node.
type RegSlot = (F, F, Option<(Bits, F)>);

/// A resolved port or signal, for fast repeated access.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Handle {
    node: F,
    input: bool,
}

/// One levelized instruction: the operation plus operand offsets and widths.
#[derive(Debug, Clone)]
struct Instr {
    op: FOp,
    dst: usize,
    width: u32,
    /// Offsets and widths of the operands, in `FOp::comb_inputs` order.
    args: Vec<(usize, u32)>,
}

/// Simulates a validated design cycle by cycle: [`Sim::poke`] inputs,
/// [`Sim::step`] one rising clock edge (registers with a reset value take it
/// when `rst` is high), [`Sim::peek`] any port or named signal (`inst.sig`
/// below the top). Memories start at zero.
///
/// ```
/// use rtl_gen::{Module, Sim};
/// let m = Module::new("counter");
/// let count = m.reg("count", 4);
/// count.next(count.add(1, 4));
/// m.output("q", count);
/// let mut sim = Sim::new(&m).unwrap();
/// sim.poke("rst", 1u64).unwrap();
/// sim.step();
/// sim.poke("rst", 0u64).unwrap();
/// sim.step_n(18);
/// assert_eq!(sim.peek("q").unwrap().to_u64(), Some(18 % 16));
/// ```
pub struct Sim {
    top: Rc<std::cell::RefCell<crate::graph::Graph>>,
    widths: Vec<u32>,
    offsets: Vec<usize>,
    vals: Vec<u64>,
    comb: Vec<Instr>,
    regs: Vec<RegSlot>,
    /// (node, memory, addr, en)
    sync_reads: Vec<(F, usize, F, F)>,
    mems: Vec<flatten::FMem>,
    mem_data: Vec<Vec<u64>>,
    staging: Vec<u64>,
    names: BTreeMap<String, F>,
    top_map: Vec<F>,
    ports: BTreeMap<String, (F, Direction)>,
    dirty: bool,
    cycle: u64,
    vcd: Option<vcd::Vcd>,
}

impl Sim {
    /// Builds a simulator for `top` and everything it instantiates, after
    /// validating the whole design.
    pub fn new(top: &Module) -> Result<Sim, Diagnostics> {
        top.validate_design()?;
        let g = top.graph();
        let flat = flatten(&g);
        let order = comb_order(&flat.nodes);
        // Sources and state first, then combinational nodes in order.
        let mut offsets = vec![0usize; flat.nodes.len()];
        let mut next = 0usize;
        for (i, n) in flat.nodes.iter().enumerate() {
            if n.op.is_state_or_source() {
                offsets[i] = next;
                next += words_for(n.width);
            }
        }
        for &i in &order {
            offsets[i] = next;
            next += words_for(flat.nodes[i].width);
        }
        let widths: Vec<u32> = flat.nodes.iter().map(|n| n.width).collect();
        let mut vals = vec![0u64; next];
        let mut regs = Vec::new();
        let mut sync_reads = Vec::new();
        let mut staging_len = 0;
        for (i, n) in flat.nodes.iter().enumerate() {
            match &n.op {
                FOp::Const(b) => {
                    let o = offsets[i];
                    vals[o..o + b.words().len()].copy_from_slice(b.words());
                }
                FOp::Reg(nx, r) => {
                    regs.push((i, *nx, r.clone()));
                    staging_len += words_for(n.width);
                }
                FOp::MemReadSync(m, a, e) => {
                    sync_reads.push((i, *m, *a, *e));
                    staging_len += words_for(n.width);
                }
                _ => {}
            }
        }
        let comb = order
            .iter()
            .map(|&i| {
                let op = flat.nodes[i].op.clone();
                let args = op
                    .comb_inputs()
                    .iter()
                    .map(|&a| (offsets[a], widths[a]))
                    .collect();
                Instr {
                    op,
                    dst: offsets[i],
                    width: widths[i],
                    args,
                }
            })
            .collect();
        let mem_data = flat
            .mems
            .iter()
            .map(|m| vec![0u64; m.depth as usize * words_for(m.width)])
            .collect();
        let mut ports = BTreeMap::new();
        for &p in &g.ports {
            let n = g.node(p);
            ports.insert(
                n.name.clone().unwrap_or_default(),
                (flat.top[p as usize], n.port.unwrap_or(Direction::Input)),
            );
        }
        drop(g);
        let mut sim = Sim {
            top: Rc::clone(&top.g),
            widths,
            offsets,
            vals,
            comb,
            regs,
            sync_reads,
            mems: flat.mems,
            mem_data,
            staging: vec![0; staging_len],
            names: flat.names,
            top_map: flat.top,
            ports,
            dirty: true,
            cycle: 0,
            vcd: None,
        };
        sim.settle();
        Ok(sim)
    }

    /// Clock edges so far.
    pub fn cycle(&self) -> u64 {
        self.cycle
    }

    /// Resolves a top-level port or named signal once, for [`Sim::set`] / [`Sim::get`].
    pub fn handle(&self, name: &str) -> Result<Handle, SimError> {
        if let Some(&(node, dir)) = self.ports.get(name) {
            return Ok(Handle {
                node,
                input: dir == Direction::Input && name != crate::CLOCK,
            });
        }
        self.names
            .get(name)
            .map(|&node| Handle { node, input: false })
            .ok_or_else(|| SimError::UnknownName(name.into()))
    }

    /// Sets a top-level input port.
    pub fn poke(&mut self, port: &str, value: impl SimValue) -> Result<(), SimError> {
        if port == crate::CLOCK {
            return Err(SimError::ClockIsImplicit);
        }
        let h = self.handle(port)?;
        if !h.input {
            return Err(SimError::NotAnInput(port.into()));
        }
        let b = value
            .to_bits(self.widths[h.node])
            .map_err(|e| SimError::DoesNotFit(port.into(), e))?;
        self.set(h, &b)
    }

    /// Sets an input through a handle; `value` must have the port's width.
    pub fn set(&mut self, h: Handle, value: &Bits) -> Result<(), SimError> {
        let w = self.widths[h.node];
        if !h.input {
            return Err(SimError::NotAnInput(self.name_of(h)));
        }
        if value.width() != w {
            let e = BitsError::DoesNotFit {
                value: value.to_string(),
                width: w,
            };
            return Err(SimError::DoesNotFit(self.name_of(h), e));
        }
        let o = self.offsets[h.node];
        self.vals[o..o + value.words().len()].copy_from_slice(value.words());
        self.dirty = true;
        Ok(())
    }

    /// Sets an input through a handle from a `u64`, which must fit the port.
    pub fn set_u64(&mut self, h: Handle, value: u64) -> Result<(), SimError> {
        let w = self.widths[h.node];
        if !h.input {
            return Err(SimError::NotAnInput(self.name_of(h)));
        }
        if w < 64 && value >> w != 0 {
            let e = BitsError::DoesNotFit {
                value: value.to_string(),
                width: w,
            };
            return Err(SimError::DoesNotFit(self.name_of(h), e));
        }
        let o = self.offsets[h.node];
        self.vals[o] = value;
        for x in &mut self.vals[o + 1..o + words_for(w)] {
            *x = 0;
        }
        self.dirty = true;
        Ok(())
    }

    /// The port name behind a handle, for error messages.
    fn name_of(&self, h: Handle) -> String {
        self.ports
            .iter()
            .find(|(_, (node, _))| *node == h.node)
            .map(|(n, _)| n.clone())
            .unwrap_or_default()
    }

    /// The current value of a port or named signal (`inst.name` below the top).
    pub fn peek(&mut self, name: &str) -> Result<Bits, SimError> {
        let h = self.handle(name)?;
        Ok(self.get(h))
    }

    /// The current value of a top-level signal by its handle.
    pub fn peek_signal(&mut self, s: Signal<'_>) -> Result<Bits, SimError> {
        if !Rc::ptr_eq(&s.m.g, &self.top) {
            return Err(SimError::ForeignSignal);
        }
        let node = self.top_map[s.id as usize];
        Ok(self.get(Handle { node, input: false }))
    }

    /// The current value through a handle.
    pub fn get(&mut self, h: Handle) -> Bits {
        let w = self.widths[h.node];
        let words = self.get_words(h).to_vec();
        Bits::from_words(&words, w).unwrap_or_else(|_| Bits::zero(w))
    }

    /// The current value's words (little-endian) through a handle, without allocating.
    pub fn get_words(&mut self, h: Handle) -> &[u64] {
        self.settle();
        let o = self.offsets[h.node];
        &self.vals[o..o + words_for(self.widths[h.node])]
    }

    /// The low 64 bits of the current value.
    pub fn get_u64(&mut self, h: Handle) -> u64 {
        self.get_words(h)[0]
    }

    /// Holds `rst` high for one clock edge, then low (when the design has a reset).
    pub fn reset(&mut self) {
        if self.poke(crate::RESET, 1u64).is_ok() {
            self.step();
            let _ = self.poke(crate::RESET, 0u64);
        }
    }

    /// `n` clock edges.
    pub fn step_n(&mut self, n: u64) {
        for _ in 0..n {
            self.step();
        }
    }

    /// One rising clock edge: registers load their next value (or their
    /// reset value while their reset is high), synchronous reads load the
    /// addressed word when enabled, then memory writes apply in port order.
    pub fn step(&mut self) {
        self.settle();
        let mut s = 0;
        for (node, next, reset) in &self.regs {
            let w = self.widths[*node];
            let n = words_for(w);
            let in_reset = reset
                .as_ref()
                .filter(|(_, r)| self.vals[self.offsets[*r]] & 1 == 1);
            match in_reset {
                Some((value, _)) => self.staging[s..s + n].copy_from_slice(value.words()),
                None => {
                    let o = self.offsets[*next];
                    self.staging[s..s + n].copy_from_slice(&self.vals[o..o + n]);
                }
            }
            s += n;
        }
        for (node, mem, addr, en) in &self.sync_reads {
            let n = words_for(self.widths[*node]);
            let src = if self.vals[self.offsets[*en]] & 1 == 1 {
                let a = self.vals[self.offsets[*addr]] as usize;
                &self.mem_data[*mem][a * n..a * n + n]
            } else {
                let o = self.offsets[*node];
                &self.vals[o..o + n]
            };
            self.staging[s..s + n].copy_from_slice(src);
            s += n;
        }
        for (mi, mem) in self.mems.iter().enumerate() {
            let n = words_for(mem.width);
            for &(addr, data, en) in &mem.writes {
                if self.vals[self.offsets[en]] & 1 == 1 {
                    let a = self.vals[self.offsets[addr]] as usize;
                    let o = self.offsets[data];
                    self.mem_data[mi][a * n..a * n + n].copy_from_slice(&self.vals[o..o + n]);
                }
            }
        }
        let mut s = 0;
        for &node in self
            .regs
            .iter()
            .map(|r| &r.0)
            .chain(self.sync_reads.iter().map(|r| &r.0))
        {
            let n = words_for(self.widths[node]);
            let o = self.offsets[node];
            self.vals[o..o + n].copy_from_slice(&self.staging[s..s + n]);
            s += n;
        }
        self.cycle += 1;
        self.dirty = true;
        self.sample_vcd();
    }

    /// Starts writing a VCD waveform of every port and named signal (with
    /// `inst.name` flattened to `inst_name`) to `out`: the current values at
    /// time 0, then the changes after each edge at 10 ns per cycle (the
    /// values a testbench would sample just before the next edge).
    ///
    /// ```
    /// # use rtl_gen::{examples::counter, Sim};
    /// let mut sim = Sim::new(&counter(4)).unwrap();
    /// let file = std::env::temp_dir().join("rtl_gen_doc_counter.vcd");
    /// sim.trace_vcd(Box::new(std::fs::File::create(&file).unwrap())).unwrap();
    /// sim.reset();
    /// sim.poke("en", 1u64).unwrap();
    /// sim.step_n(5);
    /// let text = std::fs::read_to_string(&file).unwrap();
    /// assert!(text.contains("$var wire 4 ") && text.contains("b0101 "));
    /// ```
    pub fn trace_vcd(&mut self, out: Box<dyn std::io::Write>) -> std::io::Result<()> {
        let signals: Vec<(String, usize, u32)> = self
            .names
            .iter()
            .map(|(name, &node)| (name.clone(), node, self.widths[node]))
            .collect();
        let top = self.top.borrow().name.clone();
        self.vcd = Some(vcd::Vcd::new(out, &top, &signals)?);
        self.sample_vcd();
        Ok(())
    }

    /// Writes the changed values when tracing; a write error stops tracing.
    fn sample_vcd(&mut self) {
        if self.vcd.is_none() {
            return;
        }
        self.settle();
        let time = self.cycle * 10;
        let (vals, offsets, widths) = (&self.vals, &self.offsets, &self.widths);
        let value =
            |node: usize| vals[offsets[node]..offsets[node] + words_for(widths[node])].to_vec();
        if let Some(v) = self.vcd.as_mut() {
            if v.sample(time, value).is_err() {
                self.vcd = None;
            }
        }
    }

    /// Recomputes every combinational node in levelized order.
    fn settle(&mut self) {
        if !self.dirty {
            return;
        }
        for ins in &self.comb {
            let (src, dst) = self.vals.split_at_mut(ins.dst);
            eval(ins, src, &mut dst[..words_for(ins.width)], &self.mem_data);
        }
        self.dirty = false;
    }
}

fn arg(src: &[u64], a: (usize, u32)) -> &[u64] {
    &src[a.0..a.0 + words_for(a.1)]
}

/// Computes one node into `dst` from operands that all lie in `src`.
fn eval(ins: &Instr, src: &[u64], dst: &mut [u64], mems: &[Vec<u64>]) {
    let w = ins.width;
    let a = || arg(src, ins.args[0]);
    let b = || arg(src, ins.args[1]);
    match &ins.op {
        FOp::Copy(_) => dst.copy_from_slice(a()),
        FOp::Not(_) => words::not(dst, a(), w),
        FOp::Bin(op, ..) => match op {
            BinOp::And => words::bitwise(dst, a(), b(), w, |x, y| x & y),
            BinOp::Or => words::bitwise(dst, a(), b(), w, |x, y| x | y),
            BinOp::Xor => words::bitwise(dst, a(), b(), w, |x, y| x ^ y),
            BinOp::Add => words::add(dst, a(), b(), w),
            BinOp::Sub => words::sub(dst, a(), b(), w),
        },
        FOp::Shift(kind, _, amount_node, k) => {
            let amount = match amount_node {
                Some(_) => words::shift_amount(b(), ins.args[1].1),
                None => *k as u64,
            };
            match kind {
                ShiftKind::Left => words::shl(dst, a(), amount, w),
                ShiftKind::RightLogical => words::shr(dst, a(), amount, w, false),
                ShiftKind::RightArith => words::shr(dst, a(), amount, w, true),
            }
        }
        FOp::Cmp(op, signed, ..) => {
            let ow = ins.args[0].1;
            let ord = if *signed {
                words::cmp_signed(a(), b(), ow)
            } else {
                words::cmp_unsigned(a(), b(), ow)
            };
            let r = match op {
                CmpOp::Eq => ord.is_eq(),
                CmpOp::Ne => ord.is_ne(),
                CmpOp::Lt => ord.is_lt(),
                CmpOp::Le => ord.is_le(),
                CmpOp::Gt => ord.is_gt(),
                CmpOp::Ge => ord.is_ge(),
            };
            dst[0] = r as u64;
        }
        FOp::Mux(..) => {
            let pick = if arg(src, ins.args[0])[0] & 1 == 1 {
                ins.args[1]
            } else {
                ins.args[2]
            };
            dst.copy_from_slice(arg(src, pick));
        }
        FOp::Concat(_) => {
            dst.iter_mut().for_each(|x| *x = 0);
            let mut lo = 0;
            for &p in ins.args.iter().rev() {
                words::deposit(dst, arg(src, p), lo, p.1);
                lo += p.1;
            }
        }
        FOp::Slice(_, lo) => words::extract(dst, a(), *lo, w),
        FOp::Ext(_, signed) => words::extend(dst, a(), ins.args[0].1, w, *signed),
        FOp::Reduce(op, _) => {
            let aw = ins.args[0].1;
            dst[0] = match op {
                RedOp::And => words::all_ones(a(), aw),
                RedOp::Or => words::any_one(a(), aw),
                RedOp::Xor => words::parity(a(), aw),
            } as u64;
        }
        FOp::MemRead(mem, _) => {
            let n = dst.len();
            let addr = a()[0] as usize;
            dst.copy_from_slice(&mems[*mem][addr * n..addr * n + n]);
        }
        FOp::Input | FOp::Const(_) | FOp::Reg(..) | FOp::MemReadSync(..) => {}
    }
}
