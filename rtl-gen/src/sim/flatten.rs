//! Flattens a design (the top module and every instance below it) into one
//! netlist of flat nodes, in an order where every combinational node comes
//! after everything it reads.

use crate::graph::{Amount, BinOp, CmpOp, Direction, Graph, NodeId, Op, RedOp, ShiftKind};
use crate::Bits;
use std::collections::BTreeMap;

/// Index into the flat netlist.
pub(crate) type F = usize;

#[derive(Debug, Clone)]
pub(crate) enum FOp {
    Input,
    Const(Bits),
    /// Takes the value of another node (wires, ports across hierarchy).
    Copy(F),
    Not(F),
    Bin(BinOp, F, F),
    Shift(ShiftKind, F, Option<F>, u32),
    Cmp(CmpOp, bool, F, F),
    Mux(F, F, F),
    Concat(Vec<F>),
    Slice(F, u32),
    Ext(F, bool),
    Reduce(RedOp, F),
    MemRead(usize, F),
    /// Register: next value, reset value, reset signal.
    Reg(F, Option<(Bits, F)>),
    /// Registered memory read: memory, address, enable.
    MemReadSync(usize, F, F),
}

#[derive(Debug, Clone)]
pub(crate) struct FNode {
    pub op: FOp,
    pub width: u32,
}

#[derive(Debug, Clone)]
pub(crate) struct FMem {
    pub width: u32,
    pub depth: u32,
    /// (addr, data, en) in port order.
    pub writes: Vec<(F, F, F)>,
}

pub(crate) struct Flat {
    pub nodes: Vec<FNode>,
    pub mems: Vec<FMem>,
    /// Hierarchical name (`u_a.u_b.sig`) of named nodes and ports, first wins.
    pub names: BTreeMap<String, F>,
    /// Flat node of each top-level node.
    pub top: Vec<F>,
}

/// Flattens `g`; `inputs` gives the flat driver of each of its input ports
/// (empty at the top, where inputs stay free).
pub(crate) fn flatten(g: &Graph) -> Flat {
    let mut flat = Flat {
        nodes: Vec::new(),
        mems: Vec::new(),
        names: BTreeMap::new(),
        top: Vec::new(),
    };
    flat.top = add_module(&mut flat, g, "", &BTreeMap::new());
    flat
}

