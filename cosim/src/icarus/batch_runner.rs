//! What both Icarus batch modes (`super::batch`, one beat sequence over
//! lanes; `super::multi_batch`, a driver per stream) do around their
//! generated testbench the same way: compile it once, give every run its own
//! directory, stream the per-cycle stall masks to vvp through a named pipe,
//! run vvp under a timeout, and read back the common records of `out.txt`
//! (`X`, `H`, `M`; see `super::batch_tb_frame`), a window VCD included.

use crate::design::{Design, PortId};
use crate::error::{io_err, CosimError, Result};
use crate::tb::{BenchConfig, Hang, Transaction};
use crate::tools::INSTALL_HINT;
use crate::waves::WaveFormat;
use golden::bits::Bits;
use std::fs;
use std::io::{BufWriter, Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Engine name in batch reports (both modes).
pub const BATCH_ENGINE_NAME: &str = "iverilog-batch";

/// Name of the named pipe the stall masks go through (in the run directory).
pub const MASKS_FIFO: &str = "masks.fifo";

/// The VCD the testbench writes when a dump window is set.
pub const WINDOW_VCD: &str = "window.vcd";

/// Mask lines the writer thread produces per write.
const MASK_LINES_PER_WRITE: usize = 16;

/// A generated batch testbench compiled with `iverilog -g2005`, and the
/// scratch directory that holds it and one directory per run.
pub struct BatchImage {
    work: tempfile::TempDir,
    image: PathBuf,
    /// How long one `vvp` run may take before it is killed.
    pub timeout: Duration,
}

impl BatchImage {
    /// Writes `text` as `<stem>.v` into a fresh scratch directory named
    /// `<prefix>...` and compiles it with top `module`.
    pub fn compile(
        design: &Design,
        prefix: &str,
        stem: &str,
        module: &str,
        text: &str,
        timeout: Duration,
    ) -> Result<BatchImage> {
        let work = tempfile::Builder::new()
            .prefix(prefix)
            .tempdir()
            .map_err(io_err(std::env::temp_dir()))?;
        let tb = work.path().join(format!("{stem}.v"));
        fs::write(&tb, text).map_err(io_err(&tb))?;
        let image = work.path().join(format!("{stem}.vvp"));
        super::engine::compile_top(design, &tb, &image, module)?;
        Ok(BatchImage {
            work,
            image,
            timeout,
        })
    }

    /// The scratch directory (testbench, compiled image, run directories).
    pub fn work_dir(&self) -> &Path {
        self.work.path()
    }

    /// A fresh directory for one run (removed when dropped).
    pub fn run_dir(&self) -> Result<tempfile::TempDir> {
        tempfile::Builder::new()
            .prefix("run-")
            .tempdir_in(self.work.path())
            .map_err(io_err(self.work.path()))
    }

    /// Runs vvp in `dir` while a thread writes `mask_lines()` into the
    /// named pipe ahead of it; returns vvp's wall time. A failed vvp is
    /// `ToolFailed` with its log; one past the timeout is killed.
    pub fn run_vvp(
        &self,
        dir: &Path,
        fst: bool,
        mask_lines: impl FnMut() -> String + Send + 'static,
    ) -> Result<Duration> {
        let start = Instant::now();
        let log_path = dir.join("vvp.log");
        let log = fs::File::create(&log_path).map_err(io_err(&log_path))?;
        let log_err = log.try_clone().map_err(io_err(&log_path))?;
        let masks = MaskFifo::open(dir, mask_lines)?;
        let mut vvp = Command::new("vvp");
        vvp.arg("-n").arg(&self.image);
        if fst {
            // The window dump as FST (complete when vvp ends, as here).
            vvp.arg("-fst");
        }
        let child = vvp
            .current_dir(dir)
            .stdin(Stdio::null())
            .stdout(log)
            .stderr(log_err)
            .spawn()
            .map_err(|e| CosimError::ToolMissing {
                tool: "vvp".to_string(),
                hint: format!("{e}; {INSTALL_HINT}"),
            });
        let status = child.and_then(|mut child| self.wait_for(&mut child, dir));
        masks.close()?;
        if !status?.success() {
            return Err(CosimError::ToolFailed {
                tool: "vvp".to_string(),
                command: format!("vvp -n {} (in {})", self.image.display(), dir.display()),
                log: fs::read_to_string(&log_path).unwrap_or_default(),
            });
        }
        Ok(start.elapsed())
    }

    /// Waits for `child` at most the run timeout (then kills it).
    fn wait_for(&self, child: &mut Child, dir: &Path) -> Result<ExitStatus> {
        let started = Instant::now();
        loop {
            if let Some(status) = child.try_wait().map_err(io_err(&self.image))? {
                return Ok(status);
            }
            if started.elapsed() > self.timeout {
                let _ = child.kill();
                let _ = child.wait();
                return Err(CosimError::Protocol {
                    what: format!(
                        "batch vvp run in {} did not finish within {:?} (hung simulation?)",
                        dir.display(),
                        self.timeout
                    ),
                });
            }
            std::thread::sleep(Duration::from_millis(5));
        }
    }
}

/// One mask line: the words in `%h`, space separated.
pub fn mask_line(words: impl Iterator<Item = u64>) -> String {
    let mut line = words
        .map(|w| format!("{w:x}"))
        .collect::<Vec<_>>()
        .join(" ");
    line.push('\n');
    line
}

/// The named pipe `MASKS_FIFO` and the thread writing the stall masks into
/// it ahead of vvp. The writer thread holds the only write end; Rust holds
/// a read end (`drain`) for as long as the writer may write, so a write
/// never meets a pipe without readers: no SIGPIPE when vvp has exited (a
/// process that restores SIGPIPE's default, as the `hiermerge` CLI does,
/// would otherwise end). `close` stops the writer and reads the pipe until
/// end of file, which comes when the writer has left and dropped its end:
/// a writer blocked on a full pipe is unblocked by the reads, and nothing
/// depends on the pipe's contents, so another reader of the pipe (a
/// person's `cat masks.fifo`) cannot make it wait forever.
struct MaskFifo {
    drain: fs::File,
    path: PathBuf,
    stop: Arc<AtomicBool>,
    writer: std::thread::JoinHandle<()>,
}

impl MaskFifo {
    fn open(
        dir: &Path,
        mut mask_line: impl FnMut() -> String + Send + 'static,
    ) -> Result<MaskFifo> {
        let path = dir.join(MASKS_FIFO);
        let made =
            Command::new("mkfifo")
                .arg(&path)
                .output()
                .map_err(|e| CosimError::ToolMissing {
                    tool: "mkfifo".to_string(),
                    hint: e.to_string(),
                })?;
        if !made.status.success() {
            return Err(CosimError::ToolFailed {
                tool: "mkfifo".to_string(),
                command: format!("mkfifo {}", path.display()),
                log: String::from_utf8_lossy(&made.stderr).into_owned(),
            });
        }
        let open = |read: bool, write: bool| {
            fs::OpenOptions::new()
                .read(read)
                .write(write)
                .open(&path)
                .map_err(io_err(&path))
        };
        // Opening one end of a FIFO waits for the other; a read-write
        // handle is both, so the two single ends open at once after it.
        let both = open(true, true)?;
        let drain = open(true, false)?;
        let mut out = open(false, true)?;
        drop(both);
        let stop = Arc::new(AtomicBool::new(false));
        let stopped = stop.clone();
        let writer = std::thread::spawn(move || {
            while !stopped.load(Ordering::SeqCst) {
                let block: String = (0..MASK_LINES_PER_WRITE).map(|_| mask_line()).collect();
                if out.write_all(block.as_bytes()).is_err() {
                    return;
                }
            }
        });
        Ok(MaskFifo {
            drain,
            path,
            stop,
            writer,
        })
    }

    /// Stop the writer, read the pipe to its end of file (the writer gone),
    /// join it.
    fn close(mut self) -> Result<()> {
        self.stop.store(true, Ordering::SeqCst);
        let mut buf = vec![0u8; 1 << 16];
        while self.drain.read(&mut buf).map_err(io_err(&self.path))? > 0 {}
        let _ = self.writer.join();
        Ok(())
    }
}

/// `lines`, one per line, into `path`.
pub fn write_lines(path: &Path, lines: &[String]) -> Result<()> {
    let file = fs::File::create(path).map_err(io_err(path))?;
    let mut w = BufWriter::with_capacity(1 << 16, file);
    for l in lines {
        writeln!(w, "{l}").map_err(io_err(path))?;
    }
    w.flush().map_err(io_err(path))
}

/// `words` (`%h`) on one line into `params.txt`.
pub fn write_params(dir: &Path, words: &[u64]) -> Result<()> {
    let text: Vec<String> = words.iter().map(|w| format!("{w:x}")).collect();
    let path = dir.join("params.txt");
    fs::write(&path, text.join(" ") + "\n").map_err(io_err(&path))
}

/// The first and last cycle of the VCD window around a run's failure
/// cycle (`failure_cycle()` of its report), and where the VCD goes: None
/// when the run passed or `config.vcd_path` is unset.
pub fn failure_window(
    failure_cycle: Option<u64>,
    config: &BenchConfig,
) -> Option<((u64, u64), PathBuf)> {
    let cycle = failure_cycle?;
    let path = config.vcd_path.clone()?;
    let window = (
        cycle.saturating_sub(config.vcd_radius),
        cycle.saturating_add(config.vcd_radius),
    );
    Some((window, path))
}

/// The cycles `config` asks to be dumped in every run, and where.
pub fn asked_window(config: &BenchConfig) -> Option<((u64, u64), PathBuf)> {
    Some((config.wave_window?, config.vcd_path.clone()?))
}

/// True when the window dump of a run whose failure waveform goes to
/// `dump` is FST (its file name's format); an FST of one scope is refused:
/// the batch testbench dumps every signal, and only a VCD is cut here.
pub fn dump_is_fst(dump: Option<&Path>, config: &BenchConfig) -> Result<bool> {
    let fst = dump.is_some_and(|p| WaveFormat::of(p) == WaveFormat::Fst);
    if fst && config.wave_scope.is_some() {
        return Err(CosimError::Unsupported {
            what: "an FST of one scope comes from Verilator; the Icarus batch's FST holds \
                   every signal: give VCD with the scope, or no scope"
                .into(),
        });
    }
    Ok(fst)
}

/// Copies the run's window VCD (if the testbench wrote one) to `path`,
/// atomically, cut to `scope` when given.
pub fn keep_window_vcd(dir: &Path, path: &Path, scope: Option<&str>) -> Result<Option<PathBuf>> {
    let vcd = dir.join(WINDOW_VCD);
    if !vcd.exists() {
        return Ok(None);
    }
    if let Some(parent) = path.parent() {
        fs::create_dir_all(parent).map_err(io_err(parent))?;
    }
    // Atomically (SPEC 15.3): no half-copied VCD, none left by a signal.
    let failed = |e: String| crate::error::CosimError::Io {
        path: path.to_path_buf(),
        source: std::io::Error::other(e),
    };
    let mut out = golden::output::AtomicFile::create(path).map_err(failed)?;
    let mut from = fs::File::open(&vcd).map_err(io_err(&vcd))?;
    std::io::copy(&mut from, out.file()).map_err(io_err(path))?;
    if let Some(s) = scope {
        crate::tb::trace_window::narrow_to_scope(out.path(), s).map_err(failed)?;
    }
    out.commit().map_err(failed)?;
    Ok(Some(path.to_path_buf()))
}

/// One line of `out.txt` split into its tag and words, and the error that
/// names the file, the line and the text.
pub struct OutLine<'a> {
    /// The record tag (`O`, `E`, ...).
    pub tag: &'a str,
    /// The words after the tag.
    pub words: Vec<&'a str>,
    n: usize,
    line: &'a str,
    what: &'a str,
}

