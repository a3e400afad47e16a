//! Vector files of the multi-stream units (`hiermerge vectors --unit merge-module`,
//! `--unit merger`; SPEC.md section 9): JSON Lines through
//! [`super::write_jsonl`], one record per merge, every beat of every stream
//! field by field (each stream a [`Layout`] called by its name):
//!
//! `{"merge": n, "in": {"cfg": [{"lo": 2, "hi": 5}], "in0": [...], ...},
//!   "out": {"report": [{"lod": 2, ...}], "out": [...]}}`
//!
//! `in` holds every input stream's beats as driven, `out` every output
//! stream's beats as expected, in stream order; a field is an integer when
//! at most 64 bits wide, else a `"0x..."` hex string ([`super::wide_to_json`]).
//! Every stream and every field of each beat is present; an unknown one is
//! an error naming it.

use std::path::Path;

use serde_json::{json, Map, Value};

use super::streams::{
    merger_beats, merger_layout, merger_ports, module_merge, module_ports, random_merger_merge,
    MergeBeats, UnitPorts, DEFAULT_MOST_VOXELS,
};
use super::{read_jsonl, wide_to_json, Fields, Header, ParamMap, UnitKind, VectorError};
use crate::bits::Bits;
use crate::layout::{Field, Layout};
use crate::merge::merge_module::MergeDesign;
use crate::merge::merger::MergerSizes;
use crate::translate::stimulus::SplitMix64;

/// Field `f` of `b` as 64-bit words, least significant first.
fn field_words(b: &Bits, f: &Field) -> Result<Vec<u64>, VectorError> {
    (0..f.width.div_ceil(64))
        .map(|j| {
            let part = Field::new(f.name, f.offset + 64 * j, (f.width - 64 * j).min(64));
            b.get(&part).map_err(model)
        })
        .collect()
}

fn model(e: impl std::fmt::Display) -> VectorError {
    VectorError::Model {
        what: e.to_string(),
    }
}

/// A beat as its JSON object of fields.
fn beat_json(s: &Layout, b: &Bits) -> Result<Value, VectorError> {
    let mut m = Map::new();
    for f in s.fields() {
        let w = field_words(b, f)?;
        let v = match f.width <= 64 {
            true => json!(w.first().copied().unwrap_or(0)),
            false => wide_to_json(&w, f.width),
        };
        m.insert(f.name.to_string(), v);
    }
    Ok(Value::Object(m))
}

/// One merge's record.
fn record_json(ports: &UnitPorts, n: usize, m: &MergeBeats) -> Result<Value, VectorError> {
    let side = |streams: &[Layout], beats: &[Vec<Bits>]| -> Result<Value, VectorError> {
        let mut o = Map::new();
        for (s, bs) in streams.iter().zip(beats) {
            let arr = bs
                .iter()
                .map(|b| beat_json(s, b))
                .collect::<Result<Vec<_>, _>>()?;
            o.insert(s.name().to_string(), Value::Array(arr));
        }
        Ok(Value::Object(o))
    };
    Ok(json!({
        "merge": n,
        "in": side(&ports.inputs, &m.inputs)?,
        "out": side(&ports.outputs, &m.outputs)?,
    }))
}

/// The beats of one side (`in` or `out`) of a record.
fn read_side(rec: &Fields, key: &str, streams: &[Layout]) -> Result<Vec<Vec<Bits>>, VectorError> {
    let side = rec.object(key)?;
    if let Some(extra) = side
        .keys()
        .find(|k| !streams.iter().any(|s| s.name() == *k))
    {
        return Err(side.bad(extra, "no such stream of the unit (unknown)"));
    }
    streams
        .iter()
        .map(|s| {
            let n = side.array_len(s.name())?;
            (0..n)
                .map(|i| {
                    let beat = side.item(s.name(), i)?;
                    if let Some(extra) = beat.keys().find(|k| s.field(k).is_none()) {
                        return Err(beat.bad(extra, "no such field of the beat (unknown)"));
                    }
                    let mut b = s.zero();
                    for f in s.fields() {
                        let words = match f.width <= 64 {
                            true => vec![beat.uint(f.name, f.width)?],
                            false => beat.wide(f.name, f.width)?,
                        };
                        let v = Bits::from_words(&words, f.width).map_err(model)?;
                        b.put(f.offset, &v).map_err(model)?;
                    }
                    Ok(b)
                })
                .collect()
        })
        .collect()
}

