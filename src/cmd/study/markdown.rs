//! `study.md`: the report for people, with the plots embedded, what the
//! default costs and what each step of accuracy buys, in numbers, beside
//! the two published points of issue 18.

use std::fmt::Write as _;
use std::path::Path;

use super::plots::PLOTS;
use super::run::Study;
use super::sweep::Row;
use super::table::{main_rows, render, render_distance, NOT_MEASURED};
use golden::output::write_atomic;

fn pct(a: f64, b: f64) -> String {
    if b == 0.0 {
        return "n/a".into();
    }
    format!("{:+.1}%", (a / b - 1.0) * 100.0)
}

/// Area, clock and ns per merge of a row, as a sentence part.
fn synth_line(r: &Row) -> String {
    let Some(s) = r.synth.as_ref() else {
        return format!("area, Fmax and ns per merge {NOT_MEASURED}");
    };
    let mut parts = Vec::new();
    if let Some(n) = s.nand2_eq {
        parts.push(format!("{n:.0} NAND2-equivalent gates"));
    }
    if let (Some(l), Some(e)) = (s.ecp5_lut4, s.ecp5_ebr) {
        parts.push(format!(
            "{l} ECP5 LUT4 and {e} EBR ({})",
            s.ecp5_verdict.as_deref().unwrap_or("")
        ));
    }
    match (s.fmax_mhz, &s.fmax_of, s.fmax_bound) {
        (Some(f), Some(m), true) => parts.push(format!(
            "the top is not placed, so its clock is at most {f:.1} MHz (its slowest part placed alone, `{m}`)"
        )),
        (Some(f), _, false) => parts.push(format!("{f:.1} MHz on ECP5")),
        _ => parts.push(format!("Fmax {NOT_MEASURED}")),
    }
    match (r.ns_per_merge, s.fmax_bound) {
        (Some(ns), true) => parts.push(format!("at least {ns:.1} ns per merge")),
        (Some(ns), false) => parts.push(format!("{ns:.1} ns per merge")),
        (None, _) => parts.push(format!("ns per merge {NOT_MEASURED}")),
    }
    parts.join(", ")
}

fn default_costs(s: &Study, r: &Row, md: &mut String) {
    let rtl = r.rtl.as_ref();
    let _ = writeln!(
        md,
        "## What the default costs ({}, D = {}, Q = {})\n",
        r.case, r.max_lod, r.quant_bits
    );
    let _ = writeln!(md, "- a node record is {} bits ({} with binary32 box bounds); the hierarchy of {} triangles is {} nodes, {} bytes ({:.2} bytes per triangle);", r.record_bits, r.record_bits_f32_boxes, r.triangles, r.nodes, r.bytes, r.bytes_per_triangle);
    let _ = writeln!(md, "- a ray makes {:.2} node tests and {:.2} triangle tests; {:.2} box tests per ray pass only because a stored box is looser than the exact box of its content; stored boxes have {:.3} times the surface area of the exact ones on average ({:.3} at the 99th percentile);", r.node_tests_per_ray, r.prim_tests_per_ray, r.false_hits_per_ray, r.looseness.all.mean, r.looseness.all.p99);
    let _ = writeln!(md, "- software (median of {}, {}): build {:.2} ms, trace {:.2} us per ray, merge of the pair {:.3} ms;", s.repeats, s.machine.cpu, r.build_ms, r.trace_us_per_ray, r.merge_ms);
    let _ = writeln!(
        md,
        "- RTL: {} cycles per merge, {} cycles per translated record; synthesis: {}.\n",
        rtl.map_or(NOT_MEASURED.into(), |f| format!(
            "{:.1}",
            f.cycles_per_merge
        )),
        rtl.map_or(NOT_MEASURED.into(), |f| format!(
            "{:.2}",
            f.cycles_per_translated_record
        )),
        synth_line(r)
    );
}

fn per_lod(r: &Row, md: &mut String) {
    let _ = writeln!(
        md,
        "Looseness per LOD at the default (stored over exact surface area):\n"
    );
    let _ = writeln!(
        md,
        "| LOD | nodes | degenerate | mean | p99 | max |\n| --: | --: | --: | --: | --: | --: |"
    );
    for l in &r.looseness.per_lod {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {:.3} | {:.3} | {:.3} |",
            l.lod.map_or("all".into(), |v| v.to_string()),
            l.nodes,
            l.degenerate,
            l.mean,
            l.p99,
            l.max
        );
    }
    let _ = writeln!(md);
}

