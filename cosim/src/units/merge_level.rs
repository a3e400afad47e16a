//! The merging module's S614 merge-level stage (unit 506,
//! `rtl_gen::merge::merge_level_unit`) against the golden model through
//! `golden::vectors::merge` (stage `merge_level`), bit for bit, with random
//! back-pressure on both streams and an in-order scoreboard
//! ([`crate::tb::run_stream_bench`]). A transaction is one level: its input
//! beats in and its base-node / reference beats out; all of a level's
//! outputs are expected after its first input beat.

use std::path::{Path, PathBuf};

use golden::bits::Bits;
use golden::merge::merge_level::unit::BeatLayout;
use golden::merge::merge_module::MergeDesign;
use golden::params::Params;
use golden::translate::stimulus::SplitMix64;
use golden::vectors::merge::{generate, read_merge_vectors, MergeVector};

use super::{EngineFactory, ProgressFn};
use crate::error::{CosimError, Result};
use crate::export_tb::{ExportSpec, InputSpec, OutputSpec, StreamSpec};
use crate::tb::{
    run_with_vcd_on_failure, BenchConfig, BenchReport, StreamNames, Transaction, Vector,
};
use golden::layout::Layout;

/// The stage `hiermerge cosim --unit merge-module --stage merge-level` exercises
/// (`--unit merge-module` alone runs the whole module, [`super::merge_module::STAGE`]).
pub const STAGE: &str = "merge_level";

/// The unit under test.
pub fn merge_level_module(p: &Params) -> rtl_gen::Module {
    rtl_gen::merge::merge_level_unit(p)
}

/// `count` merge-level transactions from `seed`: the `merge_level` record
/// of `golden::vectors::merge::generate`, drawn `count` times from one stream.
pub fn generate_levels(d: &MergeDesign, seed: u64, count: usize) -> Result<Vec<MergeVector>> {
    let mut rng = SplitMix64(seed);
    (0..count)
        .map(|_| {
            generate(d, &mut rng, 0).map_err(|e| CosimError::Design {
                what: format!("golden merge vectors: {e}"),
            })
        })
        .collect()
}

/// The `merge_level` records of a file written by
/// `golden::vectors::merge::write_merge_vectors` for `d` (other stages are
/// skipped; a header whose parameters differ from `d` is an error naming them).
pub fn read_levels(path: &Path, d: &MergeDesign) -> std::result::Result<Vec<MergeVector>, String> {
    let all = read_merge_vectors(path, d).map_err(|e| e.to_string())?;
    Ok(all.into_iter().filter(|v| v.stage == STAGE).collect())
}

fn port_value(words: &[u64], width: u32) -> Result<Bits> {
    Ok(Bits::from_words(words, width)?)
}

/// Bench vectors of the levels: one per input beat, each level's expected
/// outputs on its first beat; a level with no input beat is an error.
pub fn bench_vectors(levels: &[MergeVector], flip_expected: Option<usize>) -> Result<Vec<Vector>> {
    let mut out = Vec::new();
    for (n, level) in levels.iter().enumerate() {
        let mut outputs: Vec<Transaction> = level
            .outputs
            .iter()
            .map(|w| port_value(w, level.out_width).map(|v| vec![v]))
            .collect::<Result<_>>()?;
        if flip_expected == Some(n) {
            if let Some(first) = outputs.first_mut() {
                let mut w = first[0].words().to_vec();
                w[0] ^= 1;
                first[0] = Bits::from_words(&w, level.out_width)?;
            }
        }
        if level.inputs.is_empty() {
            // Its expected outputs ride on its first input beat: a level
            // without one would check nothing and pass.
            return Err(CosimError::Design {
                what: format!("level {n} has no input beat (a level ends with an `End` beat)"),
            });
        }
        for (j, beat) in level.inputs.iter().enumerate() {
            out.push(Vector {
                input: vec![port_value(beat, level.in_width)?],
                outputs: if j == 0 {
                    std::mem::take(&mut outputs)
                } else {
                    Vec::new()
                },
            });
        }
    }
    Ok(out)
}

/// The `out` stream's layout: the node record's fields (`rec.*`), the
/// reference's (`ref.*`), `kind` and `err` (golden's `BeatLayout::output`).
pub fn output_fields(p: &Params) -> Layout {
    let out = BeatLayout::output(p);
    golden::vectors::streams::level_beat_stream("out", &out, &out)
}

