//! Simulator behaviour beyond single operators: memories, hierarchy,
//! resets, wide registers and API errors.

use rtl_gen::{Bits, Module, Sim, SimError};

#[test]
fn register_file_reads_asynchronously_and_ram_reads_old_word_on_write() {
    let m = Module::new("mems");
    let rf = m.memory("rf", 8, 4);
    let (wa, wd, we) = (m.input("wa", 2), m.input("wd", 8), m.input("we", 1));
    rf.write(wa, wd, we);
    let ram = m.memory("ram", 8, 4);
    ram.write(wa, wd, we);
    let ra = m.input("ra", 2);
    m.output("async_q", rf.read(ra));
    m.output("sync_q", ram.read_sync(ra, m.input("re", 1)));
    let mut sim = Sim::new(&m).unwrap();
    sim.poke("wa", 1u64).unwrap();
    sim.poke("wd", 0xAAu64).unwrap();
    sim.poke("we", 1u64).unwrap();
    sim.poke("ra", 1u64).unwrap();
    sim.poke("re", 1u64).unwrap();
    assert_eq!(sim.peek("async_q").unwrap().to_u64(), Some(0));
    sim.step(); // writes 0xAA; the synchronous read saw the old word
    assert_eq!(
        sim.peek("async_q").unwrap().to_u64(),
        Some(0xAA),
        "async read sees the write at once"
    );
    assert_eq!(
        sim.peek("sync_q").unwrap().to_u64(),
        Some(0),
        "sync read returned the word before the write"
    );
    sim.poke("we", 0u64).unwrap();
    sim.step();
    assert_eq!(sim.peek("sync_q").unwrap().to_u64(), Some(0xAA));
    // A disabled synchronous read holds its output.
    sim.poke("re", 0u64).unwrap();
    sim.poke("ra", 0u64).unwrap();
    sim.step();
    assert_eq!(sim.peek("sync_q").unwrap().to_u64(), Some(0xAA));
}

#[test]
fn later_write_port_wins_on_the_same_address() {
    let m = Module::new("two_ports");
    let mem = m.memory("mem", 4, 2);
    let a = m.input("a", 1);
    mem.write(a, m.input("d0", 4), m.input("e0", 1));
    mem.write(a, m.input("d1", 4), m.input("e1", 1));
    m.output("q", mem.read(a));
    let mut sim = Sim::new(&m).unwrap();
    for (p, v) in [("a", 1u64), ("d0", 3), ("e0", 1), ("d1", 9), ("e1", 1)] {
        sim.poke(p, v).unwrap();
    }
    sim.step();
    assert_eq!(sim.peek("q").unwrap().to_u64(), Some(9));
}

#[test]
fn hierarchical_names_and_child_registers_share_clock_and_reset() {
    let child = Module::new("child");
    let d = child.input("d", 8);
    let r = child.reg_reset("r", 8, Bits::from_u128(7, 8).unwrap());
    r.next(d);
    child.output("q", r);
    let top = Module::new("top");
    let u = top.instance("u", &child);
    u.connect("d", top.input("d", 8));
    top.output("q", u.output("q"));
    let mut sim = Sim::new(&top).unwrap();
    sim.reset();
    assert_eq!(sim.peek("q").unwrap().to_u64(), Some(7));
    assert_eq!(sim.peek("u.r").unwrap().to_u64(), Some(7));
    sim.poke("d", 200u64).unwrap();
    sim.step();
    assert_eq!(sim.peek("u.q").unwrap().to_u64(), Some(200));
}

#[test]
fn wide_registers_and_handles() {
    let m = Module::new("wide");
    let a = m.input("a", 300);
    let acc = m.reg("acc", 300);
    acc.next(acc.add(a, 300));
    m.output("y", acc);
    let mut sim = Sim::new(&m).unwrap();
    let ha = sim.handle("a").unwrap();
    let hy = sim.handle("y").unwrap();
    let big = Bits::from_i128(-1, 300).unwrap(); // 2^300 - 1
    sim.set(ha, &big).unwrap();
    assert!(matches!(
        sim.set(ha, &Bits::zero(3)),
        Err(SimError::DoesNotFit(..))
    ));
    assert!(matches!(sim.set(hy, &big), Err(SimError::NotAnInput(..))));
    sim.step_n(3); // 3 * (2^300 - 1) mod 2^300 = 2^300 - 3
    assert_eq!(sim.get(hy), Bits::from_i128(-3, 300).unwrap());
    assert_eq!(
        sim.peek_signal(acc).unwrap(),
        Bits::from_i128(-3, 300).unwrap()
    );
    assert_eq!(sim.cycle(), 3);
}

#[test]
fn api_misuse_is_an_error_not_a_panic() {
    let m = Module::new("m");
    let a = m.input("a", 4);
    let r = m.reg("r", 4);
    r.next(a);
    m.output("y", r);
    let mut sim = Sim::new(&m).unwrap();
    assert_eq!(
        sim.poke("nope", 1u64),
        Err(SimError::UnknownName("nope".into()))
    );
    assert_eq!(sim.poke("y", 1u64), Err(SimError::NotAnInput("y".into())));
    assert_eq!(sim.poke("clk", 1u64), Err(SimError::ClockIsImplicit));
    assert!(matches!(
        sim.poke("a", 16u64),
        Err(SimError::DoesNotFit(..))
    ));
    assert!(sim.poke("a", -8i64).is_ok(), "-8 fits 4 bits signed");
    let other = Module::new("other");
    let x = other.input("x", 1);
    assert_eq!(sim.peek_signal(x), Err(SimError::ForeignSignal));
}

#[test]
fn registers_without_reset_keep_their_value_through_reset() {
    let m = Module::new("m");
    let d = m.input("d", 4);
    let keep = m.reg_no_reset("keep", 4);
    keep.next(d);
    let cleared = m.reg("cleared", 4);
    cleared.next(d);
    m.output("k", keep);
    m.output("c", cleared);
    let mut sim = Sim::new(&m).unwrap();
    sim.poke("d", 5u64).unwrap();
    sim.step();
    sim.poke("rst", 1u64).unwrap();
    sim.step();
    assert_eq!(sim.peek("k").unwrap().to_u64(), Some(5));
    assert_eq!(sim.peek("c").unwrap().to_u64(), Some(0));
}

#[test]
fn select_picks_every_option_and_checks_its_shape() {
    let m = Module::new("sel");
    let idx = m.input("idx", 3);
    let opts: Vec<_> = (0..8).map(|i| m.lit(i * 3 + 1, 6)).collect();
    m.output("y", idx.select(&opts));
    let mut sim = Sim::new(&m).unwrap();
    for i in 0..8u64 {
        sim.poke("idx", i).unwrap();
        assert_eq!(sim.peek("y").unwrap().to_u64(), Some(i * 3 + 1));
    }
    let bad = Module::new("bad");
    let idx = bad.input("idx", 2);
    let three = [bad.lit(1, 4), bad.lit(2, 4), bad.lit(3, 4)];
    bad.output("y", idx.select(&three));
    assert!(bad.validate().unwrap_err().has(rtl_gen::DiagKind::Width));
}
