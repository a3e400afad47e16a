//! The counter fixture on both engines against a Rust model, with a random
//! enable and resets in the middle of the run.
mod common;

use cosim::tb::Prng;
use golden::seed::seeded;

/// The counter's specification: sync reset to 0, +1 mod 256 when enabled.
fn model_next(count: u8, rst: bool, en: bool) -> u8 {
    if rst {
        0
    } else if en {
        count.wrapping_add(1)
    } else {
        count
    }
}

#[test]
fn counter_matches_model_on_every_engine() {
    if !common::all_tools_present() {
        return;
    }
    let design = common::counter();
    for kind in common::ENGINES {
        let mut e = common::make_engine(kind, &design, false).unwrap();
        let (rst, en, count) = (
            e.port_id("rst").unwrap(),
            e.port_id("en").unwrap(),
            e.port_id("count").unwrap(),
        );
        e.reset(3).unwrap();
        let mut rng = Prng::new(seeded(42));
        let mut model = 0u8;
        for cycle in 0..700 {
            let r = rng.chance(0.02);
            let n = rng.chance(0.7);
            e.poke_u64(rst, r as u64).unwrap();
            e.poke_u64(en, n as u64).unwrap();
            e.eval().unwrap();
            assert_eq!(
                e.peek_u64(count).unwrap(),
                model as u64,
                "{kind} cycle {cycle}"
            );
            e.step().unwrap();
            model = model_next(model, r, n);
        }
        // 3 reset edges + 700 run edges.
        assert_eq!(e.cycle(), 703, "{kind}");
        assert_eq!(e.peek_u64(count).unwrap(), model as u64, "{kind} final");
    }
}

#[test]
fn poking_a_value_wider_than_the_port_is_an_error() {
    if !common::all_tools_present() {
        return;
    }
    let design = common::counter();
    for kind in common::ENGINES {
        let mut e = common::make_engine(kind, &design, false).unwrap();
        let en = e.port_id("en").unwrap();
        let count = e.port_id("count").unwrap();
        assert!(e.poke_u64(en, 2).is_err(), "{kind}: 2 does not fit 1 bit");
        assert!(
            e.poke_u64(count, 0).is_err(),
            "{kind}: outputs cannot be poked"
        );
        assert!(e.port_id("nope").is_err());
    }
}
