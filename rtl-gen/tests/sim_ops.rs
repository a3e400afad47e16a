//! Every operator at every suite width, signed and unsigned, in the IR
//! simulator against a bit-level reference written here (vectors of bools,
//! LSB first), itself cross-checked against i128 arithmetic for narrow widths.

mod common;

use common::{edge_values, from_bits, to_bits, Rng};
use rtl_gen::optest::{op_test_module, OpKind, WIDTHS};
use rtl_gen::Sim;
use std::cmp::Ordering;

type V = Vec<bool>;

fn ext(a: &[bool], width: usize, signed: bool) -> V {
    let fill = signed && *a.last().unwrap_or(&false);
    (0..width)
        .map(|i| if i < a.len() { a[i] } else { fill })
        .collect()
}

fn add(a: &[bool], b: &[bool]) -> V {
    let mut carry = false;
    a.iter()
        .zip(b)
        .map(|(&x, &y)| {
            let s = x ^ y ^ carry;
            carry = (x & y) | (carry & (x ^ y));
            s
        })
        .collect()
}

fn neg_add(a: &[bool], b: &[bool]) -> V {
    // a - b = a + !b + 1
    let nb: V = b.iter().map(|x| !x).collect();
    let mut one = vec![false; a.len()];
    one[0] = true;
    add(&add(a, &nb), &one)
}

fn cmp(a: &[bool], b: &[bool], signed: bool) -> Ordering {
    let n = a.len();
    if signed && a[n - 1] != b[n - 1] {
        return if a[n - 1] {
            Ordering::Less
        } else {
            Ordering::Greater
        };
    }
    for i in (0..n).rev() {
        if a[i] != b[i] {
            return if a[i] {
                Ordering::Greater
            } else {
                Ordering::Less
            };
        }
    }
    Ordering::Equal
}

fn b1(x: bool) -> V {
    vec![x]
}

/// The reference result(s) of `op` given the inputs by port name.
#[allow(clippy::too_many_arguments)]
fn reference(
    op: OpKind,
    w: usize,
    signed: bool,
    a: &[bool],
    b: &[bool],
    c: &[bool],
    s: u64,
    sel: bool,
) -> Vec<V> {
    let shift_const = OpKind::const_shift(w as u32) as u64;
    let shl = |amt: u64| -> V {
        (0..w)
            .map(|i| (i as u64) >= amt && a[i - amt as usize])
            .collect()
    };
    let shr = |amt: u64| -> V {
        let fill = signed && a[w - 1];
        (0..w)
            .map(|i| {
                if (i as u64 + amt) < w as u64 {
                    a[i + amt as usize]
                } else {
                    fill
                }
            })
            .collect()
    };
    match op {
        OpKind::Add => vec![add(&ext(a, w + 1, signed), &ext(b, w + 1, signed))],
        OpKind::AddWrap => vec![add(a, b)],
        OpKind::AddExt => vec![add(&ext(a, w + 2, signed), &ext(c, w + 2, signed))],
        OpKind::Sub => vec![neg_add(&ext(a, w + 1, signed), &ext(b, w + 1, signed))],
        OpKind::SubWrap => vec![neg_add(a, b)],
        OpKind::And => vec![a.iter().zip(b).map(|(x, y)| x & y).collect()],
        OpKind::Or => vec![a.iter().zip(b).map(|(x, y)| x | y).collect()],
        OpKind::Xor => vec![a.iter().zip(b).map(|(x, y)| x ^ y).collect()],
        OpKind::Not => vec![a.iter().map(|x| !x).collect()],
        OpKind::ShlConst => vec![shl(shift_const)],
        OpKind::ShrConst => vec![shr(shift_const)],
        OpKind::ShlVar => vec![shl(s)],
        OpKind::ShrVar => vec![shr(s)],
        OpKind::Eq => vec![b1(a == b)],
        OpKind::Ne => vec![b1(a != b)],
        OpKind::Lt => vec![b1(cmp(a, b, signed).is_lt())],
        OpKind::Le => vec![b1(cmp(a, b, signed).is_le())],
        OpKind::Gt => vec![b1(cmp(a, b, signed).is_gt())],
        OpKind::Ge => vec![b1(cmp(a, b, signed).is_ge())],
        OpKind::LtMixed => vec![b1(
            cmp(&ext(a, w + 1, true), &ext(b, w + 1, false), true).is_lt()
        )],
        OpKind::Mux => vec![if sel { a.to_vec() } else { b.to_vec() }],
        OpKind::Concat => vec![b.iter().chain(a).copied().collect()],
        OpKind::Slice if w == 1 => vec![a.to_vec()],
        OpKind::Slice => vec![a[w / 2..].to_vec(), a[..w / 2].to_vec()],
        OpKind::ReduceAnd => vec![b1(a.iter().all(|&x| x))],
        OpKind::ReduceOr => vec![b1(a.iter().any(|&x| x))],
        OpKind::ReduceXor => vec![b1(a.iter().filter(|&&x| x).count() % 2 == 1)],
        OpKind::Ext => vec![ext(a, 2 * w, signed)],
    }
}

fn to_i128(v: &[bool], signed: bool) -> i128 {
    let mut x: i128 = 0;
    for (i, &b) in v.iter().enumerate() {
        if b {
            x |= 1 << i;
        }
    }
    if signed && v[v.len() - 1] {
        x -= 1 << v.len();
    }
    x
}

