//! A design's structural identity: what its ports compute, with every name
//! inside it forgotten.
//!
//! Evidence about a design (a long co-simulation run, a synthesis result)
//! must survive edits that cannot change behaviour: renaming a net, giving
//! an auto-named net a name, splitting a generator function (which renumbers
//! every auto-name), moving logic into or out of a submodule, computing the
//! same expression twice or once. A digest of the Verilog text changes with
//! all of them. [`identity`] instead labels the flattened design by
//! partition refinement (colour refinement, as in Weisfeiler-Leman and in
//! Moore's minimisation of automata):
//!
//! - a top-level input is labelled by its name and width, a constant by its
//!   width and value; wires, ports across the hierarchy and instance outputs
//!   take the label of what drives them, so names and hierarchy vanish;
//! - a combinational node is labelled by its operator, width and operand
//!   labels, operands sorted for commutative operators, so two nodes that
//!   compute the same thing get the same label and duplicates collapse;
//! - state (registers, memories, registered reads) starts with a label of its
//!   kind, width and reset value; each round gives it a new label from its
//!   old one and the labels of what it takes on the clock edge.
//!
//! Round `k` therefore labels each node by what it computes from the inputs
//! through `k` clock edges. The rounds stop when a round splits no class of
//! the nodes that reach an output; the identity is the round count and the
//! labels of the output ports by name. Logic that reaches no output is
//! ignored: it cannot be observed.
//!
//! Two designs with the same identity compute the same function of their
//! inputs' history at every output, up to a collision of the 128-bit labels,
//! as far as the refinement reaches (it separates any two computations that
//! differ within the round count). What the identity does not see is the
//! Verilog emitter: the text emitted for the design. The emitter is checked
//! on its own, by every unit's co-simulation on Verilator and Icarus against
//! the golden model and against this crate's IR simulator.

use crate::graph::{BinOp, CmpOp, Direction, RedOp, ShiftKind};
use crate::sim::flatten::{comb_order, flatten, FOp, F};
use crate::{Bits, Diagnostics, Module};
use std::collections::HashSet;

/// The structural identity of a design (see the module documentation).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Identity {
    /// Refinement rounds until no class split.
    pub rounds: u32,
    /// Distinct labels among the nodes that reach an output, at the end.
    pub classes: usize,
    /// Every top-level port in name order (benches connect by name, so the
    /// declaration order is no part of the identity): name, width,
    /// direction, and for an output its label (an input's is 0: its name
    /// and width are its label).
    pub ports: Vec<(String, u32, Direction, u128)>,
}

/// The structural identity of `top` and everything it instantiates, after
/// validating the design.
pub fn identity(top: &Module) -> Result<Identity, Diagnostics> {
    top.validate_design()?;
    let g = top.graph();
    let flat = flatten(&g);
    let order = comb_order(&flat.nodes);
    let ports: Vec<(String, u32, Direction, F)> = g
        .ports
        .iter()
        .map(|&p| {
            let n = g.node(p);
            let name = n.name.clone().unwrap_or_default();
            let dir = n.port.unwrap_or(Direction::Input);
            (name, n.width, dir, flat.top[p as usize])
        })
        .collect();
    let outputs: Vec<F> = ports
        .iter()
        .filter(|p| p.2 == Direction::Output)
        .map(|p| p.3)
        .collect();
    let live = cone(&flat, &outputs);
    let mut labels = Labels::start(&flat, &ports);
    let mut classes = 0;
    let mut rounds = 0u32;
    loop {
        labels.combinational(&flat, &order);
        let now = live
            .iter()
            .filter(|&&i| !matches!(flat.nodes[i].op, FOp::Copy(_)))
            .map(|&i| labels.node[i])
            .collect::<HashSet<_>>()
            .len();
        // Refinement only splits classes, so an unchanged count is a fixed
        // point; the bound is a backstop that a correct refinement never hits.
        if now == classes || rounds as usize > live.len() {
            break;
        }
        classes = now;
        labels.clock_edge(&flat);
        rounds += 1;
    }
    let mut ports: Vec<_> = ports
        .into_iter()
        .map(|(name, width, dir, f)| {
            let label = match dir {
                Direction::Output => labels.node[f],
                Direction::Input => 0,
            };
            (name, width, dir, label)
        })
        .collect();
    ports.sort();
    Ok(Identity {
        rounds,
        classes,
        ports,
    })
}

