//! Value-change-dump output of the IR simulator, for waveform viewers.

use golden::bits::words::words_for;
use std::io::Write;

/// One traced signal: flat node, width, VCD identifier code.
pub(crate) struct Traced {
    pub node: usize,
    pub width: u32,
    pub code: String,
}

/// An open VCD file and the last values written.
pub(crate) struct Vcd {
    pub out: Box<dyn Write>,
    pub traced: Vec<Traced>,
    pub last: Vec<Vec<u64>>,
}

/// Short printable identifier for the `i`-th signal (`!`, `"`, ... base 94).
fn code(mut i: usize) -> String {
    let mut s = String::new();
    loop {
        s.push((b'!' + (i % 94) as u8) as char);
        i /= 94;
        if i == 0 {
            return s;
        }
    }
}

impl Vcd {
    /// Writes the header for `signals` (`(name, node, width)`, names may contain
    /// `.` for hierarchy, flattened to `_` in the single VCD scope).
    pub fn new(
        mut out: Box<dyn Write>,
        top: &str,
        signals: &[(String, usize, u32)],
    ) -> std::io::Result<Vcd> {
        writeln!(out, "$timescale 1ns $end\n$scope module {top} $end")?;
        let mut traced = Vec::new();
        for (i, (name, node, width)) in signals.iter().enumerate() {
            let c = code(i);
            writeln!(out, "$var wire {width} {c} {} $end", name.replace('.', "_"))?;
            traced.push(Traced {
                node: *node,
                width: *width,
                code: c,
            });
        }
        writeln!(out, "$upscope $end\n$enddefinitions $end")?;
        let last = traced
            .iter()
            .map(|t| vec![u64::MAX; words_for(t.width)])
            .collect();
        Ok(Vcd { out, traced, last })
    }

    /// Dumps the values that changed at `time`.
    pub fn sample(&mut self, time: u64, value: impl Fn(usize) -> Vec<u64>) -> std::io::Result<()> {
        let mut header_written = false;
        for (t, last) in self.traced.iter().zip(self.last.iter_mut()) {
            let now = value(t.node);
            if &now == last {
                continue;
            }
            if !header_written {
                writeln!(self.out, "#{time}")?;
                header_written = true;
            }
            let bits: String = (0..t.width)
                .rev()
                .map(|i| {
                    if (now[(i / 64) as usize] >> (i % 64)) & 1 == 1 {
                        '1'
                    } else {
                        '0'
                    }
                })
                .collect();
            if t.width == 1 {
                writeln!(self.out, "{bits}{}", t.code)?;
            } else {
                writeln!(self.out, "b{bits} {}", t.code)?;
            }
            *last = now;
        }
        self.out.flush()
    }
}