fn from_i128(x: i128, w: usize) -> V {
    (0..w).map(|i| (x >> i.min(127)) & 1 == 1).collect()
}

#[test]
fn reference_agrees_with_integer_math_up_to_60_bits() {
    let mut rng = Rng(7);
    for w in [1usize, 7, 8, 31, 32, 33, 60] {
        for signed in [false, true] {
            for _ in 0..200 {
                let (a, b) = (rng.bits(w as u32), rng.bits(w as u32));
                let (x, y) = (to_i128(&a, signed), to_i128(&b, signed));
                let r = |op| reference(op, w, signed, &a, &b, &a, 0, false);
                assert_eq!(r(OpKind::Add)[0], from_i128(x + y, w + 1));
                assert_eq!(r(OpKind::Sub)[0], from_i128(x - y, w + 1));
                assert_eq!(r(OpKind::SubWrap)[0], from_i128(x - y, w));
                assert_eq!(r(OpKind::Lt)[0][0], x < y);
                assert_eq!(r(OpKind::Ge)[0][0], x >= y);
                let ub = to_i128(&b, false);
                let sa = to_i128(&a, true);
                assert_eq!(r(OpKind::LtMixed)[0][0], sa < ub);
                assert_eq!(r(OpKind::ShrConst)[0], from_i128(x >> (w / 3), w));
                assert_eq!(r(OpKind::Ext)[0], from_i128(x, 2 * w));
            }
        }
    }
}

fn stimulus(rng: &mut Rng, w: u32) -> Vec<(V, V)> {
    let edges = edge_values(w);
    let mut v = Vec::new();
    for a in &edges {
        for b in &edges {
            v.push((a.clone(), b.clone()));
        }
    }
    for _ in 0..24 {
        v.push((rng.bits(w), rng.bits(w)));
    }
    // Nearly equal operands stress comparisons and carries.
    for _ in 0..6 {
        let a = rng.bits(w);
        let mut b = a.clone();
        let i = rng.below(w as u64) as usize;
        b[i] = !b[i];
        v.push((a, b));
    }
    v
}

fn run_op(op: OpKind, w: u32, signed: bool, rng: &mut Rng) {
    let m = op_test_module(op, w, signed, false);
    let mut sim = Sim::new(&m).unwrap_or_else(|e| panic!("{}: {e}", m.name()));
    let ports: Vec<String> = m.ports().into_iter().map(|p| p.name).collect();
    let has = |p: &str| ports.iter().any(|x| x == p);
    let sw = OpKind::shift_amount_width(w);
    let cw = OpKind::narrow_width(w);
    for (i, (a, b)) in stimulus(rng, w).into_iter().enumerate() {
        let s = match i % 6 {
            0 => 0,
            1 => (w - 1) as u64,
            2 => w as u64,
            3 => (w + 1) as u64,
            4 => (1u64 << sw) - 1,
            _ => rng.below(1 << sw),
        };
        let c = if i % 3 == 0 {
            b[..cw as usize].to_vec()
        } else {
            rng.bits(cw)
        };
        let sel = rng.bit();
        sim.poke("a", to_bits(&a)).unwrap();
        if has("b") {
            sim.poke("b", to_bits(&b)).unwrap();
        }
        if has("c") {
            sim.poke("c", to_bits(&c)).unwrap();
        }
        if has("s") {
            sim.poke("s", s).unwrap();
        }
        if has("sel") {
            sim.poke("sel", sel).unwrap();
        }
        let want = reference(op, w as usize, signed, &a, &b, &c, s, sel);
        for (k, port) in ["y", "y2"].iter().enumerate().take(want.len()) {
            let got = from_bits(&sim.peek(port).unwrap());
            assert_eq!(
                got,
                want[k],
                "{} port {port}: a={} b={} c={} s={s} sel={sel}",
                m.name(),
                to_bits(&a),
                to_bits(&b),
                to_bits(&c)
            );
        }
    }
}

#[test]
fn every_operator_every_width_signed_and_unsigned() {
    let mut rng = Rng(2024);
    for &w in &WIDTHS {
        for signed in [false, true] {
            for op in OpKind::ALL {
                run_op(op, w, signed, &mut rng);
            }
        }
    }
}

#[test]
fn registered_operators_show_the_result_one_edge_later() {
    let mut rng = Rng(99);
    for &w in &[1u32, 65, 300] {
        for op in [OpKind::Add, OpKind::ShrVar, OpKind::Lt, OpKind::Concat] {
            let m = op_test_module(op, w, true, true);
            let mut sim = Sim::new(&m).unwrap();
            sim.reset();
            let (a, b) = (rng.bits(w), rng.bits(w));
            let zero_len = from_bits(&sim.peek("y").unwrap()).len();
            assert_eq!(
                from_bits(&sim.peek("y").unwrap()),
                vec![false; zero_len],
                "reset value"
            );
            sim.poke("a", to_bits(&a)).unwrap();
            if op != OpKind::ShrVar {
                sim.poke("b", to_bits(&b)).unwrap();
            } else {
                sim.poke("s", 3u64).unwrap();
            }
            assert_eq!(
                from_bits(&sim.peek("y").unwrap()),
                vec![false; zero_len],
                "before the edge"
            );
            sim.step();
            let want = reference(op, w as usize, true, &a, &b, &a, 3, false);
            assert_eq!(from_bits(&sim.peek("y").unwrap()), want[0], "{}", m.name());
        }
    }
}
