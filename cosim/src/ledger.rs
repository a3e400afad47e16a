//! The long-run ledger (SPEC 10.2): one JSON entry per co-simulation run,
//! kept in the repository (`longruns/`), so that a regression too long for
//! one machine's session (100,000 merges of the merger top in Icarus take
//! hours) is run in pieces, on any machine, and still adds up to evidence
//! about *this* code.
//!
//! An entry is tied to the code by two SHA-256 digests: of the netlist's
//! structural identity ([`rtl_gen::identity`]: what each output port
//! computes, every internal name, wire, hierarchy boundary and duplicate
//! forgotten) and of the stimulus (every beat in and every expected beat
//! out, with the seed, count and stall that drive the bench). Regenerating
//! both from the entry's own command line and finding the same digests shows
//! that rerunning it today would simulate a design that computes the same
//! thing on the same beats against the same expectations. A refactor that
//! renames nets, splits generator functions or moves logic between modules
//! keeps every entry current; a change of behaviour makes the entry stale,
//! and `hiermerge ledger` reports which configurations then lack evidence.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::cache::CacheKey;
use crate::error::{io_err, Result};
use crate::tb::{Stalls, StreamBeats, StreamStalls};

/// The `format` every entry carries; bumped when fields change meaning.
pub const FORMAT: &str = "hiermerge-longrun-2";

/// SHA-256 of `top`'s structural identity ([`rtl_gen::identity`]): the
/// refinement's round count and class count and every port's name, width,
/// direction and label, as 64 hex digits.
pub fn netlist_digest(top: &rtl_gen::Module) -> Result<String> {
    let id = rtl_gen::identity::identity(top).map_err(|d| crate::CosimError::Design {
        what: format!("netlist identity of {}: {d}", top.name()),
    })?;
    let mut key = CacheKey::new();
    key.add("format", FORMAT.as_bytes());
    key.add("rounds", &id.rounds.to_le_bytes());
    key.add("classes", &(id.classes as u64).to_le_bytes());
    for (name, width, dir, label) in &id.ports {
        key.add("port", name.as_bytes());
        key.add("width", &width.to_le_bytes());
        key.add("dir", &[*dir as u8]);
        key.add("label", &label.to_le_bytes());
    }
    Ok(key.finish())
}

/// SHA-256 over a run's stimulus, fed chunk by chunk.
pub struct StimulusDigest {
    key: CacheKey,
}

impl StimulusDigest {
    /// Starts the digest of a run of `count` transactions from `seed` with
    /// the stall pattern `stalls` and the named streams' own `streams`
    /// (every number that drives the bench). A coin is keyed by its
    /// probability alone, as before there were other patterns, and no
    /// stream's own pattern adds nothing, so the entries of earlier runs
    /// stay current.
    pub fn new(seed: u64, count: u64, stalls: Stalls, streams: &StreamStalls) -> Self {
        let mut key = CacheKey::new();
        key.add("format", FORMAT.as_bytes());
        key.add("seed", &seed.to_le_bytes());
        key.add("count", &count.to_le_bytes());
        match stalls {
            Stalls::Coin(p) => key.add("stall", &p.to_bits().to_le_bytes()),
            other => key.add("stalls", other.to_string().as_bytes()),
        };
        if !streams.is_empty() {
            key.add("stream stalls", streams.to_string().as_bytes());
        }
        StimulusDigest { key }
    }

    /// Adds one chunk: its input streams and its expected output streams,
    /// every beat's width and bits.
    pub fn add_chunk(&mut self, inputs: &[StreamBeats], outputs: &[StreamBeats]) {
        for (side, streams) in [("in", inputs), ("out", outputs)] {
            for s in streams {
                self.key.add(side, s.name.as_bytes());
                self.key.add("beats", &(s.beats.len() as u64).to_le_bytes());
                for beat in &s.beats {
                    for v in beat {
                        let mut bytes = Vec::with_capacity(8 + 8 * v.words().len());
                        bytes.extend((v.width() as u64).to_le_bytes());
                        for w in v.words() {
                            bytes.extend(w.to_le_bytes());
                        }
                        self.key.add("v", &bytes);
                    }
                }
            }
        }
    }

    /// The digest as 64 hex digits.
    pub fn finish(self) -> String {
        self.key.finish()
    }
}

