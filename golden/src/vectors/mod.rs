//! Test-vector files (SPEC.md section 9): JSON Lines, one header line and
//! one line per transaction, with inputs and expected outputs exactly as the
//! RTL ports carry them.
//!
//! Line 1 is the header:
//! `{"format":"hiermerge-vectors","version":1,"unit":"translate","params":{...},"seed":S,"count":N}`
//! where `params` holds every parameter of the design under test (the
//! golden [`crate::Params`] fields and the unit's configuration). Then `N`
//! record lines follow; their schema belongs to the unit ([`translate`],
//! [`merge`], [`stream_file`]).
//!
//! Bit fields are JSON integers when at most 64 bits wide, and hex strings
//! `"0x..."` (exactly `ceil(width / 4)` digits, most significant first) when
//! wider ([`wide_to_json`]). Files are written atomically: a temporary file in
//! the destination's directory, renamed over the destination only when every
//! line was written. Reading checks the header against the design's
//! parameters and names every parameter that differs, and every malformed
//! line is an error naming the file, the line and the field.

pub mod classes;
pub mod hard_merges;
pub mod merge;
pub mod stream_file;
pub mod streams;
pub mod translate;

#[cfg(test)]
mod file_tests;

use std::collections::BTreeMap;
use std::fmt;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use serde_json::{Map, Value};

/// The `format` string of the header.
pub const FORMAT_NAME: &str = "hiermerge-vectors";
/// The `version` of the format this module writes and reads.
pub const FORMAT_VERSION: u64 = 1;

/// The most transactions `hiermerge cosim --count` may ask for, and a
/// translate vector file may hold (SPEC.md section 15): a million, ten
/// times the longest regression run, so that a typo cannot exhaust memory
/// or fill the disk (a million translate records are about 380 MB).
pub const MAX_COUNT: u64 = 1_000_000;

/// The most records a merge vector file may hold (SPEC.md section 15):
/// its records are ten to twenty times larger (100,000 are 0.4 to 0.7 GB).
pub const MAX_MERGE_COUNT: u64 = 100_000;

/// The most bytes a vector file may have (SPEC.md section 15): 2 GiB, above
/// the largest file either limit allows.
pub const MAX_FILE_BYTES: u64 = 2 << 30;

impl UnitKind {
    /// The most records a vector file of this unit may hold.
    pub fn max_count(self) -> u64 {
        match self {
            UnitKind::Translate => MAX_COUNT,
            UnitKind::Merge | UnitKind::MergeModule | UnitKind::Merger => MAX_MERGE_COUNT,
        }
    }

    /// The most bytes one record line of this unit's files may have
    /// (SPEC.md section 15): one merge's beats are larger than a
    /// translation's or a stage's transaction.
    pub fn max_line_bytes(self) -> u64 {
        match self {
            UnitKind::Translate | UnitKind::Merge => crate::input::MAX_LINE_BYTES,
            UnitKind::MergeModule | UnitKind::Merger => crate::input::MAX_MERGE_LINE_BYTES,
        }
    }
}

/// Refuses a `count` above `limit`, naming `what` asked for it.
pub fn check_count(what: &str, count: u64, limit: u64) -> Result<(), String> {
    match count > limit {
        true => Err(format!(
            "{what} {count}: expected at most {limit} transactions (SPEC.md section 15)"
        )),
        false => Ok(()),
    }
}

/// The first key of `read` (a record line as read) that `written` (the
/// record decoded and written again, or a value with the format's keys) does
/// not have, as a field path: an unknown field. Objects are compared key by
/// key at every depth; arrays element by element.
pub fn unknown_field(read: &Value, written: &Value) -> Option<String> {
    fn walk(read: &Value, written: &Value, at: &str) -> Option<String> {
        match (read, written) {
            (Value::Object(r), Value::Object(w)) => r.iter().find_map(|(k, v)| {
                let here = if at.is_empty() {
                    k.clone()
                } else {
                    format!("{at}.{k}")
                };
                match w.get(k) {
                    None => Some(here),
                    Some(wv) => walk(v, wv, &here),
                }
            }),
            (Value::Array(r), Value::Array(w)) => r
                .iter()
                .zip(w)
                .enumerate()
                .find_map(|(i, (rv, wv))| walk(rv, wv, &format!("{at}[{i}]"))),
            _ => None,
        }
    }
    walk(read, written, "")
}

