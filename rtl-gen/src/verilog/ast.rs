//! A small Verilog-2005 syntax tree: just what the emitter produces.

use crate::Bits;

/// An expression. Every literal carries its width.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Expr {
    /// A net, variable or port name.
    Ident(String),
    /// A sized literal such as `8'd3` or `1'b1`.
    Literal(Bits),
    /// One bit of a name: `a[3]`.
    Index(String, u32),
    /// A part-select of a name: `a[7:4]`.
    Range(String, u32, u32),
    /// `{a, b, c}`, most significant first.
    Concat(Vec<Expr>),
    /// `{n{e}}`.
    Repeat(u32, Box<Expr>),
    /// Prefix operator: `~`, a reduction `&`, `|`, `^`, or `!` (the
    /// negated condition of an `if`, one bit).
    Unary(&'static str, Box<Expr>),
    /// Infix operator.
    Binary(&'static str, Box<Expr>, Box<Expr>),
    /// `c ? t : e`.
    Ternary(Box<Expr>, Box<Expr>, Box<Expr>),
    /// `$signed(e)`.
    Signed(Box<Expr>),
    /// `$unsigned(e)`: `e` evaluated on its own (an arithmetic shift nested
    /// in an unsigned expression).
    Unsigned(Box<Expr>),
    /// A memory word: `mem[addr]`.
    MemIndex(String, Box<Expr>),
}

/// A target of a non-blocking assignment.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LValue {
    /// A variable.
    Ident(String),
    /// A memory word.
    Mem(String, Expr),
}

/// A statement inside `always @(posedge clk)`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Stmt {
    /// `lhs <= rhs;` with a trailing comment (none when empty).
    NonBlocking(LValue, Expr, String),
    /// `if (c) begin ... end else begin ... end` (no else when empty; an
    /// else holding only an `if` is printed `end else if (..) begin`).
    If(Expr, Vec<Stmt>, Vec<Stmt>),
}

/// Net or variable kind of a declaration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NetKind {
    /// `wire`
    Wire,
    /// `reg`
    Reg,
}

/// A module item.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Item {
    /// `// text`
    Comment(String),
    /// An empty line.
    Blank,
    /// `wire [w-1:0] name;` or a memory `reg [w-1:0] name [0:depth-1];`
    Decl {
        /// `wire` or `reg`.
        kind: NetKind,
        /// Declared name.
        name: String,
        /// Width in bits (a scalar when 1).
        width: u32,
        /// Memory depth, for arrays.
        depth: Option<u32>,
        /// Trailing comment (the generator source line).
        comment: String,
    },
    /// `localparam [w-1:0] name = value;` (a named constant, such as a state code).
    Localparam {
        /// Declared name.
        name: String,
        /// The value, its width the parameter's.
        value: Bits,
        /// Trailing comment (the generator source line).
        comment: String,
    },
    /// `assign lhs = rhs;`
    Assign(String, Expr),
    /// `always @(posedge clock) begin ... end`
    AlwaysPosedge(String, Vec<Stmt>),
    /// `module name ( .port(expr), ... );`
    Instance {
        /// Instantiated module.
        module: String,
        /// Instance name.
        name: String,
        /// Port connections in the child's port order.
        connections: Vec<(String, Expr)>,
        /// Trailing comment.
        comment: String,
    },
}

/// Port direction keyword.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PortDir {
    /// `input wire`
    Input,
    /// `output wire`
    Output,
}

/// A port of the module header.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Port {
    /// Direction.
    pub dir: PortDir,
    /// Name.
    pub name: String,
    /// Width in bits.
    pub width: u32,
    /// Trailing comment.
    pub comment: String,
}

/// One Verilog module (one file).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct VModule {
    /// Comment lines before `module`.
    pub header: Vec<String>,
    /// Module name.
    pub name: String,
    /// Ports in order.
    pub ports: Vec<Port>,
    /// Body.
    pub items: Vec<Item>,
}
