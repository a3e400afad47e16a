//! Every Verilator storage-class boundary (CData/SData/IData/QData/VlWide)
//! round-trips exact bits on both engines: each output is the bitwise NOT of
//! its input, so any lost, shifted or unmasked bit shows.
mod common;

use cosim::tb::Prng;
use cosim::{Bits, Design, PortSpec};
use golden::seed::seeded;

const WIDTHS: [u32; 16] = [
    1, 7, 8, 9, 16, 17, 31, 32, 33, 63, 64, 65, 96, 127, 128, 129,
];

fn design(dir: &std::path::Path) -> Design {
    let mut ports = Vec::new();
    let mut body = String::new();
    for w in WIDTHS {
        ports.push(PortSpec::input(&format!("i{w}"), w));
        ports.push(PortSpec::output(&format!("o{w}"), w));
        body.push_str(&format!("    assign o{w} = ~i{w};\n"));
    }
    let decls: Vec<String> = WIDTHS
        .iter()
        .flat_map(|w| {
            [
                format!("    input  wire [{}:0] i{w}", w - 1),
                format!("    output wire [{}:0] o{w}", w - 1),
            ]
        })
        .collect();
    let text = format!(
        "module widths (\n{}\n);\n{body}endmodule\n",
        decls.join(",\n")
    );
    let file = dir.join("widths.v");
    std::fs::write(&file, text).unwrap();
    Design::new("widths", vec![file], ports, None, None).unwrap()
}

fn not(v: &Bits) -> Bits {
    let mut out = v.clone();
    for i in 0..v.width() {
        out.flip_bit(i).unwrap();
    }
    out
}

#[test]
fn every_storage_class_boundary_round_trips_on_every_engine() {
    if !common::all_tools_present() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let design = design(dir.path());
    for kind in common::ENGINES {
        let mut e = common::make_engine(kind, &design, false).unwrap();
        let mut rng = Prng::new(seeded(64));
        for round in 0..12 {
            let mut pokes = Vec::new();
            for w in WIDTHS {
                let v = match round {
                    0 => Bits::zero(w),
                    1 => Bits::ones(w),
                    _ => rng.bits(w),
                };
                e.poke(e.port_id(&format!("i{w}")).unwrap(), &v).unwrap();
                pokes.push((w, v));
            }
            e.eval().unwrap();
            for (w, v) in pokes {
                let got = e.peek(e.port_id(&format!("o{w}")).unwrap()).unwrap();
                assert_eq!(got, not(&v), "{kind} round {round} width {w}");
            }
        }
    }
}
