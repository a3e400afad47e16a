//! The closing table: one row per frame.

use std::fmt::Write;

use super::pipeline::RunReport;

/// Translation unit plus merging-module cycles, `-` when no RTL ran.
fn rtl_cycles(f: &super::pipeline::FrameOut) -> String {
    let t = f.rtl.as_ref().map(|r| r.cycles);
    let mut m = f
        .groups
        .iter()
        .filter_map(|g| g.merge_rtl.as_ref())
        .map(|r| r.cycles)
        .peekable();
    let m = m.peek().is_some().then(|| m.sum::<u64>());
    match (t, m) {
        (None, None) => "-".into(),
        (t, m) => (t.unwrap_or(0) + m.unwrap_or(0)).to_string(),
    }
}

/// `redone` or `reused` for one merge group (`-` with nothing to merge);
/// with several, how many of the merged groups were redone, `2/3`.
fn merge_column(f: &super::pipeline::FrameOut) -> String {
    let merged: Vec<_> = f.groups.iter().filter(|g| g.merged_nodes > 0).collect();
    match merged.as_slice() {
        [] => "-".into(),
        [g] if f.groups.len() == 1 => if g.merged { "redone" } else { "reused" }.into(),
        gs => format!("{}/{}", gs.iter().filter(|g| g.merged).count(), gs.len()),
    }
}

/// The merging level of each group, `/`-separated; `-` for none.
fn level_column(f: &super::pipeline::FrameOut) -> String {
    f.groups
        .iter()
        .map(|g| g.merge_level.map_or("-".into(), |l| l.to_string()))
        .collect::<Vec<_>>()
        .join("/")
}

/// The merger top's cycles, cycles per merged node, store reads per
/// merged node, and records per cycle (with a shared store port, `/` what
/// the port allows) over the frame's merges; `-` when it ran on none.
fn merger_columns(f: &super::pipeline::FrameOut) -> [String; 4] {
    match &f.merger {
        None => ["-".into(), "-".into(), "-".into(), "-".into()],
        Some(m) => [
            m.merge_cycles.to_string(),
            format!("{:.2}", m.cycles_per_node),
            format!("{:.2}", m.store_reads_per_node),
            match m.records_allowed_per_cycle {
                Some(a) => format!("{:.4}/{a:.4}", m.records_per_cycle),
                None => format!("{:.4}", m.records_per_cycle),
            },
        ],
    }
}

/// The per-frame table printed at the end of a run.
pub fn closing_table(r: &RunReport) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "scene {} (D={} Q={}), merge {}, translation {}; RTL ({}): translation {}; merge {}; \
         merger {} ({})",
        r.scene,
        r.params.max_lod,
        r.params.quant_bits,
        r.effects.merge_mode,
        if r.effects.translation { "on" } else { "off" },
        r.rtl.engine.name(),
        r.rtl.translation,
        r.rtl.merge,
        r.rtl.merger,
        r.rtl.merger_store
    );
    let _ = writeln!(
        s,
        "{:>5} {:>19} {:>6} {:>5} {:>7} {:>8} {:>10} {:>8} {:>7} {:>13} {:>5} {:>24} {:>33}",
        "frame",
        "hierarchies",
        "merge",
        "level",
        "created",
        "RTL cyc",
        "merger cyc",
        "cyc/node",
        "rd/node",
        "rec/cyc",
        "mism",
        "node tests/ray m/s/full",
        "ms step/check/rtl/trace/cmp/png"
    );
    let _ = writeln!(
        s,
        "{:>5} {:>19} {:>6} {:>5} {:>7} {:>8} {:>10} {:>8} {:>7} {:>13} {:>5} {:>24} {:>33}",
        "",
        "reused/built/moved/retr",
        "",
        "",
        "",
        "",
        "",
        "",
        "",
        "/port allows",
        "",
        "(subsample)",
        ""
    );
    for f in &r.frames {
        let hier = format!(
            "{}/{}/{}/{}",
            f.reused,
            f.built + f.rebuilt,
            f.moved,
            f.retranslated
        );
        let tests = f.comparison.as_ref().map_or("-".to_string(), |c| {
            format!("{:.1}/{:.1}/{:.1}", c.merged, c.separate, c.full_rebuild)
        });
        let ms = |x: f64| format!("{:.0}", x * 1e3);
        let t = &f.seconds;
        let times = [t.step, t.check, t.rtl, t.trace, t.compare, t.write]
            .map(ms)
            .join("/");
        let [mc, mcn, mrn, mrc] = merger_columns(f);
        let _ = writeln!(
            s,
            "{:>5} {:>19} {:>6} {:>5} {:>7} {:>8} {:>10} {:>8} {:>7} {:>13} {:>5} {:>24} {:>33}",
            f.frame,
            hier,
            merge_column(f),
            level_column(f),
            f.nodes_created,
            rtl_cycles(f),
            mc,
            mcn,
            mrn,
            mrc,
            f.mismatches,
            tests,
            times
        );
    }
    let _ = writeln!(s, "total {:.1} s, {} mismatches", r.seconds, r.mismatches);
    s
}
