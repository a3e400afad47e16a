//! [`Module`]: the builder. Ports, wires, registers, constants, memories and
//! instances are made here; operators live on [`Signal`].

use crate::diagnostic::{DiagKind, Loc};
use crate::graph::{
    Direction, Graph, GraphRef, InstData, InstInput, Node, NodeId, Op, CLOCK, RESET,
};
use crate::names::check_identifier;
use crate::{Bits, Instance, Memory, Signal};
use std::cell::{Ref, RefCell, RefMut};
use std::panic::Location;
use std::rc::Rc;

/// A hardware module being built: an arena of signals plus its ports.
///
/// Construction never panics on a design mistake: the mistake is recorded
/// with the generator line that made it and reported by
/// [`Module::validate`], [`crate::emit_verilog`] and [`crate::Sim::new`].
/// Registers and memories use one implicit clock input `clk`, and registers
/// with a reset value an implicit synchronous active-high reset input `rst`;
/// both ports appear (first) only when something uses them.
///
/// ```
/// use rtl_gen::{Module, emit_verilog};
/// let m = Module::new("adder");
/// let a = m.input("a", 8);
/// let b = m.input("b", 8);
/// m.output("sum", a.add(b, 9));
/// let v = emit_verilog(&m).unwrap();
/// assert!(v.contains("module adder ("));
/// ```
pub struct Module {
    pub(crate) g: GraphRef,
}

/// One port of a module, as [`Module::ports`] lists it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PortInfo {
    /// The port's Verilog name.
    pub name: String,
    /// Width in bits.
    pub width: u32,
    /// Input or output.
    pub direction: Direction,
}

impl Module {
    /// A new, empty module named `name` (which must be a Verilog identifier).
    #[track_caller]
    pub fn new(name: &str) -> Module {
        let loc = Location::caller();
        let mut g = Graph::new(name, loc);
        if let Err(why) = check_identifier(name) {
            g.error(DiagKind::Name, None, loc, format!("module name: {why}"));
        }
        Module {
            g: Rc::new(RefCell::new(g)),
        }
    }

    /// The module's name.
    pub fn name(&self) -> String {
        self.graph().name.clone()
    }

    /// True when `path` (instance names from this module down, `u_a.u_b`)
    /// names an instance in its hierarchy: what a waveform's scope filter
    /// may ask for.
    pub fn has_instance_path(&self, path: &str) -> bool {
        fn walk(g: &Graph, parts: &[&str]) -> bool {
            match parts.split_first() {
                None => true,
                Some((first, rest)) => g
                    .insts
                    .iter()
                    .any(|i| i.name == *first && walk(&i.child.borrow(), rest)),
            }
        }
        let parts: Vec<&str> = path.split('.').collect();
        walk(&self.graph(), &parts)
    }

