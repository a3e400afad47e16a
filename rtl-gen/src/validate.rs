//! Checks a module before emission or simulation: undriven signals, multiple
//! drivers, combinational loops and unused logic, plus every error recorded
//! while building.

use crate::diagnostic::{DiagKind, Diagnostic, Diagnostics, Loc, Severity};
use crate::graph::{Direction, Graph, NodeId, Op};
use crate::Module;

impl Module {
    /// Checks this module (not its children; see [`Module::validate_design`]).
    /// Returns the warnings when there is no error, or every error then every
    /// warning.
    ///
    /// ```
    /// use rtl_gen::{DiagKind, Module};
    /// let m = Module::new("m");
    /// let a = m.input("a", 8);
    /// let w = m.wire("w", 8);          // never driven
    /// m.output("y", a ^ w);
    /// let errs = m.validate().unwrap_err();
    /// assert!(errs.has(DiagKind::Undriven));
    /// assert!(errs.to_string().contains("`w`"));
    /// ```
    pub fn validate(&self) -> Result<Vec<Diagnostic>, Diagnostics> {
        let g = self.graph();
        split(check_graph(&g))
    }

    /// Checks this module and every module it instantiates, each once.
    pub fn validate_design(&self) -> Result<Vec<Diagnostic>, Diagnostics> {
        let mut all = Vec::new();
        for m in crate::verilog::design_modules(self) {
            all.extend(check_graph(&m.borrow()));
        }
        split(all)
    }
}

fn split(all: Vec<Diagnostic>) -> Result<Vec<Diagnostic>, Diagnostics> {
    let (mut errors, warnings): (Vec<_>, Vec<_>) =
        all.into_iter().partition(|d| d.severity == Severity::Error);
    if errors.is_empty() {
        Ok(warnings)
    } else {
        errors.extend(warnings);
        Err(Diagnostics(errors))
    }
}

/// All findings for one module graph.
pub(crate) fn check_graph(g: &Graph) -> Vec<Diagnostic> {
    if !g.errors.is_empty() {
        // Construction errors come first; later checks would only echo them.
        return g.errors.clone();
    }
    let mut out = Vec::new();
    check_instances_current(g, &mut out);
    check_drivers(g, &mut out);
    match g.instance_comb_inputs(0) {
        Ok(deps) => check_loops(g, &deps, &mut out),
        Err(msg) => out.push(diag(
            g,
            Severity::Error,
            DiagKind::CombLoop,
            None,
            g.loc,
            msg,
        )),
    }
    check_unused(g, &mut out);
    out
}

fn diag(
    g: &Graph,
    severity: Severity,
    kind: DiagKind,
    signal: Option<String>,
    location: Loc,
    message: String,
) -> Diagnostic {
    Diagnostic {
        severity,
        kind,
        module: g.name.clone(),
        signal,
        location,
        message,
        related: Vec::new(),
    }
}

/// Each instance still matches its child's ports (the child was finished first).
fn check_instances_current(g: &Graph, out: &mut Vec<Diagnostic>) {
    for inst in &g.insts {
        if let Ok(child) = inst.child.try_borrow() {
            let now: Vec<(String, u32)> = child
                .ports
                .iter()
                .map(|&p| (child.describe(p), child.node(p).width))
                .collect();
            let then: Vec<(String, u32)> = inst
                .inputs
                .iter()
                .map(|i| (i.port.clone(), i.width))
                .chain(
                    inst.outputs
                        .iter()
                        .map(|(p, id)| (p.clone(), g.node(*id).width)),
                )
                .collect();
            let same = now.len() == then.len() && now.iter().all(|p| then.contains(p));
            if !same {
                out.push(diag(
                    g,
                    Severity::Error,
                    DiagKind::Misuse,
                    Some(inst.name.clone()),
                    inst.loc,
                    format!("module `{}` gained or changed ports after it was instantiated here; finish it first", child.name),
                ));
            }
        }
    }
}

