//! Reading Yosys's `stat`, `dump` and `ltp` output.

use std::collections::BTreeMap;

/// The cell counts of the last `Number of cells:` block of a `stat` report.
pub fn cell_counts(stat: &str) -> BTreeMap<String, u64> {
    let mut cells = BTreeMap::new();
    let Some(start) = stat.rfind("Number of cells:") else {
        return cells;
    };
    for line in stat[start..].lines().skip(1) {
        let mut words = line.split_whitespace();
        let (Some(kind), Some(n), None) = (words.next(), words.next(), words.next()) else {
            break;
        };
        let Ok(n) = n.parse::<u64>() else { break };
        cells.insert(kind.to_string(), n);
    }
    cells
}

/// The sum of the counts of the cell kinds `keep` accepts.
pub fn count_where(cells: &BTreeMap<String, u64>, keep: impl Fn(&str) -> bool) -> u64 {
    cells.iter().filter(|(k, _)| keep(k)).map(|(_, n)| n).sum()
}

/// (memories, bits) of the `$mem_v2` cells of a `dump` (SIZE x WIDTH each).
pub fn memory_bits(dump: &str) -> (u64, u64) {
    let (mut count, mut bits) = (0, 0);
    let (mut size, mut width) = (None::<u64>, None::<u64>);
    let mut flush = |size: &mut Option<u64>, width: &mut Option<u64>| {
        if let (Some(s), Some(w)) = (size.take(), width.take()) {
            count += 1;
            bits += s * w;
        }
    };
    for line in dump.lines().map(str::trim) {
        if line.starts_with("cell ") {
            flush(&mut size, &mut width);
        }
        let value = |l: &str| l.split_whitespace().nth(2).and_then(|v| v.parse().ok());
        if line.starts_with("parameter \\SIZE ") {
            size = value(line);
        } else if line.starts_with("parameter \\WIDTH ") {
            width = value(line);
        }
    }
    flush(&mut size, &mut width);
    (count, bits)
}

/// The length of `ltp`'s longest topological path.
pub fn ltp_length(ltp: &str) -> Option<u64> {
    let at = ltp.rfind("(length=")? + "(length=".len();
    ltp[at..].split(')').next()?.trim().parse().ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_stat_dump_and_ltp() {
        let stat = "   Number of cells:      5\n     $_AND_   3\n     $_DFF_P_  2\n\n";
        let c = cell_counts(stat);
        assert_eq!(c["$_AND_"], 3);
        assert_eq!(count_where(&c, |k| k.contains("DFF")), 2);
        let dump = "cell $mem_v2 $m\n  parameter \\SIZE 16\n  parameter \\WIDTH 56\nend\n";
        assert_eq!(memory_bits(dump), (1, 896));
        assert_eq!(
            ltp_length("Longest topological path in t (length=71):"),
            Some(71)
        );
    }
}
