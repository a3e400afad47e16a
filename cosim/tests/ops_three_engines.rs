//! rtl-gen's operator suite, bit for bit, on three engines: the IR simulator
//! (`IrEngine` over `rtl_gen::Sim`), Verilator and Icarus Verilog, driven by
//! one Rust testbench through the `Engine` trait.
//!
//! Every operator of `OpKind::ALL` at every width of `optest::WIDTHS`,
//! signed and unsigned. To pay for one Verilator build per signedness
//! instead of one per (width, signedness), the test builds one top per
//! signedness that instantiates `op_suite(w, signed, false)` for all 13
//! widths (ports `w<width>_<op>_<port>`). Operands: first the cross product
//! of edge values (0, 1, all ones, signed min, signed max, alternating bits)
//! on `a` and `b`, then random vectors where each port is an edge value, a
//! small or small-negative value, or uniformly random, and `b` often equals
//! `a` or differs from it in one bit (comparisons). Shift amounts include
//! 0, w-1, w, w+1 and 2w. Icarus runs 4-state: an X or Z on any output is a
//! failure (`Engine::reset` enables the check).
//!
//! The engines are compared with each other; the IR simulator itself is
//! checked against a bit-level reference in rtl-gen's `sim_ops` test.
//! `HIERMERGE_OPS_VECTORS=<n>` changes the vector count (default below).

mod common;

use cosim::from_rtl::design_from_module;
use cosim::ir_engine::IrEngine;
use cosim::tb::Prng;
use cosim::{open_engine, Bits, Design, Engine, EngineKind, PortDir, PortId};
use golden::seed::seeded;
use rtl_gen::optest::{op_suite, OpKind, WIDTHS};
use rtl_gen::{Direction, Module};
use std::time::Instant;

/// Vectors per run; every operator at every width sees each of them.
const DEFAULT_VECTORS: usize = 400;

