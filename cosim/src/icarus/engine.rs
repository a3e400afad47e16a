//! `IcarusEngine`: a 4-state Icarus Verilog simulation driven over pipes.

use super::testbench::{generate_testbench, REPLY_PREFIX, TB_MODULE};
use crate::design::{Design, PortId};
use crate::engine::Engine;
use crate::error::{io_err, CosimError, Result};
use crate::tools::INSTALL_HINT;
use golden::bits::Bits;
use std::cell::RefCell;
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::time::Duration;

/// How long one reply may take before the simulation is declared hung.
pub const DEFAULT_REPLY_TIMEOUT: Duration = Duration::from_secs(120);

/// An Icarus Verilog (iverilog + vvp) simulation of one design.
///
/// `step` sends `S` without waiting; the outputs are marked stale and read
/// back (`R`) only if peeked before the next `eval`, so the usual
/// poke-eval-peek-step cycle costs one pipe round trip, not two.
pub struct IcarusEngine {
    design: Design,
    child: Child,
    pipe: RefCell<Pipe>,
    outputs: RefCell<Outputs>,
    work: tempfile::TempDir,
    output_ids: Vec<PortId>,
    cycle: u64,
    check_unknown: bool,
    tracing: bool,
}

struct Pipe {
    stdin: ChildStdin,
    replies: Receiver<String>,
    timeout: Duration,
}

struct Outputs {
    /// Port values with X/Z bits read as 0, indexed like `design.ports`.
    values: Vec<Bits>,
    /// Raw `%h` text of each output as of the last reply (empty for inputs).
    raw: Vec<String>,
    /// True after a step whose reply has not been read.
    stale: bool,
}