    pub(crate) fn graph(&self) -> Ref<'_, Graph> {
        self.g.borrow()
    }

    pub(crate) fn graph_mut(&self) -> RefMut<'_, Graph> {
        self.g.borrow_mut()
    }

    /// Ports in declaration order (`clk` and `rst` first when present).
    ///
    /// ```
    /// use rtl_gen::{Direction, Module};
    /// let m = Module::new("m");
    /// let a = m.input("a", 3);
    /// m.output("y", !a);
    /// let ports = m.ports();
    /// assert_eq!(ports[0].name, "a");
    /// assert_eq!((ports[1].width, ports[1].direction), (3, Direction::Output));
    /// ```
    pub fn ports(&self) -> Vec<PortInfo> {
        let g = self.graph();
        g.ports
            .iter()
            .map(|&id| {
                let n = g.node(id);
                PortInfo {
                    name: n.name.clone().unwrap_or_default(),
                    width: n.width,
                    direction: n.port.unwrap_or(Direction::Input),
                }
            })
            .collect()
    }

    pub(crate) fn sig(&self, id: NodeId, signed: bool) -> Signal<'_> {
        Signal {
            m: self,
            id,
            signed,
        }
    }

    pub(crate) fn add_node(
        &self,
        op: Op,
        width: u32,
        base: &str,
        opname: &'static str,
        loc: Loc,
    ) -> NodeId {
        self.graph_mut().push(Node {
            op,
            width,
            name: None,
            base: base.to_string(),
            opname,
            loc,
            port: None,
        })
    }

    /// Records an error and returns a stand-in signal of `width` bits so that
    /// construction can go on and report every mistake at once.
    pub(crate) fn fail(
        &self,
        kind: DiagKind,
        signal: Option<String>,
        loc: Loc,
        msg: String,
        width: u32,
    ) -> Signal<'_> {
        self.graph_mut().error(kind, signal, loc, msg);
        let id = self.add_node(Op::Poison, width.max(1), "error", "poison", loc);
        self.sig(id, false)
    }

    /// A stand-in signal for a construct whose error is already recorded.
    pub(crate) fn poison(&self, width: u32, loc: Loc) -> Signal<'_> {
        let id = self.add_node(Op::Poison, width.max(1), "error", "poison", loc);
        self.sig(id, false)
    }

    fn named_node(
        &self,
        name: &str,
        width: u32,
        op: Op,
        port: Option<Direction>,
        loc: Loc,
    ) -> Result<NodeId, Signal<'_>> {
        if width == 0 || width > crate::MAX_WIDTH {
            return Err(self.fail(
                DiagKind::Width,
                Some(name.into()),
                loc,
                format!("a signal needs 1 to {} bits, not {width}", crate::MAX_WIDTH),
                1,
            ));
        }
        if port.is_some() {
            let problem = {
                let g = self.graph();
                if let Err(why) = check_identifier(name) {
                    Some(why)
                } else if name == CLOCK || name == RESET {
                    Some(format!("`{name}` is the implicit clock/reset port's name"))
                } else if g
                    .ports
                    .iter()
                    .any(|&p| g.node(p).name.as_deref() == Some(name))
                {
                    Some(format!("a port named `{name}` already exists"))
                } else {
                    None
                }
            };
            if let Some(why) = problem {
                return Err(self.fail(DiagKind::Name, Some(name.into()), loc, why, width));
            }
        }
        let name = match port {
            Some(_) => name.to_string(),
            None => self.scoped(name),
        };
        let mut g = self.graph_mut();
        let id = g.push(Node {
            op,
            width,
            name: Some(name.clone()),
            base: name,
            opname: "",
            loc,
            port,
        });
        if port.is_some() {
            g.ports.push(id);
        }
        Ok(id)
    }

    /// An input port of `width` bits (unsigned; see [`Signal::as_signed`]).
    ///
    /// ```
    /// # use rtl_gen::Module;
    /// let m = Module::new("m");
    /// let a = m.input("a", 300); // any width
    /// assert_eq!(a.width(), 300);
    /// ```
    #[track_caller]
    pub fn input(&self, name: &str, width: u32) -> Signal<'_> {
        let loc = Location::caller();
        match self.named_node(name, width, Op::Input, Some(Direction::Input), loc) {
            Ok(id) => self.sig(id, false),
            Err(s) => s,
        }
    }

    /// An output port driven by `value`; returns the port's signal, which
    /// the module may also read.
    ///
    /// ```
    /// # use rtl_gen::Module;
    /// let m = Module::new("m");
    /// let a = m.input("a", 4);
    /// let y = m.output("y", !a);
    /// assert_eq!(y.width(), 4);
    /// ```
    #[track_caller]
    pub fn output<'m>(&'m self, name: &str, value: Signal<'m>) -> Signal<'m> {
        let loc = Location::caller();
        let width = value.width();
        match self.named_node(
            name,
            width,
            Op::Wire { drivers: vec![] },
            Some(Direction::Output),
            loc,
        ) {
            Ok(id) => {
                let out = self.sig(id, value.signed);
                out.drive_at(value, loc);
                out
            }
            Err(s) => s,
        }
    }

    /// An output port to be driven later with [`Signal::drive`] (for values
    /// computed after the port is needed, such as a stream's `ready`).
    ///
    /// ```
    /// # use rtl_gen::Module;
    /// let m = Module::new("m");
    /// let ready = m.output_wire("ready", 1);
    /// ready.drive(m.lit(1, 1));
    /// # assert!(m.validate().is_ok());
    /// ```
    #[track_caller]
    pub fn output_wire(&self, name: &str, width: u32) -> Signal<'_> {
        let loc = Location::caller();
        match self.named_node(
            name,
            width,
            Op::Wire { drivers: vec![] },
            Some(Direction::Output),
            loc,
        ) {
            Ok(id) => self.sig(id, false),
            Err(s) => s,
        }
    }

    /// A named wire, driven once with [`Signal::drive`]; it may be read
    /// before it is driven (forward reference).
    ///
    /// ```
    /// # use rtl_gen::Module;
    /// let m = Module::new("m");
    /// let a = m.input("a", 8);
    /// let w = m.wire("w", 8);
    /// m.output("y", w ^ a);
    /// w.drive(!a);
    /// # assert!(m.validate().is_ok());
    /// ```
    #[track_caller]
    pub fn wire(&self, name: &str, width: u32) -> Signal<'_> {
        let loc = Location::caller();
        match self.named_node(name, width, Op::Wire { drivers: vec![] }, None, loc) {
            Ok(id) => self.sig(id, false),
            Err(s) => s,
        }
    }

    /// A register that resets to zero; give it its next value with [`Signal::next`].
    ///
    /// ```
    /// # use rtl_gen::Module;
    /// let m = Module::new("counter");
    /// let count = m.reg("count", 8);
    /// count.next(count.add(1, 8));
    /// m.output("value", count);
    /// # assert!(m.validate().is_ok());
    /// ```
    #[track_caller]
    pub fn reg(&self, name: &str, width: u32) -> Signal<'_> {
        let loc = Location::caller();
        self.make_reg(name, width, Some(Bits::zero(width)), loc)
    }

    /// A register with the given reset value (which must fit in `width` bits).
    ///
    /// ```
    /// # use rtl_gen::{Bits, Module};
    /// let m = Module::new("m");
    /// let state = m.reg_reset("state", 4, Bits::from_u128(9, 4).unwrap());
    /// state.next(state);
    /// # m.output("s", state);
    /// # assert!(m.validate().is_ok());
    /// ```
    #[track_caller]
    pub fn reg_reset(&self, name: &str, width: u32, reset: Bits) -> Signal<'_> {
        let loc = Location::caller();
        if reset.width() != width {
            return self.fail(
                DiagKind::Width,
                Some(name.into()),
                loc,
                format!(
                    "reset value is {} bits, the register {} bits",
                    reset.width(),
                    width
                ),
                width,
            );
        }
        self.make_reg(name, width, Some(reset), loc)
    }

    /// A register without reset (its value is undefined until first loaded).
    ///
    /// ```
    /// # use rtl_gen::Module;
    /// let m = Module::new("m");
    /// let d = m.input("d", 8);
    /// let q = m.reg_no_reset("q", 8);
    /// q.next(d);
    /// # m.output("y", q);
    /// # assert!(m.validate().is_ok());
    /// ```
    #[track_caller]
    pub fn reg_no_reset(&self, name: &str, width: u32) -> Signal<'_> {
        let loc = Location::caller();
        self.make_reg(name, width, None, loc)
    }

    fn make_reg(&self, name: &str, width: u32, reset: Option<Bits>, loc: Loc) -> Signal<'_> {
        let has_reset = reset.is_some();
        match self.named_node(
            name,
            width,
            Op::Reg {
                next: vec![],
                reset,
            },
            None,
            loc,
        ) {
            Ok(id) => {
                self.clock(loc);
                if has_reset {
                    self.reset(loc);
                }
                self.sig(id, false)
            }
            Err(s) => s,
        }
    }

    /// The implicit clock input, made on first use.
    pub(crate) fn clock(&self, loc: Loc) -> NodeId {
        self.implicit_port(CLOCK, loc)
    }

    /// The implicit reset input, made on first use.
    pub(crate) fn reset(&self, loc: Loc) -> NodeId {
        self.implicit_port(RESET, loc)
    }

    fn implicit_port(&self, name: &str, loc: Loc) -> NodeId {
        let mut g = self.graph_mut();
        let existing = if name == CLOCK { g.clk } else { g.rst };
        if let Some(id) = existing {
            return id;
        }
        let id = g.push(Node {
            op: Op::Input,
            width: 1,
            name: Some(name.to_string()),
            base: name.to_string(),
            opname: "",
            loc,
            port: Some(Direction::Input),
        });
        // Clock first, reset second, then the user's ports.
        let at = if name == CLOCK {
            0
        } else {
            usize::from(g.clk.is_some())
        };
        g.ports.insert(at, id);
        if name == CLOCK {
            g.clk = Some(id);
        } else {
            g.rst = Some(id);
        }
        id
    }

    /// The implicit reset input as a signal (so logic can also see reset).
    ///
    /// ```
    /// # use rtl_gen::Module;
    /// let m = Module::new("m");
    /// m.output("in_reset", m.reset_signal());
    /// assert_eq!(m.ports()[0].name, "rst");
    /// ```
    #[track_caller]
    pub fn reset_signal(&self) -> Signal<'_> {
        let id = self.reset(Location::caller());
        self.sig(id, false)
    }

    /// An unsigned constant of `width` bits; an error if `value` needs more bits.
    ///
    /// ```
    /// # use rtl_gen::Module;
    /// let m = Module::new("m");
    /// let k = m.lit(200, 8);
    /// assert_eq!(k.width(), 8);
    /// ```
    #[track_caller]
    pub fn lit(&self, value: u128, width: u32) -> Signal<'_> {
        let loc = Location::caller();
        match Bits::from_u128(value, width) {
            Ok(b) if width > 0 => self.constant(b, false, loc),
            Ok(_) => self.fail(
                DiagKind::Width,
                None,
                loc,
                "a constant needs at least one bit".into(),
                1,
            ),
            Err(e) => self.fail(DiagKind::Width, None, loc, e.to_string(), width),
        }
    }

    /// A signed constant of `width` bits (two's complement); an error if it does not fit.
    ///
    /// ```
    /// # use rtl_gen::Module;
    /// let m = Module::new("m");
    /// let k = m.lit_signed(-3, 8);
    /// assert!(k.is_signed());
    /// ```
    #[track_caller]
    pub fn lit_signed(&self, value: i128, width: u32) -> Signal<'_> {
        let loc = Location::caller();
        match Bits::from_i128(value, width) {
            Ok(b) => self.constant(b, true, loc),
            Err(e) => self.fail(DiagKind::Width, None, loc, e.to_string(), width),
        }
    }

    /// A constant with exactly the given bits (any width).
    ///
    /// ```
    /// # use rtl_gen::{Bits, Module};
    /// let m = Module::new("m");
    /// let k = m.lit_bits(Bits::ones(200));
    /// assert_eq!(k.width(), 200);
    /// ```
    #[track_caller]
    pub fn lit_bits(&self, value: Bits) -> Signal<'_> {
        let loc = Location::caller();
        if value.width() == 0 {
            return self.fail(
                DiagKind::Width,
                None,
                loc,
                "a constant needs at least one bit".into(),
                1,
            );
        }
        self.constant(value, false, loc)
    }

    pub(crate) fn constant(&self, value: Bits, signed: bool, loc: Loc) -> Signal<'_> {
        let w = value.width();
        let id = self.add_node(Op::Const(value), w, "const", "k", loc);
        self.sig(id, signed)
    }

    /// `{parts[0], parts[1], ...}`: the first part in the most significant bits.
    ///
    /// ```
    /// # use rtl_gen::Module;
    /// let m = Module::new("m");
    /// let a = m.input("a", 3);
    /// let b = m.input("b", 5);
    /// assert_eq!(m.concat(&[a, b, a]).width(), 11);
    /// ```
    #[track_caller]
    pub fn concat<'m>(&'m self, parts: &[Signal<'m>]) -> Signal<'m> {
        let loc = Location::caller();
        let Some(first) = parts.first() else {
            return self.fail(
                DiagKind::Misuse,
                None,
                loc,
                "concatenation of nothing".into(),
                1,
            );
        };
        for p in parts {
            if !self.owns(*p, loc) {
                return self.fail(
                    DiagKind::Misuse,
                    None,
                    loc,
                    "concatenation across modules".into(),
                    1,
                );
            }
        }
        if parts.len() == 1 {
            return first.as_unsigned();
        }
        let width: u64 = parts.iter().map(|p| p.width() as u64).sum();
        let Some(width) = u32::try_from(width).ok().filter(|&w| w <= crate::MAX_WIDTH) else {
            return self.fail(
                DiagKind::Width,
                None,
                loc,
                format!("concatenation of {width} bits is too wide"),
                1,
            );
        };
        let base = self.graph().node(first.id).base.clone();
        let id = self.add_node(
            Op::Concat(parts.iter().map(|p| p.id).collect()),
            width,
            &base,
            "cat",
            loc,
        );
        self.sig(id, false)
    }

    /// True when `s` belongs to this module; records an error otherwise.
    pub(crate) fn owns(&self, s: Signal<'_>, loc: Loc) -> bool {
        if std::ptr::eq(s.m, self) {
            return true;
        }
        let other = s.m.name();
        let what = s.m.graph().describe(s.id);
        self.graph_mut().error(
            DiagKind::Misuse,
            Some(what),
            loc,
            format!("signal belongs to module `{other}`; connect modules through an instance"),
        );
        false
    }

    /// A memory of `depth` words of `width` bits (`depth` a power of two, at
    /// least 2) written on the clock edge; see [`Memory`].
    ///
    /// ```
    /// # use rtl_gen::Module;
    /// let m = Module::new("regfile");
    /// let mem = m.memory("regs", 32, 16);
    /// let (wa, wd, we) = (m.input("wa", 4), m.input("wd", 32), m.input("we", 1));
    /// mem.write(wa, wd, we);
    /// m.output("rd", mem.read(m.input("ra", 4)));
    /// # assert!(m.validate().is_ok());
    /// ```
    #[track_caller]
    pub fn memory(&self, name: &str, width: u32, depth: u32) -> Memory<'_> {
        let loc = Location::caller();
        let addr_width = depth.max(2).next_power_of_two().trailing_zeros();
        if depth < 2 || !depth.is_power_of_two() {
            self.graph_mut().error(
                DiagKind::Misuse,
                Some(name.into()),
                loc,
                format!("memory depth {depth} must be a power of two, at least 2, so every address is in range"),
            );
        }
        if width == 0 {
            self.graph_mut().error(
                DiagKind::Width,
                Some(name.into()),
                loc,
                "a memory word needs at least one bit".into(),
            );
        }
        let name = self.scoped(name);
        let mut g = self.graph_mut();
        g.mems.push(crate::graph::MemData {
            name,
            width: width.max(1),
            depth,
            addr_width,
            writes: vec![],
            loc,
        });
        Memory {
            m: self,
            idx: g.mems.len() - 1,
        }
    }

    /// An instance named `name` of the finished module `child`; connect its
    /// inputs with [`Instance::connect`] and read its outputs with
    /// [`Instance::output`]. The child's `clk` and `rst` are connected to
    /// this module's.
    ///
    /// ```
    /// # use rtl_gen::Module;
    /// let inv = Module::new("inv");
    /// let a = inv.input("a", 4);
    /// inv.output("y", !a);
    ///
    /// let top = Module::new("top");
    /// let x = top.input("x", 4);
    /// let u = top.instance("u_inv", &inv);
    /// u.connect("a", x);
    /// top.output("y", u.output("y"));
    /// # assert!(top.validate().is_ok());
    /// ```
    #[track_caller]
    pub fn instance<'m>(&'m self, name: &str, child: &Module) -> Instance<'m> {
        let loc = Location::caller();
        if Rc::ptr_eq(&self.g, &child.g) {
            self.graph_mut().error(
                DiagKind::Misuse,
                Some(name.into()),
                loc,
                "a module cannot instantiate itself".into(),
            );
            let mut g = self.graph_mut();
            g.insts.push(InstData {
                name: name.to_string(),
                child: Rc::clone(&child.g),
                inputs: vec![],
                outputs: vec![],
                loc,
            });
            return Instance {
                m: self,
                idx: g.insts.len() - 1,
            };
        }
        if let Err(why) = check_identifier(name) {
            self.graph_mut().error(
                DiagKind::Name,
                Some(name.into()),
                loc,
                format!("instance name: {why}"),
            );
        }
        let child_ports: Vec<(String, u32, Direction)> = child
            .ports()
            .into_iter()
            .map(|p| (p.name, p.width, p.direction))
            .collect();
        let idx = self.graph().insts.len();
        let mut inputs = vec![];
        let mut outputs = vec![];
        for (port, width, dir) in child_ports {
            match dir {
                Direction::Input => {
                    let drivers = if port == CLOCK {
                        vec![(self.clock(loc), loc)]
                    } else if port == RESET {
                        vec![(self.reset(loc), loc)]
                    } else {
                        vec![]
                    };
                    inputs.push(InstInput {
                        port,
                        width,
                        drivers,
                    });
                }
                Direction::Output => {
                    let op = Op::InstOut {
                        inst: idx,
                        port: port.clone(),
                    };
                    let id = self.graph_mut().push(Node {
                        op,
                        width,
                        name: None,
                        base: name.to_string(),
                        opname: "",
                        loc,
                        port: None,
                    });
                    outputs.push((port, id));
                }
            }
        }
        self.graph_mut().insts.push(InstData {
            name: name.to_string(),
            child: Rc::clone(&child.g),
            inputs,
            outputs,
            loc,
        });
        Instance { m: self, idx }
    }
}