/// One run, as the ledger keeps it. Unknown fields are refused.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Entry {
    /// [`FORMAT`].
    pub format: String,
    /// The unit (`merger` or `hierarchy`).
    pub unit: String,
    /// The top module's name: the configuration, spelled by the generator.
    pub top: String,
    /// The engine (`verilator`, `iverilog`, `ir`).
    pub engine: String,
    /// The `hiermerge cosim` arguments that reproduce the run.
    pub args: Vec<String>,
    /// Seed of the transactions and stalls.
    pub seed: u64,
    /// Transactions run.
    pub count: u64,
    /// Every beat matched, nothing missing or hung, status outputs right.
    pub passed: bool,
    /// Output beats that differed.
    pub mismatches: u64,
    /// Cycles simulated.
    pub cycles: u64,
    /// Bench wall seconds (build excluded), where the run was made.
    pub wall_seconds: f64,
    /// [`netlist_digest`] of the simulated design.
    pub netlist_sha256: String,
    /// [`StimulusDigest`] of the run.
    pub stimulus_sha256: String,
    /// The version of hiermerge that ran it.
    pub hiermerge_version: String,
}

impl Entry {
    /// Where the entry goes in a ledger folder:
    /// `<top>/<engine>-seed<seed>-n<count>.json`.
    pub fn relative_path(&self) -> std::path::PathBuf {
        Path::new(&self.top).join(format!(
            "{}-seed{}-n{}.json",
            self.engine, self.seed, self.count
        ))
    }

    /// Writes the entry under `dir` (folders created); refuses to replace
    /// an entry already there, so that no run's record is lost. The entry
    /// is written whole into a temporary file beside it and then linked
    /// into place, so a run stopped while it writes leaves no half entry.
    pub fn write_into(&self, dir: &Path) -> Result<std::path::PathBuf> {
        let path = dir.join(self.relative_path());
        let parent = path.parent().unwrap_or(dir);
        std::fs::create_dir_all(parent).map_err(io_err(parent))?;
        let text = serde_json::to_string_pretty(self).map_err(|e| crate::CosimError::Design {
            what: format!("ledger entry: {e}"),
        })? + "\n";
        let mut file = tempfile::Builder::new()
            .permissions(std::os::unix::fs::PermissionsExt::from_mode(0o666))
            .tempfile_in(parent)
            .map_err(io_err(parent))?;
        std::io::Write::write_all(&mut file, text.as_bytes()).map_err(io_err(file.path()))?;
        file.as_file().sync_all().map_err(io_err(file.path()))?;
        file.persist_noclobber(&path)
            .map_err(|e| io_err(&path)(e.error))?;
        Ok(path)
    }
}

/// Reads every `*.json` entry under `dir` (recursively, in path order),
/// each through [`read_entry`]: a file that is no entry, or an entry that
/// contradicts itself or its place, comes back as the reason, naming the
/// file and the field, so that every bad entry is named. Only a folder that
/// cannot be listed is an error.
pub fn read_ledger(
    dir: &Path,
) -> Result<Vec<(std::path::PathBuf, std::result::Result<Entry, String>)>> {
    let mut files = Vec::new();
    collect_json(dir, &mut files)?;
    files.sort();
    Ok(files
        .into_iter()
        .map(|path| {
            let entry = read_entry(dir, &path);
            (path, entry)
        })
        .collect())
}

/// Reads the entry at `path` inside the ledger folder `dir` (a regular
/// file of at most [`golden::input::MAX_JSON_BYTES`], one JSON object and
/// nothing after it, no unknown field) and checks it against itself
/// ([`Entry::inconsistencies`]) and its place (the folder `dir/<top>`).
pub fn read_entry(dir: &Path, path: &Path) -> std::result::Result<Entry, String> {
    let shown = path.display();
    let text =
        golden::input::read_text(path, golden::input::MAX_JSON_BYTES).map_err(|e| e.to_string())?;
    let doc =
        golden::json::parse(&text).map_err(|e| format!("{shown}: not a ledger entry: {e}"))?;
    let entry: Entry = golden::json::from_value(&doc)
        .map_err(|(at, e)| format!("{shown}: not a ledger entry: {at}: {e}"))?;
    if entry.format != FORMAT {
        return Err(format!("{shown}: field format `{}`: expected `{FORMAT}` (entries of hiermerge-longrun-1 digest the Verilog text; rerun them)", entry.format));
    }
    let mut bad = entry.inconsistencies();
    let folder = dir.join(&entry.top);
    if path.parent() != Some(folder.as_path()) {
        bad.push(format!(
            "field top `{}`: the entry is filed under another configuration's folder (it belongs in `{}`)",
            entry.top,
            folder.display()
        ));
    }
    match bad.is_empty() {
        true => Ok(entry),
        false => Err(format!("{shown}: {}", bad.join("; "))),
    }
}