/// [`unknown_field`] as the error of line `line` of `path`.
pub fn refuse_unknown(
    path: &Path,
    line: usize,
    read: &Value,
    written: &Value,
) -> Result<(), VectorError> {
    match unknown_field(read, written) {
        Some(field) => Err(malformed(path, line, &field, "no such field (unknown)")),
        None => Ok(()),
    }
}

/// Which unit a vector file exercises.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum UnitKind {
    /// The translation unit (SPEC 7.8); records in [`translate`].
    Translate,
    /// The merging module's stream stages (SPEC 8.9); records in [`merge`].
    Merge,
    /// The whole merging module (SPEC 8.10), one merge per record; records
    /// in [`stream_file`].
    MergeModule,
    /// The hierarchy merger top (SPEC 8.15), one merge per record; records
    /// in [`stream_file`].
    Merger,
}

impl UnitKind {
    /// The header's `unit` string.
    pub fn name(self) -> &'static str {
        match self {
            UnitKind::Translate => "translate",
            UnitKind::Merge => "merge",
            UnitKind::MergeModule => "merge_module",
            UnitKind::Merger => "hierarchy_merger",
        }
    }

    fn from_name(s: &str) -> Option<UnitKind> {
        match s {
            "translate" => Some(UnitKind::Translate),
            "merge" => Some(UnitKind::Merge),
            "merge_module" => Some(UnitKind::MergeModule),
            "hierarchy_merger" => Some(UnitKind::Merger),
            _ => None,
        }
    }
}

/// Parameters by name (integers or booleans), in name order.
pub type ParamMap = BTreeMap<String, Value>;

/// The header line.
#[derive(Clone, Debug, PartialEq)]
pub struct Header {
    /// The unit the records are for.
    pub unit: UnitKind,
    /// Every parameter of the design the vectors were generated for.
    pub params: ParamMap,
    /// The generator's seed (the same seed gives the same file).
    pub seed: u64,
    /// Number of record lines after the header.
    pub count: u64,
}

impl Header {
    /// The header as its JSON line value.
    pub fn to_json(&self) -> Value {
        let params: Map<String, Value> = self
            .params
            .iter()
            .map(|(k, v)| (k.clone(), v.clone()))
            .collect();
        serde_json::json!({
            "format": FORMAT_NAME,
            "version": FORMAT_VERSION,
            "unit": self.unit.name(),
            "params": params,
            "seed": self.seed,
            "count": self.count,
        })
    }
}

/// One parameter whose value in the file differs from the design's (`None`:
/// absent on that side).
#[derive(Clone, Debug, PartialEq)]
pub struct ParamDiff {
    /// The parameter's name.
    pub name: String,
    /// Its value in the file's header.
    pub in_file: Option<Value>,
    /// Its value in the design under test.
    pub in_design: Option<Value>,
}

/// Everything reading or writing a vector file can refuse.
#[derive(Clone, Debug, PartialEq)]
pub enum VectorError {
    /// The file system refused (`action`: create, write, rename, open, read).
    Io {
        /// The file, or the directory the temporary file was to be created in.
        path: PathBuf,
        /// What failed: `create`, `write`, `rename`, `open` or `read`.
        action: &'static str,
        /// The underlying error's message.
        message: String,
    },
    /// Line `line` (1-based) has a bad `field` (a path like
    /// `in.placement[1]`); `expected` says what was wanted.
    Malformed {
        /// The vector file.
        path: PathBuf,
        /// 1-based line number; the header is line 1.
        line: usize,
        /// Path of the bad field, e.g. `in.placement[1]`; `<line>` or `<header>` for the whole line.
        field: String,
        /// What was wanted.
        expected: String,
    },
    /// The file was generated for a design with other parameters.
    ParamsDiffer {
        /// The vector file.
        path: PathBuf,
        /// Every parameter that differs, in name order.
        diffs: Vec<ParamDiff>,
    },
    /// The golden model refused a transaction while generating (a bug in
    /// the generator), or the records given to [`write_jsonl`] are not as
    /// many as its header's `count`.
    Model {
        /// What the model refused, and why.
        what: String,
    },
}

