//! Content-addressed build cache shared by tests, benches and the CLI.
//!
//! An entry is a directory named by a SHA-256 over everything that can change
//! the build output (sources, tool version, flags, generator version), never
//! by timestamps. Builders work in a private temporary directory under an
//! exclusive file lock and publish with one atomic `rename`, so a directory
//! that exists under its final name is complete, and a hit needs no lock.

use crate::error::{io_err, CosimError, Result};
use fs2::FileExt;
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Marker file written last into an entry before it is published.
const READY_MARKER: &str = "READY";

static BUILDS_IN_PROCESS: AtomicU64 = AtomicU64::new(0);

/// How many cache entries this process has built (not loaded) so far.
pub fn builds_in_this_process() -> u64 {
    BUILDS_IN_PROCESS.load(Ordering::SeqCst)
}

/// Accumulates the inputs of a build into a cache key.
pub struct CacheKey {
    hasher: Sha256,
}

impl Default for CacheKey {
    fn default() -> Self {
        CacheKey::new()
    }
}

impl CacheKey {
    /// An empty key.
    pub fn new() -> CacheKey {
        CacheKey {
            hasher: Sha256::new(),
        }
    }

    /// Add a named field. Names and values are length-prefixed so that
    /// ("ab", "c") and ("a", "bc") hash differently.
    pub fn add(&mut self, name: &str, value: &[u8]) -> &mut CacheKey {
        for part in [name.as_bytes(), value] {
            self.hasher.update((part.len() as u64).to_le_bytes());
            self.hasher.update(part);
        }
        self
    }

    /// The key as 64 hex digits.
    pub fn finish(self) -> String {
        self.hasher
            .finalize()
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect()
    }
}

/// The cache root: `$HIERMERGE_CACHE`, else `<cargo target dir>/cosim-cache`.
///
/// The target dir is `$CARGO_TARGET_DIR`, else the nearest ancestor of the
/// running executable holding cargo's `CACHEDIR.TAG`, else `target/` next to
/// the nearest `Cargo.lock` above the working directory, else the system temp dir.
pub fn cache_root() -> PathBuf {
    if let Some(dir) = std::env::var_os("HIERMERGE_CACHE").filter(|v| !v.is_empty()) {
        return PathBuf::from(dir);
    }
    target_dir()
        .unwrap_or_else(|| std::env::temp_dir().join("hiermerge"))
        .join("cosim-cache")
}

fn target_dir() -> Option<PathBuf> {
    if let Some(dir) = std::env::var_os("CARGO_TARGET_DIR").filter(|v| !v.is_empty()) {
        let dir = PathBuf::from(dir);
        return Some(if dir.is_absolute() {
            dir
        } else {
            std::env::current_dir().ok()?.join(dir)
        });
    }
    if let Ok(exe) = std::env::current_exe() {
        if let Some(found) = exe.ancestors().find(|a| a.join("CACHEDIR.TAG").is_file()) {
            return Some(found.to_path_buf());
        }
    }
    let cwd = std::env::current_dir().ok()?;
    cwd.ancestors()
        .find(|a| a.join("Cargo.lock").is_file())
        .map(|a| a.join("target"))
}

/// One cache entry, found or freshly built.
#[derive(Clone, Debug)]
pub struct CacheEntry {
    /// The published entry directory.
    pub dir: PathBuf,
    /// True when this call built it; false when it was already there.
    pub built: bool,
}

/// The entry `kind/label-key` under `root`, building it with `build` (which
/// fills the directory it is given) when absent. Concurrent callers for the
/// same key wait on a file lock; only one builds.
pub fn get_or_build(
    root: &Path,
    kind: &str,
    label: &str,
    key: &str,
    build: impl FnOnce(&Path) -> Result<()>,
) -> Result<CacheEntry> {
    let short = &key[..key.len().min(24)];
    let dir = root.join(kind).join(format!("{label}-{short}"));
    if dir.join(READY_MARKER).is_file() {
        return Ok(CacheEntry { dir, built: false });
    }
    let locks = root.join("locks");
    std::fs::create_dir_all(&locks).map_err(io_err(&locks))?;
    let lock_path = locks.join(format!("{kind}-{short}.lock"));
    let lock = std::fs::OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .open(&lock_path)
        .map_err(io_err(&lock_path))?;
    lock.lock_exclusive().map_err(io_err(&lock_path))?;
    let result = build_locked(root, &dir, short, build);
    let _ = lock.unlock();
    result
}

