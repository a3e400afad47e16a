//! The SystemVerilog text of a [`Proof`]'s property harness.
//!
//! Every property is an immediate assertion with a label (`p_*` for a
//! property, `inv_*` for an invariant), so a failure names it. The harness
//! state (reset bookkeeping, the flows' counters and the chosen beat) is
//! built in every task; each check's assertions only under its define.

use std::collections::BTreeMap;
use std::fmt::Write;

use super::{Check, Flow, Mode, Proof, Status};
use crate::verilog::ast::{Expr, Item, LValue, Stmt, VModule};
use crate::Direction;

/// Nets of the flattened design by hierarchical name (`a`, `u_x.b`), with
/// their widths, and the registers that take a reset value.
struct Nets {
    widths: BTreeMap<String, u32>,
    reset_regs: Vec<String>,
}

fn collect_nets(p: &Proof) -> Result<Nets, String> {
    let asts = crate::verilog::design_asts(&p.module).map_err(|d| d.to_string())?;
    let by_name: BTreeMap<&str, &VModule> = asts.iter().map(|m| (m.name.as_str(), m)).collect();
    let top = by_name
        .get(p.module.name().as_str())
        .ok_or("the module's own syntax tree is missing")?;
    let mut nets = Nets {
        widths: BTreeMap::new(),
        reset_regs: Vec::new(),
    };
    walk(top, "", &by_name, &mut nets, 0);
    Ok(nets)
}

fn walk(m: &VModule, prefix: &str, all: &BTreeMap<&str, &VModule>, nets: &mut Nets, depth: u32) {
    for port in &m.ports {
        nets.widths
            .insert(format!("{prefix}{}", port.name), port.width);
    }
    for item in &m.items {
        match item {
            Item::Decl {
                name,
                width,
                depth: None,
                ..
            } => {
                nets.widths.insert(format!("{prefix}{name}"), *width);
            }
            Item::AlwaysPosedge(_, stmts) => {
                for s in stmts {
                    if let Stmt::If(Expr::Ident(c), then, _) = s {
                        if c == crate::RESET {
                            reset_targets(then, prefix, &mut nets.reset_regs);
                        }
                    }
                }
            }
            Item::Instance { module, name, .. } if depth < 64 => {
                if let Some(child) = all.get(module.as_str()) {
                    walk(child, &format!("{prefix}{name}."), all, nets, depth + 1);
                }
            }
            _ => {}
        }
    }
}

fn reset_targets(stmts: &[Stmt], prefix: &str, out: &mut Vec<String>) {
    for s in stmts {
        match s {
            Stmt::NonBlocking(LValue::Ident(r), _, _) => out.push(format!("{prefix}{r}")),
            Stmt::NonBlocking(LValue::Mem(..), _, _) => {}
            Stmt::If(_, a, b) => {
                reset_targets(a, prefix, out);
                reset_targets(b, prefix, out);
            }
        }
    }
}

/// `expr` with every `dut.<net>` written as the escaped identifier the
/// harness declares; the nets named are added to `used`.
fn resolve(expr: &str, nets: &Nets, used: &mut BTreeMap<String, u32>) -> Result<String, String> {
    let mut out = String::new();
    let mut rest = expr;
    while let Some(i) = rest.find("dut.") {
        let boundary = rest[..i]
            .chars()
            .last()
            .is_none_or(|c| !(c.is_ascii_alphanumeric() || c == '_' || c == '\\'));
        out.push_str(&rest[..i]);
        let tail = &rest[i + 4..];
        if !boundary {
            out.push_str("dut.");
            rest = tail;
            continue;
        }
        let end = tail
            .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_' || c == '.'))
            .unwrap_or(tail.len());
        let net = &tail[..end];
        let w = *nets
            .widths
            .get(net)
            .ok_or_else(|| format!("`dut.{net}` in `{expr}`: the module has no net `{net}`"))?;
        used.insert(net.to_string(), w);
        write!(out, "\\dut.{net} ").unwrap();
        rest = &tail[end..];
    }
    out.push_str(rest);
    Ok(out)
}

fn range(w: u32) -> String {
    if w == 1 {
        String::new()
    } else {
        format!("[{}:0] ", w - 1)
    }
}

/// Bits to hold `0..=n`.
fn bits_for(n: u32) -> u32 {
    (32 - n.leading_zeros()).max(1)
}