impl IcarusEngine {
    /// Compile `design` with a generated testbench and start `vvp`.
    pub fn new(design: &Design) -> Result<IcarusEngine> {
        design.validate()?;
        let work = tempfile::Builder::new()
            .prefix("hm-icarus-")
            .tempdir()
            .map_err(io_err(std::env::temp_dir()))?;
        let tb = work.path().join("hm_tb.v");
        std::fs::write(&tb, generate_testbench(design)).map_err(io_err(&tb))?;
        let vvp_file = work.path().join("hm_tb.vvp");
        compile(design, &tb, &vvp_file)?;

        let stderr_path = work.path().join("vvp.stderr");
        let stderr = std::fs::File::create(&stderr_path).map_err(io_err(&stderr_path))?;
        let mut child = Command::new("vvp")
            .arg("-n")
            .arg(&vvp_file)
            .current_dir(work.path())
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(stderr)
            .spawn()
            .map_err(|e| CosimError::ToolMissing {
                tool: "vvp".to_string(),
                hint: format!("{e}; {INSTALL_HINT}"),
            })?;
        let stdin = child.stdin.take().ok_or_else(|| CosimError::Protocol {
            what: "vvp stdin not captured".to_string(),
        })?;
        let stdout = child.stdout.take().ok_or_else(|| CosimError::Protocol {
            what: "vvp stdout not captured".to_string(),
        })?;
        let (tx, replies) = std::sync::mpsc::channel();
        // A reader thread turns blocking reads into a channel with a timeout,
        // so a hung simulator is reported instead of hanging the test.
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines() {
                let Ok(line) = line else { break };
                if line.starts_with(REPLY_PREFIX) && tx.send(line).is_err() {
                    break;
                }
            }
        });
        Ok(IcarusEngine {
            design: design.clone(),
            child,
            pipe: RefCell::new(Pipe {
                stdin,
                replies,
                timeout: DEFAULT_REPLY_TIMEOUT,
            }),
            outputs: RefCell::new(Outputs {
                values: design.ports.iter().map(|p| Bits::zero(p.width)).collect(),
                raw: vec![String::new(); design.ports.len()],
                stale: false,
            }),
            work,
            output_ids: design.output_ids(),
            cycle: 0,
            check_unknown: false,
            tracing: false,
        })
    }

    /// Change how long a reply may take before `Protocol` "hung" is returned.
    pub fn set_reply_timeout(&mut self, timeout: Duration) {
        self.pipe.get_mut().timeout = timeout;
    }

    /// The 4-state text (`%h`, with x/z digits) of an output as of the last reply.
    pub fn peek_raw(&self, port: PortId) -> Result<String> {
        self.design.port(port)?;
        self.refresh_if_stale()?;
        Ok(self.outputs.borrow().raw[port.0].clone())
    }

    /// The scratch directory holding the testbench, the compiled image and vvp's stderr.
    pub fn work_dir(&self) -> &Path {
        self.work.path()
    }

    fn send(&self, line: &str) -> Result<()> {
        let mut pipe = self.pipe.borrow_mut();
        let result = writeln!(pipe.stdin, "{line}").and_then(|_| pipe.stdin.flush());
        drop(pipe);
        result.map_err(|e| CosimError::Protocol {
            what: format!("writing `{line}` to vvp: {e}; {}", self.stderr_tail()),
        })
    }

    fn stderr_tail(&self) -> String {
        let text = std::fs::read_to_string(self.work.path().join("vvp.stderr")).unwrap_or_default();
        let tail: Vec<&str> = text.lines().rev().take(10).collect();
        format!(
            "vvp stderr: {}",
            tail.into_iter().rev().collect::<Vec<_>>().join(" | ")
        )
    }

    fn refresh_if_stale(&self) -> Result<()> {
        if self.outputs.borrow().stale {
            self.command_with_reply("R")?;
        }
        Ok(())
    }

    fn command_with_reply(&self, cmd: &str) -> Result<()> {
        self.send(cmd)?;
        let pipe = self.pipe.borrow();
        let received = pipe.replies.recv_timeout(pipe.timeout);
        let timeout = pipe.timeout;
        drop(pipe);
        let line = match received {
            Ok(l) => l,
            Err(RecvTimeoutError::Timeout) => {
                return Err(CosimError::Protocol {
                    what: format!(
                        "no reply to `{cmd}` within {timeout:?} at cycle {} (hung simulation?)",
                        self.cycle
                    ),
                })
            }
            Err(RecvTimeoutError::Disconnected) => {
                return Err(CosimError::Protocol {
                    what: format!(
                        "vvp exited before replying to `{cmd}`; {}",
                        self.stderr_tail()
                    ),
                })
            }
        };
        self.absorb_reply(&line)
    }

    fn absorb_reply(&self, line: &str) -> Result<()> {
        let tokens: Vec<&str> = line[REPLY_PREFIX.len()..].split_whitespace().collect();
        if tokens.len() != self.output_ids.len() {
            return Err(CosimError::Protocol {
                what: format!(
                    "reply `{line}` has {} values, expected {}",
                    tokens.len(),
                    self.output_ids.len()
                ),
            });
        }
        let mut outputs = self.outputs.borrow_mut();
        outputs.stale = false;
        let mut first_unknown = None;
        for (&id, text) in self.output_ids.iter().zip(tokens) {
            let port = &self.design.ports[id.0];
            let unknown = text.contains(['x', 'X', 'z', 'Z']);
            let known: String = text
                .chars()
                .map(|c| if "xXzZ".contains(c) { '0' } else { c })
                .collect();
            outputs.values[id.0] =
                Bits::from_hex(&known, port.width).map_err(|e| CosimError::Protocol {
                    what: format!("output `{}`: {e}", port.name),
                })?;
            outputs.raw[id.0] = text.to_string();
            if unknown && first_unknown.is_none() {
                first_unknown = Some((port.name.clone(), text.to_string()));
            }
        }
        match first_unknown {
            Some((port, value)) if self.check_unknown => Err(CosimError::UnknownOutput {
                port,
                cycle: self.cycle,
                value,
            }),
            _ => Ok(()),
        }
    }
}

fn compile(design: &Design, tb: &Path, out: &Path) -> Result<()> {
    compile_top(design, tb, out, TB_MODULE)
}

