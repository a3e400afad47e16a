//! A design with one bit flipped is caught: the report names the cycle, the
//! output and input record, each field by name (the differing one marked),
//! the seed and a reproduce command, and a VCD around the failure is written.
//! A design that never accepts input is failed by the watchdog with its ports dumped.
mod common;

use cosim::tb::{run_with_vcd_on_failure, BenchConfig, FieldDecoder, StreamNames, Vector};
use cosim::{Bits, Design, PortSpec};

/// Splits the 16-bit payload into named bytes, as a record decoder would.
fn decoder() -> Option<Box<FieldDecoder>> {
    Some(Box::new(|txn: &Vec<Bits>| {
        let v = txn[0].to_u64().unwrap_or(0);
        vec![
            ("hi".to_string(), format!("{:#04x}", v >> 8)),
            ("lo".to_string(), format!("{:#04x}", v & 0xff)),
        ]
    }))
}

#[test]
fn one_flipped_bit_is_reported_with_cycle_fields_and_vcd_on_every_engine() {
    if !common::all_tools_present() {
        return;
    }
    let design = common::skid_from("skid_broken.v");
    let vectors: Vec<Vector> = (0u64..200)
        .map(|i| {
            let x = (i * 0x0101 + 3) & 0xffff;
            Vector {
                input: vec![Bits::from_u64(x, 16).unwrap()],
                outputs: vec![vec![Bits::from_u64((x + 1) & 0xffff, 16).unwrap()]],
            }
        })
        .collect();
    // The first output whose low nibble is 0xa is the first the flipped bit corrupts.
    let first_bad = vectors
        .iter()
        .position(|v| v.outputs[0][0].to_u64().unwrap() & 0xf == 0xa)
        .unwrap() as u64;
    let out_dir = tempfile::tempdir().unwrap();
    for kind in common::ENGINES {
        let vcd = out_dir.path().join(format!("{kind}-mismatch.vcd"));
        let config = BenchConfig {
            seed: 77,
            in_stall: cosim::tb::Stalls::Coin(0.4),
            out_stall: cosim::tb::Stalls::Coin(0.4),
            vcd_path: Some(vcd.clone()),
            vcd_radius: 8,
            reproduce: Some(format!(
                "cargo test -p cosim --test broken_design # engine {kind} seed 77"
            )),
            ..BenchConfig::default()
        };
        let mut make = |trace: bool| common::make_engine(kind, &design, trace);
        let report = run_with_vcd_on_failure(
            &mut make,
            &StreamNames::single("data"),
            &vectors,
            &decoder,
            &config,
            &mut |_| {},
        )
        .unwrap();
        let text = report.to_string();
        eprintln!("{text}");
        assert!(!report.passed());
        let m = report.first_mismatch.as_ref().expect("mismatch reported");
        assert_eq!(m.output_index, first_bad, "{kind}");
        assert_eq!(m.input_id, first_bad, "{kind}");
        assert!(
            m.cycle >= first_bad + 2,
            "{kind}: cycle {} too early",
            m.cycle
        );
        let hi = &m.fields[0];
        let lo = &m.fields[1];
        assert!(hi.name == "hi" && hi.differs(), "{kind}: {text}");
        assert!(lo.name == "lo" && !lo.differs(), "{kind}: {text}");
        let exp = m.expected[0].to_u64().unwrap();
        assert_eq!(
            m.got[0].to_u64().unwrap(),
            exp ^ 0x100,
            "{kind}: exactly bit 8 flipped"
        );
        assert!(
            text.contains(&format!("mismatch at cycle {}", m.cycle)),
            "{text}"
        );
        assert!(text.contains("hi") && text.contains("<-- differs") && text.contains("seed 77"));
        assert!(text.contains("reproduce: cargo test"));
        assert_eq!(report.vcd.as_deref(), Some(vcd.as_path()));
        let dump = std::fs::read_to_string(&vcd).unwrap();
        assert!(dump.contains("$enddefinitions"), "{kind}: VCD header");
        assert!(dump.contains("out_data"), "{kind}: VCD has the output");
        assert!(
            dump.lines().filter(|l| l.starts_with('#')).count() >= 8,
            "{kind}: VCD has samples"
        );
    }
}

#[test]
fn a_design_that_never_accepts_input_is_failed_by_the_watchdog() {
    if !common::all_tools_present() {
        return;
    }
    let design = Design::new(
        "stuck",
        vec![common::fixture("stuck.v")],
        vec![
            PortSpec::input("clk", 1),
            PortSpec::input("rst", 1),
            PortSpec::input("in_valid", 1),
            PortSpec::output("in_ready", 1),
            PortSpec::input("in_data", 8),
            PortSpec::output("out_valid", 1),
            PortSpec::input("out_ready", 1),
            PortSpec::output("out_data", 8),
        ],
        Some("clk"),
        Some("rst"),
    )
    .unwrap();
    let vectors = vec![Vector {
        input: vec![Bits::from_u64(5, 8).unwrap()],
        outputs: vec![vec![Bits::from_u64(5, 8).unwrap()]],
    }];
    for kind in common::ENGINES {
        let config = BenchConfig {
            watchdog_cycles: 40,
            ..BenchConfig::default()
        };
        let mut make = |trace: bool| common::make_engine(kind, &design, trace);
        let report = run_with_vcd_on_failure(
            &mut make,
            &StreamNames::single("data"),
            &vectors,
            &|| None,
            &config,
            &mut |_| {},
        )
        .unwrap();
        let hang = report.hang.as_ref().expect("watchdog fired");
        assert_eq!(hang.idle_cycles, 41, "{kind}");
        assert!(
            hang.ports
                .iter()
                .any(|(n, v)| n == "in_valid" && v == "1'h1"),
            "{kind}: {hang}"
        );
        assert!(
            hang.ports
                .iter()
                .any(|(n, v)| n == "in_ready" && v == "1'h0"),
            "{kind}: {hang}"
        );
        assert!(!report.passed());
        assert_eq!(report.inputs_sent, 0);
        let e = common::make_engine(kind, &design, false).unwrap();
        assert_eq!(e.cycle(), 0);
    }
}
