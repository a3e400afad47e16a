//! Accounting: every input record yields exactly its expected outputs.
//!
//! Each input is registered with the number of outputs it must produce; the
//! scoreboard credits each matched-in-position output to the input it belongs
//! to. At the end an input with fewer deliveries than expected has lost
//! outputs, and any output beyond the expected stream is a duplicate.

use std::fmt;

/// Per-input expected and delivered output counts.
#[derive(Clone, Debug, Default)]
pub struct Accounting {
    expected: Vec<u64>,
    delivered: Vec<u64>,
    extra_outputs: u64,
}

/// The verdict of `Accounting::report`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct AccountingReport {
    /// Input records registered.
    pub inputs: u64,
    /// Outputs the inputs should produce in total.
    pub expected_outputs: u64,
    /// Outputs credited to an input.
    pub delivered_outputs: u64,
    /// Outputs that arrived when no more were expected.
    pub duplicated_outputs: u64,
    /// Inputs missing outputs: (input id, expected, delivered); at most 16 listed.
    pub lost: Vec<(u64, u64, u64)>,
    /// Number of inputs missing at least one output.
    pub inputs_with_lost_outputs: u64,
}

impl AccountingReport {
    /// True when nothing was lost and nothing duplicated.
    pub fn balanced(&self) -> bool {
        self.inputs_with_lost_outputs == 0
            && self.duplicated_outputs == 0
            && self.delivered_outputs == self.expected_outputs
    }
}

impl fmt::Display for AccountingReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "accounting: {} inputs, {} outputs expected, {} delivered, {} duplicated, {} inputs with lost outputs",
            self.inputs,
            self.expected_outputs,
            self.delivered_outputs,
            self.duplicated_outputs,
            self.inputs_with_lost_outputs
        )?;
        for (id, exp, got) in &self.lost {
            write!(f, "\n  input {id}: expected {exp} outputs, delivered {got}")?;
        }
        Ok(())
    }
}

impl Accounting {
    /// Empty books.
    pub fn new() -> Accounting {
        Accounting::default()
    }

    /// Register the next input (ids count up from 0) with its expected output count.
    pub fn register_input(&mut self, expected_outputs: u64) -> u64 {
        self.expected.push(expected_outputs);
        self.delivered.push(0);
        (self.expected.len() - 1) as u64
    }

    /// Credit one output to `input`; an unknown id or an over-delivery counts
    /// as a duplicate.
    pub fn deliver(&mut self, input: u64) {
        let i = input as usize;
        match (self.delivered.get_mut(i), self.expected.get(i)) {
            (Some(d), Some(&e)) if *d < e => *d += 1,
            _ => self.extra_outputs += 1,
        }
    }

    /// Record an output that belongs to no input.
    pub fn unexpected_output(&mut self) {
        self.extra_outputs += 1;
    }

    /// The current verdict.
    pub fn report(&self) -> AccountingReport {
        let mut lost = Vec::new();
        let mut with_lost = 0;
        for (i, (&e, &d)) in self.expected.iter().zip(&self.delivered).enumerate() {
            if d < e {
                with_lost += 1;
                if lost.len() < 16 {
                    lost.push((i as u64, e, d));
                }
            }
        }
        AccountingReport {
            inputs: self.expected.len() as u64,
            expected_outputs: self.expected.iter().sum(),
            delivered_outputs: self.delivered.iter().sum(),
            duplicated_outputs: self.extra_outputs,
            lost,
            inputs_with_lost_outputs: with_lost,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lost_and_duplicated_are_both_seen() {
        let mut a = Accounting::new();
        let i0 = a.register_input(2);
        let i1 = a.register_input(0);
        let i2 = a.register_input(1);
        a.deliver(i0);
        a.deliver(i0);
        a.deliver(i1); // i1 expects nothing: a duplicate
        let r = a.report();
        assert_eq!(r.duplicated_outputs, 1);
        assert_eq!(r.lost, vec![(i2, 1, 0)]);
        assert!(!r.balanced());
        a.deliver(i2);
        let mut b = a.clone();
        b.extra_outputs = 0;
        assert!(b.report().balanced());
    }
}