/// `iverilog -g2005 -s <top>` of the testbench `tb` and the design's files
/// into `out`; a port-width warning is a `PortMismatch`.
pub(crate) fn compile_top(design: &Design, tb: &Path, out: &Path, top: &str) -> Result<()> {
    let mut cmd = Command::new("iverilog");
    cmd.arg("-g2005")
        .arg("-s")
        .arg(top)
        .arg("-o")
        .arg(out)
        .arg(tb)
        .args(&design.verilog_files);
    let shown = format!("{cmd:?}");
    let result = cmd.output().map_err(|e| CosimError::ToolMissing {
        tool: "iverilog".to_string(),
        hint: format!("{e}; {INSTALL_HINT}"),
    })?;
    let log = String::from_utf8_lossy(&result.stderr).into_owned()
        + &String::from_utf8_lossy(&result.stdout);
    if !result.status.success() {
        return Err(CosimError::ToolFailed {
            tool: "iverilog".to_string(),
            command: shown,
            log,
        });
    }
    check_port_binding(design, &log)
}

/// iverilog only warns when a connection's width differs from the port's;
/// here that is an error naming the port.
fn check_port_binding(design: &Design, log: &str) -> Result<()> {
    for line in log.lines() {
        if let Some(rest) = line.split("warning: Port ").nth(1) {
            let name = rest.split(['(', ')']).nth(1).unwrap_or("?").to_string();
            let described = design
                .ports
                .iter()
                .find(|p| p.name == name)
                .map(|p| p.width);
            return Err(CosimError::PortMismatch {
                port: name,
                what: format!(
                    "described as {} bits but iverilog says: {}",
                    described.map_or("?".to_string(), |w| w.to_string()),
                    rest.trim()
                ),
            });
        }
    }
    Ok(())
}

impl Engine for IcarusEngine {
    fn name(&self) -> &'static str {
        "iverilog"
    }

    fn design(&self) -> &Design {
        &self.design
    }

    fn poke(&mut self, port: PortId, value: &Bits) -> Result<()> {
        self.design.check_poke(port, value)?;
        self.send(&format!("P {} {}", port.0, value.to_hex()))?;
        self.outputs.borrow_mut().values[port.0] = value.clone();
        Ok(())
    }

    fn peek(&self, port: PortId) -> Result<Bits> {
        self.design.port(port)?;
        self.refresh_if_stale()?;
        Ok(self.outputs.borrow().values[port.0].clone())
    }

    fn eval(&mut self) -> Result<()> {
        self.command_with_reply("E")
    }

    fn step(&mut self) -> Result<()> {
        self.cycle += 1;
        self.send("S")?;
        self.outputs.get_mut().stale = true;
        Ok(())
    }

    fn cycle(&self) -> u64 {
        self.cycle
    }

    fn trace_start(&mut self, path: &Path) -> Result<()> {
        crate::waves::check_engine_writes(
            Some(crate::waves::WaveFormat::Vcd),
            path,
            "Icarus through its pipe",
        )?;
        let text = path.to_string_lossy().into_owned();
        if text.chars().any(char::is_whitespace) || text.is_empty() {
            return Err(CosimError::Io {
                path: path.to_path_buf(),
                source: std::io::Error::new(
                    std::io::ErrorKind::InvalidInput,
                    "the Icarus pipe protocol needs a VCD path without whitespace",
                ),
            });
        }
        let absolute: PathBuf = if path.is_absolute() {
            path.to_path_buf()
        } else {
            std::env::current_dir().map_err(io_err(path))?.join(path)
        };
        self.send(&format!("T {}", absolute.display()))?;
        self.tracing = true;
        Ok(())
    }

    fn trace_stop(&mut self) -> Result<()> {
        if self.tracing {
            self.send("U")?;
            self.tracing = false;
            // A round trip makes sure vvp has flushed before the caller reads the file.
            self.command_with_reply("R")?;
        }
        Ok(())
    }

    fn reset_released(&mut self) {
        self.check_unknown = true;
    }
}

impl Drop for IcarusEngine {
    fn drop(&mut self) {
        let pipe = self.pipe.get_mut();
        let _ = writeln!(pipe.stdin, "Q").and_then(|_| pipe.stdin.flush());
        for _ in 0..50 {
            if let Ok(Some(_)) = self.child.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