/// The text of the harness.
pub(super) fn emit(p: &Proof) -> Result<String, String> {
    let nets = collect_nets(p)?;
    let ports = p.module.ports();
    let width_of = |name: &str| ports.iter().find(|q| q.name == name).map(|q| q.width);
    for s in p.inputs.iter().chain(&p.outputs) {
        for suffix in ["valid", "ready", "data"] {
            width_of(&format!("{s}_{suffix}"))
                .ok_or_else(|| format!("stream `{s}`: the module has no port `{s}_{suffix}`"))?;
        }
    }
    let mut used = BTreeMap::new();
    let mut body = String::new();
    let picks = p.flows.iter().any(|f| matches!(f, Flow::Fifo { .. }));
    reset_and_assumptions(p, &mut body);
    handshake(p, &mut body);
    for (j, f) in p.flows.iter().enumerate() {
        flow(j, f, &nets, &mut used, &width_of, &mut body)?;
    }
    trackers(p, &nets, &mut used, &mut body)?;
    for a in &p.assumptions {
        let line = format!(
            "    // The environment's promise `{}` (assumed).\n    always @* if (!f_init) a_{}: assume({});\n",
            a.label,
            a.label,
            resolve(&a.expr, &nets, &mut used)?
        );
        if a.checks.is_empty() {
            writeln!(body, "{line}").unwrap();
        }
        // One define per task: a promise of several checks is written
        // under each.
        for c in &a.checks {
            let define = c.name().to_uppercase();
            writeln!(body, "`ifdef CHECK_{define}\n{line}`endif\n").unwrap();
        }
    }
    if let Some(s) = &p.status {
        status(p, s, &nets, &mut used, &mut body)?;
    }
    let mut inv = String::new();
    for (label, e) in &p.invariants {
        writeln!(
            inv,
            "        inv_{label}: assert({});",
            resolve(e, &nets, &mut used)?
        )
        .unwrap();
    }
    if !inv.is_empty() {
        writeln!(body, "    // Invariants over internal nets: proven in every task, they make induction converge.\n    always @* if (!f_init) begin\n{inv}    end\n").unwrap();
    }
    let determined_mode = p
        .checks
        .iter()
        .find(|c| c.0 == Check::Determined)
        .map(|c| c.1);
    let mut b_nets = BTreeMap::new();
    if let Some(mode) = determined_mode {
        determined(p, &nets, mode, &mut b_nets, &mut body);
    }

    let name = p.module.name();
    let mut s = String::new();
    writeln!(
        s,
        "// Property harness of {name} generated by rtl-gen from rtl-gen/src/formal. Do not edit."
    )
    .unwrap();
    writeln!(s, "// Read with `read_verilog -formal -DCHECK_<NAME>`, one check per SymbiYosys task; the design file is unchanged.").unwrap();
    writeln!(
        s,
        "`default_nettype none\n\nmodule {name}_formal (\n    input wire clk,\n    input wire rst,"
    )
    .unwrap();
    let mut decl_in = Vec::new();
    for q in &ports {
        if q.direction == Direction::Input && q.name != crate::CLOCK && q.name != crate::RESET {
            decl_in.push(format!("    input wire {}{}", range(q.width), q.name));
        }
    }
    if picks {
        decl_in.push("    input wire f_pick  // the solver's choice of the tracked beat".into());
    }
    writeln!(s, "{}\n);", decl_in.join(",\n")).unwrap();
    for q in &ports {
        if q.direction == Direction::Output {
            writeln!(s, "    wire {}{};", range(q.width), q.name).unwrap();
        }
    }
    for (net, w) in &used {
        writeln!(s, "    (* hierconn *) wire {}\\dut.{net} ;", range(*w)).unwrap();
    }
    let conns: Vec<String> = ports.iter().map(|q| format!(".{0}({0})", q.name)).collect();
    writeln!(s, "\n    {name} dut ({});\n", conns.join(", ")).unwrap();
    if determined_mode.is_some() {
        writeln!(s, "`ifdef CHECK_DETERMINED").unwrap();
        for q in &ports {
            if q.direction == Direction::Output {
                writeln!(s, "    wire {}b_{};", range(q.width), q.name).unwrap();
            }
        }
        for (net, w) in &b_nets {
            if !used.contains_key(net) {
                writeln!(s, "    (* hierconn *) wire {}\\dut.{net} ;", range(*w)).unwrap();
            }
            writeln!(s, "    (* hierconn *) wire {}\\dut_b.{net} ;", range(*w)).unwrap();
        }
        let conns: Vec<String> = ports
            .iter()
            .map(|q| match q.direction {
                Direction::Output => format!(".{0}(b_{0})", q.name),
                Direction::Input => format!(".{0}({0})", q.name),
            })
            .collect();
        writeln!(s, "    {name} dut_b ({});\n`endif\n", conns.join(", ")).unwrap();
    }
    s += &body;
    s += "endmodule\n\n`default_nettype wire\n";
    Ok(s)
}