/// Decodes an output beat by field name ([`output_fields`]).
pub fn decoder(p: &Params) -> Box<crate::tb::FieldDecoder> {
    let fields = output_fields(p);
    Box::new(move |t: &Transaction| {
        t.first()
            .map_or_else(Vec::new, |v| super::multi_stream::decode_fields(v, &fields))
    })
}

/// The exported testbench of the S614 stage (`hiermerge export-tb --unit
/// merge --stage merge-level`): `count` levels from `seed`
/// ([`generate_levels`]) on streams `in` and `out`, the Verilog written to
/// `rtl`.
pub fn export_spec(
    d: &MergeDesign,
    seed: u64,
    count: usize,
    stalls: crate::tb::Stalls,
    rtl: &Path,
) -> Result<ExportSpec> {
    let levels = generate_levels(d, seed, count)?;
    let design = crate::from_rtl::design_from_module(&merge_level_module(&d.params), rtl)?;
    let (mut ins, mut outs, mut txn) = (Vec::new(), Vec::new(), Vec::new());
    for (n, level) in levels.iter().enumerate() {
        for beat in &level.inputs {
            ins.push(port_value(beat, level.in_width)?);
        }
        for beat in &level.outputs {
            outs.push(port_value(beat, level.out_width)?);
            txn.push(n as u64);
        }
    }
    let fields = output_fields(&d.params);
    Ok(ExportSpec {
        design,
        transaction: "level".into(),
        transactions: count as u64,
        inputs: vec![InputSpec {
            stream: StreamSpec::prefixed("in", ins),
            after: Vec::new(),
        }],
        outputs: vec![OutputSpec {
            stream: StreamSpec::prefixed("out", outs),
            transaction: txn,
            fields,
        }],
        checks: Vec::new(),
        seed,
        stalls,
        stream_stalls: crate::tb::StreamStalls::default(),
        command: String::new(),
        store: None,
    })
}

/// How one merge-level run is driven.
#[derive(Clone, Debug)]
pub struct RunConfig {
    /// Seed of the stall patterns.
    pub seed: u64,
    /// The stall pattern of the driver and of the monitor.
    pub stall: crate::tb::Stalls,
    /// Copied into the report.
    pub reproduce: Option<String>,
    /// Trace only this instance path of the design, when given.
    pub wave_scope: Option<String>,
    /// Trace these cycles whatever the outcome (not only around a failure).
    pub wave_window: Option<(u64, u64)>,
}

/// Runs `vectors` on `make_engine(false)`; on a mismatch or hang, when `vcd`
/// is given, again on `make_engine(true)` writing the cycles within
/// `radius` of the failure to `vcd`. `progress` gets (outputs compared, cycle).
pub fn run_with_vcd_on_mismatch(
    make_engine: &mut EngineFactory,
    p: &Params,
    vectors: &[Vector],
    config: &RunConfig,
    vcd: Option<PathBuf>,
    radius: u64,
    progress: &mut ProgressFn,
) -> Result<BenchReport> {
    let bench = BenchConfig {
        seed: config.seed,
        in_stall: config.stall,
        out_stall: config.stall,
        reproduce: config.reproduce.clone(),
        vcd_path: vcd,
        vcd_radius: radius,
        wave_scope: config.wave_scope.clone(),
        wave_window: config.wave_window,
        ..BenchConfig::default()
    };
    run_with_vcd_on_failure(
        make_engine,
        &StreamNames::single("data"),
        vectors,
        &|| Some(decoder(p)),
        &bench,
        &mut |pr| progress(pr.outputs, pr.cycle),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_level_without_input_beats_is_refused_not_passed() {
        let level = |inputs: Vec<Vec<u64>>| MergeVector {
            stage: STAGE,
            in_width: 8,
            out_width: 8,
            inputs,
            outputs: vec![vec![3]],
        };
        let v = bench_vectors(&[level(vec![vec![1], vec![2]])], None).unwrap();
        assert_eq!(v.len(), 2);
        assert_eq!(
            v[0].outputs.len(),
            1,
            "the level's outputs ride on its first beat"
        );
        let e = bench_vectors(&[level(vec![vec![1]]), level(vec![])], None).unwrap_err();
        assert!(e.to_string().contains("level 1 has no input beat"), "{e}");
    }
}
