//! Running an external synthesis tool with a time limit, its output kept in
//! a log file of the work folder.

use crate::error::{io_err, CosimError, Result};
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// The last `n` lines of `text`.
pub fn tail(text: &str, n: usize) -> String {
    let lines: Vec<&str> = text.lines().collect();
    lines[lines.len().saturating_sub(n)..].join("\n")
}

/// Runs `program args` in `dir` with stdout and stderr in `dir/<log>`,
/// killing it after `timeout`. A missing program is `ToolMissing`; a
/// non-zero exit or a timeout is `ToolFailed` with the log's tail.
pub fn run_logged(
    program: &Path,
    args: &[String],
    dir: &Path,
    log: &str,
    timeout: Duration,
) -> Result<()> {
    let log_path = dir.join(log);
    let out = std::fs::File::create(&log_path).map_err(io_err(&log_path))?;
    let err = out.try_clone().map_err(io_err(&log_path))?;
    let command = format!("{} {}", program.display(), args.join(" "));
    let mut child = Command::new(program)
        .args(args)
        .current_dir(dir)
        .stdin(Stdio::null())
        .stdout(out)
        .stderr(err)
        .spawn()
        .map_err(|e| CosimError::ToolMissing {
            tool: program.display().to_string(),
            hint: format!("{e}; {}", super::tools::SYNTH_INSTALL_HINT),
        })?;
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().map_err(io_err(&log_path))? {
            break Some(status);
        }
        if start.elapsed() > timeout {
            let _ = child.kill();
            let _ = child.wait();
            break None;
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    let text = std::fs::read_to_string(&log_path).unwrap_or_default();
    match status {
        Some(s) if s.success() => Ok(()),
        Some(s) => Err(CosimError::ToolFailed {
            tool: program.display().to_string(),
            command,
            log: format!(
                "exit status {s}; last lines of its log:\n{}",
                tail(&text, 25)
            ),
        }),
        None => Err(CosimError::ToolFailed {
            tool: program.display().to_string(),
            command,
            log: format!(
                "timed out after {} s (--timeout) and was stopped; last lines of its log:\n{}",
                timeout.as_secs(),
                tail(&text, 10)
            ),
        }),
    }
}
