//! The study's plots (SPEC 13.5), each as PNG and SVG.

use std::path::Path;
use std::sync::OnceLock;

use plotters::prelude::*;

use super::chart::{Chart, Series};
use super::run::Study;
use golden::output::write_atomic;

/// Number of plots [`write_all`] draws.
pub const COUNT: usize = 6;

const SIZE: (u32, u32) = (960, 600);

/// Fonts looked for, in order (Debian's fonts-dejavu-core first).
const FONTS: [&str; 4] = [
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
];

/// Registers a sans-serif font for plotters' text, once; names what it tried on failure.
fn font() -> Result<(), String> {
    static FONT: OnceLock<Result<(), String>> = OnceLock::new();
    FONT.get_or_init(|| {
        for path in FONTS {
            if let Ok(bytes) = std::fs::read(path) {
                let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
                if plotters::style::register_font("sans-serif", FontStyle::Normal, bytes).is_ok() {
                    return Ok(());
                }
            }
        }
        Err(format!(
            "plots: no font found (tried {}); install Debian's fonts-dejavu-core (scripts/setup does)",
            FONTS.join(", ")
        ))
    })
    .clone()
}

/// Writes every plot into `out`; returns the paths written. `progress` is
/// called once per plot.
pub fn write_all(s: &Study, out: &Path, progress: &mut dyn FnMut()) -> Result<Vec<String>, String> {
    font()?;
    let mut written = Vec::new();
    for chart in charts(s) {
        let png = out.join(format!("{}.png", chart.file));
        let mut rgb = vec![0u8; (SIZE.0 * SIZE.1 * 3) as usize];
        {
            let root = BitMapBackend::with_buffer(&mut rgb, SIZE).into_drawing_area();
            chart.draw(&root)?;
        }
        hiermerge::image::write_png_small(&png, SIZE.0, SIZE.1, &rgb)?;
        let mut svg = String::new();
        {
            let root = SVGBackend::with_string(&mut svg, SIZE).into_drawing_area();
            chart.draw(&root)?;
        }
        let svg_path = out.join(format!("{}.svg", chart.file));
        write_atomic(&svg_path, svg.as_bytes())?;
        written.push(png.display().to_string());
        written.push(svg_path.display().to_string());
        progress();
    }
    Ok(written)
}

/// The file stems, in order, with what each shows (for study.md).
pub const PLOTS: [(&str, &str); COUNT] = [
    (
        "node_tests_vs_q",
        "node tests per ray against Q, one line per D",
    ),
    ("bytes_vs_q", "bytes per triangle against Q, one line per D"),
    ("merge_time_vs_q", "RTL time per merge against Q and D"),
    (
        "hit_error_vs_distance",
        "wrong, missed and extra hits per ray against distance from the origin",
    ),
    (
        "position_error_vs_distance",
        "position error against distance from the origin",
    ),
    (
        "pareto",
        "cost against accuracy, every configuration, with the Pareto front",
    ),
];

fn charts(s: &Study) -> Vec<Chart> {
    let case = s.cases.first().map(|c| c.name.clone()).unwrap_or_default();
    let rows: Vec<_> = s.rows.iter().filter(|r| r.case == case).collect();
    let default = rows.iter().find(|r| r.default_config);
    let per_d = |f: &dyn Fn(&super::sweep::Row) -> Option<f64>| -> Vec<Series> {
        s.max_lod
            .iter()
            .map(|&d| Series {
                name: format!("D = {d}"),
                points: rows
                    .iter()
                    .filter(|r| r.max_lod == d)
                    .filter_map(|r| Some((r.quant_bits as f64, f(r)?)))
                    .collect(),
                line: true,
            })
            .filter(|s| !s.points.is_empty())
            .collect()
    };
    let mark = |y: Option<f64>| {
        default.zip(y).map(|(r, y)| {
            (
                (r.quant_bits as f64, y),
                format!("default D = {} Q = {}", r.max_lod, r.quant_bits),
            )
        })
    };
    let ns = rows.iter().any(|r| r.ns_per_merge.is_some());
    let merge_y = move |r: &super::sweep::Row| {
        if ns {
            r.ns_per_merge
        } else {
            r.rtl.as_ref().map(|f| f.cycles_per_merge)
        }
    };
    vec![
        Chart {
            file: PLOTS[0].0,
            title: format!("Node tests per ray against Q ({case}, {} rays)", s.rays),
            x_label: "Q (bits per box bound)".into(),
            y_label: "node tests per ray (box tests)".into(),
            x_log: false,
            y_log: false,
            series: per_d(&|r| Some(r.node_tests_per_ray)),
            marked: mark(default.map(|r| r.node_tests_per_ray)),
            legend: SeriesLabelPosition::UpperRight,
            room_below: 0.0,
        },
        Chart {
            file: PLOTS[1].0,
            title: format!("Hierarchy size against Q ({case})"),
            x_label: "Q (bits per box bound)".into(),
            y_label: "bytes per triangle (nodes + refs + prims, bit-packed)".into(),
            x_log: false,
            y_log: false,
            series: per_d(&|r| Some(r.bytes_per_triangle)),
            marked: mark(default.map(|r| r.bytes_per_triangle)),
            legend: SeriesLabelPosition::UpperLeft,
            room_below: 0.0,
        },
        Chart {
            file: PLOTS[2].0,
            title: if ns {
                "Time per merge against Q and D (RTL cycles / Fmax)".into()
            } else {
                "RTL cycles per merge against Q and D (ns per merge: not measured, no Fmax yet)"
                    .into()
            },
            x_label: "Q (bits per box bound)".into(),
            y_label: if ns {
                "ns per merge".into()
            } else {
                "cycles per merge (Verilator, no stalls)".into()
            },
            x_log: false,
            y_log: false,
            series: per_d(&merge_y),
            marked: mark(default.and_then(|r| merge_y(r))),
            legend: SeriesLabelPosition::UpperLeft,
            room_below: 0.0,
        },
        distance_chart(s, true),
        distance_chart(s, false),
        pareto(s, &case),
    ]
}

