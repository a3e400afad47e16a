//! The one way input files are read (SPEC.md section 15): only a regular
//! file (after following symbolic links), never more than a stated number
//! of bytes, so that a device (`/dev/zero`), a FIFO or a huge file gives
//! an error at once instead of a hang or a growing allocation.
//!
//! Whole-file readers ([`read_bytes`], [`read_text`]) serve meshes, scene
//! files, ledger entries and plans; [`open_lines`] streams a file line by
//! line with a bound on each line (vector files).

use std::fmt;
use std::fs::File;
use std::io::{BufRead, BufReader, Read};
use std::path::Path;

/// The most bytes a mesh file may have (256 MiB).
pub const MAX_MESH_BYTES: u64 = 256 << 20;
/// The most bytes a JSON document (scene file, ledger entry, plan) may have (16 MiB).
pub const MAX_JSON_BYTES: u64 = 16 << 20;
/// The most bytes one line of a streamed file (a vector record) may have (1 MiB).
pub const MAX_LINE_BYTES: u64 = 1 << 20;
/// The most bytes one record of a multi-stream unit's vector file (every
/// beat of one merge) may have (64 MiB): a per-node merge of the largest
/// grids runs to a few MB.
pub const MAX_MERGE_LINE_BYTES: u64 = 64 << 20;

/// A file that cannot be read as input: `expected` says what was wanted,
/// `found` what the file is.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct InputError {
    /// The file, as given.
    pub file: String,
    /// What the file should have been.
    pub expected: String,
    /// What it is, or the system's reason.
    pub found: String,
}

impl fmt::Display for InputError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}: expected {}, found {}",
            self.file, self.expected, self.found
        )
    }
}

impl std::error::Error for InputError {}

fn error(path: &Path, expected: impl Into<String>, found: impl Into<String>) -> InputError {
    InputError {
        file: path.display().to_string(),
        expected: expected.into(),
        found: found.into(),
    }
}

/// What kind of file `meta` describes, for an error message.
fn kind(meta: &std::fs::Metadata) -> &'static str {
    use std::os::unix::fs::FileTypeExt;
    let t = meta.file_type();
    if t.is_dir() {
        "a directory"
    } else if t.is_fifo() {
        "a FIFO (named pipe)"
    } else if t.is_char_device() {
        "a character device"
    } else if t.is_block_device() {
        "a block device"
    } else if t.is_socket() {
        "a socket"
    } else {
        "a special file"
    }
}

/// Opens `path` when it is a regular file of at most `limit` bytes. The
/// type is checked before opening, since opening a FIFO blocks until a
/// writer comes, and again on the open file.
pub fn open_regular(path: &Path, limit: u64) -> Result<File, InputError> {
    let readable = "a readable regular file";
    let meta = std::fs::metadata(path).map_err(|e| error(path, readable, e.to_string()))?;
    if !meta.is_file() {
        return Err(error(path, "a regular file", kind(&meta)));
    }
    let file = File::open(path).map_err(|e| error(path, readable, e.to_string()))?;
    let meta = file
        .metadata()
        .map_err(|e| error(path, readable, e.to_string()))?;
    if !meta.is_file() {
        return Err(error(path, "a regular file", kind(&meta)));
    }
    if meta.len() > limit {
        return Err(too_large(path, limit, meta.len()));
    }
    Ok(file)
}

fn too_large(path: &Path, limit: u64, len: u64) -> InputError {
    error(
        path,
        format!("a file of at most {limit} bytes (SPEC.md section 15)"),
        format!("{len} bytes"),
    )
}

/// Reads a whole regular file of at most `limit` bytes. A file that grows
/// past the limit while being read is refused too.
pub fn read_bytes(path: &Path, limit: u64) -> Result<Vec<u8>, InputError> {
    let file = open_regular(path, limit)?;
    let mut bytes = Vec::new();
    file.take(limit + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| error(path, "a readable regular file", e.to_string()))?;
    if bytes.len() as u64 > limit {
        return Err(too_large(path, limit, bytes.len() as u64));
    }
    Ok(bytes)
}