impl fmt::Display for VectorError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            VectorError::Io {
                path,
                action,
                message,
            } => write!(f, "{}: cannot {action}: {message}", path.display()),
            VectorError::Malformed {
                path,
                line,
                field,
                expected,
            } => write!(
                f,
                "{}:{line}: field `{field}`: expected {expected}",
                path.display()
            ),
            VectorError::ParamsDiffer { path, diffs } => {
                write!(
                    f,
                    "{}: vectors were generated for other parameters than the design under test:",
                    path.display()
                )?;
                let show = |v: &Option<Value>| match v {
                    Some(v) => v.to_string(),
                    None => "absent".to_string(),
                };
                for d in diffs {
                    write!(
                        f,
                        " `{}` is {} in the file, {} in the design;",
                        d.name,
                        show(&d.in_file),
                        show(&d.in_design)
                    )?;
                }
                Ok(())
            }
            VectorError::Model { what } => write!(f, "vector generation: {what}"),
        }
    }
}

impl std::error::Error for VectorError {}

fn io_error(path: &Path, action: &'static str, e: impl fmt::Display) -> VectorError {
    VectorError::Io {
        path: path.to_path_buf(),
        action,
        message: e.to_string(),
    }
}

/// Writes `header` and `records` to `path` atomically: into a temporary
/// file in the same directory, renamed over `path` only after the last
/// record was written and flushed. When a record is an error, or writing
/// fails, the temporary file is removed and `path` is left as it was.
/// The header's `count` must equal the number of records.
pub fn write_jsonl<I>(path: &Path, header: &Header, records: I) -> Result<(), VectorError>
where
    I: IntoIterator<Item = Result<Value, VectorError>>,
{
    let fail = |action: &'static str| {
        move |message: String| VectorError::Io {
            path: path.to_path_buf(),
            action,
            message,
        }
    };
    let mut out = crate::output::AtomicFile::create(path).map_err(fail("create"))?;
    let mut w = BufWriter::new(out.file());
    let line = |v: &Value, w: &mut BufWriter<&mut std::fs::File>| {
        serde_json::to_writer(&mut *w, v)
            .map_err(|e| io_error(path, "write", e))
            .and_then(|_| w.write_all(b"\n").map_err(|e| io_error(path, "write", e)))
    };
    line(&header.to_json(), &mut w)?;
    let mut written = 0u64;
    let most = header.unit.max_line_bytes();
    let mut bytes = header.to_json().to_string().len() as u64 + 1;
    for r in records {
        let text = serde_json::to_string(&r?).map_err(|e| io_error(path, "write", e))?;
        if text.len() as u64 > most {
            return Err(VectorError::Model {
                what: format!(
                    "record {written} is {} bytes, above the {most} a reader takes (SPEC.md section 15)",
                    text.len()
                ),
            });
        }
        bytes += text.len() as u64 + 1;
        if bytes > MAX_FILE_BYTES {
            return Err(VectorError::Model {
                what: format!(
                    "record {written} takes the file past {MAX_FILE_BYTES} bytes, the most a reader takes (SPEC.md section 15): expected a smaller --count"
                ),
            });
        }
        w.write_all(text.as_bytes())
            .and_then(|_| w.write_all(b"\n"))
            .map_err(|e| io_error(path, "write", e))?;
        written += 1;
    }
    if written != header.count {
        return Err(VectorError::Model {
            what: format!(
                "header count {} but {written} records were produced",
                header.count
            ),
        });
    }
    w.flush().map_err(|e| io_error(path, "write", e))?;
    drop(w);
    out.commit().map_err(fail("rename"))
}

/// A vector file read back: the header and every record line as JSON, with
/// its 1-based line number.
#[derive(Clone, Debug)]
pub struct RawVectors {
    /// The file read.
    pub path: PathBuf,
    /// Its header, already checked against the design's parameters.
    pub header: Header,
    /// Each record line's 1-based number and its JSON object, in file order.
    pub records: Vec<(usize, Value)>,
}