impl Entry {
    /// What in the entry contradicts itself, one message per field: a
    /// digest that is not 64 lower-case hexadecimal digits, `passed` that
    /// disagrees with `mismatches` (a run passes exactly when nothing
    /// differed), a `count` of 0, fewer `cycles` than merges (a merge takes
    /// at least one cycle), or `wall_seconds` that is not a finite number
    /// above 0.
    pub fn inconsistencies(&self) -> Vec<String> {
        let mut bad = Vec::new();
        for (field, digest) in [
            ("netlist_sha256", &self.netlist_sha256),
            ("stimulus_sha256", &self.stimulus_sha256),
        ] {
            if !is_sha256_hex(digest) {
                bad.push(format!(
                    "field {field}: `{digest}`, expected 64 lower-case hexadecimal digits"
                ));
            }
        }
        if self.passed && self.mismatches != 0 {
            bad.push(format!(
                "field passed: true with {} mismatches: a run passes only when none differed",
                self.mismatches
            ));
        }
        if self.count == 0 {
            bad.push("field count: 0, expected at least one merge".into());
        }
        if self.cycles < self.count {
            bad.push(format!(
                "field cycles: {} for {} merges, expected at least one cycle per merge",
                self.cycles, self.count
            ));
        }
        if !(self.wall_seconds.is_finite() && self.wall_seconds > 0.0) {
            bad.push(format!(
                "field wall_seconds: {}, expected a finite number of seconds above 0",
                self.wall_seconds
            ));
        }
        bad
    }
}

/// A SHA-256 digest as [`netlist_digest`] and [`StimulusDigest`] print it.
fn is_sha256_hex(text: &str) -> bool {
    text.len() == 64 && text.bytes().all(|b| matches!(b, b'0'..=b'9' | b'a'..=b'f'))
}

