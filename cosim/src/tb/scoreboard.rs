//! In-order scoreboard: each output transaction is compared with the next
//! expected one; the first mismatch is kept whole, decoded field by field.

use super::accounting::Accounting;
use super::stream::Transaction;
use std::collections::VecDeque;
use std::fmt;

/// Turns a transaction into named fields (`lod`, `x`, ... for hiermerge
/// records); the default names each payload port and prints it in hex.
pub type FieldDecoder = dyn Fn(&Transaction) -> Vec<(String, String)>;

/// One decoded field of the first mismatch.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FieldDiff {
    /// Field name.
    pub name: String,
    /// Expected value, as the decoder printed it.
    pub expected: String,
    /// Observed value.
    pub got: String,
}

impl FieldDiff {
    /// True when the field differs.
    pub fn differs(&self) -> bool {
        self.expected != self.got
    }
}

/// The first transaction that did not match.
#[derive(Clone, Debug)]
pub struct Mismatch {
    /// 0-based number of the output transaction.
    pub output_index: u64,
    /// The input record this output belongs to.
    pub input_id: u64,
    /// Cycle at which the output was accepted.
    pub cycle: u64,
    /// The expected transaction.
    pub expected: Transaction,
    /// The observed transaction.
    pub got: Transaction,
    /// Field-by-field comparison.
    pub fields: Vec<FieldDiff>,
}

impl fmt::Display for Mismatch {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "mismatch at cycle {}: output #{} (from input record {})",
            self.cycle, self.output_index, self.input_id
        )?;
        let width = self.fields.iter().map(|d| d.name.len()).max().unwrap_or(0);
        for d in &self.fields {
            let mark = if d.differs() { "  <-- differs" } else { "" };
            writeln!(
                f,
                "  {:width$}  expected {}  got {}{mark}",
                d.name, d.expected, d.got
            )?;
        }
        Ok(())
    }
}

/// The in-order scoreboard with its accounting.
pub struct Scoreboard {
    expected: VecDeque<(u64, Transaction)>,
    decoder: Box<FieldDecoder>,
    accounting: Accounting,
    compared: u64,
    matched: u64,
    mismatches: u64,
    first_mismatch: Option<Mismatch>,
}

impl Scoreboard {
    /// A scoreboard decoding transactions with `decoder`.
    pub fn new(decoder: Box<FieldDecoder>) -> Scoreboard {
        Scoreboard {
            expected: VecDeque::new(),
            decoder,
            accounting: Accounting::new(),
            compared: 0,
            matched: 0,
            mismatches: 0,
            first_mismatch: None,
        }
    }

    /// A scoreboard whose fields are the payload ports, printed in hex.
    pub fn with_port_names(names: Vec<String>) -> Scoreboard {
        Scoreboard::new(Box::new(move |txn: &Transaction| {
            txn.iter()
                .enumerate()
                .map(|(i, v)| {
                    let name = names.get(i).cloned().unwrap_or_else(|| format!("field{i}"));
                    (name, format!("0x{}", v.to_hex()))
                })
                .collect()
        }))
    }

    /// Register one input record and the outputs it must produce, in order.
    pub fn expect_input(&mut self, outputs: Vec<Transaction>) -> u64 {
        let id = self.accounting.register_input(outputs.len() as u64);
        self.expected.extend(outputs.into_iter().map(|t| (id, t)));
        id
    }

    /// Compare an output accepted at `cycle` with the next expected one;
    /// true when it matches.
    pub fn check(&mut self, got: Transaction, cycle: u64) -> bool {
        let index = self.compared;
        self.compared += 1;
        let Some((input_id, expected)) = self.expected.pop_front() else {
            self.accounting.unexpected_output();
            self.record_mismatch(index, u64::MAX, cycle, Vec::new(), got);
            return false;
        };
        self.accounting.deliver(input_id);
        if expected == got {
            self.matched += 1;
            return true;
        }
        self.record_mismatch(index, input_id, cycle, expected, got);
        false
    }

    fn record_mismatch(
        &mut self,
        index: u64,
        input_id: u64,
        cycle: u64,
        expected: Transaction,
        got: Transaction,
    ) {
        self.mismatches += 1;
        if self.first_mismatch.is_some() {
            return;
        }
        let e = (self.decoder)(&expected);
        let g = (self.decoder)(&got);
        let n = e.len().max(g.len());
        let fields = (0..n)
            .map(|i| FieldDiff {
                name: e
                    .get(i)
                    .or(g.get(i))
                    .map(|f| f.0.clone())
                    .unwrap_or_default(),
                expected: e
                    .get(i)
                    .map(|f| f.1.clone())
                    .unwrap_or_else(|| "(none)".into()),
                got: g
                    .get(i)
                    .map(|f| f.1.clone())
                    .unwrap_or_else(|| "(none)".into()),
            })
            .collect();
        self.first_mismatch = Some(Mismatch {
            output_index: index,
            input_id,
            cycle,
            expected,
            got,
            fields,
        });
    }

    /// Outputs still expected.
    pub fn outstanding(&self) -> usize {
        self.expected.len()
    }

    /// Outputs compared so far.
    pub fn compared(&self) -> u64 {
        self.compared
    }

    /// Outputs that matched.
    pub fn matched(&self) -> u64 {
        self.matched
    }

    /// Outputs that did not match (including unexpected ones).
    pub fn mismatches(&self) -> u64 {
        self.mismatches
    }

    /// The first mismatch, if any.
    pub fn first_mismatch(&self) -> Option<&Mismatch> {
        self.first_mismatch.as_ref()
    }

    /// The books.
    pub fn accounting(&self) -> &Accounting {
        &self.accounting
    }
}
