//! IR to syntax tree. Every operand is exactly the width of its operator,
//! so no Verilog width rule can change a result: an unnamed result read
//! once is written inside its reader's expression ([`nested_nodes`]), where
//! every operator it can meet (`&`, `+`, `==`, `?:`, `{}`, a shift amount,
//! an index) gives it its own width; the one operator whose meaning depends
//! on its context's signedness, `$signed(a) >>> n`, is nested as
//! `$unsigned(..)`, so it stays arithmetic inside an unsigned expression.

use super::ast::{Expr, Item, LValue, NetKind, Port, PortDir, Stmt, VModule};
use super::enables::{reader_counts, register_plans, statements, Entry, RegisterPlans};
use super::share::share;
use super::RegisterStyle;
use crate::diagnostic::Loc;
use crate::graph::{
    Amount, BinOp, CmpOp, Direction, Graph, NodeId, Op, RedOp, ShiftKind, FIELD_VIEW,
};
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

fn is_view(n: &crate::graph::Node) -> bool {
    n.name.is_none() && n.opname == FIELD_VIEW && matches!(n.op, Op::Slice(..))
}

/// Most operators one nested expression holds: a reader keeps the
/// intermediate names of longer ones.
const MAX_NESTED_OPERATORS: u32 = 6;

/// Most operands (names and literals) one nested expression holds, so a
/// wide concatenation keeps its own line.
const MAX_NESTED_LEAVES: u32 = 8;

/// Unnamed operator results read exactly once, by an operator or statement
/// that can take an expression there: written inside their reader instead
/// of declared. A result whose bits are selected (a slice, the sign of a
/// signed extension) keeps its name, as Verilog selects bits of names only;
/// so does one whose expression would exceed [`MAX_NESTED_OPERATORS`].
fn nested_nodes(g: &Graph, kept: &[bool], readers: &[u32]) -> Vec<bool> {
    let mut selected = vec![false; g.nodes.len()];
    for n in &g.nodes {
        match n.op {
            Op::Slice(a, _) => selected[a as usize] = true,
            Op::Ext(a, true) if g.node(a).width > 1 => selected[a as usize] = true,
            _ => {}
        }
    }
    let mut nested = vec![false; g.nodes.len()];
    let mut size = vec![0u32; g.nodes.len()];
    let mut leaves = vec![0u32; g.nodes.len()];
    // Operands come before their readers in the arena, so sizes are final
    // when read.
    for (id, n) in g.nodes.iter().enumerate() {
        let operator = matches!(
            n.op,
            Op::Not(_)
                | Op::Bin(..)
                | Op::Shift(..)
                | Op::Cmp(..)
                | Op::Mux { .. }
                | Op::Concat(_)
                | Op::Reduce(..)
                | Op::MemRead { .. }
                | Op::Ext(..)
        );
        if !operator || kept[id] || n.name.is_some() || n.port.is_some() {
            continue;
        }
        for x in g.comb_inputs(id as NodeId) {
            let x = x as usize;
            let (s, l) = if nested[x] {
                (size[x], leaves[x])
            } else {
                (0, 1)
            };
            size[id] += s;
            leaves[id] += l;
        }
        size[id] += u32::from(!matches!(n.op, Op::Ext(..)));
        nested[id] = readers[id] == 1
            && !selected[id]
            && size[id] <= MAX_NESTED_OPERATORS
            && leaves[id] <= MAX_NESTED_LEAVES;
    }
    nested
}

struct Lower<'g> {
    g: &'g Graph,
    inline: Vec<bool>,
    /// Unnamed results written inside their one reader's expression.
    nested: Vec<bool>,
    /// Nodes another node computing the same thing replaced ([`share`]).
    dead: Vec<bool>,
    /// Unnamed temporaries written straight into the one wire or port they drive.
    absorbed: Vec<bool>,
    /// How each register is written, and the muxes folded into those plans.
    regs: RegisterPlans,
    names: Vec<String>,
    mem_names: Vec<String>,
    inst_names: Vec<String>,
}

