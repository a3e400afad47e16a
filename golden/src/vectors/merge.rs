//! Test vectors of the merging module's stream units (`hiermerge vectors
//! --unit merge-module`; SPEC.md section 8.9): JSON Lines through
//! [`super::write_jsonl`], header params = every generator parameter.
//!
//! Record `i` exercises stage `stages[i % stages.len()]` (the stages the
//! configuration builds, [`MergeDesign::stages`]) with one transaction from the
//! seeded stimulus of [`crate::merge::merge_level::unit`], [`crate::merge::level_choice::unit`], [`crate::merge::upper_builder::level_unit`], [`crate::merge::fetcher::root_sorter`]:
//! `{"stage": "merge_level" | "overlap_counter" | "upper_level" | "root_sorter",
//!   "in": [beat, ...], "out": [beat, ...]}`, every beat the unit's `in_data` /
//! `out_data` port value (an integer up to 64 bits, else a `"0x..."` hex string
//! of `ceil(width / 4)` digits), in stream order.

use serde_json::{json, Value};
use std::path::Path;

use super::{read_jsonl, wide_from_hex, wide_to_json, Header, ParamMap, UnitKind, VectorError};
use crate::bits::Bits;
use crate::merge::fetcher::root_sorter::*;
use crate::merge::level_choice::unit::*;
use crate::merge::merge_level::unit::*;
use crate::merge::merge_module::MergeDesign;
use crate::merge::upper_builder::level_unit::*;
use crate::translate::stimulus::SplitMix64;

/// The stages, in record order.
pub const STAGES: [&str; 4] = [
    "merge_level",
    "overlap_counter",
    "upper_level",
    "root_sorter",
];

impl MergeDesign {
    /// The stream stages this configuration builds, in record order: the
    /// overlap counter only in overlap mode.
    pub fn stages(&self) -> Vec<&'static str> {
        STAGES
            .iter()
            .copied()
            .filter(|s| *s != "overlap_counter" || self.threshold().is_some())
            .collect()
    }

    /// Every parameter by name, as the header holds them.
    pub fn param_map(&self) -> ParamMap {
        let p = &self.params;
        [
            ("max_lod", json!(p.max_lod)),
            ("quant_bits", json!(p.quant_bits)),
            ("index_bits", json!(p.index_bits)),
            ("hier_bits", json!(p.hier_bits)),
            ("inputs", json!(self.inputs)),
            ("mode", json!(self.mode.to_string())),
            ("roots", json!(self.roots)),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v))
        .collect()
    }
}

/// One record: a stage and its beats in and out, as port words (LSB first).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MergeVector {
    /// One of [`STAGES`].
    pub stage: &'static str,
    /// Width of the stage's `in_data` port, in bits.
    pub in_width: u32,
    /// Width of the stage's `out_data` port, in bits.
    pub out_width: u32,
    /// Input beats in stream order, each as 64-bit words, least significant first.
    pub inputs: Vec<Vec<u64>>,
    /// Expected output beats in stream order, in the same form.
    pub outputs: Vec<Vec<u64>>,
}

fn words(b: Result<Bits, crate::layout::LayoutError>) -> Result<Vec<u64>, VectorError> {
    b.map(|b| b.words().to_vec())
        .map_err(|e| VectorError::Model {
            what: e.to_string(),
        })
}

fn model(e: impl std::fmt::Display) -> VectorError {
    VectorError::Model {
        what: e.to_string(),
    }
}

