//! The translation unit's testbench, the same on rtl-gen's IR simulator,
//! Verilator and Icarus Verilog (through cosim's `Engine`).
//!
//! A transaction list (golden vectors) is cut into runs of one kind
//! (determine or apply). Each run goes through its stream with random
//! back-pressure: the driver raises `valid` with probability `1 - stall`
//! and holds the payload until accepted; the monitor raises `ready` with
//! probability `1 - stall`. Outputs are compared in order, bit for bit,
//! with the golden expected outputs; a run ends when all its outputs
//! arrived (then nothing of it is in flight, so the next run's table
//! reads see every earlier write). Every cycle `done == idle && !idle
//! one cycle earlier`; at the end the sticky error bits equal what the
//! golden outputs imply. A watchdog fails a run that stops moving.
#![allow(dead_code)]

use cosim::{BitVec, Engine, PortId};
use golden::translate::stimulus::SplitMix64;
use golden::vectors::translate::{ApplyCode, TranslateDesign, TranslateTxn};
use rtl_gen::translate::ports::{
    apply_out_layout, det_out_layout, pack_apply_in, pack_apply_out, pack_det_in, pack_det_out,
    PortLayout,
};
use rtl_gen::{Bits, Sim};

/// The ports the testbench drives or reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Port {
    DetInValid,
    DetInData,
    DetInReady,
    DetOutValid,
    DetOutData,
    DetOutReady,
    ApplyInValid,
    ApplyInData,
    ApplyInReady,
    ApplyOutValid,
    ApplyOutData,
    ApplyOutReady,
    Idle,
    Done,
    DetErrorSeen,
    ApplyErrorSeen,
}

pub const PORTS: [(Port, &str); 16] = [
    (Port::DetInValid, "det_in_valid"),
    (Port::DetInData, "det_in_data"),
    (Port::DetInReady, "det_in_ready"),
    (Port::DetOutValid, "det_out_valid"),
    (Port::DetOutData, "det_out_data"),
    (Port::DetOutReady, "det_out_ready"),
    (Port::ApplyInValid, "apply_in_valid"),
    (Port::ApplyInData, "apply_in_data"),
    (Port::ApplyInReady, "apply_in_ready"),
    (Port::ApplyOutValid, "apply_out_valid"),
    (Port::ApplyOutData, "apply_out_data"),
    (Port::ApplyOutReady, "apply_out_ready"),
    (Port::Idle, "idle"),
    (Port::Done, "done"),
    (Port::DetErrorSeen, "det_error_seen"),
    (Port::ApplyErrorSeen, "apply_error_seen"),
];

fn index(p: Port) -> usize {
    PORTS.iter().position(|(q, _)| *q == p).expect("listed")
}

/// A simulator of the unit: poke, settle, peek, clock.
pub trait Dut {
    fn name(&self) -> String;
    fn set(&mut self, p: Port, v: &Bits);
    fn set_bit(&mut self, p: Port, v: bool);
    /// Settles combinational logic (engines that need it).
    fn eval(&mut self);
    fn get(&mut self, p: Port) -> Bits;
    fn get_bit(&mut self, p: Port) -> bool;
    fn step(&mut self);
    fn reset(&mut self);
    fn cycle(&self) -> u64;
}

/// rtl-gen's IR simulator.
pub struct SimDut {
    sim: Sim,
    handles: Vec<rtl_gen::sim::Handle>,
}

impl SimDut {
    pub fn new(m: &rtl_gen::Module) -> SimDut {
        let sim = Sim::new(m).unwrap_or_else(|e| panic!("{e}"));
        let handles = PORTS
            .iter()
            .map(|(_, n)| sim.handle(n).unwrap_or_else(|e| panic!("{n}: {e:?}")))
            .collect();
        SimDut { sim, handles }
    }
}

