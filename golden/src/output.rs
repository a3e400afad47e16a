//! The one way output files and folders are written (SPEC.md section 15):
//! atomically, with ordinary permissions, never over a symbolic link or a
//! special file, and without a temporary left behind by an interrupted run.
//!
//! A file ([`AtomicFile`], [`write_atomic`]) is written into a temporary
//! file beside its destination, created with mode `0666` less the umask
//! (as any program's output), synced and renamed over the destination only
//! when complete. A folder ([`AtomicDir`]) is filled as a fresh temporary
//! folder beside it and swapped in only when complete, so that the previous
//! output stays whole until then. Every temporary is registered while it
//! exists; [`remove_temporaries`] removes them, for a signal handler (the
//! CLI's, on SIGINT and SIGTERM) to call before the process ends.

use std::fs::Permissions;
use std::io::Write;
use std::os::unix::fs::PermissionsExt;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// Temporaries in existence, files and folders.
static TEMPORARIES: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn register(p: &Path) {
    if let Ok(mut t) = TEMPORARIES.lock() {
        t.push(p.to_path_buf());
    }
}

fn unregister(p: &Path) {
    if let Ok(mut t) = TEMPORARIES.lock() {
        t.retain(|q| q != p);
    }
}

/// Removes every registered temporary file and folder (for a handler of
/// SIGINT/SIGTERM, just before the process ends).
pub fn remove_temporaries() {
    remove_registered(|_| true)
}

/// Removes the registered temporaries `which` selects.
fn remove_registered(which: impl Fn(&Path) -> bool) {
    let list = match TEMPORARIES.lock() {
        Ok(mut t) => {
            let (gone, kept) = t.drain(..).partition(|p| which(p));
            *t = kept;
            gone
        }
        Err(_) => return,
    };
    let list: Vec<PathBuf> = list;
    for p in list {
        match std::fs::symlink_metadata(&p) {
            Ok(m) if m.is_dir() => {
                // A writer may still be adding a file: try again.
                for _ in 0..3 {
                    if std::fs::remove_dir_all(&p).is_ok() {
                        break;
                    }
                }
            }
            Ok(_) => {
                let _ = std::fs::remove_file(&p);
            }
            Err(_) => {}
        }
    }
}

/// The folder a destination's temporary goes in: its parent, or `.`.
fn parent_of(dest: &Path) -> &Path {
    dest.parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
}

/// Refuses a destination that exists and is not what would be written: a
/// symbolic link (writing would replace the link, not what it points at),
/// a device, FIFO or socket, or a file where a folder goes and the other
/// way round. A missing destination is fine.
pub fn check_destination(dest: &Path, folder: bool) -> Result<(), String> {
    let meta = match std::fs::symlink_metadata(dest) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => {
            return Err(format!(
                "{}: cannot inspect the output: {e}",
                dest.display()
            ))
        }
    };
    let t = meta.file_type();
    let what = if t.is_symlink() {
        "a symbolic link (the output would replace the link, not go where it points)"
    } else if folder && t.is_dir() || !folder && t.is_file() {
        return Ok(());
    } else if t.is_dir() {
        "a folder"
    } else if t.is_file() {
        "a regular file"
    } else {
        "a special file (device, FIFO or socket)"
    };
    Err(format!(
        "{}: refusing to write the output over {what}; expected {} or nothing there",
        dest.display(),
        if folder { "a folder" } else { "a regular file" }
    ))
}

/// A file being written; it replaces its destination only on [`AtomicFile::commit`].
pub struct AtomicFile {
    tmp: Option<tempfile::NamedTempFile>,
    dest: PathBuf,
}

impl AtomicFile {
    /// Starts writing `dest` (refused as [`check_destination`] says).
    pub fn create(dest: &Path) -> Result<AtomicFile, String> {
        check_destination(dest, false)?;
        let dir = parent_of(dest);
        // The destination's extension too, for a writer that picks its
        // format by the file name (a simulator's waveform).
        let suffix = dest
            .extension()
            .map(|e| format!(".{}", e.to_string_lossy()))
            .unwrap_or_default();
        let tmp = tempfile::Builder::new()
            .prefix(".hiermerge-")
            .suffix(&suffix)
            .permissions(Permissions::from_mode(0o666))
            .tempfile_in(dir)
            .map_err(|e| format!("{}: cannot create a temporary file: {e}", dir.display()))?;
        register(tmp.path());
        Ok(AtomicFile {
            tmp: Some(tmp),
            dest: dest.to_path_buf(),
        })
    }

    /// The temporary file's path, for a writer that opens the file itself
    /// (a simulator writing a waveform); it is written in place, not replaced.
    pub fn path(&self) -> &Path {
        self.tmp.as_ref().expect("not committed").path()
    }

    /// The temporary file, to write into.
    pub fn file(&mut self) -> &mut std::fs::File {
        self.tmp.as_mut().expect("not committed").as_file_mut()
    }

    /// Syncs the file and renames it over the destination.
    pub fn commit(mut self) -> Result<(), String> {
        let tmp = self.tmp.take().expect("not committed");
        let dest = &self.dest;
        let at = |e: std::io::Error| format!("{}: {e}", dest.display());
        tmp.as_file().sync_all().map_err(at)?;
        check_destination(dest, false)?;
        let tmp_path = tmp.path().to_path_buf();
        let persisted = tmp
            .persist(dest)
            .map_err(|e| format!("{}: {}", dest.display(), e.error));
        unregister(&tmp_path);
        persisted.map(|_| ())
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if let Some(t) = &self.tmp {
            unregister(t.path());
        }
    }
}

