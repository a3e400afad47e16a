//! Common subexpressions, shared before lowering: an unnamed node that
//! computes what an earlier node computes (same operator, width and
//! operands, after sharing those) is written once, its readers reading the
//! earlier node. Generators then need not thread a `~absorb` through their
//! code to avoid writing it twice.
//!
//! Only combinational, side-effect-free nodes are shared. A named node is
//! never replaced by another of a different name (its name is what a
//! reader looks for), but an unnamed duplicate of it reads it, and two
//! nodes of one name computing the same thing are one (a layout field read
//! twice). A named constant (a state code) is shared only with constants
//! of its name, so a plain `2'd1` never reads as a state.

use crate::graph::{Amount, BinOp, CmpOp, Graph, NodeId, Op, FIELD_VIEW};
use std::collections::HashMap;

/// Whether sharing may merge two nodes with this operator.
fn pure(op: &Op) -> bool {
    matches!(
        op,
        Op::Const(_)
            | Op::Not(_)
            | Op::Bin(..)
            | Op::Shift(..)
            | Op::Cmp(..)
            | Op::Mux { .. }
            | Op::Concat(_)
            | Op::Slice(..)
            | Op::Ext(..)
            | Op::Reduce(..)
            | Op::MemRead { .. }
    )
}

/// `op` with every operand replaced by its representative.
fn remap(op: &Op, rep: &[NodeId]) -> Op {
    let r = |x: &NodeId| rep[*x as usize];
    let drivers =
        |d: &[(NodeId, crate::diagnostic::Loc)]| d.iter().map(|(x, l)| (r(x), *l)).collect();
    match op {
        Op::Wire { drivers: d } => Op::Wire {
            drivers: drivers(d),
        },
        Op::Reg { next, reset } => Op::Reg {
            next: drivers(next),
            reset: reset.clone(),
        },
        Op::Not(a) => Op::Not(r(a)),
        Op::Bin(o, a, b) => Op::Bin(*o, r(a), r(b)),
        Op::Shift(k, a, Amount::Signal(s)) => Op::Shift(*k, r(a), Amount::Signal(r(s))),
        Op::Shift(k, a, amt) => Op::Shift(*k, r(a), *amt),
        Op::Cmp(o, s, a, b) => Op::Cmp(*o, *s, r(a), r(b)),
        Op::Mux { sel, then_, else_ } => Op::Mux {
            sel: r(sel),
            then_: r(then_),
            else_: r(else_),
        },
        Op::Concat(p) => Op::Concat(p.iter().map(r).collect()),
        Op::Slice(a, lo) => Op::Slice(r(a), *lo),
        Op::Ext(a, s) => Op::Ext(r(a), *s),
        Op::Reduce(o, a) => Op::Reduce(*o, r(a)),
        Op::MemRead { mem, addr } => Op::MemRead {
            mem: *mem,
            addr: r(addr),
        },
        Op::MemReadSync { mem, addr, en } => Op::MemReadSync {
            mem: *mem,
            addr: r(addr),
            en: r(en),
        },
        Op::Input | Op::Const(_) | Op::InstOut { .. } | Op::Poison => op.clone(),
    }
}

/// The text that equal computations share (operands already remapped;
/// commutative operands in order).
fn key(op: &Op, width: u32) -> String {
    let sorted = |a: NodeId, b: NodeId| (a.min(b), a.max(b));
    let op = match op {
        Op::Bin(o @ (BinOp::And | BinOp::Or | BinOp::Xor | BinOp::Add), a, b) => {
            let (a, b) = sorted(*a, *b);
            Op::Bin(*o, a, b)
        }
        Op::Cmp(o @ (CmpOp::Eq | CmpOp::Ne), s, a, b) => {
            let (a, b) = sorted(*a, *b);
            Op::Cmp(*o, *s, a, b)
        }
        _ => op.clone(),
    };
    format!("{width}:{op:?}")
}

/// `g` with duplicates shared: the same nodes (ids kept), every operand
/// read through its representative, and the replaced nodes turned into
/// [`Op::Poison`] (they read nothing); `dead` marks those.
pub(crate) fn share(g: &Graph) -> (Graph, Vec<bool>) {
    let mut rep: Vec<NodeId> = (0..g.nodes.len() as NodeId).collect();
    let mut by_op: HashMap<String, NodeId> = HashMap::new();
    let mut by_name: HashMap<(String, String), NodeId> = HashMap::new();
    for (id, n) in g.nodes.iter().enumerate() {
        if n.port.is_some() || !pure(&n.op) {
            continue;
        }
        // Operands are created before their readers, so theirs are final.
        let op = remap(&n.op, &rep);
        // `c ? x : x` is `x` (a select tree over equal options).
        if let (None, Op::Mux { then_, else_, .. }) = (&n.name, &op) {
            if then_ == else_ {
                rep[id] = *then_;
                continue;
            }
        }
        let k = key(&op, n.width);
        rep[id] = match (&n.name, &n.op) {
            (Some(name), Op::Const(_)) => *by_name.entry((name.clone(), k)).or_insert(id as NodeId),
            (Some(name), _) => {
                let r = *by_name
                    .entry((name.clone(), k.clone()))
                    .or_insert(id as NodeId);
                by_op.entry(k).or_insert(r);
                r
            }
            (None, Op::Const(_)) => *by_op.entry(format!("unnamed {k}")).or_insert(id as NodeId),
            // A field view is shared with views of its name only.
            (None, _) if n.opname == FIELD_VIEW => *by_op
                .entry(format!("{k} view {}", n.base))
                .or_insert(id as NodeId),
            (None, _) => *by_op.entry(k).or_insert(id as NodeId),
        };
    }
    let dead: Vec<bool> = rep
        .iter()
        .enumerate()
        .map(|(i, r)| *r as usize != i)
        .collect();
    let nodes = g
        .nodes
        .iter()
        .enumerate()
        .map(|(id, n)| {
            let mut n = n.clone();
            n.op = if dead[id] {
                Op::Poison
            } else {
                remap(&n.op, &rep)
            };
            n
        })
        .collect();
    let mut mems = g.mems.clone();
    for m in &mut mems {
        for w in &mut m.writes {
            w.addr = rep[w.addr as usize];
            w.data = rep[w.data as usize];
            w.en = rep[w.en as usize];
        }
    }
    let mut insts = g.insts.clone();
    for i in &mut insts {
        for input in &mut i.inputs {
            for d in &mut input.drivers {
                d.0 = rep[d.0 as usize];
            }
        }
    }
    let shared = Graph {
        name: g.name.clone(),
        loc: g.loc,
        nodes,
        ports: g.ports.clone(),
        mems,
        insts,
        clk: g.clk,
        rst: g.rst,
        errors: Vec::new(),
        scopes: Vec::new(),
    };
    (shared, dead)
}
