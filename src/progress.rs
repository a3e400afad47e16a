//! Progress of long work on stderr: a bar on a terminal; in a log (stderr
//! redirected, as in CI or `nohup`) one line when a stage starts, one per
//! tenth of it done and one when it ends, so an hour-long run is never
//! silent.

use std::io::IsTerminal;
use std::time::Instant;

use indicatif::{ProgressBar, ProgressStyle};

/// One stage's progress.
pub struct Progress {
    bar: ProgressBar,
    /// `Some` when stderr is not a terminal: lines instead of a bar.
    log: Option<Log>,
}

struct Log {
    stage: String,
    len: u64,
    pos: u64,
    tenths: u64,
    message: String,
    started: Instant,
}

impl Progress {
    /// A stage of `len` steps named `stage`; nothing at all when `quiet`.
    pub fn new(len: u64, quiet: bool, stage: &str) -> Progress {
        if quiet {
            return Progress {
                bar: ProgressBar::hidden(),
                log: None,
            };
        }
        if !std::io::stderr().is_terminal() {
            eprintln!("{stage}: started, {len} steps");
            return Progress {
                bar: ProgressBar::hidden(),
                log: Some(Log {
                    stage: stage.to_string(),
                    len,
                    pos: 0,
                    tenths: 0,
                    message: String::new(),
                    started: Instant::now(),
                }),
            };
        }
        let bar = ProgressBar::new(len);
        bar.set_style(
            ProgressStyle::with_template(
                "{prefix:>9} {bar:36} {pos}/{len} {msg} [{elapsed_precise} / ~{eta}]",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        bar.set_prefix(stage.to_string());
        Progress { bar, log: None }
    }

    /// What the stage is on now.
    pub fn set_message(&mut self, message: String) {
        match &mut self.log {
            Some(l) => l.message = message,
            None => self.bar.set_message(message),
        }
    }

    /// `n` more steps done.
    pub fn inc(&mut self, n: u64) {
        let Some(l) = &mut self.log else {
            self.bar.inc(n);
            return;
        };
        l.pos += n;
        let tenths = (l.pos * 10).checked_div(l.len).unwrap_or(10).min(10);
        if tenths > l.tenths && tenths < 10 {
            l.tenths = tenths;
            eprintln!(
                "{}: {}/{} ({}%) {} [{:.0} s]",
                l.stage,
                l.pos,
                l.len,
                tenths * 10,
                l.message,
                l.started.elapsed().as_secs_f64()
            );
        }
    }

    /// The stage is over.
    pub fn finish_and_clear(&mut self) {
        match &self.log {
            Some(l) => eprintln!(
                "{}: done, {}/{} steps in {:.1} s",
                l.stage,
                l.pos,
                l.len,
                l.started.elapsed().as_secs_f64()
            ),
            None => self.bar.finish_and_clear(),
        }
    }
}
