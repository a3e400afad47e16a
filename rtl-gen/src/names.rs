//! Identifier rules: what a user may call a port or signal, and how emitted
//! names are made unique deterministically.

use std::collections::BTreeSet;

/// Verilog-2005 and SystemVerilog keywords (Verilator parses `.v` files as
/// SystemVerilog by default, so both sets are reserved).
const KEYWORDS: &[&str] = &[
    "alias",
    "always",
    "always_comb",
    "always_ff",
    "always_latch",
    "and",
    "assert",
    "assign",
    "assume",
    "automatic",
    "before",
    "begin",
    "bind",
    "bins",
    "binsof",
    "bit",
    "break",
    "buf",
    "bufif0",
    "bufif1",
    "byte",
    "case",
    "casex",
    "casez",
    "cell",
    "chandle",
    "checker",
    "class",
    "clocking",
    "cmos",
    "config",
    "const",
    "constraint",
    "context",
    "continue",
    "cover",
    "covergroup",
    "coverpoint",
    "cross",
    "deassign",
    "default",
    "defparam",
    "design",
    "disable",
    "dist",
    "do",
    "edge",
    "else",
    "end",
    "endcase",
    "endchecker",
    "endclass",
    "endclocking",
    "endconfig",
    "endfunction",
    "endgenerate",
    "endgroup",
    "endinterface",
    "endmodule",
    "endpackage",
    "endprimitive",
    "endprogram",
    "endproperty",
    "endsequence",
    "endspecify",
    "endtable",
    "endtask",
    "enum",
    "event",
    "eventually",
    "expect",
    "export",
    "extends",
    "extern",
    "final",
    "first_match",
    "for",
    "force",
    "foreach",
    "forever",
    "fork",
    "forkjoin",
    "function",
    "generate",
    "genvar",
    "global",
    "highz0",
    "highz1",
    "if",
    "iff",
    "ifnone",
    "ignore_bins",
    "illegal_bins",
    "implements",
    "implies",
    "import",
    "incdir",
    "include",
    "initial",
    "inout",
    "input",
    "inside",
    "instance",
    "int",
    "integer",
    "interconnect",
    "interface",
    "intersect",
    "join",
    "join_any",
    "join_none",
    "large",
    "let",
    "liblist",
    "library",
    "local",
    "localparam",
    "logic",
    "longint",
    "macromodule",
    "matches",
    "medium",
    "modport",
    "module",
    "nand",
    "negedge",
    "nettype",
    "new",
    "nexttime",
    "nmos",
    "nor",
    "noshowcancelled",
    "not",
    "notif0",
    "notif1",
    "null",
    "or",
    "output",
    "package",
    "packed",
    "parameter",
    "pmos",
    "posedge",
    "primitive",
    "priority",
    "program",
    "property",
    "protected",
    "pull0",
    "pull1",
    "pulldown",
    "pullup",
    "pulsestyle_ondetect",
    "pulsestyle_onevent",
    "pure",
    "rand",
    "randc",
    "randcase",
    "randsequence",
    "rcmos",
    "real",
    "realtime",
    "ref",
    "reg",
    "reject_on",
    "release",
    "repeat",
    "restrict",
    "return",
    "rnmos",
    "rpmos",
    "rtran",
    "rtranif0",
    "rtranif1",
    "s_always",
    "s_eventually",
    "s_nexttime",
    "s_until",
    "s_until_with",
    "scalared",
    "sequence",
    "shortint",
    "shortreal",
    "showcancelled",
    "signed",
    "small",
    "soft",
    "solve",
    "specify",
    "specparam",
    "static",
    "string",
    "strong",
    "strong0",
    "strong1",
    "struct",
    "super",
    "supply0",
    "supply1",
    "sync_accept_on",
    "sync_reject_on",
    "table",
    "tagged",
    "task",
    "this",
    "throughout",
    "time",
    "timeprecision",
    "timeunit",
    "tran",
    "tranif0",
    "tranif1",
    "tri",
    "tri0",
    "tri1",
    "triand",
    "trior",
    "trireg",
    "type",
    "typedef",
    "union",
    "unique",
    "unique0",
    "unsigned",
    "until",
    "until_with",
    "untyped",
    "use",
    "uwire",
    "var",
    "vectored",
    "virtual",
    "void",
    "wait",
    "wait_order",
    "wand",
    "weak",
    "weak0",
    "weak1",
    "while",
    "wildcard",
    "wire",
    "with",
    "within",
    "wor",
    "xnor",
    "xor",
];