/// The nodes that reach one of `outputs`, through logic and through state.
fn cone(flat: &crate::sim::flatten::Flat, outputs: &[F]) -> Vec<F> {
    let mut seen = vec![false; flat.nodes.len()];
    let mut mems_seen = vec![false; flat.mems.len()];
    let mut stack: Vec<F> = outputs.to_vec();
    let mut out = Vec::new();
    while let Some(i) = stack.pop() {
        if std::mem::replace(&mut seen[i], true) {
            continue;
        }
        out.push(i);
        let op = &flat.nodes[i].op;
        stack.extend(op.comb_inputs());
        let mem = match *op {
            FOp::Reg(next, ref reset) => {
                stack.push(next);
                stack.extend(reset.as_ref().map(|r| r.1));
                None
            }
            FOp::MemReadSync(m, a, e) => {
                stack.extend([a, e]);
                Some(m)
            }
            FOp::MemRead(m, _) => Some(m),
            _ => None,
        };
        if let Some(m) = mem {
            if !std::mem::replace(&mut mems_seen[m], true) {
                for &(a, d, e) in &flat.mems[m].writes {
                    stack.extend([a, d, e]);
                }
            }
        }
    }
    out
}

/// The labels of one round: every flat node's and every memory's.
struct Labels {
    node: Vec<u128>,
    mem: Vec<u128>,
}

impl Labels {
    /// Round 0: sources by what they are, state by its kind, width and reset.
    fn start(flat: &crate::sim::flatten::Flat, ports: &[(String, u32, Direction, F)]) -> Labels {
        let mut node = vec![0u128; flat.nodes.len()];
        for (i, n) in flat.nodes.iter().enumerate() {
            node[i] = match &n.op {
                FOp::Const(b) => bits(Hash::new(tag::CONST).u(n.width as u64), b).done(),
                FOp::Reg(_, reset) => {
                    let h = Hash::new(tag::REG).u(n.width as u64);
                    match reset {
                        Some((b, _)) => bits(h.u(1), b).done(),
                        None => h.u(0).done(),
                    }
                }
                FOp::MemReadSync(..) => Hash::new(tag::MEM_READ_SYNC).u(n.width as u64).done(),
                // An input below the top is bound (a Copy); one left free
                // here is unconnected, as the simulator sees it.
                FOp::Input => Hash::new(tag::FREE).u(n.width as u64).done(),
                _ => 0,
            };
        }
        for (name, width, dir, f) in ports {
            if *dir == Direction::Input {
                node[*f] = Hash::new(tag::INPUT)
                    .bytes(name.as_bytes())
                    .u(*width as u64)
                    .done();
            }
        }
        let mem = flat
            .mems
            .iter()
            .map(|m| {
                Hash::new(tag::MEM)
                    .u(m.width as u64)
                    .u(m.depth as u64)
                    .done()
            })
            .collect();
        Labels { node, mem }
    }

    /// Labels every combinational node from its operands, in `order`.
    fn combinational(&mut self, flat: &crate::sim::flatten::Flat, order: &[F]) {
        for &i in order {
            let n = &flat.nodes[i];
            let l = |f: F| self.node[f];
            let h = Hash::new(tag::OP).u(n.width as u64);
            self.node[i] = match &n.op {
                FOp::Copy(a) => l(*a),
                FOp::Not(a) => h.u(1).w(l(*a)).done(),
                FOp::Bin(op, a, b) => {
                    let (x, y) = (l(*a), l(*b));
                    // Every binary operator but subtraction commutes.
                    let (x, y) = if *op != BinOp::Sub && y < x {
                        (y, x)
                    } else {
                        (x, y)
                    };
                    h.u(2).u(bin_code(*op)).w(x).w(y).done()
                }
                FOp::Shift(k, a, s, c) => {
                    let h = h.u(3).u(shift_code(*k)).w(l(*a));
                    match s {
                        Some(s) => h.u(1).w(l(*s)).done(),
                        None => h.u(0).u(*c as u64).done(),
                    }
                }
                FOp::Cmp(op, signed, a, b) => {
                    let (x, y) = (l(*a), l(*b));
                    let commutes = matches!(op, CmpOp::Eq | CmpOp::Ne);
                    let (x, y) = if commutes && y < x { (y, x) } else { (x, y) };
                    let signed = *signed && !commutes;
                    h.u(4).u(cmp_code(*op)).u(signed as u64).w(x).w(y).done()
                }
                FOp::Mux(s, t, e) => h.u(5).w(l(*s)).w(l(*t)).w(l(*e)).done(),
                FOp::Concat(parts) => {
                    let h = h.u(6).u(parts.len() as u64);
                    parts
                        .iter()
                        .fold(h, |h, p| h.u(flat.nodes[*p].width as u64).w(l(*p)))
                        .done()
                }
                FOp::Slice(a, lo) => h.u(7).u(*lo as u64).w(l(*a)).done(),
                FOp::Ext(a, signed) => h
                    .u(8)
                    .u(*signed as u64)
                    .u(flat.nodes[*a].width as u64)
                    .w(l(*a))
                    .done(),
                FOp::Reduce(op, a) => h.u(9).u(red_code(*op)).w(l(*a)).done(),
                FOp::MemRead(m, a) => h.u(10).w(self.mem[*m]).w(l(*a)).done(),
                FOp::Input | FOp::Const(_) | FOp::Reg(..) | FOp::MemReadSync(..) => {
                    unreachable!("comb_order holds combinational nodes only")
                }
            };
        }
    }