fn vector_count() -> usize {
    std::env::var("HIERMERGE_OPS_VECTORS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(DEFAULT_VECTORS)
}

/// One top instantiating the operator suite of every width; `registered`
/// puts a reset-to-zero register before every output (the children's `clk`
/// and `rst` are the top's).
fn all_widths_top(signed: bool, registered: bool) -> Module {
    let top = Module::new(&format!(
        "op_suites_{}{}",
        if signed { "s" } else { "u" },
        if registered { "_reg" } else { "" }
    ));
    for w in WIDTHS {
        let suite = op_suite(w, signed, registered);
        let u = top.instance(&format!("u_w{w}"), &suite);
        for p in suite.ports() {
            let name = format!("w{w}_{}", p.name);
            match p.direction {
                _ if p.name == rtl_gen::CLOCK || p.name == rtl_gen::RESET => {}
                Direction::Input => u.connect(&p.name, top.input(&name, p.width)),
                Direction::Output => {
                    top.output(&name, u.output(&p.name));
                }
            }
        }
    }
    top
}

/// The operator inputs: every input but the clock and the reset.
fn operand_ports(design: &Design) -> Vec<PortId> {
    let special = [
        design.clock.as_deref(),
        design.reset.as_ref().map(|r| r.port.as_str()),
    ];
    (0..design.ports.len())
        .filter(|&i| design.ports[i].dir == PortDir::Input)
        .filter(|&i| !special.contains(&Some(design.ports[i].name.as_str())))
        .map(PortId)
        .collect()
}

/// What a top-level port of `all_widths_top` is: width, operator, port.
#[derive(Clone, Debug)]
struct PortRole {
    width: u32,
    op: String,
    port: String,
}

fn port_role(name: &str) -> PortRole {
    // `w<width>_<op>_<port>`; operator names have no underscore.
    let mut parts = name.splitn(3, '_');
    let width = parts.next().unwrap()[1..].parse().unwrap();
    let op = parts.next().unwrap().to_string();
    let port = parts.next().unwrap().to_string();
    PortRole { width, op, port }
}

fn shift_op(op: &str) -> bool {
    op == OpKind::ShlVar.name() || op == OpKind::ShrVar.name()
}

/// Edge values of a `width`-bit operand.
fn edges(width: u32) -> Vec<Bits> {
    let mut v = vec![
        Bits::zero(width),
        Bits::from_u64(1, width).unwrap(),
        Bits::ones(width),
    ];
    let mut min = Bits::zero(width);
    min.set_bit(width - 1, true).unwrap();
    let mut max = Bits::ones(width);
    max.set_bit(width - 1, false).unwrap();
    let mut alternating = Bits::zero(width);
    for i in (0..width).step_by(2) {
        alternating.set_bit(i, true).unwrap();
    }
    v.extend([min, max, alternating]);
    v
}

/// Shift amounts around the operand width `w`, for a `port_width`-bit port.
fn shift_edges(w: u32, port_width: u32) -> Vec<Bits> {
    let limit = 1u64 << port_width;
    [
        0,
        1,
        w as u64 - 1,
        w as u64,
        w as u64 + 1,
        2 * w as u64,
        limit - 1,
    ]
    .into_iter()
    .filter(|&s| s < limit)
    .map(|s| Bits::from_u64(s, port_width).unwrap())
    .collect()
}

/// A value with only the low `k` bits random (or its bitwise complement,
/// a small negative number when read as signed).
fn small(rng: &mut Prng, width: u32) -> Bits {
    let mut v = Bits::zero(width);
    let k = (rng.below(9) as u32).min(width);
    for i in 0..k {
        v.set_bit(i, rng.chance(0.5)).unwrap();
    }
    if rng.chance(0.5) {
        for i in 0..width {
            v.flip_bit(i).unwrap();
        }
    }
    v
}

/// True when input `i` is a `b` right after the `a` of the same operator
/// (then `b` may copy `a`, so equality and near-equality are exercised).
fn follows_its_a(inputs: &[(PortRole, u32)], i: usize) -> bool {
    let (role, width) = &inputs[i];
    match i.checked_sub(1).map(|j| &inputs[j]) {
        Some((prev, prev_width)) => {
            role.port == "b"
                && prev.port == "a"
                && prev.op == role.op
                && prev.width == role.width
                && prev_width == width
        }
        None => false,
    }
}

/// The input vectors for `design` (one value per input port, port order).
fn vectors(design: &Design, count: usize, seed: u64) -> Vec<Vec<Bits>> {
    let inputs: Vec<(PortRole, u32)> = operand_ports(design)
        .iter()
        .map(|&id| &design.ports[id.0])
        .map(|p| (port_role(&p.name), p.width))
        .collect();
    let mut rng = Prng::new(seed);
    (0..count)
        .map(|k| {
            let mut values: Vec<Bits> = Vec::with_capacity(inputs.len());
            for (i, (role, width)) in inputs.iter().enumerate() {
                let set = if shift_op(&role.op) && role.port == "s" {
                    shift_edges(role.width, *width)
                } else {
                    edges(*width)
                };
                let e = set.len();
                let value = if k < e * e {
                    // Cross product: `a` walks slowly, every other port fast.
                    let j = if role.port == "a" { k / e } else { k % e };
                    set[j].clone()
                } else if follows_its_a(&inputs, i) && rng.chance(0.25) {
                    let mut near = values[i - 1].clone();
                    if rng.chance(0.5) {
                        near.flip_bit(rng.below(*width as u64) as u32).unwrap();
                    }
                    near
                } else {
                    match rng.below(8) {
                        0 | 1 => set[rng.below(e as u64) as usize].clone(),
                        2 => small(&mut rng, *width),
                        _ => rng.bits(*width),
                    }
                };
                values.push(value);
            }
            values
        })
        .collect()
}

/// The one testbench every engine runs: apply each vector, read every
/// output once it shows that vector's result: after `eval` for the
/// combinational tops, after one rising edge for the registered ones (whose
/// outputs must all be zero right after reset). `reset` also turns on
/// Icarus's X/Z check; on a reset-less design it only settles.
fn apply_vectors(engine: &mut dyn Engine, vectors: &[Vec<Bits>]) -> cosim::Result<Vec<Vec<Bits>>> {
    let design = engine.design().clone();
    let inputs = operand_ports(&design);
    let outputs = design.output_ids();
    let clocked = design.clock.is_some();
    engine.reset(2)?;
    if clocked {
        for &id in &outputs {
            let value = engine.peek(id)?;
            assert!(
                value.is_zero(),
                "{}: {} = {value} after reset, expected 0",
                engine.name(),
                design.ports[id.0].name
            );
        }
    }
    let mut results = Vec::with_capacity(vectors.len());
    for v in vectors {
        for (&id, value) in inputs.iter().zip(v) {
            engine.poke(id, value)?;
        }
        if clocked {
            engine.step()?;
        } else {
            engine.eval()?;
        }
        results.push(
            outputs
                .iter()
                .map(|&id| engine.peek(id))
                .collect::<cosim::Result<Vec<_>>>()?,
        );
    }
    Ok(results)
}

/// One output on which the engines disagree.
#[derive(Debug)]
struct Disagreement {
    vector: usize,
    output: String,
    operands: Vec<(String, Bits)>,
    values: Vec<(&'static str, Bits)>,
}

impl std::fmt::Display for Disagreement {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(f, "vector {}, output {}:", self.vector, self.output)?;
        for (name, v) in &self.operands {
            writeln!(f, "    operand {name} = {v}")?;
        }
        for (engine, v) in &self.values {
            writeln!(f, "    {engine:>9}: {v}")?;
        }
        Ok(())
    }
}

/// Every output where any engine differs from the first one, with the
/// operands of that output's operator.
fn disagreements(
    design: &Design,
    vectors: &[Vec<Bits>],
    runs: &[(&'static str, Vec<Vec<Bits>>)],
) -> Vec<Disagreement> {
    let input_names: Vec<&str> = operand_ports(design)
        .iter()
        .map(|&id| design.ports[id.0].name.as_str())
        .collect();
    let output_names: Vec<&str> = design
        .ports
        .iter()
        .filter(|p| p.dir == PortDir::Output)
        .map(|p| p.name.as_str())
        .collect();
    let mut found = Vec::new();
    for (k, vector) in vectors.iter().enumerate() {
        for (o, name) in output_names.iter().enumerate() {
            let reference = &runs[0].1[k][o];
            if runs.iter().all(|(_, r)| &r[k][o] == reference) {
                continue;
            }
            let role = port_role(name);
            let prefix = format!("w{}_{}_", role.width, role.op);
            found.push(Disagreement {
                vector: k,
                output: name.to_string(),
                operands: input_names
                    .iter()
                    .zip(vector)
                    .filter(|(n, _)| n.starts_with(&prefix))
                    .map(|(n, v)| (n.to_string(), v.clone()))
                    .collect(),
                values: runs.iter().map(|(e, r)| (*e, r[k][o].clone())).collect(),
            });
        }
    }
    found
}

fn check_operators(signed: bool, registered: bool, count: usize) {
    if !common::all_tools_present() {
        return;
    }
    let total = Instant::now();
    let sign = match (signed, registered) {
        (false, false) => "unsigned",
        (true, false) => "signed",
        (false, true) => "unsigned registered",
        (true, true) => "signed registered",
    };
    let top = all_widths_top(signed, registered);
    let dir = tempfile::tempdir().unwrap();
    let design = design_from_module(&top, dir.path()).unwrap();
    let seed = seeded(0x5eed_0000 + 2 * registered as u64 + signed as u64);
    let vecs = vectors(&design, count, seed);
    let outputs = design.output_ids().len();
    eprintln!(
        "{sign}: {} operators x {} widths, {} input and {outputs} output ports, {count} vectors",
        OpKind::ALL.len(),
        WIDTHS.len(),
        design.ports.len() - outputs,
    );

    let mut runs = Vec::new();
    let t = Instant::now();
    let mut ir = IrEngine::new(&top, &design).unwrap();
    runs.push(("ir", apply_vectors(&mut ir, &vecs).unwrap()));
    eprintln!("{sign}: ir ran in {:?}", t.elapsed());
    for kind in EngineKind::ALL {
        let t = Instant::now();
        let mut engine = open_engine(kind, &design, false)
            .unwrap_or_else(|e| panic!("{sign}: opening {}: {e}", kind.name()));
        let opened = t.elapsed();
        let result = apply_vectors(engine.as_mut(), &vecs)
            .unwrap_or_else(|e| panic!("{sign}: running {}: {e}", kind.name()));
        eprintln!(
            "{sign}: {} built/loaded in {opened:?}, ran in {:?}",
            kind.name(),
            t.elapsed() - opened
        );
        runs.push((engine.name(), result));
    }

    let found = disagreements(&design, &vecs, &runs);
    let shown: Vec<String> = found.iter().take(10).map(|d| d.to_string()).collect();
    assert!(
        found.is_empty(),
        "{sign}: {} disagreements, the first ones:\n{}",
        found.len(),
        shown.join("")
    );
    eprintln!(
        "{sign}: {} outputs x {count} vectors agree on ir, verilator and iverilog; total {:?}",
        outputs,
        total.elapsed()
    );
}

#[test]
fn unsigned_operators_agree_bit_for_bit_on_ir_verilator_and_icarus() {
    check_operators(false, false, vector_count());
}

#[test]
fn signed_operators_agree_bit_for_bit_on_ir_verilator_and_icarus() {
    check_operators(true, false, vector_count());
}

/// The same operators behind a reset-to-zero register: clock, reset and
/// register widths up to 600 bits (`Ext` at 300), with fewer vectors (the
/// operators themselves are covered above).
#[test]
fn registered_operators_agree_bit_for_bit_on_ir_verilator_and_icarus() {
    for signed in [false, true] {
        check_operators(signed, true, vector_count() / 4);
    }
}

/// The comparison itself can fail: a single flipped bit in one engine's
/// results is reported with its output and operands.
#[test]
fn a_single_flipped_bit_in_one_engine_is_reported() {
    let top = all_widths_top(true, false);
    let dir = tempfile::tempdir().unwrap();
    let design = design_from_module(&top, dir.path()).unwrap();
    let vecs = vectors(&design, 40, 7);
    let mut ir = IrEngine::new(&top, &design).unwrap();
    let good = apply_vectors(&mut ir, &vecs).unwrap();
    let out = design
        .output_ids()
        .iter()
        .position(|&id| design.ports[id.0].name == "w129_sub_y")
        .unwrap();
    let mut bad = good.clone();
    bad[37][out].flip_bit(128).unwrap();
    let found = disagreements(&design, &vecs, &[("ir", good.clone()), ("mutant", bad)]);
    assert_eq!(found.len(), 1);
    assert_eq!(
        (found[0].vector, found[0].output.as_str()),
        (37, "w129_sub_y")
    );
    let operands: Vec<&str> = found[0].operands.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(operands, ["w129_sub_a", "w129_sub_b"]);
    assert!(disagreements(&design, &vecs, &[("a", good.clone()), ("b", good)]).is_empty());
}
