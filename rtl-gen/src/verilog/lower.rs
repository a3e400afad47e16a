//! IR to syntax tree. One operator per `assign`, every operand exactly the
//! width of the operator, so no Verilog width rule can change a result.

use super::ast::{Expr, Item, LValue, NetKind, Port, PortDir, Stmt, VModule};
use super::enables::{reader_counts, register_plans, statements, Entry, RegisterPlans};
use super::RegisterStyle;
use crate::diagnostic::Loc;
use crate::graph::{Amount, BinOp, CmpOp, Direction, Graph, NodeId, Op, RedOp, ShiftKind};
use crate::names::Namer;
use crate::Bits;

/// Source comment for a generator location, with `/` separators.
pub(crate) fn loc_comment(loc: Loc) -> String {
    format!("{}:{}", loc.file().replace('\\', "/"), loc.line())
}

/// Unnamed operator results whose only reader is a wire or output port:
/// the wire's `assign` takes the operator directly, so `y = ~a` is one line.
fn absorbed_temporaries(g: &Graph, inline: &[bool], readers: &[u32]) -> Vec<bool> {
    let mut absorbed = vec![false; g.nodes.len()];
    for n in &g.nodes {
        if let Op::Wire { drivers } = &n.op {
            if let [(d, _)] = drivers.as_slice() {
                let dn = g.node(*d);
                // A temporary named like the port it drives also merges into it.
                let temp = (dn.name.is_none() || (n.port.is_some() && dn.name == n.name))
                    && !inline[*d as usize]
                    && !matches!(
                        dn.op,
                        Op::Reg { .. }
                            | Op::MemReadSync { .. }
                            | Op::InstOut { .. }
                            | Op::Input
                            | Op::Wire { .. }
                    );
                if temp && readers[*d as usize] == 1 {
                    absorbed[*d as usize] = true;
                }
            }
        }
    }
    absorbed
}

struct Lower<'g> {
    g: &'g Graph,
    inline: Vec<bool>,
    /// Unnamed temporaries written straight into the one wire or port they drive.
    absorbed: Vec<bool>,
    /// How each register is written, and the muxes folded into those plans.
    regs: RegisterPlans,
    names: Vec<String>,
    mem_names: Vec<String>,
    inst_names: Vec<String>,
}

/// The syntax tree of one module (validated beforehand).
pub(crate) fn lower(g: &Graph, style: RegisterStyle) -> VModule {
    let inline = g.inline_nodes();
    let readers = reader_counts(g);
    let absorbed = absorbed_temporaries(g, &inline, &readers);
    let regs = register_plans(g, &inline, &readers, style == RegisterStyle::Enables);
    let mut namer = Namer::default();
    let mut names = vec![String::new(); g.nodes.len()];
    for &p in &g.ports {
        let n = g.node(p).name.clone().unwrap_or_default();
        namer.reserve(&n);
        names[p as usize] = n;
    }
    let inst_names: Vec<String> = g.insts.iter().map(|i| namer.fresh(&i.name)).collect();
    let mem_names: Vec<String> = g.mems.iter().map(|m| namer.fresh(&m.name)).collect();
    for (id, n) in g.nodes.iter().enumerate() {
        if inline[id] || absorbed[id] || n.port.is_some() {
            continue;
        }
        names[id] = match (&n.name, &n.op) {
            // A register sharing its output port's name becomes `<name>_q`.
            (Some(user), Op::Reg { .. }) if !namer.reserve(user) => {
                namer.fresh(&format!("{user}_q"))
            }
            (Some(user), Op::Reg { .. }) => user.clone(),
            (Some(user), _) => namer.fresh(user),
            (None, Op::InstOut { port, .. }) => namer.fresh(&format!("{}_{}", n.base, port)),
            (None, _) => namer.fresh(&format!("{}_{}", n.base, n.opname)),
        };
    }
    let l = Lower {
        g,
        inline,
        absorbed,
        regs,
        names,
        mem_names,
        inst_names,
    };
    l.module()
}