/// The `i`-th record's transaction from `rng`.
pub fn generate(
    d: &MergeDesign,
    rng: &mut SplitMix64,
    i: usize,
) -> Result<MergeVector, VectorError> {
    let p = &d.params;
    let stages = d.stages();
    let stage = stages[i % stages.len()];
    let (iw, ow, ins, outs) = match stage {
        "merge_level" => {
            let (li, lo) = (BeatLayout::input(p), BeatLayout::output(p));
            let case = random_level_case(rng, p, d.inputs.min(p.hier_capacity() as usize), 12);
            let tx = case.transaction(p).map_err(model)?;
            let ins = tx
                .inputs
                .iter()
                .map(|b| words(b.pack(&li)))
                .collect::<Result<_, _>>()?;
            let outs = tx
                .outputs
                .iter()
                .map(|b| words(b.pack(&lo)))
                .collect::<Result<_, _>>()?;
            (li.width(), lo.width(), ins, outs)
        }
        "overlap_counter" => {
            let l = OverlapLayout::new(p, d.inputs);
            let voxels = random_overlap_case(rng, p, d.inputs, 8);
            let (num, den) = d.threshold().expect("overlap_counter only in overlap mode");
            let (beats, r) = overlap_transaction(&voxels, p, num, den);
            let ins = beats
                .iter()
                .map(|b| words(b.pack(&l)))
                .collect::<Result<_, _>>()?;
            (
                l.input.width(),
                l.output.width(),
                ins,
                vec![words(r.pack(&l))?],
            )
        }
        "upper_level" => {
            let l = UpperLayout::new(p);
            let level = random_upper_level(rng, p, 24);
            let (ins, outs) = upper_transaction(&level, p);
            let i = ins
                .iter()
                .map(|b| words(b.pack(&l, false)))
                .collect::<Result<_, _>>()?;
            let o = outs
                .iter()
                .map(|b| words(b.pack(&l, true)))
                .collect::<Result<_, _>>()?;
            (l.input.width(), l.output.width(), i, o)
        }
        _ => {
            let (li, lo) = (BeatLayout::input(p), BeatLayout::output(p));
            let err = lo.err.expect("output beats have err");
            let roots = random_roots(rng, p, d.roots);
            let (ins, outs) = root_sort_transaction(&roots, d.roots);
            let i = ins
                .iter()
                .map(|b| words(b.pack(&li)))
                .collect::<Result<_, _>>()?;
            let mut o = Vec::new();
            for (b, e) in outs {
                let mut bits = Bits::zero(lo.width());
                bits.put(0, &b.pack(&li).map_err(model)?).map_err(model)?;
                bits.set(&err, e as u64).map_err(model)?;
                o.push(bits.words().to_vec());
            }
            (li.width(), lo.width(), i, o)
        }
    };
    Ok(MergeVector {
        stage,
        in_width: iw,
        out_width: ow,
        inputs: ins,
        outputs: outs,
    })
}

fn beat_json(w: &[u64], width: u32) -> Value {
    if width <= 64 {
        json!(w.first().copied().unwrap_or(0))
    } else {
        wide_to_json(w, width)
    }
}

/// Writes `count` records for `d` from `seed` to `path`, atomically.
pub fn write_merge_vectors(
    path: &Path,
    d: &MergeDesign,
    seed: u64,
    count: u64,
) -> Result<(), VectorError> {
    super::check_count("--count", count, super::MAX_MERGE_COUNT)
        .map_err(|what| VectorError::Model { what })?;
    let header = Header {
        unit: UnitKind::Merge,
        params: d.param_map(),
        seed,
        count,
    };
    let mut rng = SplitMix64(seed);
    let records = (0..count as usize).map(move |i| {
        let v = generate(d, &mut rng, i)?;
        Ok(json!({
            "stage": v.stage,
            "in": v.inputs.iter().map(|w| beat_json(w, v.in_width)).collect::<Vec<_>>(),
            "out": v.outputs.iter().map(|w| beat_json(w, v.out_width)).collect::<Vec<_>>(),
        }))
    });
    super::write_jsonl(path, &header, records)
}