/// Reads `path`: checks the header (format, version, `unit`, every
/// parameter against `design_params`, seed, count) and parses each record
/// line as a JSON object. The record schema is the caller's
/// ([`translate::read_translate_vectors`]).
pub fn read_jsonl(
    path: &Path,
    unit: UnitKind,
    design_params: &ParamMap,
) -> Result<RawVectors, VectorError> {
    let input = |e: crate::input::InputError| VectorError::Io {
        path: path.to_path_buf(),
        action: "read",
        message: format!("expected {}, found {}", e.expected, e.found),
    };
    let mut lines = crate::input::open_lines(path, MAX_FILE_BYTES)
        .map_err(input)?
        .with_line_limit(unit.max_line_bytes());
    let first = match lines.next_line() {
        Some(l) => l.map_err(input)?.1,
        None => {
            return Err(malformed(
                path,
                1,
                "header",
                "a header line (the file is empty)",
            ));
        }
    };
    let header = parse_header(path, &first, unit)?;
    if header.count > unit.max_count() {
        return Err(malformed(
            path,
            1,
            "count",
            &format!(
                "at most {} records (SPEC.md section 15), found {}",
                unit.max_count(),
                header.count
            ),
        ));
    }
    let diffs = param_diffs(&header.params, design_params);
    if !diffs.is_empty() {
        return Err(VectorError::ParamsDiffer {
            path: path.to_path_buf(),
            diffs,
        });
    }
    let mut records = Vec::new();
    while let Some(l) = lines.next_line() {
        let (n, text) = l.map_err(input)?;
        let n = n as usize;
        if records.len() as u64 == header.count {
            return Err(malformed(
                path,
                n,
                "<line>",
                &format!(
                    "the end of the file after the {} records the header counts",
                    header.count
                ),
            ));
        }
        let v: Value = serde_json::from_str(&text).map_err(|e| {
            malformed(
                path,
                n,
                "<line>",
                &format!("one JSON object per line ({e})"),
            )
        })?;
        if !v.is_object() {
            return Err(malformed(path, n, "<line>", "a JSON object"));
        }
        records.push((n, v));
    }
    if records.len() as u64 != header.count {
        return Err(malformed(
            path,
            records.len() + 1,
            "count",
            &format!(
                "{} record lines as the header says, found {}",
                header.count,
                records.len()
            ),
        ));
    }
    Ok(RawVectors {
        path: path.to_path_buf(),
        header,
        records,
    })
}

/// Parameters that differ between a file and a design, in name order.
pub fn param_diffs(in_file: &ParamMap, in_design: &ParamMap) -> Vec<ParamDiff> {
    let mut names: Vec<&String> = in_file.keys().chain(in_design.keys()).collect();
    names.sort();
    names.dedup();
    names
        .into_iter()
        .filter(|n| in_file.get(*n) != in_design.get(*n))
        .map(|n| ParamDiff {
            name: n.clone(),
            in_file: in_file.get(n).cloned(),
            in_design: in_design.get(n).cloned(),
        })
        .collect()
}

fn malformed(path: &Path, line: usize, field: &str, expected: &str) -> VectorError {
    VectorError::Malformed {
        path: path.to_path_buf(),
        line,
        field: field.to_string(),
        expected: expected.to_string(),
    }
}