fn build_locked(
    root: &Path,
    dir: &Path,
    short: &str,
    build: impl FnOnce(&Path) -> Result<()>,
) -> Result<CacheEntry> {
    if dir.join(READY_MARKER).is_file() {
        return Ok(CacheEntry {
            dir: dir.to_path_buf(),
            built: false,
        });
    }
    let tmp_parent = root.join("tmp");
    std::fs::create_dir_all(&tmp_parent).map_err(io_err(&tmp_parent))?;
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos())
        .unwrap_or(0);
    let tmp = tmp_parent.join(format!("{short}-{}-{nanos}", std::process::id()));
    std::fs::create_dir_all(&tmp).map_err(io_err(&tmp))?;
    if let Err(e) = build(&tmp) {
        // Keep the failed build directory's logs out of the way but inspectable.
        let failed = tmp_parent.join(format!("failed-{short}"));
        let _ = std::fs::remove_dir_all(&failed);
        let _ = std::fs::rename(&tmp, &failed);
        return Err(e);
    }
    let marker = tmp.join(READY_MARKER);
    std::fs::write(&marker, b"ok\n").map_err(io_err(&marker))?;
    if let Some(parent) = dir.parent() {
        std::fs::create_dir_all(parent).map_err(io_err(parent))?;
    }
    if dir.exists() {
        // A stale, unmarked directory from a crashed build: replace it.
        std::fs::remove_dir_all(dir).map_err(io_err(dir))?;
    }
    std::fs::rename(&tmp, dir).map_err(io_err(dir))?;
    BUILDS_IN_PROCESS.fetch_add(1, Ordering::SeqCst);
    Ok(CacheEntry {
        dir: dir.to_path_buf(),
        built: true,
    })
}

/// What the cache holds.
#[derive(Clone, Debug)]
pub struct CacheReport {
    /// The cache root.
    pub root: PathBuf,
    /// Published entries (directories holding the ready marker).
    pub entries: Vec<PathBuf>,
    /// Bytes used by everything under the root.
    pub total_bytes: u64,
}

impl std::fmt::Display for CacheReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(
            f,
            "cosim cache {}: {} entries, {:.1} MiB",
            self.root.display(),
            self.entries.len(),
            self.total_bytes as f64 / (1024.0 * 1024.0)
        )?;
        for e in &self.entries {
            writeln!(f, "  {}", e.display())?;
        }
        Ok(())
    }
}

fn dir_bytes(path: &Path) -> u64 {
    let Ok(rd) = std::fs::read_dir(path) else {
        return 0;
    };
    rd.flatten()
        .map(|e| match e.file_type() {
            Ok(t) if t.is_dir() => dir_bytes(&e.path()),
            _ => e.metadata().map(|m| m.len()).unwrap_or(0),
        })
        .sum()
}

/// List the entries and size of the cache at `root`.
pub fn cache_report(root: &Path) -> CacheReport {
    let mut entries = Vec::new();
    if let Ok(kinds) = std::fs::read_dir(root) {
        for kind in kinds.flatten() {
            if let Ok(items) = std::fs::read_dir(kind.path()) {
                for item in items.flatten() {
                    if item.path().join(READY_MARKER).is_file() {
                        entries.push(item.path());
                    }
                }
            }
        }
    }
    entries.sort();
    CacheReport {
        root: root.to_path_buf(),
        entries,
        total_bytes: dir_bytes(root),
    }
}

/// Delete the whole cache at `root` (a missing root is not an error).
pub fn clear_cache(root: &Path) -> Result<()> {
    match std::fs::remove_dir_all(root) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
        Err(source) => Err(CosimError::Io {
            path: root.to_path_buf(),
            source,
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn key_fields_are_separated() {
        let mut a = CacheKey::new();
        a.add("ab", b"c");
        let mut b = CacheKey::new();
        b.add("a", b"bc");
        assert_ne!(a.finish(), b.finish());
    }

    #[test]
    fn second_call_is_a_hit_and_failed_builds_publish_nothing() {
        let root = tempfile::tempdir().unwrap();
        let e1 = get_or_build(root.path(), "k", "x", "00ff", |d| {
            std::fs::write(d.join("f"), b"1").map_err(io_err(d))
        })
        .unwrap();
        assert!(e1.built);
        let e2 = get_or_build(root.path(), "k", "x", "00ff", |_| {
            panic!("must not rebuild")
        })
        .unwrap();
        assert!(!e2.built);
        assert_eq!(std::fs::read(e2.dir.join("f")).unwrap(), b"1");
        let bad = get_or_build(root.path(), "k", "y", "0100", |_| {
            Err(CosimError::Protocol { what: "no".into() })
        });
        assert!(bad.is_err());
        assert_eq!(cache_report(root.path()).entries.len(), 1);
        clear_cache(root.path()).unwrap();
        assert!(!root.path().exists());
    }
}