/// Writes `header` and `count` merges drawn by `merge` for `ports`,
/// atomically.
fn write_merges(
    path: &Path,
    header: &Header,
    ports: &UnitPorts,
    mut merge: impl FnMut() -> Result<MergeBeats, String>,
) -> Result<(), VectorError> {
    let records = (0..header.count as usize).map(|n| {
        let m = merge().map_err(|what| VectorError::Model { what })?;
        record_json(ports, n, &m)
    });
    super::write_jsonl(path, header, records)
}

/// Reads the merges of a file written for `unit`, `params` and `ports` (a
/// parameter that differs is an error naming it; so is a missing or
/// unknown stream or field, or a value that does not fit its field).
fn read_merges(
    path: &Path,
    unit: UnitKind,
    params: &ParamMap,
    ports: &UnitPorts,
) -> Result<Vec<MergeBeats>, VectorError> {
    let raw = read_jsonl(path, unit, params)?;
    let mut out = Vec::with_capacity(raw.records.len());
    for (n, (line, v)) in raw.records.iter().enumerate() {
        let rec = Fields::root(path, *line, v)?;
        if let Some(extra) = rec.keys().find(|k| !["merge", "in", "out"].contains(k)) {
            return Err(rec.bad(extra, "no such field (unknown)"));
        }
        if rec.uint("merge", 64)? != n as u64 {
            return Err(rec.bad("merge", &format!("{n}, the record's index")));
        }
        out.push(MergeBeats {
            inputs: read_side(&rec, "in", &ports.inputs)?,
            outputs: read_side(&rec, "out", &ports.outputs)?,
        });
    }
    Ok(out)
}

/// The merging module's header parameters: the design's.
pub fn module_params(d: &MergeDesign) -> ParamMap {
    d.param_map()
}

/// Writes `count` random merges of the merging module `d` from `seed`
/// (as `cosim --unit merge-module` draws them: [`module_merge`], levels of at
/// most [`DEFAULT_MOST_VOXELS`] voxels) to `path`, atomically.
pub fn write_module_vectors(
    path: &Path,
    d: &MergeDesign,
    seed: u64,
    count: u64,
) -> Result<(), VectorError> {
    check(count, d.validate())?;
    let header = Header {
        unit: UnitKind::MergeModule,
        params: module_params(d),
        seed,
        count,
    };
    let mut rng = SplitMix64(seed);
    write_merges(path, &header, &module_ports(d), || {
        module_merge(&mut rng, d, DEFAULT_MOST_VOXELS)
    })
}

/// Reads a file written by [`write_module_vectors`] for `d`.
pub fn read_module_vectors(path: &Path, d: &MergeDesign) -> Result<Vec<MergeBeats>, VectorError> {
    read_merges(
        path,
        UnitKind::MergeModule,
        &module_params(d),
        &module_ports(d),
    )
}

/// The hierarchy merger's header parameters: the merging module's, the
/// fetchers' root sorter capacity and frontier, the writer's
/// `capacity_bits` and the leaf FIFOs' `leaf_bits`.
pub fn merger_params(d: &MergeDesign, sizes: &MergerSizes) -> ParamMap {
    let mut m = d.param_map();
    for (k, v) in [
        ("fetch_roots", json!(sizes.fetch.roots)),
        ("frontier", json!(sizes.fetch.frontier)),
        ("capacity_bits", json!(sizes.capacity_bits)),
        ("leaf_bits", json!(sizes.leaf_bits)),
    ] {
        m.insert(k.to_string(), v);
    }
    m
}

/// Writes `count` random merges of the hierarchy merger (`d`, `sizes`)
/// from `seed` (as `cosim --unit merger` draws them:
/// [`random_merger_merge`]) to `path`, atomically.
pub fn write_merger_vectors(
    path: &Path,
    d: &MergeDesign,
    sizes: MergerSizes,
    seed: u64,
    count: u64,
) -> Result<(), VectorError> {
    check(count, d.validate())?;
    let ml = merger_layout(d, &sizes).map_err(model)?;
    let ports = merger_ports(d, &sizes).map_err(model)?;
    let header = Header {
        unit: UnitKind::Merger,
        params: merger_params(d, &sizes),
        seed,
        count,
    };
    let mut rng = SplitMix64(seed);
    write_merges(path, &header, &ports, || {
        let tx = random_merger_merge(&mut rng, d, sizes)?;
        merger_beats(d, &ml, &tx)
    })
}