fn parse_header(path: &Path, text: &str, unit: UnitKind) -> Result<Header, VectorError> {
    let v: Value = serde_json::from_str(text)
        .map_err(|e| malformed(path, 1, "<header>", &format!("a JSON object ({e})")))?;
    let f = Fields::root(path, 1, &v)?;
    let format = f.string("format")?;
    if format != FORMAT_NAME {
        return Err(malformed(path, 1, "format", &format!("\"{FORMAT_NAME}\"")));
    }
    let version = f.uint("version", 64)?;
    if version != FORMAT_VERSION {
        return Err(malformed(path, 1, "version", &format!("{FORMAT_VERSION}")));
    }
    let unit_name = f.string("unit")?;
    match UnitKind::from_name(unit_name) {
        Some(u) if u == unit => {}
        _ => {
            return Err(malformed(
                path,
                1,
                "unit",
                &format!("\"{}\" (the design under test)", unit.name()),
            ))
        }
    }
    let params = match f.get("params")? {
        Value::Object(m) => m.iter().map(|(k, v)| (k.clone(), v.clone())).collect(),
        _ => return Err(f.bad("params", "an object of parameters")),
    };
    Ok(Header {
        unit,
        params,
        seed: f.uint("seed", 64)?,
        count: f.uint("count", 64)?,
    })
}

/// A JSON object being decoded, remembering where it came from so that
/// every error names file, line and field path.
#[derive(Clone)]
pub struct Fields<'a> {
    path: &'a Path,
    line: usize,
    prefix: String,
    obj: &'a Map<String, Value>,
}

impl<'a> Fields<'a> {
    /// The top-level object of line `line`.
    pub fn root(path: &'a Path, line: usize, v: &'a Value) -> Result<Fields<'a>, VectorError> {
        match v {
            Value::Object(obj) => Ok(Fields {
                path,
                line,
                prefix: String::new(),
                obj,
            }),
            _ => Err(malformed(path, line, "<line>", "a JSON object")),
        }
    }

    fn name(&self, key: &str) -> String {
        if self.prefix.is_empty() {
            key.to_string()
        } else {
            format!("{}.{key}", self.prefix)
        }
    }

    /// An error about field `key` of this object.
    pub fn bad(&self, key: &str, expected: &str) -> VectorError {
        malformed(self.path, self.line, &self.name(key), expected)
    }

    /// The value of `key` (absent: an error).
    pub fn get(&self, key: &str) -> Result<&'a Value, VectorError> {
        self.obj
            .get(key)
            .ok_or_else(|| self.bad(key, "a value (missing)"))
    }

    /// A string field.
    pub fn string(&self, key: &str) -> Result<&'a str, VectorError> {
        self.get(key)?
            .as_str()
            .ok_or_else(|| self.bad(key, "a string"))
    }

    /// An unsigned integer field of at most `width` (<= 64) bits.
    pub fn uint(&self, key: &str, width: u32) -> Result<u64, VectorError> {
        uint_of(self.get(key)?, width).ok_or_else(|| self.bad(key, &uint_expected(width)))
    }

    /// An array of exactly `N` unsigned integers of at most `width` bits.
    pub fn uints<const N: usize>(&self, key: &str, width: u32) -> Result<[u64; N], VectorError> {
        let expected = format!("an array of {N} integers of {width} bits");
        let arr = self
            .get(key)?
            .as_array()
            .filter(|a| a.len() == N)
            .ok_or_else(|| self.bad(key, &expected))?;
        let mut out = [0u64; N];
        for (i, v) in arr.iter().enumerate() {
            out[i] = uint_of(v, width)
                .ok_or_else(|| self.bad(&format!("{key}[{i}]"), &uint_expected(width)))?;
        }
        Ok(out)
    }

    /// A bit field wider than 64 bits, written as a hex string: its words,
    /// least significant first.
    pub fn wide(&self, key: &str, width: u32) -> Result<Vec<u64>, VectorError> {
        let expected = format!(
            "a hex string \"0x\" + {} digits ({width} bits)",
            width.div_ceil(4)
        );
        let s = self.string(key).map_err(|_| self.bad(key, &expected))?;
        wide_from_hex(s, width).ok_or_else(|| self.bad(key, &expected))
    }

    /// The keys of this object, in file order.
    pub fn keys(&self) -> impl Iterator<Item = &'a str> + 'a {
        self.obj.keys().map(String::as_str)
    }

    /// The length of the array field `key`.
    pub fn array_len(&self, key: &str) -> Result<usize, VectorError> {
        self.get(key)?
            .as_array()
            .map(Vec::len)
            .ok_or_else(|| self.bad(key, "an array"))
    }

    /// Element `i` of the array field `key`, an object, for decoding its
    /// own fields (named `key[i].field`).
    pub fn item(&self, key: &str, i: usize) -> Result<Fields<'a>, VectorError> {
        let at = format!("{key}[{i}]");
        match self.get(key)?.as_array().and_then(|a| a.get(i)) {
            Some(Value::Object(obj)) => Ok(Fields {
                path: self.path,
                line: self.line,
                prefix: self.name(&at),
                obj,
            }),
            _ => Err(self.bad(&at, "an object of fields")),
        }
    }

    /// The object field `key`, for decoding its own fields.
    pub fn object(&self, key: &str) -> Result<Fields<'a>, VectorError> {
        match self.obj.get(key) {
            Some(Value::Object(obj)) => Ok(Fields {
                path: self.path,
                line: self.line,
                prefix: self.name(key),
                obj,
            }),
            _ => Err(self.bad(key, "an object")),
        }
    }
}

