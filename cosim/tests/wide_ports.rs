//! 300-bit ports round-trip exact bits on both engines: every input bit and
//! every output bit (sum, xor, a 65-bit slice) against Rust arithmetic.
mod common;

use cosim::tb::Prng;
use cosim::Bits;
use golden::seed::seeded;

/// (a + b) mod 2^width, word by word with carries.
fn add(a: &Bits, b: &Bits) -> Bits {
    let mut words = Vec::new();
    let mut carry = 0u64;
    for (x, y) in a.words().iter().zip(b.words()) {
        let (s1, c1) = x.overflowing_add(*y);
        let (s2, c2) = s1.overflowing_add(carry);
        words.push(s2);
        carry = (c1 || c2) as u64;
    }
    let mut sum = Bits::zero(a.width());
    for i in 0..a.width() {
        sum.set_bit(i, words[(i / 64) as usize] >> (i % 64) & 1 == 1)
            .unwrap();
    }
    sum
}

fn xor(a: &Bits, b: &Bits) -> Bits {
    let mut out = Bits::zero(a.width());
    for i in 0..a.width() {
        out.set_bit(i, a.bit(i) ^ b.bit(i)).unwrap();
    }
    out
}

/// Edge patterns plus random ones: carries across every 32/64-bit boundary.
fn operands(rng: &mut Prng) -> Vec<(Bits, Bits)> {
    let w = common::WIDE;
    let one = Bits::from_u64(1, w).unwrap();
    let mut v = vec![
        (Bits::ones(w), one.clone()),
        (Bits::ones(w), Bits::ones(w)),
        (Bits::zero(w), Bits::zero(w)),
    ];
    let mut top = Bits::zero(w);
    top.set_bit(w - 1, true).unwrap();
    v.push((top.clone(), top));
    for _ in 0..60 {
        v.push((rng.bits(w), rng.bits(w)));
    }
    v
}

#[test]
fn three_hundred_bit_ports_round_trip_exactly_on_every_engine() {
    if !common::all_tools_present() {
        return;
    }
    let design = common::wide();
    for kind in common::ENGINES {
        let mut e = common::make_engine(kind, &design, false).unwrap();
        let ids: Vec<_> = ["a", "b", "sum", "mix", "low65"]
            .iter()
            .map(|n| e.port_id(n).unwrap())
            .collect();
        e.reset(0).unwrap();
        let mut rng = Prng::new(seeded(300));
        for (k, (a, b)) in operands(&mut rng).into_iter().enumerate() {
            e.poke(ids[0], &a).unwrap();
            e.poke(ids[1], &b).unwrap();
            e.eval().unwrap();
            assert_eq!(e.peek(ids[0]).unwrap(), a, "{kind} #{k}: a read back");
            assert_eq!(e.peek(ids[2]).unwrap(), add(&a, &b), "{kind} #{k}: sum");
            assert_eq!(e.peek(ids[3]).unwrap(), xor(&a, &b), "{kind} #{k}: mix");
            assert_eq!(
                e.peek(ids[4]).unwrap(),
                a.extract(0, 65).unwrap(),
                "{kind} #{k}: low65"
            );
        }
        let narrow = Bits::zero(299);
        assert!(
            e.poke(ids[0], &narrow).is_err(),
            "{kind}: 299-bit value into a 300-bit port"
        );
    }
}

#[test]
fn a_port_description_that_disagrees_with_the_verilog_is_named() {
    if !common::all_tools_present() {
        return;
    }
    let mut design = common::wide();
    design.ports[4].width = 64; // the Verilog says 65
    for kind in common::ENGINES {
        let err = match common::make_engine(kind, &design, false) {
            Ok(_) => panic!("{kind}: width disagreement not caught"),
            Err(e) => e.to_string(),
        };
        assert!(err.contains("low65"), "{kind}: {err}");
    }
}
