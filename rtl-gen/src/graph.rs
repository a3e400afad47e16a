//! The intermediate representation: a module is an arena of nodes.
//!
//! Every node has an exact width. The builder makes every operand width
//! explicit (extension nodes), so operators here combine equal-width
//! operands, except where noted; the emitter and the simulator read the same
//! nodes and therefore cannot disagree about widths.

use crate::diagnostic::{DiagKind, Diagnostic, Loc, Severity};
use crate::Bits;
use std::cell::RefCell;
use std::rc::Rc;

/// Index of a node in its module's arena.
pub(crate) type NodeId = u32;

/// Shared handle to a module graph (instances keep their child alive).
pub(crate) type GraphRef = Rc<RefCell<Graph>>;

/// Bitwise and arithmetic binary operators on equal-width operands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum BinOp {
    And,
    Or,
    Xor,
    Add,
    Sub,
}

/// Comparison operators; the result is one bit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CmpOp {
    /// `==`
    Eq,
    /// `!=`
    Ne,
    /// `<`
    Lt,
    /// `<=`
    Le,
    /// `>`
    Gt,
    /// `>=`
    Ge,
}

/// Shift direction and fill.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum ShiftKind {
    Left,
    RightLogical,
    RightArith,
}

/// A shift amount: a constant or an unsigned signal (any width).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Amount {
    Const(u32),
    Signal(NodeId),
}

/// Reduction operators; the result is one bit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum RedOp {
    And,
    Or,
    Xor,
}

/// What a node computes.
#[derive(Debug, Clone)]
pub(crate) enum Op {
    /// An input port.
    Input,
    /// A wire (or an output port): takes the value of its single driver.
    Wire {
        drivers: Vec<(NodeId, Loc)>,
    },
    /// A register: on each rising clock edge takes `next`; `reset` on a
    /// synchronous reset when present.
    Reg {
        next: Vec<(NodeId, Loc)>,
        reset: Option<Bits>,
    },
    Const(Bits),
    Not(NodeId),
    Bin(BinOp, NodeId, NodeId),
    /// `a` shifted; the result has `a`'s width.
    Shift(ShiftKind, NodeId, Amount),
    /// Comparison of equal-width operands, signed or unsigned.
    Cmp(CmpOp, bool, NodeId, NodeId),
    Mux {
        sel: NodeId,
        then_: NodeId,
        else_: NodeId,
    },
    /// Concatenation, most significant part first.
    Concat(Vec<NodeId>),
    /// Bits `lo .. lo+width` of the operand.
    Slice(NodeId, u32),
    /// Zero (`false`) or sign (`true`) extension of a narrower operand.
    Ext(NodeId, bool),
    Reduce(RedOp, NodeId),
    /// Asynchronous read of memory `mem` at `addr`.
    MemRead {
        mem: usize,
        addr: NodeId,
    },
    /// Synchronous read: a register that takes `mem[addr]` on the clock edge when `en`.
    MemReadSync {
        mem: usize,
        addr: NodeId,
        en: NodeId,
    },
    /// Output port `port` of instance `inst`.
    InstOut {
        inst: usize,
        port: String,
    },
    /// Stands in for the result of a construct that was rejected with an error.
    Poison,
}

/// Port direction.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Direction {
    /// Driven from outside the module.
    Input,
    /// Driven by the module.
    Output,
}

/// One node of the arena.
#[derive(Debug, Clone)]
pub(crate) struct Node {
    pub op: Op,
    pub width: u32,
    /// Name given by the user (ports, wires, registers, `.name()`).
    pub name: Option<String>,
    /// Name of the nearest named source, to name derived temporaries.
    pub base: String,
    /// Operator word used in the derived name (`add`, `mux`, ...).
    pub opname: &'static str,
    pub loc: Loc,
    pub port: Option<Direction>,
}

/// A memory: `depth` words of `width` bits, written on the clock edge.
#[derive(Debug, Clone)]
pub(crate) struct MemData {
    pub name: String,
    pub width: u32,
    pub depth: u32,
    pub addr_width: u32,
    pub writes: Vec<WritePort>,
    pub loc: Loc,
}