fn steps(s: &Study, case: &str, md: &mut String) {
    let at_d: Vec<&Row> = s
        .rows
        .iter()
        .filter(|r| r.case == case && r.max_lod == s.default_max_lod)
        .collect();
    let _ = writeln!(md, "## What each step buys ({case})\n");
    let _ = writeln!(md, "Each step of Q at D = {}:\n", s.default_max_lod);
    for w in at_d.windows(2) {
        let (a, b) = (w[0], w[1]);
        let _ = writeln!(
            md,
            "- Q {} -> {}: looseness {:.3} -> {:.3}, false box hits per ray {:.2} -> {:.2}, node tests per ray {:.2} -> {:.2} ({}), for {} more bits per record and {} bytes ({})",
            a.quant_bits, b.quant_bits, a.looseness.all.mean, b.looseness.all.mean, a.false_hits_per_ray, b.false_hits_per_ray,
            a.node_tests_per_ray, b.node_tests_per_ray, pct(b.node_tests_per_ray, a.node_tests_per_ray),
            b.record_bits as i64 - a.record_bits as i64, b.bytes as i64 - a.bytes as i64, pct(b.bytes as f64, a.bytes as f64)
        );
    }
    let at_q: Vec<&Row> = s
        .rows
        .iter()
        .filter(|r| r.case == case && r.quant_bits == s.default_quant_bits)
        .collect();
    let _ = writeln!(md, "\nEach step of D at Q = {}:\n", s.default_quant_bits);
    for w in at_q.windows(2) {
        let (a, b) = (w[0], w[1]);
        let _ = writeln!(
            md,
            "- D {} -> {}: node tests per ray {:.2} -> {:.2}, triangle tests per ray {:.2} -> {:.2}, looseness {:.3} -> {:.3}, nodes {} -> {}, bytes {} -> {} ({}), build {:.2} -> {:.2} ms",
            a.max_lod, b.max_lod, a.node_tests_per_ray, b.node_tests_per_ray, a.prim_tests_per_ray, b.prim_tests_per_ray,
            a.looseness.all.mean, b.looseness.all.mean, a.nodes, b.nodes, a.bytes, b.bytes, pct(b.bytes as f64, a.bytes as f64), a.build_ms, b.build_ms
        );
    }
    let same_tree = at_q
        .windows(2)
        .all(|w| w[0].nodes == w[1].nodes && w[0].node_tests_per_ray == w[1].node_tests_per_ray);
    if at_q.len() > 1 && same_tree {
        let deepest = at_q[0]
            .looseness
            .per_lod
            .iter()
            .filter_map(|l| l.lod)
            .max()
            .unwrap_or(0);
        let _ = writeln!(
            md,
            "\nThe tree is the same at every D of the sweep: no triangle of {case} sits deeper than LOD {deepest}, so a larger D adds no node and no test; it buys a finer translation grid (the position error of the translated formats below) and range, for {} bits per record per level.",
            (at_q[1].record_bits as i64 - at_q[0].record_bits as i64)
                / (at_q[1].max_lod as i64 - at_q[0].max_lod as i64).max(1)
        );
    }
    let _ = writeln!(md);
}

fn published(s: &Study, r: &Row, md: &mut String) {
    let _ = writeln!(md, "## Beside the published points\n");
    let _ = writeln!(
        md,
        "- Ylitie et al. 2017, 8-bit quantized child boxes: 35-60% of the memory of an uncompressed BVH. Here the Q = {} record is {} bits against {} bits for the same record with six binary32 bounds: {:.0}% (records only; references and primitive indices are the same in both).",
        r.quant_bits, r.record_bits, r.record_bits_f32_boxes, r.record_bits as f64 / r.record_bits_f32_boxes as f64 * 100.0
    );
    let q16 = s
        .rows
        .iter()
        .find(|x| x.case == r.case && x.max_lod == r.max_lod && x.quant_bits == 16);
    let _ = writeln!(
        md,
        "- Koskela et al. 2015, half-precision boxes: about +2.5% ray-box tests. Here, at Q = {}, the walk with stored boxes makes {:+.1}% box tests against the same walk with exact boxes{}.\n",
        r.quant_bits,
        r.extra_box_tests_vs_exact * 100.0,
        q16.map_or(String::new(), |x| format!(
            "; golden's traversal makes {} node tests per ray against Q = 16 ({:.2} vs {:.2})",
            pct(r.node_tests_per_ray, x.node_tests_per_ray), r.node_tests_per_ray, x.node_tests_per_ray
        ))
    );
}

/// What each translation level costs and buys, at one distance.
fn levels(s: &Study, md: &mut String) {
    let at = 1e3;
    let rows: Vec<String> = s
        .distance
        .iter()
        .filter(|d| d.distance == at && d.max_lod == s.default_max_lod && d.format == "b64-local")
        .map(|d| match (&d.refused, d.level) {
            (Some(_), Some(l)) => format!("L = {l} ({}): refused by the extents rule", d.level_role),
            (None, Some(l)) => format!(
                "L = {l} ({}): position error {:.3e}, hit error {:.3} per ray, {} nodes added by the expanding variant",
                d.level_role,
                d.position_error,
                d.hits.error_rate(),
                d.nodes_added.map_or("not computable".into(), |n| n.to_string())
            ),
            _ => String::new(),
        })
        .collect();
    let _ = writeln!(
        md,
        "\nEach translation level at d = {at:e} (b64-local, D = {}): {}.",
        s.default_max_lod,
        rows.join("; ")
    );
}