/// The trackers: every register declared first, so a tracker's `next`
/// may read any of them.
fn trackers(
    p: &Proof,
    nets: &Nets,
    used: &mut BTreeMap<String, u32>,
    b: &mut String,
) -> Result<(), String> {
    if p.trackers.is_empty() {
        return Ok(());
    }
    b.push_str(
        "    // Environment-side state the promises read (not the design's): zero after reset.\n",
    );
    let mut next = String::new();
    for t in &p.trackers {
        if t.width == 0 {
            return Err(format!("tracker `{}`: width 0", t.name));
        }
        writeln!(b, "    reg {}t_{};", range(t.width), t.name).unwrap();
        writeln!(
            next,
            "        t_{} <= rst ? {}'d0 : ({});",
            t.name,
            t.width,
            resolve(&t.next, nets, used)?
        )
        .unwrap();
    }
    writeln!(b, "    always @(posedge clk) begin\n{next}    end\n").unwrap();
    Ok(())
}

fn reset_and_assumptions(p: &Proof, b: &mut String) {
    b.push_str(
        "    // Reset is high in the first cycle only; `f_prev`: a cycle after reset precedes this one.\n    reg f_init = 1'b1;\n    reg f_prev = 1'b0;\n    always @(posedge clk) begin\n        f_init <= 1'b0;\n        f_prev <= !f_init;\n    end\n    always @* assume(rst == f_init);\n    always @* if (f_init) assert(!f_prev);\n\n",
    );
    for s in &p.inputs {
        writeln!(b, "    // Input `{s}` holds valid and data until ready (assumed).\n    always @(posedge clk) if (f_prev && $past({s}_valid && !{s}_ready)) assume({s}_valid && {s}_data == $past({s}_data));").unwrap();
    }
    b.push('\n');
}

fn handshake(p: &Proof, b: &mut String) {
    b.push_str("`ifdef CHECK_HANDSHAKE\n");
    for s in &p.outputs {
        writeln!(b, "    always @(posedge clk) if (f_prev && $past({s}_valid && !{s}_ready)) begin\n        p_{s}_valid_held: assert({s}_valid);\n        p_{s}_data_held: assert({s}_data == $past({s}_data));\n    end").unwrap();
    }
    b.push_str("`endif\n\n");
}