impl OutLine<'_> {
    /// A protocol error naming this line.
    pub fn bad(&self, why: &str) -> CosimError {
        CosimError::Protocol {
            what: format!(
                "{} out.txt line {}: {why}: `{}`",
                self.what, self.n, self.line
            ),
        }
    }

    /// Word `i` as a decimal number.
    pub fn number(&self, i: usize) -> Result<u64> {
        self.words
            .get(i)
            .and_then(|t| t.parse().ok())
            .ok_or_else(|| self.bad("expected a decimal number"))
    }

    /// Words from `i` on as the values of `ports` (hex); X/Z in a value is
    /// `UnknownOutput` naming the port and `cycle`.
    pub fn values(
        &self,
        design: &Design,
        ports: &[PortId],
        i: usize,
        cycle: u64,
    ) -> Result<Transaction> {
        let texts = self.words.get(i..).unwrap_or(&[]);
        if texts.len() != ports.len() {
            return Err(self.bad(&format!("expected {} values", ports.len())));
        }
        ports
            .iter()
            .zip(texts)
            .map(|(&id, text)| {
                let port = &design.ports[id.0];
                if text.contains(['x', 'X', 'z', 'Z']) {
                    return Err(CosimError::UnknownOutput {
                        port: port.name.clone(),
                        cycle,
                        value: text.to_string(),
                    });
                }
                Bits::from_hex(text, port.width).map_err(|e| self.bad(&e.to_string()))
            })
            .collect()
    }
}