/// Why a name cannot be used as a port or module name, if it cannot.
pub(crate) fn check_identifier(name: &str) -> Result<(), String> {
    let mut chars = name.chars();
    let first_ok = matches!(chars.next(), Some(c) if c.is_ascii_alphabetic() || c == '_');
    if !first_ok || !chars.all(|c| c.is_ascii_alphanumeric() || c == '_') {
        return Err(format!(
            "`{name}` is not an identifier: use letters, digits and `_`, not starting with a digit"
        ));
    }
    if KEYWORDS.contains(&name) {
        return Err(format!("`{name}` is a Verilog/SystemVerilog keyword"));
    }
    Ok(())
}

/// Turns any text into a legal identifier (for internal names only).
pub(crate) fn sanitize(name: &str) -> String {
    let mut s: String = name
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect();
    if s.is_empty() || s.starts_with(|c: char| c.is_ascii_digit()) {
        s.insert(0, 'n');
    }
    if KEYWORDS.contains(&s.as_str()) {
        s.push('_');
    }
    s
}

/// Hands out unique names in request order: the first `x` stays `x`, later
/// ones become `x_1`, `x_2`, ...
#[derive(Default)]
pub(crate) struct Namer {
    taken: BTreeSet<String>,
}

impl Namer {
    /// Reserves `name` exactly; false when it was already taken.
    pub fn reserve(&mut self, name: &str) -> bool {
        self.taken.insert(name.to_string())
    }

    /// A fresh name based on `wanted`.
    pub fn fresh(&mut self, wanted: &str) -> String {
        let base = sanitize(wanted);
        if self.taken.insert(base.clone()) {
            return base;
        }
        let fresh = (1..)
            .map(|i| format!("{base}_{i}"))
            .find(|c| !self.taken.contains(c))
            .unwrap_or(base);
        self.taken.insert(fresh.clone());
        fresh
    }
}

/// The operator words of derived names (`<source>_<word>`, then `_<n>`
/// when taken): a name ending so was made by the emitter, not given. A
/// registered memory read, `<memory>_rdata`, is named after its memory and
/// role as a designer would name it, so `rdata` is not one of them, nor
/// is `rd` (an asynchronous read, `<memory>_rd`, and a read pointer).
pub const AUTO_NAME_WORDS: &[&str] = &[
    "add", "sub", "neg", "and", "or", "xor", "not", "mux", "cat", "eq", "ne", "lt", "le", "gt",
    "ge", "shl", "shr", "srl", "sra", "slice", "sext", "zext", "all", "any", "parity", "k", "next",
    "poison",
];

/// Whether `name` is a derived name: `<source>_<word>` or
/// `<source>_<word>_<n>` for a word of [`AUTO_NAME_WORDS`].
///
/// ```
/// use rtl_gen::is_auto_name;
/// assert!(is_auto_name("in_fill_and_21") && is_auto_name("fs_lod_mux"));
/// assert!(!is_auto_name("h_rec_lod") && !is_auto_name("absorb_1"));
/// ```
pub fn is_auto_name(name: &str) -> bool {
    let trimmed = match name.rsplit_once('_') {
        Some((head, n)) if !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()) => head,
        _ => name,
    };
    trimmed
        .rsplit_once('_')
        .is_some_and(|(_, word)| AUTO_NAME_WORDS.contains(&word))
}