/// The series of the distance plots: untranslated formats, and translated
/// ones at the top LOD (b64-local also at L = D); at the default D, and
/// b64-local at L = D = 31 (`true`: D = 31).
const DISTANCE_SERIES: [(&str, &str, bool); 7] = [
    ("b32-world", "-", false),
    ("b64-world", "-", false),
    ("b64-local", "top", false),
    ("b32-local", "top", false),
    ("b64-local", "D", false),
    ("b64-local", "D", true),
    ("b64-local-aligned", "top", false),
];

fn distance_series(
    s: &Study,
    f: &dyn Fn(&super::distance::DistanceRow) -> f64,
    log: bool,
) -> Vec<Series> {
    DISTANCE_SERIES
        .iter()
        .map(|&(format, role, d31)| {
            let dd = if d31 { 31 } else { s.default_max_lod };
            let points: Vec<(f64, f64)> = s
                .distance
                .iter()
                .filter(|d| d.format == format && d.level_role == role && d.max_lod == dd)
                .filter(|d| d.refused.is_none())
                .map(|d| (d.distance, f(d)))
                .collect();
            let zeros = points.iter().filter(|p| p.1 <= 0.0).count();
            let mut name = match role {
                "-" => format.to_string(),
                r => format!("{format}, L = {r}, D = {dd}"),
            };
            if log && zeros > 0 {
                name += &format!(" ({zeros} of {} at 0, not drawn)", points.len());
            }
            Series {
                name,
                points,
                line: true,
            }
        })
        .collect()
}

fn distance_chart(s: &Study, hits: bool) -> Chart {
    let (file, title, y_label, y_log): (_, _, String, _) = if hits {
        (
            PLOTS[3].0,
            format!(
                "Hit error against distance ({}, {} rays, vs binary64 reference)",
                s.distance_case, s.distance_rays
            ),
            "wrong + missed + extra hits per ray".into(),
            false,
        )
    } else {
        (
            PLOTS[4].0,
            format!("Position error against distance ({})", s.distance_case),
            "largest position error per axis, world units (log)".into(),
            true,
        )
    };
    let series = if hits {
        distance_series(s, &|d| d.hits.error_rate(), false)
    } else {
        distance_series(s, &|d| d.position_error, true)
    };
    Chart {
        file,
        title,
        x_label: "distance of the object from the origin, world units (log)".into(),
        y_label,
        x_log: true,
        y_log,
        series,
        marked: None,
        legend: if hits {
            SeriesLabelPosition::MiddleLeft
        } else {
            SeriesLabelPosition::LowerRight
        },
        room_below: if hits { 0.0 } else { 0.5 },
    }
}

fn pareto(s: &Study, case: &str) -> Chart {
    let pts: Vec<(f64, f64)> = s
        .rows
        .iter()
        .filter(|r| r.case == case)
        .map(|r| (r.bytes_per_triangle, r.false_hits_per_ray))
        .collect();
    let mut front: Vec<(f64, f64)> = pts
        .iter()
        .copied()
        .filter(|p| {
            !pts.iter()
                .any(|q| q.0 <= p.0 && q.1 <= p.1 && (q.0 < p.0 || q.1 < p.1))
        })
        .collect();
    front.sort_by(|a, b| a.0.total_cmp(&b.0));
    let default = s.rows.iter().find(|r| r.case == case && r.default_config);
    Chart {
        file: PLOTS[5].0,
        title: format!("Cost against accuracy ({case}, every D and Q)"),
        x_label: "cost: bytes per triangle".into(),
        y_label: "inaccuracy: false box hits per ray".into(),
        x_log: false,
        y_log: false,
        series: vec![
            Series {
                name: "configurations".into(),
                points: pts,
                line: false,
            },
            Series {
                name: "Pareto front".into(),
                points: front,
                line: true,
            },
        ],
        marked: default.map(|r| {
            (
                (r.bytes_per_triangle, r.false_hits_per_ray),
                format!("default D = {} Q = {}", r.max_lod, r.quant_bits),
            )
        }),
        legend: SeriesLabelPosition::UpperRight,
        room_below: 0.0,
    }
}