/// Reads a file written by [`write_merge_vectors`] for design `d` (a
/// parameter that differs is an error naming it); beats as port words.
pub fn read_merge_vectors(path: &Path, d: &MergeDesign) -> Result<Vec<MergeVector>, VectorError> {
    let raw = read_jsonl(path, UnitKind::Merge, &d.param_map())?;
    let bad = |line: usize, field: &str, expected: &str| VectorError::Malformed {
        path: path.to_path_buf(),
        line,
        field: field.to_string(),
        expected: expected.to_string(),
    };
    let mut out = Vec::new();
    // Per stage, (in width, out width), from one generated transaction.
    let mut widths: Vec<Option<(u32, u32)>> = vec![None; d.stages().len()];
    for (line, v) in raw.records {
        let keys = json!({"stage": null, "in": null, "out": null});
        super::refuse_unknown(path, line, &v, &keys)?;
        let stage = v
            .get("stage")
            .and_then(Value::as_str)
            .and_then(|s| STAGES.iter().find(|&&t| t == s).copied())
            .ok_or_else(|| {
                bad(
                    line,
                    "stage",
                    "one of merge_level, overlap_counter, upper_level, root_sorter",
                )
            })?;
        let i = d.stages().iter().position(|&s| s == stage).ok_or_else(|| {
            bad(
                line,
                "stage",
                "a stage this configuration builds (no overlap_counter outside overlap mode)",
            )
        })?;
        // Widths come from the design, never from the file.
        let (in_width, out_width) = match widths[i] {
            Some(w) => w,
            None => {
                let t = generate(d, &mut SplitMix64(0), i)?;
                *widths[i].insert((t.in_width, t.out_width))
            }
        };
        let beats = |key: &str, width: u32| -> Result<Vec<Vec<u64>>, VectorError> {
            let arr = v
                .get(key)
                .and_then(Value::as_array)
                .ok_or_else(|| bad(line, key, "an array of beats"))?;
            arr.iter()
                .enumerate()
                .map(|(k, b)| {
                    // Named only when an error is reported.
                    let field = || format!("{key}[{k}]");
                    if width <= 64 {
                        b.as_u64()
                            .filter(|&n| width == 64 || n >> width == 0)
                            .map(|n| vec![n])
                            .ok_or_else(|| {
                                bad(line, &field(), &format!("an integer below 2^{width}"))
                            })
                    } else {
                        b.as_str()
                            .and_then(|s| wide_from_hex(s, width))
                            .ok_or_else(|| {
                                bad(line, &field(), &format!("a {width}-bit 0x hex string"))
                            })
                    }
                })
                .collect()
        };
        out.push(MergeVector {
            stage,
            in_width,
            out_width,
            inputs: beats("in", in_width)?,
            outputs: beats("out", out_width)?,
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::merge::MergeMode;

    #[test]
    fn merge_vectors_round_trip_and_refuse_other_params() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("merge.jsonl");
        let d = MergeDesign::default();
        write_merge_vectors(&path, &d, 5, 12).unwrap();
        let back = read_merge_vectors(&path, &d).unwrap();
        assert_eq!(back.len(), 12);
        let mut rng = SplitMix64(5);
        for (i, v) in back.iter().enumerate() {
            assert_eq!(v, &generate(&d, &mut rng, i).unwrap());
        }
        let other = MergeDesign {
            mode: MergeMode::Overlap { num: 2, den: 3 },
            ..d
        };
        let e = read_merge_vectors(&path, &other).unwrap_err();
        assert!(e.to_string().contains("mode"), "{e}");
        // Outside overlap mode no overlap counter is built, nor tested.
        let fixed = MergeDesign {
            mode: MergeMode::Fixed(3),
            ..d
        };
        assert_eq!(
            fixed.stages(),
            vec!["merge_level", "upper_level", "root_sorter"]
        );
        let mut rng = SplitMix64(5);
        assert!((0..6).all(|i| generate(&fixed, &mut rng, i).unwrap().stage != "overlap_counter"));
        // Per-node merging is built (SPEC 8.14); its ratio is checked.
        assert!(MergeDesign {
            mode: MergeMode::PerNode { num: 1, den: 2 },
            ..d
        }
        .validate()
        .is_ok());
        assert!(MergeDesign {
            mode: MergeMode::PerNode { num: 3, den: 2 },
            ..d
        }
        .validate()
        .is_err());
        assert!(MergeDesign { inputs: 1, ..d }.validate().is_err());
    }
}