/// Writes `bytes` to `dest` atomically ([`AtomicFile`]).
pub fn write_atomic(dest: &Path, bytes: &[u8]) -> Result<(), String> {
    let mut f = AtomicFile::create(dest)?;
    f.file()
        .write_all(bytes)
        .map_err(|e| format!("{}: {e}", dest.display()))?;
    f.commit()
}

/// A folder being filled; it replaces its destination (and everything in
/// it) only on [`AtomicDir::commit`], so an interrupted run leaves the
/// previous output as it was.
pub struct AtomicDir {
    tmp: Option<tempfile::TempDir>,
    dest: PathBuf,
}

impl AtomicDir {
    /// Starts a fresh folder for `dest` (created with its parents; a
    /// destination that is a symbolic link, a file or a special file is
    /// refused).
    pub fn create(dest: &Path) -> Result<AtomicDir, String> {
        check_destination(dest, true)?;
        let dir = parent_of(dest);
        std::fs::create_dir_all(dir)
            .map_err(|e| format!("{}: cannot create the output folder: {e}", dir.display()))?;
        let tmp = tempfile::Builder::new()
            .prefix(".hiermerge-")
            .permissions(Permissions::from_mode(0o777))
            .tempdir_in(dir)
            .map_err(|e| format!("{}: cannot create a temporary folder: {e}", dir.display()))?;
        register(tmp.path());
        Ok(AtomicDir {
            tmp: Some(tmp),
            dest: dest.to_path_buf(),
        })
    }

    /// The temporary folder, to write into.
    pub fn path(&self) -> &Path {
        self.tmp.as_ref().expect("not committed").path()
    }

    /// Puts the folder in place of the destination: the old folder is moved
    /// aside, the new one renamed to its name, then the old one removed.
    pub fn commit(mut self) -> Result<(), String> {
        let tmp = self.tmp.take().expect("not committed");
        let at = |e: std::io::Error| format!("{}: {e}", self.dest.display());
        check_destination(&self.dest, true)?;
        let new = tmp.keep();
        let old = match self.dest.exists() {
            true => {
                let aside = tempfile::Builder::new()
                    .prefix(".hiermerge-old-")
                    .tempdir_in(parent_of(&self.dest))
                    .map_err(at)?
                    .keep();
                register(&aside);
                std::fs::rename(&self.dest, &aside).map_err(at)?;
                Some(aside)
            }
            false => None,
        };
        let moved = std::fs::rename(&new, &self.dest).map_err(at);
        unregister(&new);
        if let Err(e) = moved {
            // Put the old output back.
            if let Some(old) = &old {
                let _ = std::fs::rename(old, &self.dest);
            }
            let _ = std::fs::remove_dir_all(&new);
            return Err(e);
        }
        if let Some(old) = old {
            let _ = std::fs::remove_dir_all(&old);
            unregister(&old);
        }
        Ok(())
    }
}

impl Drop for AtomicDir {
    fn drop(&mut self) {
        if let Some(t) = &self.tmp {
            unregister(t.path());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn umask() -> u32 {
        // The mode a plain file gets here, less the bits of 0666.
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("plain");
        std::fs::write(&p, b"").unwrap();
        std::fs::metadata(&p).unwrap().permissions().mode() & 0o777
    }

    #[test]
    fn a_file_is_replaced_whole_with_ordinary_permissions() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("out.json");
        write_atomic(&p, b"one").unwrap();
        write_atomic(&p, b"two").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"two");
        let mode = std::fs::metadata(&p).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, umask());
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn a_symlink_or_special_file_is_refused_and_left_alone() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("target");
        std::fs::write(&target, b"keep").unwrap();
        let link = dir.path().join("link");
        std::os::unix::fs::symlink(&target, &link).unwrap();
        let e = write_atomic(&link, b"x").unwrap_err();
        assert!(e.contains("symbolic link"), "{e}");
        let e = write_atomic(Path::new("/dev/null"), b"x").unwrap_err();
        assert!(e.contains("special file"), "{e}");
        let e = AtomicDir::create(&target).err().unwrap();
        assert!(e.contains("regular file"), "{e}");
        assert_eq!(std::fs::read(&target).unwrap(), b"keep");
    }

    #[test]
    fn a_folder_replaces_the_old_only_when_committed() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("run");
        std::fs::create_dir(&out).unwrap();
        std::fs::write(out.join("old.txt"), b"old").unwrap();
        let d = AtomicDir::create(&out).unwrap();
        std::fs::write(d.path().join("new.txt"), b"new").unwrap();
        drop(d);
        // Abandoned: the old output is intact and no temporary stays.
        assert!(out.join("old.txt").exists());
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        let d = AtomicDir::create(&out).unwrap();
        std::fs::write(d.path().join("new.txt"), b"new").unwrap();
        d.commit().unwrap();
        assert!(!out.join("old.txt").exists());
        assert!(out.join("new.txt").exists());
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn registered_temporaries_are_removed() {
        let dir = tempfile::tempdir().unwrap();
        let mut f = AtomicFile::create(&dir.path().join("v.jsonl")).unwrap();
        f.file().write_all(b"partial").unwrap();
        let d = AtomicDir::create(&dir.path().join("run")).unwrap();
        // Only this test's: tests of one process run side by side.
        remove_registered(|p| p.starts_with(dir.path()));
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
        drop((f, d));
    }
}