/// The syntax tree of one module (validated beforehand).
pub(crate) fn lower(original: &Graph, style: RegisterStyle) -> VModule {
    let (shared, dead) = share(original);
    let g = &shared;
    let mut inline = g.inline_nodes();
    let readers = reader_counts(g);
    // A field view is declared under its field's name where it is read.
    for (id, n) in g.nodes.iter().enumerate() {
        if is_view(n) && readers[id] > 0 {
            inline[id] = false;
        }
    }
    let absorbed = absorbed_temporaries(g, &inline, &readers);
    let regs = register_plans(g, &inline, &readers, style == RegisterStyle::Enables);
    let mut kept: Vec<bool> = (0..g.nodes.len())
        .map(|i| inline[i] || absorbed[i] || regs.folded[i] || dead[i])
        .collect();
    // The style before the enable idiom writes `r <= r_next;`, `r_next` a wire.
    if style == RegisterStyle::NextWires {
        for n in &g.nodes {
            if let Op::Reg { next, .. } = &n.op {
                for (d, _) in next {
                    kept[*d as usize] = true;
                }
            }
        }
    }
    let nested = nested_nodes(g, &kept, &readers);
    // A named constant nothing reads (its readers shared away) is not declared.
    let dead: Vec<bool> = (0..g.nodes.len())
        .map(|i| dead[i] || (matches!(g.nodes[i].op, Op::Const(_)) && readers[i] == 0))
        .collect();
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
        if inline[id] || absorbed[id] || nested[id] || dead[id] || n.port.is_some() {
            continue;
        }
        names[id] = match (&n.name, &n.op) {
            // A register sharing its output port's name becomes `<name>_q`.
            (Some(user), Op::Reg { .. }) if !namer.reserve(user) => {
                namer.fresh(&format!("{user}_q"))
            }
            (Some(user), Op::Reg { .. }) => user.clone(),
            (Some(user), _) => namer.fresh(user),
            (None, _) if is_view(n) => namer.fresh(&n.base),
            (None, Op::InstOut { port, .. }) => namer.fresh(&format!("{}_{}", n.base, port)),
            (None, _) => namer.fresh(&format!("{}_{}", n.base, n.opname)),
        };
    }
    let l = Lower {
        g,
        inline,
        nested,
        dead,
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
            && !self.nested[id]
            && !self.dead[id]
            && self.g.nodes[id].port.is_none()
    }

    fn declarations(&self, items: &mut Vec<Item>) {
        let mut any = false;
        // Named constants (state codes) first, in the order of their values.
        let mut params: Vec<Item> = Vec::new();
        for (id, n) in self.g.nodes.iter().enumerate() {
            if let (true, Op::Const(value)) = (self.declared(id), &n.op) {
                params.push(Item::Localparam {
                    name: self.names[id].clone(),
                    value: value.clone(),
                    comment: loc_comment(n.loc),
                });
            }
        }
        params.sort_by_key(|p| match p {
            Item::Localparam { value, name, .. } => (value.to_hex(), name.clone()),
            _ => Default::default(),
        });
        any |= !params.is_empty();
        items.extend(params);
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
                Op::Const(_) => continue,
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
            if !self.declared(id) && self.g.nodes[id].port.is_none() {
                continue;
            }
            if matches!(self.g.nodes[id].op, Op::Const(_)) {
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
        if self.nested[id as usize] {
            let e = self.expr(id);
            return match n.op {
                Op::Shift(ShiftKind::RightArith, ..) => Expr::Unsigned(Box::new(e)),
                _ => e,
            };
        }
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
        match &self.g.node(id).op {
            Op::Input
            | Op::Reg { .. }
            | Op::MemReadSync { .. }
            | Op::InstOut { .. }
            | Op::Poison => None,
            Op::Wire { drivers } => {
                let d = drivers.first()?.0;
                if self.absorbed[d as usize] {
                    return self.rhs(d);
                }
                Some(self.operand(d))
            }
            _ => Some(self.expr(id)),
        }
    }

    /// The expression an operator node computes, its operands as operands.
    fn expr(&self, id: NodeId) -> Expr {
        let o = |x: &NodeId| Box::new(self.operand(*x));
        let n = self.g.node(id);
        match &n.op {
            Op::Input
            | Op::Reg { .. }
            | Op::MemReadSync { .. }
            | Op::InstOut { .. }
            | Op::Poison
            | Op::Wire { .. } => Expr::Ident(self.names[id as usize].clone()),
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
        }
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
