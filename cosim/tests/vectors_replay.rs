//! Vector files of the whole merging module (every mode it builds) and of
//! the hierarchy merger (`hiermerge vectors --unit merge-module|merger`, golden's
//! `stream_file`) replay bit for bit on the RTL: each file is read back,
//! its streams driven into the generated design on the IR simulator with
//! random stalls, and every output beat compared with the file's. The
//! files hold what `cosim` drives (the same streams as its own generator
//! for the seed), and an expected bit flipped in a file is caught at its
//! merge, naming the field.

use std::path::Path;

use cosim::tb::Stalls;
use cosim::units::merge_module::{self, ModuleEngine, ModuleMismatch, RunConfig, UnitStreams};
use cosim::units::merger;
use golden::merge::merge_module::MergeDesign;
use golden::merge::merger::MergerSizes;
use golden::merge::MergeMode;
use golden::params::Params;
use golden::vectors::stream_file::{write_merger_vectors, write_module_vectors};
use rtl_gen::merge::MergerConfig;
use serde_json::Value;

const SEED: u64 = 7;

fn small(mode: MergeMode) -> MergeDesign {
    MergeDesign {
        params: Params::new(8, 0, 12, 3).unwrap(),
        inputs: 2,
        mode,
        ..MergeDesign::default()
    }
}

fn bench() -> RunConfig {
    RunConfig {
        seed: SEED,
        stall: Stalls::Coin(0.2),
        ..RunConfig::default()
    }
}

/// Flips bit 0 of field `field` of the first beat of output stream
/// `stream` in the first record that has one; returns that record's merge.
fn flip_in_file(path: &Path, stream: &str, field: &str) -> usize {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines: Vec<Value> = text
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let (n, rec) = lines
        .iter_mut()
        .skip(1)
        .enumerate()
        .find(|(_, r)| !r["out"][stream].as_array().unwrap().is_empty())
        .expect("a record with a beat on the stream");
    let v = &mut rec["out"][stream][0][field];
    *v = Value::from(v.as_u64().unwrap() ^ 1);
    let out: Vec<String> = lines.iter().map(Value::to_string).collect();
    std::fs::write(path, out.join("\n") + "\n").unwrap();
    n
}

/// The fields the mismatch shows differing.
fn differing(m: &ModuleMismatch) -> Vec<&str> {
    m.fields
        .iter()
        .filter(|f| f.1 != f.2)
        .map(|f| f.0.as_str())
        .collect()
}

fn same_streams(a: &UnitStreams, b: &UnitStreams) {
    for (x, y) in a
        .inputs
        .iter()
        .zip(&b.inputs)
        .chain(a.outputs.iter().zip(&b.outputs))
    {
        assert_eq!(x.name, y.name);
        assert!(x.beats == y.beats, "stream `{}` differs", x.name);
    }
    assert_eq!(a.starts, b.starts);
}

/// Every mode the merging module builds: the file's streams are cosim's
/// own for the seed, replay bit for bit, and a flipped `report` bit is
/// caught at its merge with the field named.
#[test]
fn module_vectors_of_every_mode_replay_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let modes = [
        MergeMode::Overlap { num: 1, den: 2 },
        MergeMode::Fixed(3),
        MergeMode::BelowTop(1),
        MergeMode::Proportion { num: 1, den: 2 },
        MergeMode::PerNode { num: 1, den: 2 },
    ];
    for (i, mode) in modes.into_iter().enumerate() {
        let d = small(mode);
        let path = dir.path().join(format!("module{i}.jsonl"));
        let count = 5;
        write_module_vectors(&path, &d, SEED, count as u64).unwrap();
        let streams = merge_module::streams_from_vectors(&d, &path).unwrap();
        let own = merge_module::generate_streams(
            &d,
            SEED,
            count,
            merge_module::DEFAULT_MOST_VOXELS,
            None,
        )
        .unwrap();
        same_streams(&streams, &own);
        let o = merge_module::run(
            &d,
            &streams,
            ModuleEngine::Ir,
            &bench(),
            dir.path(),
            &mut |_| {},
        )
        .unwrap();
        assert!(o.passed(), "{mode}: {:?}", o.first_mismatch);
        let expected: usize = streams.outputs.iter().map(|s| s.beats.len()).sum();
        assert_eq!(o.beats_out, expected as u64, "{mode}");
        assert_eq!(o.merges, count);

        // The report's first field, flipped in the file, is named.
        let field = golden::vectors::streams::module_report(&d).at(0).name;
        let merge = flip_in_file(&path, "report", field);
        let broken = merge_module::streams_from_vectors(&d, &path).unwrap();
        let o = merge_module::run(
            &d,
            &broken,
            ModuleEngine::Ir,
            &bench(),
            dir.path(),
            &mut |_| {},
        )
        .unwrap();
        assert!(!o.passed(), "{mode}: the flipped bit went unnoticed");
        let m = o.first_mismatch.expect("a mismatch");
        assert_eq!((m.stream.as_str(), m.merge), ("report", merge), "{mode}");
        assert_eq!(differing(&m), [field], "{mode}: {:?}", m.fields);
    }
}