    /// The next round's state labels: each from its old label and what it
    /// takes on the clock edge (all read from this round's labels).
    fn clock_edge(&mut self, flat: &crate::sim::flatten::Flat) {
        let old = self.node.clone();
        let old_mem = self.mem.clone();
        for (i, n) in flat.nodes.iter().enumerate() {
            self.node[i] = match &n.op {
                FOp::Reg(next, reset) => {
                    let h = Hash::new(tag::EDGE).w(old[i]).w(old[*next]);
                    match reset {
                        Some((_, r)) => h.w(old[*r]).done(),
                        None => h.done(),
                    }
                }
                FOp::MemReadSync(m, a, e) => Hash::new(tag::EDGE)
                    .w(old[i])
                    .w(old_mem[*m])
                    .w(old[*a])
                    .w(old[*e])
                    .done(),
                _ => continue,
            };
        }
        for (m, mem) in flat.mems.iter().enumerate() {
            // Later write ports win, so their order is part of the memory.
            self.mem[m] = mem
                .writes
                .iter()
                .fold(Hash::new(tag::EDGE).w(old_mem[m]), |h, &(a, d, e)| {
                    h.w(old[a]).w(old[d]).w(old[e])
                })
                .done();
        }
    }
}

fn bits(h: Hash, b: &Bits) -> Hash {
    b.words().iter().fold(h.u(b.width() as u64), |h, &w| h.u(w))
}

fn bin_code(op: BinOp) -> u64 {
    match op {
        BinOp::And => 0,
        BinOp::Or => 1,
        BinOp::Xor => 2,
        BinOp::Add => 3,
        BinOp::Sub => 4,
    }
}

fn shift_code(k: ShiftKind) -> u64 {
    match k {
        ShiftKind::Left => 0,
        ShiftKind::RightLogical => 1,
        ShiftKind::RightArith => 2,
    }
}

fn cmp_code(op: CmpOp) -> u64 {
    match op {
        CmpOp::Eq => 0,
        CmpOp::Ne => 1,
        CmpOp::Lt => 2,
        CmpOp::Le => 3,
        CmpOp::Gt => 4,
        CmpOp::Ge => 5,
    }
}

fn red_code(op: RedOp) -> u64 {
    match op {
        RedOp::And => 0,
        RedOp::Or => 1,
        RedOp::Xor => 2,
    }
}

/// Domain tags, so that labels of different kinds never share a preimage.
mod tag {
    pub const CONST: u64 = 1;
    pub const REG: u64 = 2;
    pub const MEM_READ_SYNC: u64 = 3;
    pub const FREE: u64 = 4;
    pub const INPUT: u64 = 5;
    pub const MEM: u64 = 6;
    pub const OP: u64 = 7;
    pub const EDGE: u64 = 8;
}

/// A 128-bit hash of a sequence of words. Fixed here (not the standard
/// library's hasher, which may change between Rust releases) so that an
/// identity stays the same on every machine and toolchain.
#[derive(Clone, Copy)]
struct Hash(u128);

impl Hash {
    const K1: u128 = 0x9e37_79b9_7f4a_7c15_f39c_c060_5ced_c835;
    const K2: u128 = 0xd6e8_feb8_6659_fd93_2b2f_5a4e_83a8_f1b7;

    fn new(tag: u64) -> Hash {
        Hash(Self::K2).u(tag)
    }

    fn u(self, w: u64) -> Hash {
        self.w(w as u128)
    }

    fn w(self, w: u128) -> Hash {
        let mut x = (self.0 ^ w).wrapping_mul(Self::K1);
        x ^= x >> 67;
        x = x.wrapping_mul(Self::K2);
        x ^= x >> 61;
        Hash(x.wrapping_add(self.0.rotate_left(29)))
    }