fn flow(
    j: usize,
    f: &Flow,
    nets: &Nets,
    used: &mut BTreeMap<String, u32>,
    width_of: &dyn Fn(&str) -> Option<u32>,
    b: &mut String,
) -> Result<(), String> {
    let counter = |b: &mut String, cap: u32, inc: &str, dec: &str| {
        let w = bits_for(cap + 1);
        // `in` may count several events at once (a number, not a bit).
        writeln!(b, "    wire {}f{j}_in = {inc};\n    wire f{j}_out = {dec};\n    reg {}f{j}_occ;  // beats (events) inside, from the transfers of earlier cycles\n    always @(posedge clk) if (rst) f{j}_occ <= {w}'d0; else f{j}_occ <= f{j}_occ + f{j}_in - f{j}_out;", range(w), range(w)).unwrap();
    };
    match f {
        Flow::Fifo {
            input: i,
            output: o,
            capacity,
            occupancy,
            slots,
        } => {
            let w = bits_for(capacity + 1);
            let dw = width_of(&format!("{i}_data")).unwrap_or(1);
            writeln!(b, "    // Flow {j}: `{i}` -> `{o}`, in order, at most {capacity} inside; one beat, the solver's choice, tracked.").unwrap();
            counter(
                b,
                *capacity,
                &format!("{i}_valid && {i}_ready"),
                &format!("{o}_valid && {o}_ready"),
            );
            writeln!(b, "    reg f{j}_track, f{j}_seen;\n    reg {}f{j}_ahead;  // beats inside older than the tracked one\n    reg {}f{j}_data;", range(w), range(dw)).unwrap();
            writeln!(b, "    always @(posedge clk) begin\n        if (rst) begin\n            f{j}_track <= 1'b0;\n            f{j}_seen <= 1'b0;\n            f{j}_ahead <= {w}'d0;\n            f{j}_data <= {dw}'d0;\n        end else if (f{j}_in && f_pick && !f{j}_seen) begin\n            f{j}_track <= 1'b1;\n            f{j}_seen <= 1'b1;\n            f{j}_data <= {i}_data;\n            f{j}_ahead <= f{j}_occ - f{j}_out;\n        end else if (f{j}_track && f{j}_out) begin\n            if (f{j}_ahead == {w}'d0) f{j}_track <= 1'b0;\n            else f{j}_ahead <= f{j}_ahead - {w}'d1;\n        end\n    end").unwrap();
            writeln!(b, "`ifdef CHECK_FLOW\n    always @* if (!f_init) begin\n        p_f{j}_bounded: assert(f{j}_occ <= {w}'d{capacity});\n        p_f{j}_none_invented: assert(!(f{j}_out && f{j}_occ == {w}'d0));\n        p_f{j}_offered: assert(f{j}_occ == {w}'d0 || {o}_valid);\n        p_f{j}_tracked_inside: assert(!f{j}_track || f{j}_ahead < f{j}_occ);\n        p_f{j}_in_order: assert(!(f{j}_track && f{j}_ahead == {w}'d0 && {o}_valid) || {o}_data == f{j}_data);").unwrap();
            if let Some(occ) = occupancy {
                writeln!(
                    b,
                    "        inv_f{j}_occupancy: assert(f{j}_occ == {});",
                    resolve(occ, nets, used)?
                )
                .unwrap();
            }
            for (k, slot) in slots.iter().enumerate() {
                writeln!(b, "        inv_f{j}_slot{k}: assert(!(f{j}_track && f{j}_ahead == {w}'d{k}) || {} == f{j}_data);", resolve(slot, nets, used)?).unwrap();
            }
            b.push_str("    end\n`endif\n\n");
        }
        Flow::Priority { inputs, output: o } => {
            let fires: Vec<String> = inputs
                .iter()
                .rev()
                .map(|i| format!("{i}_valid && {i}_ready"))
                .collect();
            let n = inputs.len();
            writeln!(b, "    // Flow {j}: {} -> `{o}` in the same cycle, the lowest-numbered valid input first unless `{o}` stalled the cycle before.\n    wire [{}:0] f{j}_fires = {{{}}};\n    wire f{j}_out = {o}_valid && {o}_ready;\n    reg f{j}_stalled;\n    always @(posedge clk) f{j}_stalled <= !rst && {o}_valid && !{o}_ready;", inputs.join(", "), n - 1, fires.join(", ")).unwrap();
            writeln!(b, "`ifdef CHECK_FLOW\n    always @* if (!f_init) begin\n        p_f{j}_one_at_a_time: assert((f{j}_fires & (f{j}_fires - {n}'d1)) == {n}'d0);\n        p_f{j}_conserved: assert(f{j}_out == |f{j}_fires);").unwrap();
            for (k, i) in inputs.iter().enumerate() {
                let earlier: Vec<String> =
                    inputs[..k].iter().map(|e| format!("{e}_valid")).collect();
                writeln!(b, "        p_f{j}_{i}_passes: assert(!({i}_valid && {i}_ready) || {o}_data == {i}_data);").unwrap();
                if !earlier.is_empty() {
                    writeln!(b, "        p_f{j}_{i}_priority: assert(!({i}_valid && {i}_ready) || f{j}_stalled || !({}));", earlier.join(" || ")).unwrap();
                }
            }
            b.push_str("    end\n`endif\n\n");
        }
        Flow::Counted {
            name,
            input,
            output,
            capacity,
            occupancy,
        } => {
            let w = bits_for(capacity + 1);
            writeln!(b, "    // Flow {j} ({name}): each `{input}` answered once by `{output}`, in order, at most {capacity} outstanding.").unwrap();
            let (input, output) = (resolve(input, nets, used)?, resolve(output, nets, used)?);
            counter(b, *capacity, &input, &output);
            writeln!(b, "`ifdef CHECK_FLOW\n    always @* if (!f_init) begin\n        p_{name}_bounded: assert(f{j}_occ <= {w}'d{capacity});\n        p_{name}_none_invented: assert(!(f{j}_out && f{j}_occ == {w}'d0));").unwrap();
            if let Some(occ) = occupancy {
                writeln!(
                    b,
                    "        inv_{name}_occupancy: assert(f{j}_occ == {});",
                    resolve(occ, nets, used)?
                )
                .unwrap();
            }
            b.push_str("    end\n`endif\n\n");
        }
    }
    Ok(())
}