impl Lower<'_> {
    fn module(&self) -> VModule {
        let g = self.g;
        let ports = g
            .ports
            .iter()
            .map(|&p| {
                let n = g.node(p);
                let comment = match n.name.as_deref() {
                    Some(crate::graph::CLOCK) => "clock (implicit)".to_string(),
                    Some(crate::graph::RESET) => {
                        "synchronous reset, active high (implicit)".to_string()
                    }
                    _ => loc_comment(n.loc),
                };
                Port {
                    dir: if n.port == Some(Direction::Output) {
                        PortDir::Output
                    } else {
                        PortDir::Input
                    },
                    name: self.names[p as usize].clone(),
                    width: n.width,
                    comment,
                }
            })
            .collect();
        let mut items = Vec::new();
        self.declarations(&mut items);
        self.assigns(&mut items);
        self.instances(&mut items);
        self.registers(&mut items);
        self.memories(&mut items);
        if items.last() == Some(&Item::Blank) {
            items.pop();
        }
        VModule {
            header: vec![
                format!("Module {} generated by rtl-gen from {}. Do not edit.", g.name, loc_comment(g.loc)),
                "Every operand is explicitly sized; each signal names the generator line that made it.".into(),
            ],
            name: g.name.clone(),
            ports,
            items,
        }
    }

    fn declared(&self, id: usize) -> bool {
        !self.inline[id]
            && !self.absorbed[id]
            && !self.regs.folded[id]
            && self.g.nodes[id].port.is_none()
    }

    fn declarations(&self, items: &mut Vec<Item>) {
        let mut any = false;
        for (i, m) in self.g.mems.iter().enumerate() {
            items.push(Item::Decl {
                kind: NetKind::Reg,
                name: self.mem_names[i].clone(),
                width: m.width,
                depth: Some(m.depth),
                comment: loc_comment(m.loc),
            });
            any = true;
        }
        for (id, n) in self.g.nodes.iter().enumerate() {
            if !self.declared(id) {
                continue;
            }
            let kind = match n.op {
                Op::Reg { .. } | Op::MemReadSync { .. } => NetKind::Reg,
                _ => NetKind::Wire,
            };
            items.push(Item::Decl {
                kind,
                name: self.names[id].clone(),
                width: n.width,
                depth: None,
                comment: loc_comment(n.loc),
            });
            any = true;
        }
        if any {
            items.push(Item::Blank);
        }
    }

    fn assigns(&self, items: &mut Vec<Item>) {
        let mut any = false;
        for id in 0..self.g.nodes.len() {
            if self.inline[id] || self.absorbed[id] || self.regs.folded[id] {
                continue;
            }
            if let Some(rhs) = self.rhs(id as NodeId) {
                items.push(Item::Assign(self.names[id].clone(), rhs));
                any = true;
            }
        }
        if any {
            items.push(Item::Blank);
        }
    }

    /// The reference to a node as an operand: its name, or its inline form.
    fn operand(&self, id: NodeId) -> Expr {
        let n = self.g.node(id);
        if !self.inline[id as usize] {
            return Expr::Ident(self.names[id as usize].clone());
        }
        match &n.op {
            Op::Const(b) => Expr::Literal(b.clone()),
            Op::Slice(a, lo) => self.select(*a, *lo, n.width),
            Op::Ext(a, signed) => self.extension(*a, *signed, n.width),
            _ => Expr::Ident(self.names[id as usize].clone()),
        }
    }

    /// `{pad zeros or sign copies, a}`: `a` extended to `width` bits.
    fn extension(&self, a: NodeId, signed: bool, width: u32) -> Expr {
        let pad = width - self.g.node(a).width;
        let fill = if signed {
            let msb = self.msb(a);
            if pad == 1 {
                msb
            } else {
                Expr::Repeat(pad, Box::new(msb))
            }
        } else {
            Expr::Literal(Bits::zero(pad))
        };
        Expr::Concat(vec![fill, self.operand(a)])
    }

    /// `name[lo+w-1:lo]` of a declared node.
    fn select(&self, base: NodeId, lo: u32, width: u32) -> Expr {
        let name = self.names[base as usize].clone();
        if width == 1 {
            Expr::Index(name, lo)
        } else {
            Expr::Range(name, lo + width - 1, lo)
        }
    }

    /// The most significant bit of a node, as an operand.
    fn msb(&self, id: NodeId) -> Expr {
        let n = self.g.node(id);
        match (&n.op, self.inline[id as usize]) {
            (Op::Slice(a, lo), true) => self.select(*a, lo + n.width - 1, 1),
            (Op::Const(b), true) => Expr::Literal(Bits::from_bools(&[b.bit(n.width - 1)])),
            _ if n.width == 1 => self.operand(id),
            _ => self.select(id, n.width - 1, 1),
        }
    }

    /// The continuous-assignment right-hand side of a declared node, if it has one.
    fn rhs(&self, id: NodeId) -> Option<Expr> {
        let o = |x: &NodeId| Box::new(self.operand(*x));
        let n = self.g.node(id);
        Some(match &n.op {
            Op::Input
            | Op::Reg { .. }
            | Op::MemReadSync { .. }
            | Op::InstOut { .. }
            | Op::Poison => return None,
            Op::Wire { drivers } => {
                let d = drivers.first()?.0;
                if self.absorbed[d as usize] {
                    return self.rhs(d);
                }
                self.operand(d)
            }
            Op::Const(b) => Expr::Literal(b.clone()),
            Op::Not(a) => Expr::Unary("~", o(a)),
            Op::Bin(op, a, b) => {
                let sym = match op {
                    BinOp::And => "&",
                    BinOp::Or => "|",
                    BinOp::Xor => "^",
                    BinOp::Add => "+",
                    BinOp::Sub => "-",
                };
                Expr::Binary(sym, o(a), o(b))
            }
            Op::Shift(kind, a, amount) => {
                let amt = Box::new(match amount {
                    Amount::Const(k) => {
                        let w = 32 - k.leading_zeros().min(31);
                        Expr::Literal(Bits::from_u128_truncating(*k as u128, w))
                    }
                    Amount::Signal(s) => self.operand(*s),
                });
                match kind {
                    ShiftKind::Left => Expr::Binary("<<", o(a), amt),
                    ShiftKind::RightLogical => Expr::Binary(">>", o(a), amt),
                    ShiftKind::RightArith => Expr::Binary(">>>", Box::new(Expr::Signed(o(a))), amt),
                }
            }
            Op::Cmp(op, signed, a, b) => {
                let sym = match op {
                    CmpOp::Eq => "==",
                    CmpOp::Ne => "!=",
                    CmpOp::Lt => "<",
                    CmpOp::Le => "<=",
                    CmpOp::Gt => ">",
                    CmpOp::Ge => ">=",
                };
                let ordered = !matches!(op, CmpOp::Eq | CmpOp::Ne);
                if *signed && ordered {
                    Expr::Binary(
                        sym,
                        Box::new(Expr::Signed(o(a))),
                        Box::new(Expr::Signed(o(b))),
                    )
                } else {
                    Expr::Binary(sym, o(a), o(b))
                }
            }
            Op::Mux { sel, then_, else_ } => Expr::Ternary(o(sel), o(then_), o(else_)),
            Op::Concat(parts) => Expr::Concat(parts.iter().map(|p| self.operand(*p)).collect()),
            Op::Slice(a, lo) => self.select(*a, *lo, n.width),
            Op::Ext(a, signed) => self.extension(*a, *signed, n.width),
            Op::Reduce(op, a) => {
                let sym = match op {
                    RedOp::And => "&",
                    RedOp::Or => "|",
                    RedOp::Xor => "^",
                };
                Expr::Unary(sym, o(a))
            }
            Op::MemRead { mem, addr } => Expr::MemIndex(self.mem_names[*mem].clone(), o(addr)),
        })
    }

    fn instances(&self, items: &mut Vec<Item>) {
        for (i, inst) in self.g.insts.iter().enumerate() {
            let child = inst.child.borrow();
            let mut connections = Vec::new();
            for &p in &child.ports {
                let pn = child.node(p).name.clone().unwrap_or_default();
                if let Some(input) = inst.inputs.iter().find(|x| x.port == pn) {
                    if let Some(d) = input.drivers.first() {
                        connections.push((pn, self.operand(d.0)));
                    }
                } else if let Some((_, id)) = inst.outputs.iter().find(|o| o.0 == pn) {
                    connections.push((pn, Expr::Ident(self.names[*id as usize].clone())));
                }
            }
            items.push(Item::Instance {
                module: child.name.clone(),
                name: self.inst_names[i].clone(),
                connections,
                comment: loc_comment(inst.loc),
            });
            items.push(Item::Blank);
        }
    }

    fn clock(&self) -> String {
        self.g
            .clk
            .map(|c| self.names[c as usize].clone())
            .unwrap_or_else(|| crate::graph::CLOCK.into())
    }

    /// One `always` block for every register: reset values under `if (rst)`,
    /// then each register's plan (see [`super::enables`]), registers with
    /// a reset value in the reset's `else`, the others after it.
    fn registers(&self, items: &mut Vec<Item>) {
        let mut resets = Vec::new();
        let mut loads = Vec::new();
        let mut plain = Vec::new();
        for (id, n) in self.g.nodes.iter().enumerate() {
            let (Op::Reg { reset, .. }, Some(plan)) = (&n.op, &self.regs.plans[id]) else {
                continue;
            };
            let entry = Entry {
                name: self.names[id].clone(),
                plan,
            };
            match reset {
                Some(r) => {
                    resets.push(Stmt::NonBlocking(
                        LValue::Ident(entry.name.clone()),
                        Expr::Literal(r.clone()),
                        String::new(),
                    ));
                    loads.push(entry);
                }
                None => plain.push(entry),
            }
        }
        let operand = |x| self.operand(x);
        let mut body = Vec::new();
        if !resets.is_empty() {
            let rst = self
                .g
                .rst
                .map(|r| self.names[r as usize].clone())
                .unwrap_or_else(|| crate::graph::RESET.into());
            body.push(Stmt::If(
                Expr::Ident(rst),
                resets,
                statements(loads, &operand, &loc_comment),
            ));
        }
        body.extend(statements(plain, &operand, &loc_comment));
        if !body.is_empty() {
            items.push(Item::AlwaysPosedge(self.clock(), body));
            items.push(Item::Blank);
        }
    }

    fn guarded(&self, en: NodeId, stmt: Stmt) -> Stmt {
        match &self.g.node(en).op {
            Op::Const(b) if b.bit(0) => stmt,
            _ => Stmt::If(self.operand(en), vec![stmt], vec![]),
        }
    }

    fn memories(&self, items: &mut Vec<Item>) {
        for (mi, mem) in self.g.mems.iter().enumerate() {
            let name = &self.mem_names[mi];
            let mut body = Vec::new();
            // Synchronous reads first: with non-blocking assignments they see
            // the word before this edge's writes either way; reads first says so.
            for (id, n) in self.g.nodes.iter().enumerate() {
                if let Op::MemReadSync { mem, addr, en } = &n.op {
                    if *mem == mi {
                        let st = Stmt::NonBlocking(
                            LValue::Ident(self.names[id].clone()),
                            Expr::MemIndex(name.clone(), Box::new(self.operand(*addr))),
                            String::new(),
                        );
                        body.push(self.guarded(*en, st));
                    }
                }
            }
            for w in &mem.writes {
                let st = Stmt::NonBlocking(
                    LValue::Mem(name.clone(), self.operand(w.addr)),
                    self.operand(w.data),
                    String::new(),
                );
                body.push(self.guarded(w.en, st));
            }
            if !body.is_empty() {
                items.push(Item::Comment(format!(
                    "memory {name}: {} x {} bits",
                    mem.depth, mem.width
                )));
                items.push(Item::AlwaysPosedge(self.clock(), body));
                items.push(Item::Blank);
            }
        }
    }
}