/// Every wire, output, register, memory and instance input has exactly one driver.
fn check_drivers(g: &Graph, out: &mut Vec<Diagnostic>) {
    let mut check =
        |what: &str, signal: String, loc: Loc, drivers: &[(NodeId, Loc)]| match drivers.len() {
            0 => out.push(diag(
                g,
                Severity::Error,
                DiagKind::Undriven,
                Some(signal),
                loc,
                format!("{what} is never driven"),
            )),
            1 => {}
            _ => {
                let mut d = diag(
                    g,
                    Severity::Error,
                    DiagKind::MultipleDrivers,
                    Some(signal),
                    loc,
                    format!(
                        "{what} has {} drivers; it needs exactly one (combine them with .mux())",
                        drivers.len()
                    ),
                );
                d.related = drivers
                    .iter()
                    .map(|(_, l)| ("driven here".to_string(), *l))
                    .collect();
                out.push(d);
            }
        };
    for (id, n) in g.nodes.iter().enumerate() {
        let name = g.describe(id as NodeId);
        match &n.op {
            Op::Wire { drivers } => {
                let what = if n.port.is_some() {
                    "output port"
                } else {
                    "wire"
                };
                check(what, name, n.loc, drivers);
            }
            Op::Reg { next, .. } => check("register (its .next())", name, n.loc, next),
            _ => {}
        }
    }
    for inst in &g.insts {
        for i in &inst.inputs {
            let what = format!("input `{}` of instance `{}`", i.port, inst.name);
            check(&what, i.port.clone(), inst.loc, &i.drivers);
        }
    }
    for mem in &g.mems {
        if mem.writes.is_empty() {
            out.push(diag(
                g,
                Severity::Error,
                DiagKind::Undriven,
                Some(mem.name.clone()),
                mem.loc,
                "memory has no write port".into(),
            ));
        }
    }
}

/// Combinational cycles, found as strongly connected components (Tarjan),
/// each reported once with its signals in order.
fn check_loops(g: &Graph, inst_deps: &[Vec<Vec<NodeId>>], out: &mut Vec<Diagnostic>) {
    let n = g.nodes.len();
    let succ: Vec<Vec<NodeId>> = (0..n)
        .map(|i| g.comb_inputs_with(i as NodeId, inst_deps))
        .collect();
    for comp in strongly_connected(&succ) {
        let is_loop = comp.len() > 1 || succ[comp[0] as usize].contains(&comp[0]);
        if !is_loop {
            continue;
        }
        let mut members = comp.clone();
        members.sort_unstable();
        let names: Vec<String> = members.iter().map(|&m| g.describe(m)).collect();
        let first = members[0];
        let mut d = diag(
            g,
            Severity::Error,
            DiagKind::CombLoop,
            Some(g.describe(first)),
            g.node(first).loc,
            format!(
                "combinational loop through {}; break it with a register",
                names.join(" -> ")
            ),
        );
        d.related = members
            .iter()
            .map(|&m| (format!("`{}` made here", g.describe(m)), g.node(m).loc))
            .collect();
        out.push(d);
    }
}

/// Tarjan's algorithm, iterative so deep netlists cannot overflow the stack.
fn strongly_connected(succ: &[Vec<NodeId>]) -> Vec<Vec<NodeId>> {
    let n = succ.len();
    let mut index = vec![u32::MAX; n];
    let mut low = vec![0u32; n];
    let mut on_stack = vec![false; n];
    let mut stack = Vec::new();
    let mut comps = Vec::new();
    let mut next = 0u32;
    for root in 0..n {
        if index[root] != u32::MAX {
            continue;
        }
        let mut work: Vec<(usize, usize)> = vec![(root, 0)];
        index[root] = next;
        low[root] = next;
        next += 1;
        stack.push(root);
        on_stack[root] = true;
        while let Some(&mut (v, ref mut i)) = work.last_mut() {
            if *i < succ[v].len() {
                let w = succ[v][*i] as usize;
                *i += 1;
                if index[w] == u32::MAX {
                    index[w] = next;
                    low[w] = next;
                    next += 1;
                    stack.push(w);
                    on_stack[w] = true;
                    work.push((w, 0));
                } else if on_stack[w] {
                    low[v] = low[v].min(index[w]);
                }
            } else {
                work.pop();
                if let Some(&(parent, _)) = work.last() {
                    low[parent] = low[parent].min(low[v]);
                }
                if low[v] == index[v] {
                    let mut comp = Vec::new();
                    while let Some(w) = stack.pop() {
                        on_stack[w] = false;
                        comp.push(w as NodeId);
                        if w == v {
                            break;
                        }
                    }
                    comps.push(comp);
                }
            }
        }
    }
    comps
}