/// Reads `out.txt` (`what` names the batch mode in errors): the records
/// every batch testbench writes are handled here (`X`: X/Z on an output is
/// `UnknownOutput`; `H`: the watchdog's hang, returned; `M`: the masks ran
/// out), every other line goes to `record`, which returns false for a tag
/// it does not know.
pub fn read_out(
    text: &str,
    design: &Design,
    what: &str,
    mut record: impl FnMut(&OutLine) -> Result<bool>,
) -> Result<Option<Hang>> {
    let mut hang = None;
    for (n, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        let l = OutLine {
            tag: words.next().unwrap_or(""),
            words: words.collect(),
            n: n + 1,
            line,
            what,
        };
        match l.tag {
            "X" => {
                let cycle = l.number(0)?;
                l.values(design, &design.output_ids(), 1, cycle)?;
                return Err(l.bad("an output is X/Z but none was found"));
            }
            "H" => hang = Some(hang_of(design, &l)?),
            "M" => return Err(l.bad("the stall masks ran out")),
            _ => {
                if !record(&l)? {
                    return Err(l.bad("unknown record"));
                }
            }
        }
    }
    Ok(hang)
}

/// `H <cycle> <idle cycles> <every port's value>`.
fn hang_of(design: &Design, l: &OutLine) -> Result<Hang> {
    let (cycle, idle_cycles) = (l.number(0)?, l.number(1)?);
    let values = &l.words[2..];
    if values.len() != design.ports.len() {
        return Err(l.bad("expected every port's value"));
    }
    let ports = design
        .ports
        .iter()
        .zip(values)
        .map(|(p, v)| (p.name.clone(), format!("{}'h{v}", p.width)))
        .collect();
    Ok(Hang {
        cycle,
        idle_cycles,
        ports,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The closing does not depend on what is left in the pipe: with
    /// another reader taking everything (as `cat masks.fifo` would) it
    /// still returns.
    #[test]
    fn closing_the_mask_pipe_never_waits_on_another_reader() {
        let taken: usize = (0..40).map(|_| one_round()).sum();
        // Per round, how much the other reader gets is a race with the
        // closer's drain; over 40 rounds it must have been a real reader.
        assert!(taken > 0, "the other reader never got a byte");
    }

    /// One pipe, another reader, a close; what that reader took.
    fn one_round() -> usize {
        let dir = tempfile::tempdir().unwrap();
        let fifo = MaskFifo::open(dir.path(), || "0 0\n".to_string()).unwrap();
        // Opened here, while the writer is surely there: an open after the
        // close would wait for a writer forever.
        let mut thief = fs::File::open(dir.path().join(MASKS_FIFO)).unwrap();
        let (thief_tx, thief_rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let mut buf = vec![0u8; 4096];
            let mut taken = 0usize;
            while let Ok(n) = thief.read(&mut buf) {
                if n == 0 {
                    break;
                }
                taken += n;
            }
            thief_tx.send(taken).unwrap();
        });
        std::thread::sleep(Duration::from_millis(5));
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || tx.send(fifo.close().is_ok()).unwrap());
        assert_eq!(rx.recv_timeout(Duration::from_secs(20)), Ok(true));
        // The other reader sees the end of file too, once the writer is gone.
        let taken = thief_rx.recv_timeout(Duration::from_secs(20));
        taken.expect("the other reader saw the end of file")
    }
}