/// `if (en) mem[addr] <= data` on the clock edge; later ports win.
#[derive(Debug, Clone)]
pub(crate) struct WritePort {
    pub addr: NodeId,
    pub data: NodeId,
    pub en: NodeId,
}

/// An instance of another module.
#[derive(Debug, Clone)]
pub(crate) struct InstData {
    pub name: String,
    pub child: GraphRef,
    /// Child input ports in the child's port order, with what drives each.
    pub inputs: Vec<InstInput>,
    /// Child output ports in port order, each with the node carrying it here.
    pub outputs: Vec<(String, NodeId)>,
    pub loc: Loc,
}

/// One input connection of an instance.
#[derive(Debug, Clone)]
pub(crate) struct InstInput {
    pub port: String,
    pub width: u32,
    pub drivers: Vec<(NodeId, Loc)>,
}

/// A module under construction or finished.
#[derive(Debug)]
pub(crate) struct Graph {
    pub name: String,
    pub loc: Loc,
    pub nodes: Vec<Node>,
    /// Port nodes in declaration order (clock and reset first once created).
    pub ports: Vec<NodeId>,
    pub mems: Vec<MemData>,
    pub insts: Vec<InstData>,
    pub clk: Option<NodeId>,
    pub rst: Option<NodeId>,
    /// Errors found while building.
    pub errors: Vec<Diagnostic>,
    /// The open [`crate::Scope`]s' names, outermost first.
    pub scopes: Vec<String>,
}

/// The operator word of a field view ([`crate::Signal::field_view`]): an
/// unnamed slice the emitter declares under its `base` where it is read.
pub(crate) const FIELD_VIEW: &str = "field";

/// Name of the implicit clock input.
pub const CLOCK: &str = "clk";
/// Name of the implicit synchronous, active-high reset input.
pub const RESET: &str = "rst";

impl Graph {
    pub fn new(name: &str, loc: Loc) -> Graph {
        Graph {
            name: name.to_string(),
            loc,
            nodes: Vec::new(),
            ports: Vec::new(),
            mems: Vec::new(),
            insts: Vec::new(),
            clk: None,
            rst: None,
            errors: Vec::new(),
            scopes: Vec::new(),
        }
    }

    pub fn node(&self, id: NodeId) -> &Node {
        &self.nodes[id as usize]
    }

    pub fn push(&mut self, node: Node) -> NodeId {
        self.nodes.push(node);
        (self.nodes.len() - 1) as NodeId
    }

    /// The name a diagnostic uses for a node: its user name or a description.
    pub fn describe(&self, id: NodeId) -> String {
        let n = self.node(id);
        match (&n.name, &n.op) {
            (Some(s), _) => s.clone(),
            (None, Op::InstOut { port, .. }) => format!("{}_{}", n.base, port),
            (None, _) => format!("{}_{}", n.base, n.opname),
        }
    }

    /// Records a construction error.
    pub fn error(&mut self, kind: DiagKind, signal: Option<String>, loc: Loc, message: String) {
        let module = self.name.clone();
        self.errors.push(Diagnostic {
            severity: Severity::Error,
            kind,
            module,
            signal,
            location: loc,
            message,
            related: Vec::new(),
        });
    }

    /// The operand nodes a node reads combinationally (what it needs this cycle).
    pub fn comb_inputs(&self, id: NodeId) -> Vec<NodeId> {
        match &self.node(id).op {
            Op::Input | Op::Const(_) | Op::Poison | Op::Reg { .. } => vec![],
            Op::MemReadSync { .. } | Op::InstOut { .. } => vec![],
            Op::Wire { drivers } => drivers.iter().map(|d| d.0).collect(),
            Op::Not(a) | Op::Slice(a, _) | Op::Ext(a, _) | Op::Reduce(_, a) => vec![*a],
            Op::Bin(_, a, b) | Op::Cmp(_, _, a, b) => vec![*a, *b],
            Op::Shift(_, a, Amount::Const(_)) => vec![*a],
            Op::Shift(_, a, Amount::Signal(s)) => vec![*a, *s],
            Op::Mux { sel, then_, else_ } => vec![*sel, *then_, *else_],
            Op::Concat(parts) => parts.clone(),
            Op::MemRead { addr, .. } => vec![*addr],
        }
    }