/// Reads a file written by [`write_merger_vectors`] for `d` and `sizes`.
pub fn read_merger_vectors(
    path: &Path,
    d: &MergeDesign,
    sizes: MergerSizes,
) -> Result<Vec<MergeBeats>, VectorError> {
    let ports = merger_ports(d, &sizes).map_err(model)?;
    read_merges(path, UnitKind::Merger, &merger_params(d, &sizes), &ports)
}

fn check(count: u64, valid: Result<(), String>) -> Result<(), VectorError> {
    valid.map_err(|what| VectorError::Model { what })?;
    super::check_count("--count", count, super::MAX_MERGE_COUNT)
        .map_err(|what| VectorError::Model { what })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::merge::MergeMode;

    /// Rewrites record `merge`'s line of `path` with `f`.
    fn edit(path: &Path, merge: usize, f: impl Fn(&mut Value)) {
        let text = std::fs::read_to_string(path).unwrap();
        let mut lines: Vec<String> = text.lines().map(String::from).collect();
        let mut v: Value = serde_json::from_str(&lines[merge + 1]).unwrap();
        f(&mut v);
        lines[merge + 1] = v.to_string();
        std::fs::write(path, lines.join("\n") + "\n").unwrap();
    }

    /// A file reads back as the merges drawn for the seed; a missing,
    /// unknown or too wide field, an unknown stream and a misnumbered
    /// record are refused, naming line and field.
    #[test]
    fn stream_vectors_round_trip_and_name_bad_fields() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.jsonl");
        let d = MergeDesign {
            mode: MergeMode::PerNode { num: 1, den: 2 },
            ..MergeDesign::default()
        };
        write_module_vectors(&path, &d, 4, 3).unwrap();
        let back = read_module_vectors(&path, &d).unwrap();
        let mut rng = SplitMix64(4);
        for m in &back {
            assert_eq!(m, &module_merge(&mut rng, &d, DEFAULT_MOST_VOXELS).unwrap());
        }
        let other = MergeDesign {
            mode: MergeMode::Fixed(2),
            ..d
        };
        let e = read_module_vectors(&path, &other).unwrap_err().to_string();
        assert!(e.contains("`mode` is \"per-node:1/2\" in the file"), "{e}");

        let refused = |f: &dyn Fn(&mut Value), want: &str| {
            let p = dir.path().join("bad.jsonl");
            std::fs::copy(&path, &p).unwrap();
            edit(&p, 1, f);
            let e = read_module_vectors(&p, &d).unwrap_err().to_string();
            assert!(e.contains(":3: field `") && e.contains(want), "{e}");
        };
        refused(
            &|v| v["out"]["report"][0]["bogus"] = 1.into(),
            "out.report[0].bogus`: expected no such field",
        );
        refused(
            &|v| {
                v["in"]["cfg"][0].as_object_mut().unwrap().remove("lo");
            },
            "in.cfg[0].lo`: expected a value (missing)",
        );
        refused(
            &|v| v["out"]["report"][0]["err"] = 4.into(),
            "out.report[0].err`: expected an unsigned integer of 2 bits",
        );
        refused(
            &|v| v["in"]["in9"] = Value::Array(vec![]),
            "in.in9`: expected no such stream",
        );
        refused(&|v| v["merge"] = 0.into(), "merge`: expected 1");

        let sizes = MergerSizes::new(&d.params);
        write_merger_vectors(&path, &d, sizes, 4, 2).unwrap();
        assert_eq!(read_merger_vectors(&path, &d, sizes).unwrap().len(), 2);
        let bigger = MergerSizes {
            leaf_bits: sizes.leaf_bits + 1,
            ..sizes
        };
        let e = read_merger_vectors(&path, &d, bigger)
            .unwrap_err()
            .to_string();
        assert!(e.contains("`leaf_bits`"), "{e}");
    }
}