fn status(
    p: &Proof,
    s: &Status,
    nets: &Nets,
    used: &mut BTreeMap<String, u32>,
    b: &mut String,
) -> Result<(), String> {
    let mut quiet = Vec::new();
    for &j in &s.busy {
        if j >= p.flows.len() {
            return Err(format!("status: flow {j} does not exist"));
        }
        quiet.push(format!("f{j}_occ == 0"));
    }
    let quiet = if quiet.is_empty() {
        "1'b1".to_string()
    } else {
        quiet.join(" && ")
    };
    let (mut now, mut later) = (String::new(), String::new());
    if let Some(idle) = &s.idle {
        let free = match &s.ahead {
            Some((e, taken)) => {
                let e = resolve(e, nets, used)?;
                writeln!(
                    now,
                    "        p_{idle}_not_ahead: assert(!({idle} && ({e})));"
                )
                .unwrap();
                for i in taken {
                    writeln!(
                        now,
                        "        p_{i}_only_when_{idle}_or_ahead: assert(!{i}_ready || {idle} || ({e}));"
                    )
                    .unwrap();
                }
                format!("({idle} || ({e}))")
            }
            None => idle.clone(),
        };
        writeln!(
            now,
            "        p_{idle}_means_empty: assert({free} == ({quiet}));"
        )
        .unwrap();
        for i in &s.only_when_idle {
            writeln!(
                now,
                "        p_{i}_only_when_{idle}: assert(!{i}_ready || {idle});"
            )
            .unwrap();
        }
        if let Some(done) = &s.done {
            writeln!(
                now,
                "        if (!f_prev) p_{done}_not_at_reset: assert(!{done});"
            )
            .unwrap();
            writeln!(
                later,
                "        p_{done}_pulse: assert({done} == ({idle} && !$past({idle})));"
            )
            .unwrap();
        }
    } else if s.done.is_some()
        || !s.only_when_idle.is_empty()
        || !s.busy.is_empty()
        || s.ahead.is_some()
    {
        return Err("status: `done`, `busy`, `only_when_idle` and `ahead` need `idle`".into());
    }
    for (label, e) in &s.rules {
        let e = resolve(e, nets, used)?;
        let to = if e.contains("$past") {
            &mut later
        } else {
            &mut now
        };
        writeln!(to, "        p_{label}: assert({e});").unwrap();
    }
    writeln!(b, "`ifdef CHECK_STATUS\n    // What the status outputs promise; `done`: `idle` now and not the cycle before.\n    always @* if (!f_init) begin\n{now}    end").unwrap();
    if !later.is_empty() {
        writeln!(
            b,
            "    always @(posedge clk) if (f_prev) begin\n{later}    end"
        )
        .unwrap();
    }
    b.push_str("`endif\n\n");
    Ok(())
}

fn determined(
    p: &Proof,
    nets: &Nets,
    mode: Mode,
    b_nets: &mut BTreeMap<String, u32>,
    b: &mut String,
) {
    writeln!(b, "`ifdef CHECK_DETERMINED\n    // A second copy from its own arbitrary state, the same reset and inputs: every output agrees (a stream's data while valid).\n    always @* if (!f_init) begin").unwrap();
    for q in p.module.ports() {
        if q.direction != Direction::Output {
            continue;
        }
        let stream = p.outputs.iter().find(|s| q.name == format!("{s}_data"));
        match stream {
            Some(s) => writeln!(
                b,
                "        p_{0}_determined: assert(!{s}_valid || {0} == b_{0});",
                q.name
            )
            .unwrap(),
            None => writeln!(b, "        p_{0}_determined: assert({0} == b_{0});", q.name).unwrap(),
        }
    }
    if mode == Mode::Induction {
        for r in &nets.reset_regs {
            let w = nets.widths.get(r).copied().unwrap_or(1);
            b_nets.insert(r.clone(), w);
            let label = r.replace('.', "_");
            writeln!(
                b,
                "        inv_{label}_agrees: assert(\\dut.{r}  == \\dut_b.{r} );"
            )
            .unwrap();
        }
    }
    b.push_str("    end\n`endif\n\n");
}
