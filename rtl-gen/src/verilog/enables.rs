//! Registers that keep their value on some paths, written as the enable idiom.
//!
//! A next value built from muxes with the register itself on an arm
//! (`next_when(en, d)` is `en ? d : r`) is emitted as `if (en) r <= d;`
//! instead of `r <= r_next;` with a continuous `r_next = en ? d : r`: a
//! simulator then does nothing for the register in a cycle where it holds
//! (vvp runs every statement of an `always` block it reaches, changed or
//! not), and a reader sees the enable where the register is written.
//! Registers whose plans share a select are grouped under one `if`, so the
//! select is tested once per cycle for all of them.

use super::ast::{Expr, LValue, Stmt};
use crate::diagnostic::Loc;
use crate::graph::{Graph, NodeId, Op};

/// How a register's next value is chosen, as the `always` block writes it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum Plan {
    /// The register keeps its value: no assignment.
    Hold,
    /// `r <= value;`, the comment naming the generator line of the mux
    /// that chose it (`None` when the register always loads it).
    Load(NodeId, Option<Loc>),
    /// `if (sel) <then> else <else>`: mux node `mux` folded into the block.
    Pick {
        mux: NodeId,
        sel: NodeId,
        then_: Box<Plan>,
        else_: Box<Plan>,
    },
}

impl Plan {
    fn holds(&self) -> bool {
        match self {
            Plan::Hold => true,
            Plan::Load(..) => false,
            Plan::Pick { then_, else_, .. } => then_.holds() || else_.holds(),
        }
    }
}

/// Per node, how many times other logic reads it (a mux reading one node
/// on both arms counts twice).
pub(crate) fn reader_counts(g: &Graph) -> Vec<u32> {
    let mut readers = vec![0u32; g.nodes.len()];
    for id in 0..g.nodes.len() {
        for (r, _, _) in g.reads(id as NodeId) {
            readers[r as usize] += 1;
        }
    }
    for mem in &g.mems {
        for w in &mem.writes {
            for x in [w.addr, w.data, w.en] {
                readers[x as usize] += 1;
            }
        }
    }
    for inst in &g.insts {
        for i in &inst.inputs {
            for d in &i.drivers {
                readers[d.0 as usize] += 1;
            }
        }
    }
    readers
}

/// The plan of every register (indexed by node; `None` for other nodes and
/// registers without a next value) and which mux nodes the plans fold
/// (those are neither declared nor assigned).
pub(crate) struct RegisterPlans {
    pub plans: Vec<Option<Plan>>,
    pub folded: Vec<bool>,
}

/// Plans for `g`'s registers. With `enables` false every register loads its
/// next value every cycle (the emission before the enable idiom).
pub(crate) fn register_plans(
    g: &Graph,
    inline: &[bool],
    readers: &[u32],
    enables: bool,
) -> RegisterPlans {
    let mut plans = vec![None; g.nodes.len()];
    let mut folded = vec![false; g.nodes.len()];
    for (id, n) in g.nodes.iter().enumerate() {
        let Op::Reg { next, .. } = &n.op else {
            continue;
        };
        let Some(&(d, _)) = next.first() else {
            continue;
        };
        let reg = id as NodeId;
        let load = Plan::Load(d, None);
        let plan = if enables && foldable(g, inline, readers, d) {
            let plan = plan_of(g, inline, readers, reg, d);
            if plan.holds() && still_read(readers, reg, &plan) {
                mark_folded(&plan, &mut folded);
                plan
            } else {
                load
            }
        } else {
            load
        };
        plans[id] = Some(plan);
    }
    RegisterPlans { plans, folded }
}

/// An unnamed mux read only by the plan being built: its text would exist
/// for this register alone.
fn foldable(g: &Graph, inline: &[bool], readers: &[u32], id: NodeId) -> bool {
    let n = g.node(id);
    matches!(n.op, Op::Mux { .. })
        && n.name.is_none()
        && n.port.is_none()
        && !inline[id as usize]
        && readers[id as usize] == 1
}