    /// Every node a node reads, on this cycle or at the next clock edge,
    /// with the bit range `(lo, width)` of the operand it reads.
    pub fn reads(&self, id: NodeId) -> Vec<(NodeId, u32, u32)> {
        let n = self.node(id);
        let full = |x: NodeId| (x, 0, self.node(x).width);
        match &n.op {
            Op::Slice(a, lo) => vec![(*a, *lo, n.width)],
            Op::Reg { next, .. } => next.iter().map(|d| full(d.0)).collect(),
            Op::MemReadSync { addr, en, .. } => vec![full(*addr), full(*en)],
            _ => self.comb_inputs(id).into_iter().map(full).collect(),
        }
    }
}

impl Graph {
    /// Which nodes the emitter writes inline inside other expressions instead
    /// of declaring: unnamed constants, slices and extensions. An extension
    /// that is itself sliced or extended must be a declared wire, because
    /// Verilog can only select bits of a name.
    pub fn inline_nodes(&self) -> Vec<bool> {
        let mut inline: Vec<bool> = self
            .nodes
            .iter()
            .map(|n| n.name.is_none() && matches!(n.op, Op::Const(_) | Op::Slice(..) | Op::Ext(..)))
            .collect();
        for n in &self.nodes {
            if let Op::Slice(a, _) | Op::Ext(a, _) = n.op {
                if matches!(self.node(a).op, Op::Ext(..)) {
                    inline[a as usize] = false;
                }
            }
        }
        inline
    }

    /// For each instance, the nodes each of its outputs depends on
    /// combinationally (the drivers of the child inputs the output reads in
    /// the same cycle). `depth` guards against instantiation cycles.
    pub fn instance_comb_inputs(&self, depth: u32) -> Result<Vec<Vec<Vec<NodeId>>>, String> {
        let mut all = Vec::new();
        for inst in &self.insts {
            let child = inst
                .child
                .try_borrow()
                .map_err(|_| format!("instance `{}` instantiates its parent", inst.name))?;
            let deps = child.port_comb_deps(depth + 1)?;
            let mut per_out = Vec::new();
            for (port, _) in &inst.outputs {
                let mut v = Vec::new();
                if let Some(ins) = deps.get(port) {
                    for input in &inst.inputs {
                        if ins.contains(&input.port) {
                            v.extend(input.drivers.iter().map(|d| d.0));
                        }
                    }
                }
                per_out.push(v);
            }
            all.push(per_out);
        }
        Ok(all)
    }

    /// For each output port, the input ports it depends on combinationally.
    pub fn port_comb_deps(
        &self,
        depth: u32,
    ) -> Result<std::collections::BTreeMap<String, std::collections::BTreeSet<String>>, String>
    {
        if depth > 64 {
            return Err(format!(
                "module `{}` is instantiated more than 64 levels deep (an instantiation cycle?)",
                self.name
            ));
        }
        let inst_deps = self.instance_comb_inputs(depth)?;
        let mut out = std::collections::BTreeMap::new();
        for &p in &self.ports {
            let n = self.node(p);
            if n.port != Some(Direction::Output) {
                continue;
            }
            let mut seen = vec![false; self.nodes.len()];
            let mut stack = vec![p];
            let mut ins = std::collections::BTreeSet::new();
            while let Some(x) = stack.pop() {
                if std::mem::replace(&mut seen[x as usize], true) {
                    continue;
                }
                let xn = self.node(x);
                if matches!(xn.op, Op::Input) {
                    ins.insert(xn.name.clone().unwrap_or_default());
                }
                stack.extend(self.comb_inputs_with(x, &inst_deps));
            }
            out.insert(n.name.clone().unwrap_or_default(), ins);
        }
        Ok(out)
    }

    /// [`Graph::comb_inputs`] plus the paths through instances.
    pub fn comb_inputs_with(&self, id: NodeId, inst_deps: &[Vec<Vec<NodeId>>]) -> Vec<NodeId> {
        if let Op::InstOut { inst, port } = &self.node(id).op {
            let pos = self.insts[*inst].outputs.iter().position(|o| &o.0 == port);
            return match (inst_deps.get(*inst), pos) {
                (Some(per_out), Some(i)) => per_out[i].clone(),
                _ => vec![],
            };
        }
        self.comb_inputs(id)
    }
}