    fn bytes(self, b: &[u8]) -> Hash {
        b.chunks(8).fold(self.u(b.len() as u64), |h, c| {
            let mut w = [0u8; 8];
            w[..c.len()].copy_from_slice(c);
            h.u(u64::from_le_bytes(w))
        })
    }

    fn done(self) -> u128 {
        self.w(0).0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An accumulator built in `style`: 0 plain, 1 with extra names and a
    /// duplicate adder, 2 with the adder in a submodule.
    fn acc(style: u32) -> Module {
        let m = Module::new("acc");
        let x = m.input("x", 8);
        let en = m.input("en", 1);
        let acc = m.reg_reset("acc", 12, Bits::zero(12));
        let sum = match style {
            0 => acc.add(x, 12),
            1 => {
                let w = m.wire("renamed_sum", 12);
                w.drive(x.add(acc, 12));
                let _unused_twin = acc.add(x, 12);
                w
            }
            _ => {
                let child = Module::new("adder");
                let a = child.input("a", 12);
                let b = child.input("b", 8);
                child.output("s", a.add(b, 12));
                let i = m.instance("u_add", &child);
                i.connect("a", acc);
                i.connect("b", x);
                i.output("s")
            }
        };
        acc.next_when(en, sum);
        m.output("sum", acc);
        m
    }

    #[test]
    fn names_wiring_duplicates_and_hierarchy_do_not_change_it() {
        let base = identity(&acc(0)).unwrap();
        assert_eq!(identity(&acc(1)).unwrap(), base);
        assert_eq!(identity(&acc(2)).unwrap(), base);
        assert!(base.rounds >= 1, "{base:?}");
    }

    #[test]
    fn a_change_of_behaviour_changes_it() {
        let base = identity(&acc(0)).unwrap();
        let changed = |f: &dyn Fn(&Module)| {
            let m = Module::new("acc");
            f(&m);
            identity(&m).unwrap()
        };
        // Subtraction instead of addition.
        let sub = changed(&|m| {
            let x = m.input("x", 8);
            let en = m.input("en", 1);
            let acc = m.reg_reset("acc", 12, Bits::zero(12));
            acc.next_when(en, acc.sub(x, 12));
            m.output("sum", acc);
        });
        // Another reset value.
        let reset = changed(&|m| {
            let x = m.input("x", 8);
            let en = m.input("en", 1);
            let acc = m.reg_reset("acc", 12, Bits::from_u128(1, 12).unwrap());
            acc.next_when(en, acc.add(x, 12));
            m.output("sum", acc);
        });
        // One more register on the way out: the same values a cycle late.
        let late = changed(&|m| {
            let x = m.input("x", 8);
            let en = m.input("en", 1);
            let acc = m.reg_reset("acc", 12, Bits::zero(12));
            acc.next_when(en, acc.add(x, 12));
            let q = m.reg_reset("q", 12, Bits::zero(12));
            q.next(acc);
            m.output("sum", q);
        });
        for other in [&sub, &reset, &late] {
            assert_ne!(other.ports, base.ports, "{other:?}");
        }
    }

    /// `inner` inside a module of the same ports that only forwards them.
    fn wrapped(inner: &Module) -> Module {
        let m = Module::new("wrapper");
        let i = m.instance("u_inner", inner);
        for p in inner.ports() {
            if p.direction == Direction::Input && p.name != crate::CLOCK && p.name != crate::RESET {
                i.connect(&p.name, m.input(&p.name, p.width));
            }
        }
        for p in inner.ports() {
            if p.direction == Direction::Output {
                m.output(&p.name, i.output(&p.name));
            }
        }
        m
    }

    #[test]
    fn a_real_unit_keeps_it_inside_a_wrapper() {
        for d in crate::translate::reference_designs().iter().take(2) {
            let unit = crate::translate::translate_unit(d);
            let id = identity(&unit).unwrap();
            assert_eq!(identity(&wrapped(&unit)).unwrap(), id);
            assert!(id.rounds >= 2 && id.classes > 100, "{id:?}");
        }
    }

    #[test]
    fn a_shift_chain_refines_one_stage_per_round() {
        // Eight registers in a row differ only in how many edges separate
        // them from the input: the refinement needs a round for each.
        let m = Module::new("chain");
        let mut prev = m.input("d", 4);
        for i in 0..8 {
            let r = m.reg_no_reset(&format!("r{i}"), 4);
            r.next(prev);
            prev = r;
        }
        m.output("q", prev);
        let id = identity(&m).unwrap();
        assert!(id.rounds >= 8, "{id:?}");
    }
}
