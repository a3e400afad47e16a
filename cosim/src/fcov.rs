//! Functional coverage (issue 23 item 2, SPEC 10.5): named bins that a
//! regression must hit, counted while a process collects ([`collect`]).
//!
//! Bins are declared by whoever knows they must be reachable (the runner
//! of a unit, from golden's lists of categories, codes and modes) and hit
//! by the bench side: the runner from the transactions the scoreboard
//! matched bit for bit, the stream drivers and monitors from the DUT's
//! `valid`/`ready` ports ([`crate::tb::StreamDriver`],
//! [`crate::tb::StreamMonitor`]). A declared bin never hit is named by
//! [`Bins::unhit`].

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::sync::Mutex;

/// Every bin declared or hit, with its count.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq, Eq)]
pub struct Bins {
    /// Bin name to hits; a declared bin starts at 0.
    pub counts: BTreeMap<String, u64>,
}

impl Bins {
    /// Declares `name` (a bin the regression must hit).
    pub fn declare(&mut self, name: &str) {
        self.counts.entry(name.to_string()).or_insert(0);
    }

    /// Counts `n` hits of `name` (declaring it).
    pub fn hit(&mut self, name: &str, n: u64) {
        *self.counts.entry(name.to_string()).or_insert(0) += n;
    }

    /// Adds `other`'s bins and counts.
    pub fn add(&mut self, other: &Bins) {
        for (k, v) in &other.counts {
            self.hit(k, *v);
        }
    }

    /// The declared bins never hit, in name order.
    pub fn unhit(&self) -> Vec<&str> {
        self.counts
            .iter()
            .filter(|(_, &v)| v == 0)
            .map(|(k, _)| k.as_str())
            .collect()
    }

    /// One line per bin: `name count` (`NOT HIT` for 0).
    pub fn table(&self) -> String {
        let width = self.counts.keys().map(String::len).max().unwrap_or(0);
        self.counts
            .iter()
            .map(|(k, v)| match v {
                0 => format!("{k:width$}  NOT HIT\n"),
                v => format!("{k:width$}  {v}\n"),
            })
            .collect()
    }
}

static BINS: Mutex<Option<Bins>> = Mutex::new(None);

fn bins() -> std::sync::MutexGuard<'static, Option<Bins>> {
    BINS.lock().unwrap_or_else(|p| p.into_inner())
}

/// From now on, count the bins this process declares and hits.
pub fn collect() {
    *bins() = Some(Bins::default());
}

/// True while [`collect`] is in force.
pub fn collecting() -> bool {
    bins().is_some()
}

/// Declares `names` (nothing when not collecting).
pub fn declare<S: AsRef<str>>(names: impl IntoIterator<Item = S>) {
    if let Some(b) = bins().as_mut() {
        for n in names {
            b.declare(n.as_ref());
        }
    }
}

/// Counts `n` hits of `name` (nothing when not collecting).
pub fn hit(name: &str, n: u64) {
    if let Some(b) = bins().as_mut() {
        b.hit(name, n);
    }
}

/// Stops collecting and returns what was counted.
pub fn take() -> Bins {
    bins().take().unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unhit_names_the_declared_bins_at_zero() {
        let mut b = Bins::default();
        b.declare("a");
        b.declare("b");
        b.hit("b", 2);
        b.hit("c", 1);
        assert_eq!(b.unhit(), vec!["a"]);
        let mut all = Bins::default();
        all.add(&b);
        all.hit("a", 1);
        assert!(all.unhit().is_empty());
        assert!(b.table().contains("a  NOT HIT"));
    }
}