fn collect_json(dir: &Path, out: &mut Vec<std::path::PathBuf>) -> Result<()> {
    for item in std::fs::read_dir(dir).map_err(io_err(dir))? {
        let path = item.map_err(io_err(dir))?.path();
        if path.is_dir() {
            collect_json(&path, out)?;
        } else if path.extension().is_some_and(|x| x == "json") {
            out.push(path);
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use golden::bits::Bits;

    fn streams(bit: bool) -> Vec<StreamBeats> {
        let mut v = Bits::zero(70);
        v.set_bit(65, bit).unwrap();
        vec![StreamBeats {
            name: "s".into(),
            beats: vec![vec![v]],
        }]
    }

    #[test]
    fn the_stimulus_digest_sees_every_bit_and_every_knob() {
        let none = StreamStalls::default();
        let header = StreamStalls::parse(["header=bursty:200,2"]).unwrap();
        let digest_of = |seed, count, stall, own: &StreamStalls, bit| {
            let mut d = StimulusDigest::new(seed, count, stall, own);
            d.add_chunk(&streams(bit), &[]);
            d.finish()
        };
        let digest = |seed, count, stall, bit| digest_of(seed, count, stall, &none, bit);
        let coin = Stalls::Coin(0.3);
        let base = digest(1, 10, coin, false);
        assert_eq!(base, digest(1, 10, coin, false));
        for other in [
            digest(2, 10, coin, false),
            digest(1, 11, coin, false),
            digest(1, 10, Stalls::Coin(0.31), false),
            digest(1, 10, Stalls::BURSTY, false),
            digest(1, 10, Stalls::Bursty { stall: 16, go: 17 }, false),
            digest(1, 10, Stalls::PERIODIC, false),
            digest(1, 10, Stalls::None, false),
            digest(1, 10, coin, true),
            digest_of(1, 10, coin, &header, false),
        ] {
            assert_ne!(base, other);
        }
        // The same beats as an input or as an expected output differ too.
        let mut d = StimulusDigest::new(1, 10, coin, &none);
        d.add_chunk(&[], &streams(false));
        assert_ne!(base, d.finish());
    }

    fn entry() -> Entry {
        Entry {
            format: FORMAT.into(),
            unit: "merger".into(),
            top: "hierarchy_merger_x".into(),
            engine: "ir".into(),
            args: vec!["--unit".into(), "merger".into()],
            seed: 3,
            count: 5,
            passed: true,
            mismatches: 0,
            cycles: 100,
            wall_seconds: 0.5,
            netlist_sha256: "a".repeat(64),
            stimulus_sha256: "b".repeat(64),
            hiermerge_version: "0.1.0".into(),
        }
    }

    #[test]
    fn an_entry_is_never_overwritten() {
        let dir = tempfile::tempdir().unwrap();
        let e = entry();
        let path = e.write_into(dir.path()).unwrap();
        assert!(path.ends_with("hierarchy_merger_x/ir-seed3-n5.json"));
        assert!(e.write_into(dir.path()).is_err());
        // The refused write leaves neither a changed entry nor its temporary file.
        let folder = path.parent().unwrap();
        let names: Vec<_> = std::fs::read_dir(folder)
            .unwrap()
            .map(|f| f.unwrap().file_name())
            .collect();
        assert_eq!(names, vec![std::ffi::OsString::from("ir-seed3-n5.json")]);
        let read = read_ledger(dir.path()).unwrap();
        assert_eq!(read, vec![(path.clone(), Ok(e))]);
        std::fs::write(dir.path().join("hierarchy_merger_x/bad.json"), "{}").unwrap();
        let err = read_ledger(dir.path()).unwrap()[0].1.clone().unwrap_err();
        assert!(
            err.contains("bad.json") && err.contains("not a ledger entry"),
            "{err}"
        );
    }

    #[test]
    fn a_digest_that_is_no_sha256_is_named() {
        for (field, bad) in [
            ("netlist_sha256", "é".repeat(32)),
            ("stimulus_sha256", "A".repeat(64)),
            ("netlist_sha256", "a".repeat(63)),
        ] {
            let dir = tempfile::tempdir().unwrap();
            let mut e = entry();
            match field {
                "netlist_sha256" => e.netlist_sha256 = bad.clone(),
                _ => e.stimulus_sha256 = bad.clone(),
            }
            e.write_into(dir.path()).unwrap();
            let err = read_ledger(dir.path()).unwrap()[0].1.clone().unwrap_err();
            assert!(
                err.contains("ir-seed3-n5.json") && err.contains(&format!("field {field}")),
                "{err}"
            );
        }
    }

    /// Each piece of false evidence of issue 21 is named by file and field,
    /// and the good entry beside it still reads.
    #[test]
    fn false_evidence_is_named_entry_by_entry() {
        let dir = tempfile::tempdir().unwrap();
        entry().write_into(dir.path()).unwrap();
        let cases: [fn(&mut Entry); 4] = [
            |e| e.mismatches = 5,
            |e| e.cycles = 1,
            |e| e.wall_seconds = -5.0,
            |e| {
                e.count = 0;
                e.cycles = 0
            },
        ];
        for (i, spoil) in cases.iter().enumerate() {
            let mut e = entry();
            e.seed = 10 + i as u64;
            spoil(&mut e);
            e.write_into(dir.path()).unwrap();
        }
        let folder = dir.path().join("hierarchy_merger_x");
        // Filed under another configuration's folder.
        let other = dir.path().join("hierarchy_merger_y");
        std::fs::create_dir(&other).unwrap();
        std::fs::copy(
            folder.join("ir-seed3-n5.json"),
            other.join("ir-seed3-n5.json"),
        )
        .unwrap();
        // An unknown field.
        let mut v = serde_json::to_value(entry()).unwrap();
        v["trust_me"] = true.into();
        std::fs::write(folder.join("ir-seed4-n5.json"), v.to_string()).unwrap();
        // A FIFO named like an entry does not block.
        let fifo = folder.join("ir-seed5-n5.json");
        assert!(std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap()
            .success());
        let read = read_ledger(dir.path()).unwrap();
        let bad: Vec<String> = read.iter().filter_map(|r| r.1.clone().err()).collect();
        assert_eq!(read.len() - bad.len(), 1, "{bad:#?}");
        for want in [
            "ir-seed10-n5.json: field passed",
            "ir-seed11-n5.json: field cycles",
            "ir-seed12-n5.json: field wall_seconds",
            "ir-seed13-n0.json: field count",
            "hierarchy_merger_y/ir-seed3-n5.json: field top `hierarchy_merger_x`: the entry is filed under another",
            "ir-seed4-n5.json: not a ledger entry: trust_me: unknown field `trust_me`",
            "ir-seed5-n5.json: expected a regular file, found a FIFO",
        ] {
            assert!(bad.iter().any(|b| b.contains(want)), "{want}: {bad:#?}");
        }
    }
}