/// The hierarchy merger (overlap and per-node): the file's streams are
/// cosim's own for the seed, replay bit for bit; a merger of other sizes or
/// mode refuses the file naming the parameter; a `header` bit flipped by
/// the test hook or in the file is caught at its merge with the field
/// named.
#[test]
fn merger_vectors_replay_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    for (i, mode) in [
        MergeMode::Overlap { num: 1, den: 2 },
        MergeMode::PerNode { num: 1, den: 2 },
    ]
    .into_iter()
    .enumerate()
    {
        let design = small(mode);
        let c = MergerConfig {
            sizes: MergerSizes {
                capacity_bits: 7,
                leaf_bits: 6,
                ..MergerSizes::new(&design.params)
            },
            design,
        };
        let path = dir.path().join(format!("merger{i}.jsonl"));
        let count = 3;
        write_merger_vectors(&path, &c.design, c.sizes, SEED, count).unwrap();
        let streams = merger::streams_from_vectors(&c, &path).unwrap();
        let mut rng = golden::translate::stimulus::SplitMix64(SEED);
        let txs: Vec<_> = (0..count)
            .map(|_| merger::random_merge(&mut rng, &c).unwrap())
            .collect();
        same_streams(&streams, &merger::merger_streams(&c, &txs).unwrap().streams);
        let t = merger::run_streams(&c, &streams, ModuleEngine::Ir, &bench(), dir.path()).unwrap();
        assert!(t.passed(), "{mode}: {:?}", t.first_mismatch);
        let expected: usize = streams.outputs.iter().map(|s| s.beats.len()).sum();
        assert_eq!(t.beats_out, expected as u64, "{mode}");
        assert_eq!(t.done_pulses, count);

        // The test hook flips merge 1's expected `header` beat, out_id's bit 0.
        let mut hooked = streams.clone();
        merger::flip_header(&mut hooked, 1).unwrap();
        let t = merger::run_streams(&c, &hooked, ModuleEngine::Ir, &bench(), dir.path()).unwrap();
        let m = t.first_mismatch.expect("the hooked bit caught");
        assert_eq!((m.stream.as_str(), m.merge), ("header", 1), "{mode}");
        assert_eq!(differing(&m), ["out_id"], "{mode}: {:?}", m.fields);

        // A merger of other sizes or another mode refuses the file, naming
        // the header parameter that differs.
        let other_sizes = [
            (
                "capacity_bits",
                c.sizes.capacity_bits + 1,
                c.sizes.leaf_bits,
            ),
            ("leaf_bits", c.sizes.capacity_bits, c.sizes.leaf_bits - 1),
        ];
        for (name, capacity_bits, leaf_bits) in other_sizes {
            let other = MergerConfig {
                sizes: MergerSizes {
                    capacity_bits,
                    leaf_bits,
                    ..c.sizes
                },
                ..c.clone()
            };
            let e = merger::streams_from_vectors(&other, &path)
                .unwrap_err()
                .to_string();
            assert!(e.contains(&format!("`{name}` is")), "{mode}: {e}");
        }
        let other = MergerConfig {
            design: small(MergeMode::Fixed(3)),
            ..c.clone()
        };
        let e = merger::streams_from_vectors(&other, &path)
            .unwrap_err()
            .to_string();
        assert!(e.contains("`mode` is"), "{mode}: {e}");

        let field = merger::output_fields(&c, "header").unwrap().at(0).name;
        let merge = flip_in_file(&path, "header", field);
        let broken = merger::streams_from_vectors(&c, &path).unwrap();
        let t = merger::run_streams(&c, &broken, ModuleEngine::Ir, &bench(), dir.path()).unwrap();
        assert!(!t.passed(), "{mode}: the flipped bit went unnoticed");
        let m = t.first_mismatch.expect("a mismatch");
        assert_eq!((m.stream.as_str(), m.merge), ("header", merge), "{mode}");
        assert_eq!(differing(&m), [field], "{mode}: {:?}", m.fields);
    }
}