impl Dut for SimDut {
    fn name(&self) -> String {
        "rtl-gen IR simulator".into()
    }
    fn set(&mut self, p: Port, v: &Bits) {
        self.sim.set(self.handles[index(p)], v).unwrap();
    }
    fn set_bit(&mut self, p: Port, v: bool) {
        self.sim.set_u64(self.handles[index(p)], v as u64).unwrap();
    }
    fn eval(&mut self) {}
    fn get(&mut self, p: Port) -> Bits {
        self.sim.get(self.handles[index(p)])
    }
    fn get_bit(&mut self, p: Port) -> bool {
        self.sim.get_u64(self.handles[index(p)]) & 1 == 1
    }
    fn step(&mut self) {
        self.sim.step();
    }
    fn reset(&mut self) {
        self.sim.poke("rst", 1u64).unwrap();
        self.sim.step_n(2);
        self.sim.poke("rst", 0u64).unwrap();
    }
    fn cycle(&self) -> u64 {
        self.sim.cycle()
    }
}

/// A cosim engine (Verilator or Icarus).
pub struct EngineDut {
    engine: Box<dyn Engine>,
    ids: Vec<PortId>,
}

impl EngineDut {
    pub fn new(engine: Box<dyn Engine>) -> EngineDut {
        let ids = PORTS
            .iter()
            .map(|(_, n)| engine.port_id(n).unwrap_or_else(|e| panic!("{n}: {e}")))
            .collect();
        EngineDut { engine, ids }
    }
}

impl Dut for EngineDut {
    fn name(&self) -> String {
        self.engine.name().to_string()
    }
    fn set(&mut self, p: Port, v: &Bits) {
        let b = BitVec::from_words(v.width() as usize, v.words()).unwrap();
        self.engine.poke(self.ids[index(p)], &b).unwrap();
    }
    fn set_bit(&mut self, p: Port, v: bool) {
        self.engine.poke_u64(self.ids[index(p)], v as u64).unwrap();
    }
    fn eval(&mut self) {
        self.engine.eval().unwrap_or_else(|e| panic!("eval: {e}"));
    }
    fn get(&mut self, p: Port) -> Bits {
        let v = self.engine.peek(self.ids[index(p)]).unwrap();
        Bits::from_words(v.words(), v.width() as u32).unwrap()
    }
    fn get_bit(&mut self, p: Port) -> bool {
        self.engine.peek_u64(self.ids[index(p)]).unwrap() & 1 == 1
    }
    fn step(&mut self) {
        self.engine.step().unwrap_or_else(|e| panic!("step: {e}"));
    }
    fn reset(&mut self) {
        self.engine
            .reset(2)
            .unwrap_or_else(|e| panic!("reset: {e}"));
    }
    fn cycle(&self) -> u64 {
        self.engine.cycle()
    }
}

/// What a run measured.
#[derive(Clone, Debug, Default)]
pub struct Outcome {
    pub transactions: u64,
    pub cycles: u64,
    pub determine: u64,
    pub apply: u64,
}

struct Side {
    valid_in: Port,
    data_in: Port,
    ready_in: Port,
    valid_out: Port,
    data_out: Port,
    ready_out: Port,
    layout: PortLayout,
}