/// Which bits of each node the emitted Verilog reads. Mirrors what
/// Verilator's UNUSED lint sees: inline slices and extensions read only when
/// something emitted reads them.
pub(crate) fn used_bits(g: &Graph) -> Vec<Vec<bool>> {
    let inline = g.inline_nodes();
    let mut used: Vec<Vec<bool>> = g
        .nodes
        .iter()
        .map(|n| vec![false; n.width as usize])
        .collect();
    let mark = |used: &mut Vec<Vec<bool>>, id: NodeId, lo: u32, w: u32| {
        let u = &mut used[id as usize];
        for b in lo..lo + w {
            u[b as usize] = true;
        }
    };
    // Roots: everything that is declared in the Verilog.
    let mut work: Vec<NodeId> = Vec::new();
    for (id, n) in g.nodes.iter().enumerate() {
        if !inline[id] && !matches!(n.op, Op::Poison) {
            work.push(id as NodeId);
        }
    }
    for &p in &g.ports {
        if g.node(p).port == Some(Direction::Output) {
            let w = g.node(p).width;
            mark(&mut used, p, 0, w);
        }
    }
    // The clock is read by every always block; reset by registers that have a reset value.
    let clocked = g
        .nodes
        .iter()
        .any(|n| matches!(n.op, Op::Reg { .. } | Op::MemReadSync { .. }))
        || g.mems.iter().any(|m| !m.writes.is_empty());
    let reset = g
        .nodes
        .iter()
        .any(|n| matches!(n.op, Op::Reg { reset: Some(_), .. }));
    for (port, needed) in [(g.clk, clocked), (g.rst, reset)] {
        if let (Some(p), true) = (port, needed) {
            mark(&mut used, p, 0, 1);
        }
    }
    for mem in &g.mems {
        for wp in &mem.writes {
            for x in [wp.addr, wp.data, wp.en] {
                let w = g.node(x).width;
                mark(&mut used, x, 0, w);
                if inline[x as usize] {
                    work.push(x);
                }
            }
        }
    }
    for inst in &g.insts {
        for i in &inst.inputs {
            for &(x, _) in &i.drivers {
                let w = g.node(x).width;
                mark(&mut used, x, 0, w);
                if inline[x as usize] {
                    work.push(x);
                }
            }
        }
    }
    let mut visited_inline = vec![false; g.nodes.len()];
    while let Some(x) = work.pop() {
        if inline[x as usize] && std::mem::replace(&mut visited_inline[x as usize], true) {
            continue;
        }
        for (r, lo, w) in g.reads(x) {
            mark(&mut used, r, lo, w);
            if inline[r as usize] {
                work.push(r);
            }
        }
    }
    used
}

/// Warnings for declared logic, ports and memories that nothing reads.
fn check_unused(g: &Graph, out: &mut Vec<Diagnostic>) {
    let inline = g.inline_nodes();
    let used = used_bits(g);
    for (id, n) in g.nodes.iter().enumerate() {
        if inline[id]
            || matches!(n.op, Op::Poison | Op::Const(_))
            || n.port == Some(Direction::Output)
        {
            continue;
        }
        let unused = bit_ranges(&used[id], false);
        if unused.is_empty() {
            continue;
        }
        let msg = if unused.len() == 1 && unused[0] == (n.width - 1, 0) {
            "nothing reads this signal".to_string()
        } else {
            let r: Vec<String> = unused
                .iter()
                .map(|(h, l)| {
                    if h == l {
                        format!("[{h}]")
                    } else {
                        format!("[{h}:{l}]")
                    }
                })
                .collect();
            format!("bits {} are never read", r.join(", "))
        };
        out.push(diag(
            g,
            Severity::Warning,
            DiagKind::Unused,
            Some(g.describe(id as NodeId)),
            n.loc,
            msg,
        ));
    }
    for (mi, mem) in g.mems.iter().enumerate() {
        let read = g.nodes.iter().any(
            |n| matches!(n.op, Op::MemRead { mem, .. } | Op::MemReadSync { mem, .. } if mem == mi),
        );
        if !read {
            out.push(diag(
                g,
                Severity::Warning,
                DiagKind::Unused,
                Some(mem.name.clone()),
                mem.loc,
                "memory is never read".into(),
            ));
        }
    }
}

/// Maximal runs of bits equal to `value`, as `(hi, lo)`, highest first.
fn bit_ranges(bits: &[bool], value: bool) -> Vec<(u32, u32)> {
    let mut out = Vec::new();
    let mut i = bits.len();
    while i > 0 {
        if bits[i - 1] == value {
            let hi = i - 1;
            while i > 0 && bits[i - 1] == value {
                i -= 1;
            }
            out.push((hi as u32, i as u32));
        } else {
            i -= 1;
        }
    }
    out
}
