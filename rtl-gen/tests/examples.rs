//! The example designs in the IR simulator against Rust models, with random
//! valid/ready back-pressure on every stream.

mod common;

use common::Rng;
use rtl_gen::{examples, Sim};
use std::collections::VecDeque;

fn get(sim: &mut Sim, name: &str) -> u64 {
    sim.peek(name).unwrap().to_u64().unwrap()
}

#[test]
fn counter_counts_when_enabled_and_wraps() {
    let m = examples::counter(5);
    let mut sim = Sim::new(&m).unwrap();
    sim.reset();
    let mut rng = Rng(1);
    let mut model = 0u64;
    for _ in 0..500 {
        assert_eq!(get(&mut sim, "count"), model);
        let en = rng.bit();
        sim.poke("en", en).unwrap();
        sim.step();
        if en {
            model = (model + 1) % 32;
        }
    }
    sim.poke("rst", 1u64).unwrap();
    sim.step();
    assert_eq!(get(&mut sim, "count"), 0);
}

/// A producer that obeys the handshake: once valid, it holds its word until taken.
struct Producer {
    valid: bool,
    data: u64,
    next: u64,
    sent: Vec<u64>,
}

impl Producer {
    fn new() -> Self {
        Producer {
            valid: false,
            data: 0,
            next: 0,
            sent: vec![],
        }
    }

    /// Chooses this cycle's valid/data (keeping a pending word).
    fn offer(&mut self, rng: &mut Rng, busy_pct: u64, mask: u64) {
        if !self.valid && rng.chance(busy_pct, 100) {
            self.valid = true;
            self.data = (self.next.wrapping_mul(0x9E37_79B9) ^ rng.next_u64()) & mask;
            self.next += 1;
        }
    }

    fn after_edge(&mut self, ready: bool) {
        if self.valid && ready {
            self.sent.push(self.data);
            self.valid = false;
        }
    }
}

/// Runs a stream design with random input and output back-pressure;
/// returns (words sent, words received).
fn run_stream(
    sim: &mut Sim,
    cycles: usize,
    seed: u64,
    in_mask: u64,
    check_cycle: &mut dyn FnMut(&mut Sim, &Producer),
) -> (Vec<u64>, Vec<u64>) {
    let mut rng = Rng(seed);
    sim.reset();
    let mut p = Producer::new();
    let mut got = Vec::new();
    for cycle in 0..cycles {
        // Phases of heavy and light traffic so buffers fill and drain.
        let phase = (cycle / 200) % 3;
        let (in_pct, out_pct) = [(90, 30), (30, 90), (60, 60)][phase];
        p.offer(&mut rng, in_pct, in_mask);
        let out_ready = rng.chance(out_pct, 100);
        sim.poke("in_valid", p.valid).unwrap();
        sim.poke("in_data", p.data).unwrap();
        sim.poke("out_ready", out_ready).unwrap();
        check_cycle(sim, &p);
        let in_ready = get(sim, "in_ready") == 1;
        if get(sim, "out_valid") == 1 && out_ready {
            got.push(get(sim, "out_data"));
        }
        sim.step();
        p.after_edge(in_ready);
    }
    (p.sent, got)
}

/// `out` offers the model queue's head, and only while it holds one.
fn offers_head(sim: &mut Sim, model: &VecDeque<u64>, cycle: usize) {
    assert_eq!(
        get(sim, "out_valid") == 1,
        !model.is_empty(),
        "cycle {cycle}"
    );
    if let Some(&head) = model.front() {
        assert_eq!(get(sim, "out_data"), head, "cycle {cycle}");
    }
}