/// Runs `txns` through `dut` with stall probability `stall` on both sides
/// of every stream; panics with a decoded report at the first mismatch.
pub fn run(
    dut: &mut dyn Dut,
    d: &TranslateDesign,
    txns: &[TranslateTxn],
    stall: f64,
    seed: u64,
) -> Outcome {
    let det = Side {
        valid_in: Port::DetInValid,
        data_in: Port::DetInData,
        ready_in: Port::DetInReady,
        valid_out: Port::DetOutValid,
        data_out: Port::DetOutData,
        ready_out: Port::DetOutReady,
        layout: det_out_layout(d),
    };
    let app = Side {
        valid_in: Port::ApplyInValid,
        data_in: Port::ApplyInData,
        ready_in: Port::ApplyInReady,
        valid_out: Port::ApplyOutValid,
        data_out: Port::ApplyOutData,
        ready_out: Port::ApplyOutReady,
        layout: apply_out_layout(d),
    };
    let mut drv_rng = SplitMix64(seed ^ 0x5eed_d41e);
    let mut mon_rng = SplitMix64(seed ^ 0x0b5e_77e5);
    let go = |rng: &mut SplitMix64| (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64 >= stall;
    dut.set_bit(Port::DetInValid, false);
    dut.set_bit(Port::ApplyInValid, false);
    dut.set_bit(Port::DetOutReady, false);
    dut.set_bit(Port::ApplyOutReady, false);
    dut.reset();
    let start = dut.cycle();
    let mut out = Outcome::default();
    let mut idle_before = dut.get_bit(Port::Idle);
    let (mut det_err, mut app_err) = (false, false);
    let mut i = 0;
    while i < txns.len() {
        let is_det = matches!(txns[i], TranslateTxn::Determine(_));
        let mut j = i;
        while j < txns.len() && matches!(txns[j], TranslateTxn::Determine(_)) == is_det {
            j += 1;
        }
        let side = if is_det { &det } else { &app };
        let mut ins = Vec::new();
        let mut exps = Vec::new();
        for t in &txns[i..j] {
            match t {
                TranslateTxn::Determine(r) => {
                    ins.push(pack_det_in(d, &r.inputs).unwrap());
                    exps.push(pack_det_out(d, &r.outputs).unwrap());
                    det_err |= r.outputs.ok == 0;
                    out.determine += 1;
                }
                TranslateTxn::Apply(r) => {
                    ins.push(pack_apply_in(d, &r.inputs).unwrap());
                    exps.push(pack_apply_out(d, &r.outputs).unwrap());
                    app_err |= r.outputs.code != ApplyCode::Ok;
                    out.apply += 1;
                }
            }
        }
        let (mut sent, mut got, mut presenting) = (0usize, 0usize, false);
        let mut quiet = 0u64;
        while got < exps.len() {
            if !presenting && sent < ins.len() && go(&mut drv_rng) {
                presenting = true;
                dut.set(side.data_in, &ins[sent]);
            }
            dut.set_bit(side.valid_in, presenting);
            let ready = go(&mut mon_rng);
            dut.set_bit(side.ready_out, ready);
            dut.eval();
            let mut moved = false;
            if presenting && dut.get_bit(side.ready_in) {
                sent += 1;
                presenting = false;
                moved = true;
            }
            if ready && dut.get_bit(side.valid_out) {
                let v = dut.get(side.data_out);
                if v != exps[got] {
                    panic!(
                        "{}: transaction {} ({}), cycle {}, seed {seed}, stall {stall}:\n{}",
                        dut.name(),
                        i + got,
                        if is_det { "determine" } else { "apply" },
                        dut.cycle(),
                        diff(&side.layout, &exps[got], &v),
                    );
                }
                got += 1;
                moved = true;
            }
            let idle = dut.get_bit(Port::Idle);
            assert_eq!(
                dut.get_bit(Port::Done),
                idle && !idle_before,
                "{}: done at cycle {}",
                dut.name(),
                dut.cycle()
            );
            idle_before = idle;
            quiet = if moved { 0 } else { quiet + 1 };
            assert!(
                quiet < 1000,
                "{}: no handshake for 1000 cycles at cycle {}",
                dut.name(),
                dut.cycle()
            );
            dut.step();
        }
        dut.set_bit(side.valid_in, false);
        i = j;
    }
    dut.set_bit(Port::DetOutReady, false);
    dut.set_bit(Port::ApplyOutReady, false);
    dut.eval();
    assert!(
        dut.get_bit(Port::Idle),
        "{}: not idle after the last output",
        dut.name()
    );
    assert_eq!(dut.get_bit(Port::DetErrorSeen), det_err, "det_error_seen");
    assert_eq!(
        dut.get_bit(Port::ApplyErrorSeen),
        app_err,
        "apply_error_seen"
    );
    out.transactions = txns.len() as u64;
    out.cycles = dut.cycle() - start;
    out
}

/// Every field of a payload, expected against got, differing ones marked.
fn diff(layout: &PortLayout, expected: &Bits, got: &Bits) -> String {
    let e = layout.decode(expected);
    let g = layout.decode(got);
    e.iter()
        .zip(&g)
        .map(|((n, a), (_, b))| {
            format!(
                "  {}{n}: expected {a:#x} got {b:#x}\n",
                if a != b { "*" } else { " " }
            )
        })
        .collect()
}