/// [`read_bytes`] as UTF-8 text.
pub fn read_text(path: &Path, limit: u64) -> Result<String, InputError> {
    let bytes = read_bytes(path, limit)?;
    String::from_utf8(bytes).map_err(|e| {
        error(
            path,
            "UTF-8 text",
            format!(
                "a byte that is not UTF-8 at offset {}",
                e.utf8_error().valid_up_to()
            ),
        )
    })
}

/// A regular file read line by line, each line at most [`MAX_LINE_BYTES`]
/// (or the limit [`Lines::with_line_limit`] sets).
pub struct Lines {
    reader: BufReader<File>,
    path: std::path::PathBuf,
    line: u64,
    line_limit: u64,
}

/// Opens `path` (a regular file of any size up to `limit`) for [`Lines`].
pub fn open_lines(path: &Path, limit: u64) -> Result<Lines, InputError> {
    Ok(Lines {
        reader: BufReader::new(open_regular(path, limit)?),
        path: path.to_path_buf(),
        line: 0,
        line_limit: MAX_LINE_BYTES,
    })
}

impl Lines {
    /// These lines with at most `bytes` bytes each.
    pub fn with_line_limit(self, bytes: u64) -> Lines {
        Lines {
            line_limit: bytes,
            ..self
        }
    }

    /// The next line without its `\n`, with its 1-based number; `None` at
    /// the end. A line longer than the limit or not UTF-8 is an error
    /// naming the line.
    pub fn next_line(&mut self) -> Option<Result<(u64, String), InputError>> {
        self.line += 1;
        let mut buf = Vec::new();
        let read = (&mut self.reader)
            .take(self.line_limit + 1)
            .read_until(b'\n', &mut buf);
        let n = match read {
            Ok(n) => n,
            Err(e) => return Some(Err(self.at("a readable line", e.to_string()))),
        };
        if n == 0 {
            return None;
        }
        if buf.last() == Some(&b'\n') {
            buf.pop();
        } else if buf.len() as u64 > self.line_limit {
            let limit = self.line_limit;
            let found = format!("more than {limit} bytes");
            return Some(Err(self.at(
                &format!("a line of at most {limit} bytes (SPEC.md section 15)"),
                found,
            )));
        }
        match String::from_utf8(buf) {
            Ok(s) => Some(Ok((self.line, s))),
            Err(_) => Some(Err(self.at("UTF-8 text", "a byte that is not UTF-8".into()))),
        }
    }

    fn at(&self, expected: &str, found: String) -> InputError {
        InputError {
            file: format!("{}:{}", self.path.display(), self.line),
            expected: expected.to_string(),
            found,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn devices_fifos_and_directories_are_refused_at_once() {
        let e = read_bytes(Path::new("/dev/zero"), 10).unwrap_err();
        assert!(e.to_string().contains("character device"), "{e}");
        let dir = tempfile::tempdir().unwrap();
        let e = read_bytes(dir.path(), 10).unwrap_err();
        assert!(e.to_string().contains("a directory"), "{e}");
        let fifo = dir.path().join("entry.json");
        let status = std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap();
        assert!(status.success());
        let e = read_text(&fifo, 10).unwrap_err();
        assert!(e.to_string().contains("FIFO"), "{e}");
    }

    #[test]
    fn a_file_past_the_limit_is_refused_naming_both_sizes() {
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("big.obj");
        std::fs::write(&f, [b'x'; 11]).unwrap();
        let e = read_bytes(&f, 10).unwrap_err();
        assert!(e.to_string().contains("at most 10 bytes"), "{e}");
        assert!(e.to_string().contains("11 bytes"), "{e}");
        assert_eq!(read_bytes(&f, 11).unwrap().len(), 11);
    }

    #[test]
    fn a_long_line_is_named_by_its_number() {
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("v.jsonl");
        let mut text = b"{}\n".to_vec();
        text.extend(std::iter::repeat_n(b'x', MAX_LINE_BYTES as usize + 5));
        std::fs::write(&f, text).unwrap();
        let mut lines = open_lines(&f, u64::MAX).unwrap();
        assert_eq!(lines.next_line().unwrap().unwrap(), (1, "{}".into()));
        let e = lines.next_line().unwrap().unwrap_err();
        assert!(e.file.ends_with(":2"), "{e}");
    }
}