#[test]
fn fifo_matches_a_queue_model_under_back_pressure() {
    for (width, addr_bits) in [(8u32, 2u32), (33, 1), (16, 4)] {
        let m = examples::fifo(width, addr_bits);
        let mut sim = Sim::new(&m).unwrap();
        let cap = 1usize << addr_bits;
        let mut model: VecDeque<u64> = VecDeque::new();
        let mask = if width >= 64 {
            u64::MAX
        } else {
            (1u64 << width) - 1
        };
        let mut rng = Rng(42 + width as u64);
        sim.reset();
        let mut p = Producer::new();
        let mut received = Vec::new();
        for cycle in 0..3000 {
            let phase = (cycle / 150) % 3;
            let (in_pct, out_pct) = [(90, 25), (25, 90), (60, 60)][phase];
            p.offer(&mut rng, in_pct, mask);
            let out_ready = rng.chance(out_pct, 100);
            sim.poke("in_valid", p.valid).unwrap();
            sim.poke("in_data", p.data).unwrap();
            sim.poke("out_ready", out_ready).unwrap();
            assert_eq!(
                get(&mut sim, "in_ready") == 1,
                model.len() < cap,
                "cycle {cycle}"
            );
            offers_head(&mut sim, &model, cycle);
            let push = p.valid && model.len() < cap;
            let pop = !model.is_empty() && out_ready;
            if pop {
                received.push(model.pop_front().unwrap_or_default());
            }
            if push {
                model.push_back(p.data);
            }
            sim.step();
            p.after_edge(push);
        }
        assert!(received.len() > 600, "traffic flowed: {}", received.len());
        assert_eq!(received[..], p.sent[..received.len()]);
    }
}

#[test]
fn drop_fifo_matches_a_queue_model_that_drops_while_full() {
    for (width, cb) in [(8u32, 2u32), (33, 1)] {
        let m = examples::drop_fifo(width, cb);
        let mut sim = Sim::new(&m).unwrap();
        let cap = 1usize << cb;
        let mask = (1u64 << width) - 1;
        let mut model: VecDeque<u64> = VecDeque::new();
        let mut rng = Rng(7 + width as u64);
        sim.reset();
        let (mut dropped, mut cleared, mut popped) = (0, 0, 0);
        for cycle in 0..4000 {
            // Phases that fill it (drops), drain it, and mix.
            let (in_pct, out_pct) = [(90, 20), (20, 90), (60, 60)][(cycle / 200) % 3];
            let push = rng.chance(in_pct, 100);
            let data = rng.next_u64() & mask;
            let out_ready = rng.chance(out_pct, 100);
            let clear = rng.chance(1, 100);
            sim.poke("in_valid", push).unwrap();
            sim.poke("in_data", data).unwrap();
            sim.poke("out_ready", out_ready).unwrap();
            sim.poke("clear", clear).unwrap();
            assert_eq!(get(&mut sim, "in_ready"), 1, "cycle {cycle}");
            let full = model.len() == cap;
            assert_eq!(get(&mut sim, "dropped") == 1, push && full, "cycle {cycle}");
            offers_head(&mut sim, &model, cycle);
            dropped += (push && full) as usize;
            if clear {
                cleared += !model.is_empty() as usize;
                model.clear();
            } else {
                if !model.is_empty() && out_ready {
                    model.pop_front();
                    popped += 1;
                }
                if push && !full {
                    model.push_back(data);
                }
            }
            sim.step();
        }
        assert!(
            dropped > 50 && cleared > 5 && popped > 1000,
            "every case came: {dropped} dropped, {cleared} clears, {popped} popped"
        );
    }
}