fn uint_expected(width: u32) -> String {
    if width >= 64 {
        "an unsigned integer below 2^64".to_string()
    } else {
        format!(
            "an unsigned integer of {width} bits (0..={})",
            (1u64 << width) - 1
        )
    }
}

fn uint_of(v: &Value, width: u32) -> Option<u64> {
    let n = v.as_u64()?;
    (width >= 64 || n >> width == 0).then_some(n)
}

/// A field wider than 64 bits as its JSON form: `"0x"` and `ceil(width / 4)`
/// hex digits, most significant first (`words` least significant first).
pub fn wide_to_json(words: &[u64], width: u32) -> Value {
    let digits = width.div_ceil(4) as usize;
    let mut s = String::with_capacity(digits + 2);
    s.push_str("0x");
    for d in (0..digits).rev() {
        let bit = d * 4;
        let word = words.get(bit / 64).copied().unwrap_or(0);
        let nibble = (word >> (bit % 64)) & 0xf;
        s.push(char::from_digit(nibble as u32, 16).expect("a nibble"));
    }
    Value::String(s)
}

/// Parses [`wide_to_json`]'s form; `None` for a wrong digit count, a
/// non-hex digit or bits at or above `width`.
pub fn wide_from_hex(s: &str, width: u32) -> Option<Vec<u64>> {
    let digits = s.strip_prefix("0x")?;
    if digits.len() != width.div_ceil(4) as usize {
        return None;
    }
    let mut words = vec![0u64; width.div_ceil(64) as usize];
    for (i, c) in digits.chars().rev().enumerate() {
        let v = c.to_digit(16)? as u64;
        let bit = i * 4;
        words[bit / 64] |= v << (bit % 64);
    }
    let rem = width % 64;
    if rem != 0 && words.last().is_some_and(|w| w >> rem != 0) {
        return None;
    }
    Some(words)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wide_hex_round_trips_and_refuses_overflow() {
        let words = [0x0123_4567_89ab_cdef, 0x5];
        let v = wide_to_json(&words, 67);
        assert_eq!(v, Value::String("0x50123456789abcdef".into()));
        assert_eq!(wide_from_hex(v.as_str().unwrap(), 67), Some(words.to_vec()));
        // 67 bits: the top digit holds 3 bits, so 8 does not fit.
        assert_eq!(wide_from_hex("0x80123456789abcdef", 67), None);
        assert_eq!(wide_from_hex("0x0123456789abcdef", 67), None);
        assert_eq!(wide_from_hex("0x5012345678gabcdef", 67), None);
    }

    #[test]
    fn param_diffs_name_each_differing_parameter() {
        let a: ParamMap = [
            ("max_lod".to_string(), Value::from(16)),
            ("q".into(), 8.into()),
        ]
        .into_iter()
        .collect();
        let b: ParamMap = [
            ("max_lod".to_string(), Value::from(31)),
            ("h".into(), 4.into()),
        ]
        .into_iter()
        .collect();
        let d = param_diffs(&a, &b);
        let names: Vec<&str> = d.iter().map(|d| d.name.as_str()).collect();
        assert_eq!(names, ["h", "max_lod", "q"]);
        assert!(param_diffs(&a, &a).is_empty());
    }
}