/// The plan of register `reg` whose next value (or part of it) is `id`. A
/// mux is folded only when one of its arms leads to the register keeping
/// its value; a mux between two values stays a wire the plan loads.
fn plan_of(g: &Graph, inline: &[bool], readers: &[u32], reg: NodeId, id: NodeId) -> Plan {
    if id == reg {
        return Plan::Hold;
    }
    if foldable(g, inline, readers, id) {
        if let Op::Mux { sel, then_, else_ } = g.node(id).op {
            let loc = g.node(id).loc;
            let arm = |x: NodeId| match plan_of(g, inline, readers, reg, x) {
                Plan::Load(v, None) => Plan::Load(v, Some(loc)),
                p => p,
            };
            let (t, e) = (arm(then_), arm(else_));
            if t.holds() || e.holds() {
                return Plan::Pick {
                    mux: id,
                    sel,
                    then_: Box::new(t),
                    else_: Box::new(e),
                };
            }
        }
    }
    Plan::Load(id, None)
}

/// Whether the register is still read by something once its plan's
/// `Hold`s no longer read it (else it would be a register nobody reads).
fn still_read(readers: &[u32], reg: NodeId, plan: &Plan) -> bool {
    fn holds(p: &Plan) -> u32 {
        match p {
            Plan::Hold => 1,
            Plan::Load(..) => 0,
            Plan::Pick { then_, else_, .. } => holds(then_) + holds(else_),
        }
    }
    readers[reg as usize] > holds(plan)
}

/// Marks the muxes a plan folds: every `Pick`'s mux.
fn mark_folded(plan: &Plan, folded: &mut [bool]) {
    if let Plan::Pick {
        mux, then_, else_, ..
    } = plan
    {
        folded[*mux as usize] = true;
        mark_folded(then_, folded);
        mark_folded(else_, folded);
    }
}

/// One register of a block: its name and its plan.
pub(crate) struct Entry<'p> {
    pub name: String,
    pub plan: &'p Plan,
}

/// A slot of a statement list being built: a finished statement or the
/// group of plans that share a select, placed where its first member was.
enum Slot<'p> {
    Done(Stmt),
    Group {
        sel: NodeId,
        then_: Vec<Entry<'p>>,
        else_: Vec<Entry<'p>>,
    },
}

/// The statements of a list of registers: loads in register order, and
/// each select once, as `if (sel)`, at the place of the first register
/// that tests it, holding the statements of every register that tests it
/// (recursively grouped the same way). `operand` writes a node as an
/// operand; `comment` a generator line.
pub(crate) fn statements(
    entries: Vec<Entry<'_>>,
    operand: &dyn Fn(NodeId) -> Expr,
    comment: &dyn Fn(Loc) -> String,
) -> Vec<Stmt> {
    let mut slots: Vec<Slot> = Vec::new();
    for e in entries {
        match e.plan {
            Plan::Hold => {}
            Plan::Load(v, loc) => slots.push(Slot::Done(Stmt::NonBlocking(
                LValue::Ident(e.name),
                operand(*v),
                loc.map(comment).unwrap_or_default(),
            ))),
            Plan::Pick {
                sel, then_, else_, ..
            } => {
                let (t, f) = (
                    Entry {
                        name: e.name.clone(),
                        plan: then_,
                    },
                    Entry {
                        name: e.name,
                        plan: else_,
                    },
                );
                let group = slots.iter_mut().find_map(|s| match s {
                    Slot::Group {
                        sel: s_sel,
                        then_,
                        else_,
                    } if s_sel == sel => Some((then_, else_)),
                    _ => None,
                });
                match group {
                    Some((gt, ge)) => {
                        gt.push(t);
                        ge.push(f);
                    }
                    None => slots.push(Slot::Group {
                        sel: *sel,
                        then_: vec![t],
                        else_: vec![f],
                    }),
                }
            }
        }
    }
    slots
        .into_iter()
        .filter_map(|s| match s {
            Slot::Done(st) => Some(st),
            Slot::Group { sel, then_, else_ } => {
                let t = statements(then_, operand, comment);
                let f = statements(else_, operand, comment);
                let c = operand(sel);
                match (t.is_empty(), f.is_empty()) {
                    (true, true) => None,
                    (true, false) => Some(Stmt::If(Expr::Unary("!", Box::new(c)), f, vec![])),
                    _ => Some(Stmt::If(c, t, f)),
                }
            }
        })
        .collect()
}