fn add_module(flat: &mut Flat, g: &Graph, prefix: &str, inputs: &BTreeMap<String, F>) -> Vec<F> {
    // Reserve one flat node per local node first so forward references work.
    let base = flat.nodes.len();
    let map: Vec<F> = (0..g.nodes.len()).map(|i| base + i).collect();
    for n in &g.nodes {
        flat.nodes.push(FNode {
            op: FOp::Input,
            width: n.width,
        });
    }
    let mem_base = flat.mems.len();
    for m in &g.mems {
        let writes = m
            .writes
            .iter()
            .map(|w| {
                (
                    map[w.addr as usize],
                    map[w.data as usize],
                    map[w.en as usize],
                )
            })
            .collect();
        flat.mems.push(FMem {
            width: m.width,
            depth: m.depth,
            writes,
        });
    }
    for (id, n) in g.nodes.iter().enumerate() {
        if let Some(name) = &n.name {
            flat.names
                .entry(format!("{prefix}{name}"))
                .or_insert(map[id]);
        }
    }
    // Instances: flatten each child with its inputs bound to our drivers.
    let mut inst_outputs: Vec<BTreeMap<String, F>> = Vec::new();
    for inst in &g.insts {
        let child = inst.child.borrow();
        let mut bound = BTreeMap::new();
        for i in &inst.inputs {
            if let Some(d) = i.drivers.first() {
                bound.insert(i.port.clone(), map[d.0 as usize]);
            }
        }
        let child_map = add_module(flat, &child, &format!("{prefix}{}.", inst.name), &bound);
        let mut outs = BTreeMap::new();
        for &p in &child.ports {
            let pn = child.node(p);
            if pn.port == Some(Direction::Output) {
                outs.insert(pn.name.clone().unwrap_or_default(), child_map[p as usize]);
            }
        }
        inst_outputs.push(outs);
    }
    let rst = g.rst.map(|r| map[r as usize]);
    for (id, n) in g.nodes.iter().enumerate() {
        let m = |x: &NodeId| map[*x as usize];
        let op = match &n.op {
            Op::Input => match n.name.as_ref().and_then(|nm| inputs.get(nm)) {
                Some(&d) => FOp::Copy(d),
                None => FOp::Input,
            },
            Op::Wire { drivers } => FOp::Copy(m(&drivers[0].0)),
            Op::Reg { next, reset } => FOp::Reg(m(&next[0].0), reset.clone().zip(rst)),
            Op::Const(b) => FOp::Const(b.clone()),
            Op::Not(a) => FOp::Not(m(a)),
            Op::Bin(op, a, b) => FOp::Bin(*op, m(a), m(b)),
            Op::Shift(k, a, Amount::Const(c)) => FOp::Shift(*k, m(a), None, *c),
            Op::Shift(k, a, Amount::Signal(s)) => FOp::Shift(*k, m(a), Some(m(s)), 0),
            Op::Cmp(op, s, a, b) => FOp::Cmp(*op, *s, m(a), m(b)),
            Op::Mux { sel, then_, else_ } => FOp::Mux(m(sel), m(then_), m(else_)),
            Op::Concat(parts) => FOp::Concat(parts.iter().map(m).collect()),
            Op::Slice(a, lo) => FOp::Slice(m(a), *lo),
            Op::Ext(a, s) => FOp::Ext(m(a), *s),
            Op::Reduce(op, a) => FOp::Reduce(*op, m(a)),
            Op::MemRead { mem, addr } => FOp::MemRead(mem_base + mem, m(addr)),
            Op::MemReadSync { mem, addr, en } => FOp::MemReadSync(mem_base + mem, m(addr), m(en)),
            Op::InstOut { inst, port } => FOp::Copy(inst_outputs[*inst][port]),
            Op::Poison => FOp::Const(Bits::zero(n.width)),
        };
        flat.nodes[map[id]].op = op;
    }
    map
}

impl FOp {
    /// Nodes read in the same cycle.
    pub fn comb_inputs(&self) -> Vec<F> {
        match self {
            FOp::Input | FOp::Const(_) | FOp::Reg(..) | FOp::MemReadSync(..) => vec![],
            FOp::Copy(a) | FOp::Not(a) | FOp::Slice(a, _) | FOp::Ext(a, _) | FOp::Reduce(_, a) => {
                vec![*a]
            }
            FOp::MemRead(_, a) => vec![*a],
            FOp::Bin(_, a, b) | FOp::Cmp(_, _, a, b) => vec![*a, *b],
            FOp::Shift(_, a, s, _) => std::iter::once(*a).chain(*s).collect(),
            FOp::Mux(s, t, e) => vec![*s, *t, *e],
            FOp::Concat(p) => p.clone(),
        }
    }

    /// True for nodes whose value is held, not computed, each cycle.
    pub fn is_state_or_source(&self) -> bool {
        matches!(
            self,
            FOp::Input | FOp::Const(_) | FOp::Reg(..) | FOp::MemReadSync(..)
        )
    }
}

/// Combinational nodes in an order where each comes after what it reads
/// (iterative depth-first post-order; the design was checked loop-free).
pub(crate) fn comb_order(nodes: &[FNode]) -> Vec<F> {
    let n = nodes.len();
    let mut state = vec![0u8; n]; // 0 new, 1 on stack, 2 done
    let mut order = Vec::new();
    for root in 0..n {
        if state[root] != 0 || nodes[root].op.is_state_or_source() {
            continue;
        }
        let mut stack: Vec<(F, Vec<F>, usize)> = vec![(root, nodes[root].op.comb_inputs(), 0)];
        state[root] = 1;
        while let Some((v, ins, i)) = stack.last_mut() {
            if *i < ins.len() {
                let w = ins[*i];
                *i += 1;
                if state[w] == 0 && !nodes[w].op.is_state_or_source() {
                    state[w] = 1;
                    let wi = nodes[w].op.comb_inputs();
                    stack.push((w, wi, 0));
                }
            } else {
                state[*v] = 2;
                order.push(*v);
                stack.pop();
            }
        }
    }
    order
}
