//! The timing of the translation unit's interfaces (SPEC.md 7.9), in the
//! IR simulator: latency 5 (determine) and 4 (apply) cycles, one transfer
//! per clock, capacity under back-pressure, the table write visible to the
//! next transaction, `idle`/`done`, and the sticky error bits. Prints the
//! waveforms the SPEC's diagrams show (`-- --nocapture`).

use golden::translate::model::{TranslateDesign, TranslateTxn};

use golden::vectors::translate::generate;
use rtl_gen::translate::ports::{pack_apply_in, pack_det_in, pack_det_out};
use rtl_gen::translate::translate_unit;
use rtl_gen::{Bits, Sim};

fn determine_records(d: &TranslateDesign, n: usize) -> Vec<golden::translate::TranslateRecord> {
    generate(d, 5, 4_000)
        .unwrap()
        .into_iter()
        .filter_map(|t| match t {
            TranslateTxn::Determine(r) => Some(r),
            _ => None,
        })
        .take(n)
        .collect()
}

/// Drives determine transactions with the given per-cycle `out_ready`
/// pattern; returns per cycle (in_ready, out_valid, index of the output
/// transaction shown or None) and checks outputs against golden in order.
fn run_det(out_ready: &[bool], n: usize) -> Vec<(bool, bool, bool, Option<usize>)> {
    let d = TranslateDesign::default();
    let recs = determine_records(&d, n);
    // Expected outputs in order from a fresh golden model.
    let mut model = golden::translate::model::TranslateModel::new(d).unwrap();
    let exp: Vec<Bits> = recs
        .iter()
        .map(|r| pack_det_out(&d, &model.determine(&r.inputs).unwrap()).unwrap())
        .collect();
    let m = translate_unit(&d);
    let mut sim = Sim::new(&m).unwrap();
    sim.reset();
    let (mut sent, mut got) = (0, 0);
    let mut rows = Vec::new();
    for &ready in out_ready {
        let valid = sent < recs.len();
        sim.poke("det_in_valid", valid as u64).unwrap();
        if valid {
            sim.poke("det_in_data", pack_det_in(&d, &recs[sent].inputs).unwrap())
                .unwrap();
        }
        sim.poke("det_out_ready", ready as u64).unwrap();
        let in_ready = sim.peek("det_in_ready").unwrap().to_u64() == Some(1);
        let out_valid = sim.peek("det_out_valid").unwrap().to_u64() == Some(1);
        let shown = out_valid.then(|| {
            let v = sim.peek("det_out_data").unwrap();
            assert_eq!(v, exp[got], "output {got}");
            got
        });
        rows.push((valid, in_ready, out_valid, shown));
        if valid && in_ready {
            sent += 1;
        }
        if out_valid && ready {
            got += 1;
        }
        sim.step();
    }
    rows
}

fn show(rows: &[(bool, bool, bool, Option<usize>)], ready: &[bool]) {
    let b = |v: bool| if v { "1" } else { "0" };
    let line = |name: &str, f: &dyn Fn(usize) -> String| {
        let cells: Vec<String> = (0..rows.len()).map(|i| format!("{:>5}", f(i))).collect();
        println!("{name:<15}{}", cells.join(""));
    };
    line("cycle", &|i| i.to_string());
    line("det_in_valid", &|i| b(rows[i].0).into());
    line("det_in_ready", &|i| b(rows[i].1).into());
    line("det_out_ready", &|i| b(ready[i]).into());
    line("det_out_valid", &|i| b(rows[i].2).into());
    line("det_out_data", &|i| {
        rows[i]
            .3
            .map(|k| ((b'A' + k as u8) as char).to_string())
            .unwrap_or("x".into())
    });
}

#[test]
fn determine_latency_is_five_cycles_one_per_clock() {
    let ready = vec![true; 9];
    let rows = run_det(&ready, 3);
    show(&rows, &ready);
    let outs: Vec<Option<usize>> = rows.iter().map(|r| r.3).collect();
    assert_eq!(
        outs,
        [
            None,
            None,
            None,
            None,
            None,
            Some(0),
            Some(1),
            Some(2),
            None
        ]
    );
    assert!(
        rows.iter().all(|r| r.1),
        "ready stays high without back-pressure"
    );
}

#[test]
fn determine_back_pressure_holds_six_and_loses_nothing() {
    let mut ready = vec![true; 5];
    ready.extend([false; 4]);
    ready.extend([true; 8]);
    let rows = run_det(&ready, 11);
    show(&rows, &ready);
    // Accepted while the output stalls: four pipeline registers, the
    // output register and the skid's spare hold six transactions in all.
    let accepted = |from: usize, to: usize| (from..to).filter(|&i| rows[i].0 && rows[i].1).count();
    assert_eq!(accepted(0, 6), 6);
    // The output stalls in cycles 5..=8; `ready` is registered in the skid
    // buffer, so input resumes the cycle after the output moves again.
    assert_eq!(accepted(6, 10), 0);
    assert_eq!(accepted(10, 14), 4);
    let shown: Vec<usize> = rows
        .iter()
        .zip(&ready)
        .filter_map(|(r, &rd)| if rd { r.3 } else { None })
        .collect();
    assert_eq!(
        shown,
        (0..shown.len()).collect::<Vec<_>>(),
        "in order, once each"
    );
    assert_eq!(shown.len(), 8);
}

#[test]
fn apply_latency_is_four_cycles_and_status_follows() {
    let d = TranslateDesign::default();
    let all = generate(&d, 5, 4_000).unwrap();
    let apps: Vec<_> = all
        .iter()
        .filter_map(|t| match t {
            TranslateTxn::Apply(r) => Some(*r),
            _ => None,
        })
        .collect();
    let m = translate_unit(&d);
    let mut sim = Sim::new(&m).unwrap();
    sim.reset();
    sim.poke("apply_out_ready", 1u64).unwrap();
    let mut trace = Vec::new();
    for c in 0..9 {
        let valid = c < 3;
        sim.poke("apply_in_valid", valid as u64).unwrap();
        sim.poke(
            "apply_in_data",
            pack_apply_in(&d, &apps[c.min(2)].inputs).unwrap(),
        )
        .unwrap();
        let get = |s: &mut Sim, n: &str| s.peek(n).unwrap().to_u64().unwrap();
        trace.push((
            get(&mut sim, "apply_out_valid"),
            get(&mut sim, "idle"),
            get(&mut sim, "done"),
            get(&mut sim, "apply_error_seen"),
        ));
        sim.step();
    }
    println!("apply_out_valid/idle/done/apply_error_seen per cycle: {trace:?}");
    let out_valid: Vec<u64> = trace.iter().map(|t| t.0).collect();
    assert_eq!(out_valid, [0, 0, 0, 0, 1, 1, 1, 0, 0]);
    let idle: Vec<u64> = trace.iter().map(|t| t.1).collect();
    assert_eq!(idle, [1, 0, 0, 0, 0, 0, 0, 1, 1]);
    let done: Vec<u64> = trace.iter().map(|t| t.2).collect();
    assert_eq!(done, [0, 0, 0, 0, 0, 0, 0, 1, 0]);
}
