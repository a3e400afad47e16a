//! Pretty printer for the syntax tree: fixed layout, four-space indent,
//! deterministic output.

use super::ast::{Expr, Item, LValue, NetKind, Port, PortDir, Stmt, VModule};
use crate::Bits;
use std::fmt::Write;

/// The text of a module file, ending in a newline.
pub fn print_module(m: &VModule) -> String {
    let mut s = String::new();
    for h in &m.header {
        let _ = writeln!(s, "// {h}");
    }
    s.push_str("`default_nettype none\n\n");
    let _ = writeln!(s, "module {} (", m.name);
    print_ports(&mut s, &m.ports);
    s.push_str(");\n");
    for item in &m.items {
        print_item(&mut s, item);
    }
    s.push_str("endmodule\n\n`default_nettype wire\n");
    s
}

fn range(width: u32) -> String {
    if width == 1 {
        String::new()
    } else {
        format!("[{}:0] ", width - 1)
    }
}

fn print_ports(s: &mut String, ports: &[Port]) {
    let heads: Vec<String> = ports
        .iter()
        .map(|p| {
            let dir = match p.dir {
                PortDir::Input => "input  wire ",
                PortDir::Output => "output wire ",
            };
            format!("{dir}{}{}", range(p.width), p.name)
        })
        .collect();
    let col = heads.iter().map(|h| h.len()).max().unwrap_or(0) + 1;
    for (i, (p, h)) in ports.iter().zip(&heads).enumerate() {
        let comma = if i + 1 < ports.len() { "," } else { "" };
        let text = format!("{h}{comma}");
        if p.comment.is_empty() {
            let _ = writeln!(s, "    {text}");
        } else {
            let _ = writeln!(s, "    {text:<w$} // {}", p.comment, w = col);
        }
    }
}

fn print_item(s: &mut String, item: &Item) {
    match item {
        Item::Comment(c) => {
            let _ = writeln!(s, "    // {c}");
        }
        Item::Blank => s.push('\n'),
        Item::Decl {
            kind,
            name,
            width,
            depth,
            comment,
        } => {
            let k = match kind {
                NetKind::Wire => "wire",
                NetKind::Reg => "reg",
            };
            let arr = depth.map(|d| format!(" [0:{}]", d - 1)).unwrap_or_default();
            let decl = format!("{k} {}{name}{arr};", range(*width));
            if comment.is_empty() {
                let _ = writeln!(s, "    {decl}");
            } else {
                let _ = writeln!(s, "    {decl:<w$} // {comment}", w = COMMENT_COLUMN - 4);
            }
        }
        Item::Localparam {
            name,
            value,
            comment,
        } => {
            let decl = format!(
                "localparam {}{name} = {};",
                range(value.width()),
                literal(value)
            );
            let _ = writeln!(s, "    {decl:<w$} // {comment}", w = COMMENT_COLUMN - 4);
        }
        Item::Assign(lhs, rhs) => {
            let _ = writeln!(s, "    assign {lhs} = {};", expr(rhs));
        }
        Item::AlwaysPosedge(clk, body) => {
            let _ = writeln!(s, "    always @(posedge {clk}) begin");
            for st in body {
                print_stmt(s, st, 2);
            }
            s.push_str("    end\n");
        }
        Item::Instance {
            module,
            name,
            connections,
            comment,
        } => {
            if comment.is_empty() {
                let _ = writeln!(s, "    {module} {name} (");
            } else {
                let _ = writeln!(s, "    {module} {name} ( // {comment}");
            }
            for (i, (port, e)) in connections.iter().enumerate() {
                let comma = if i + 1 < connections.len() { "," } else { "" };
                let _ = writeln!(s, "        .{port}({}){comma}", expr(e));
            }
            s.push_str("    );\n");
        }
    }
}

/// Column where a statement's trailing comment starts (declarations use
/// the same one).
const COMMENT_COLUMN: usize = 44;

fn print_stmt(s: &mut String, st: &Stmt, depth: usize) {
    let ind = "    ".repeat(depth);
    match st {
        Stmt::NonBlocking(lv, e, comment) => {
            let l = match lv {
                LValue::Ident(n) => n.clone(),
                LValue::Mem(n, a) => format!("{n}[{}]", expr(a)),
            };
            let text = format!("{ind}{l} <= {};", expr(e));
            if comment.is_empty() {
                let _ = writeln!(s, "{text}");
            } else {
                let _ = writeln!(s, "{text:<w$} // {comment}", w = COMMENT_COLUMN);
            }
        }
        Stmt::If(c, then_, else_) => {
            let _ = writeln!(s, "{ind}if ({}) begin", expr(c));
            print_branches(s, then_, else_, depth);
        }
    }
}

/// The body of an `if` from its `begin`: an else that is one `if` reads
/// as `end else if (..) begin`, so priority chains stay flat.
fn print_branches(s: &mut String, then_: &[Stmt], else_: &[Stmt], depth: usize) {
    let ind = "    ".repeat(depth);
    for t in then_ {
        print_stmt(s, t, depth + 1);
    }
    match else_ {
        [] => {
            let _ = writeln!(s, "{ind}end");
        }
        [Stmt::If(c, t, e)] => {
            let _ = writeln!(s, "{ind}end else if ({}) begin", expr(c));
            print_branches(s, t, e, depth);
        }
        _ => {
            let _ = writeln!(s, "{ind}end else begin");
            for t in else_ {
                print_stmt(s, t, depth + 1);
            }
            let _ = writeln!(s, "{ind}end");
        }
    }
}

/// A sized literal: `1'b0`, decimal up to 64 bits, hexadecimal beyond.
pub fn literal(b: &Bits) -> String {
    let w = b.width();
    if w == 1 {
        return format!("1'b{}", u8::from(b.bit(0)));
    }
    match b.to_u64() {
        Some(v) if w <= 64 => format!("{w}'d{v}"),
        _ => format!("{w}'h{}", b.to_hex()),
    }
}

fn is_atom(e: &Expr) -> bool {
    !matches!(e, Expr::Unary(..) | Expr::Binary(..) | Expr::Ternary(..))
}

fn operand(e: &Expr) -> String {
    if is_atom(e) {
        expr(e)
    } else {
        format!("({})", expr(e))
    }
}

/// Expression text; nested operators are always parenthesized.
pub fn expr(e: &Expr) -> String {
    match e {
        Expr::Ident(n) => n.clone(),
        Expr::Literal(b) => literal(b),
        Expr::Index(n, i) => format!("{n}[{i}]"),
        Expr::Range(n, h, l) => format!("{n}[{h}:{l}]"),
        Expr::Concat(parts) => {
            let p: Vec<String> = parts.iter().map(expr).collect();
            format!("{{{}}}", p.join(", "))
        }
        Expr::Repeat(n, x) => format!("{{{n}{{{}}}}}", expr(x)),
        Expr::Unary(op, x) => format!("{op}{}", operand(x)),
        Expr::Binary(op, a, b) => format!("{} {op} {}", operand(a), operand(b)),
        Expr::Ternary(c, t, f) => format!("{} ? {} : {}", operand(c), operand(t), operand(f)),
        Expr::Signed(x) => format!("$signed({})", expr(x)),
        Expr::Unsigned(x) => format!("$unsigned({})", expr(x)),
        Expr::MemIndex(n, a) => format!("{n}[{}]", expr(a)),
    }
}