#[test]
fn skid_buffer_delivers_every_word_in_order_at_full_throughput() {
    let m = examples::skid_buffer(16);
    let mut sim = Sim::new(&m).unwrap();
    // Outputs and in_ready come straight from registers: in_ready only
    // drops after a cycle in which the consumer stalled a valid word.
    let mut prev_stall = false;
    let mut registered_ready = |sim: &mut Sim, _p: &Producer| {
        if get(sim, "in_ready") == 0 {
            assert!(prev_stall, "in_ready dropped without a stall");
        }
        prev_stall = get(sim, "out_valid") == 1 && get(sim, "out_ready") == 0;
    };
    let (sent, got) = run_stream(&mut sim, 4000, 7, 0xffff, &mut registered_ready);
    assert!(got.len() > 1000, "traffic flowed: {}", got.len());
    assert_eq!(got[..], sent[..got.len()]);
    assert!(sent.len() - got.len() <= 2, "at most two words inside");

    // With both sides always willing, one word per cycle after the first.
    sim.reset();
    sim.poke("out_ready", 1u64).unwrap();
    sim.poke("in_valid", 1u64).unwrap();
    let mut out = Vec::new();
    for i in 0..50u64 {
        sim.poke("in_data", i).unwrap();
        assert_eq!(get(&mut sim, "in_ready"), 1);
        if get(&mut sim, "out_valid") == 1 {
            out.push(get(&mut sim, "out_data"));
        }
        sim.step();
    }
    assert_eq!(out, (0..49).collect::<Vec<u64>>());
}

fn abs_diff_model(word: u64, width: u32, limit: u64) -> u64 {
    let sext = |x: u64| -> i64 { ((x << (64 - width)) as i64) >> (64 - width) };
    let a = sext(word >> width);
    let b = sext(word & ((1 << width) - 1));
    ((a - b).unsigned_abs()).min(limit)
}

#[test]
fn pipelined_datapath_matches_its_model_under_back_pressure() {
    for (width, limit) in [(8u32, 100u64), (12, 4095), (20, 77)] {
        let m = examples::abs_diff_pipeline(width, limit as u128);
        let mut sim = Sim::new(&m).unwrap();
        let mask = (1u64 << (2 * width)) - 1;
        let (sent, got) = run_stream(&mut sim, 3000, width as u64, mask, &mut |_, _| {});
        assert!(got.len() > 600, "traffic flowed: {}", got.len());
        let want: Vec<u64> = sent
            .iter()
            .map(|&w| abs_diff_model(w, width, limit))
            .collect();
        assert_eq!(got[..], want[..got.len()]);
        assert!(sent.len() - got.len() <= 3, "at most three words in flight");
    }
}

#[test]
fn hierarchy_and_merge_deliver_both_streams() {
    // Two producers into a priority merge of two instances, then a register.
    let m = {
        #[path = "designs/mod.rs"]
        mod designs;
        designs::hierarchy()
    };
    let mut sim = Sim::new(&m).unwrap();
    let mut rng = Rng(5);
    sim.reset();
    let (mut pa, mut pb) = (Producer::new(), Producer::new());
    let mut got = Vec::new();
    for _ in 0..3000 {
        pa.offer(&mut rng, 50, 0xff);
        pb.offer(&mut rng, 50, 0xff);
        let out_ready = rng.chance(70, 100);
        sim.poke("a_valid", pa.valid).unwrap();
        sim.poke("a_data", pa.data).unwrap();
        sim.poke("b_valid", pb.valid).unwrap();
        sim.poke("b_data", pb.data).unwrap();
        sim.poke("out_ready", out_ready).unwrap();
        let (ra, rb) = (get(&mut sim, "a_ready") == 1, get(&mut sim, "b_ready") == 1);
        assert!(!(ra && pa.valid && rb && pb.valid), "both granted");
        if get(&mut sim, "out_valid") == 1 && out_ready {
            got.push(get(&mut sim, "out_data"));
        }
        sim.step();
        pa.after_edge(ra);
        pb.after_edge(rb);
    }
    let mut all: Vec<u64> = pa
        .sent
        .iter()
        .chain(&pb.sent)
        .map(|x| (x + 1) & 0xff)
        .collect();
    let mut seen = got.clone();
    all.sort_unstable();
    seen.sort_unstable();
    assert!(got.len() + 1 >= all.len() && got.len() <= all.len());
    // Every delivered word is some sent word plus one (the incrementers).
    for w in &seen {
        assert!(all.binary_search(w).is_ok(), "{w} was never sent");
    }
}