fn modes(s: &Study, md: &mut String) {
    let _ = writeln!(md, "\n## Merging modes (D = {}, Q = {}; the pair: a case and its copy moved by half its extent)\n", s.default_max_lod, s.default_quant_bits);
    let _ = writeln!(md, "| case | mode | merging level | nodes created | nodes reused | merge ms |\n| --: | --: | --: | --: | --: | --: |");
    for m in &s.modes {
        let _ = writeln!(
            md,
            "| {} | {}{} | {} | {} | {} | {:.3} |",
            m.case,
            m.mode,
            if m.default_mode { " (default)" } else { "" },
            m.merging_level.map_or("per node".into(), |l| l.to_string()),
            m.nodes_created,
            m.nodes_reused,
            m.merge_ms
        );
    }
}

fn distance_summary(s: &Study, md: &mut String) {
    let _ = writeln!(md, "## Hit error against distance ({})\n", s.distance_case);
    for (f, what) in [
        ("b32-world", "binary32 world coordinates, no translation"),
        ("b64-world", "binary64 world coordinates"),
        (
            "b64-local",
            "translated at the top LOD, binary64 placement, binary32 local",
        ),
        (
            "b64-local-aligned",
            "translated at the top LOD, placement on the grid (residual 0)",
        ),
    ] {
        let v: Vec<String> = s
            .distance
            .iter()
            .filter(|d| d.max_lod == s.default_max_lod && d.refused.is_none())
            .filter(|d| d.format == f && (d.level.is_none() || d.level == Some(d.top_lod)))
            .map(|d| format!("{:e}: {:.3}", d.distance, d.hits.error_rate()))
            .collect();
        let _ = writeln!(
            md,
            "- {f} ({what}, D = {}): wrong + missed + extra hits per ray at each distance: {}",
            s.default_max_lod,
            v.join(", ")
        );
    }
    let fine: Vec<String> = s
        .distance
        .iter()
        .filter(|d| d.max_lod == 31 && d.format == "b64-local" && d.level_role == "D")
        .filter(|d| d.refused.is_none())
        .map(|d| {
            format!(
                "{:e}: {:.3} (position error {:.2e})",
                d.distance,
                d.hits.error_rate(),
                d.position_error
            )
        })
        .collect();
    let _ = writeln!(
        md,
        "- b64-local at L = D = 31 (the finest translation grid): {}",
        fine.join(", ")
    );
    levels(s, md);
    let refused = s.distance.iter().filter(|d| d.refused.is_some()).count();
    let _ = writeln!(
        md,
        "\n{refused} of {} translated moves were refused by the scene-extents rule (SPEC 7.4): the extents at L come from the top nodes' voxels, and a top node at LOD t spans 1/2^t of the scene, so a hierarchy whose top is shallow cannot move far at a fine L without splitting (the table lists each refusal).",
        s.distance.iter().filter(|d| d.level.is_some()).count()
    );
    let _ = writeln!(md, "\nThe translated formats keep the residual in their local geometry (SPEC 7.10): the object lands where it was asked to be, to the binary32 rounding of its local coordinates, which grow with the residual (up to half a LOD-L voxel) and not with the distance from the origin; binary32 world coordinates lose the geometry from about 1e4 on.\n");
}

/// Writes `study.md`; returns its path.
pub fn write(s: &Study, out: &Path, _outputs: &[String]) -> Result<String, String> {
    let mut md = String::new();
    let _ = writeln!(md, "# hiermerge study: what accuracy costs\n");
    let _ = writeln!(
        md,
        "Made by `{}` (seed {}) on {} ({} cores, load {} at the start), {:.0} s wall. Cases: {}.\n",
        s.command,
        s.seed,
        s.machine.cpu,
        s.machine.cores,
        s.machine.load(),
        s.wall_seconds,
        s.cases
            .iter()
            .map(|c| format!("{} ({} triangles)", c.name, c.triangles))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let case = s.cases.first().map(|c| c.name.clone()).unwrap_or_default();
    if let Some(r) = s.rows.iter().find(|r| r.case == case && r.default_config) {
        default_costs(s, r, &mut md);
        per_lod(r, &mut md);
        steps(s, &case, &mut md);
        published(s, r, &mut md);
    }
    distance_summary(s, &mut md);
    let _ = writeln!(md, "## Plots\n");
    for (file, what) in PLOTS {
        let _ = writeln!(md, "![{what}]({file}.png)\n\n{what} ([SVG]({file}.svg))\n");
    }
    let _ = writeln!(md, "## Table (the Q sweep at the default D, the D sweep at the default Q; every row in study.csv)\n");
    md += &render(&main_rows(s), true);
    modes(s, &mut md);
    let _ = writeln!(md, "\n## Hit error against distance\n");
    md += &render_distance(&s.distance, true);
    let _ = writeln!(md, "\n## Notes\n");
    for n in &s.notes {
        let _ = writeln!(md, "- {n}");
    }
    let path = out.join("study.md");
    write_atomic(&path, md.as_bytes())?;
    Ok(path.display().to_string())
}
