//! One line chart on any plotters backend: series, axes labelled with their
//! units, a legend, the default configuration marked. A log axis plots
//! log10 of its values and labels its ticks as powers of ten.

use plotters::coord::Shift;
use plotters::prelude::*;

/// A named series of points.
pub struct Series {
    pub name: String,
    pub points: Vec<(f64, f64)>,
    /// Joined by a line (else points only).
    pub line: bool,
}

/// A chart and what it shows.
pub struct Chart {
    /// File stem: `<file>.png`, `<file>.svg`.
    pub file: &'static str,
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub x_log: bool,
    pub y_log: bool,
    pub series: Vec<Series>,
    /// The default configuration: point and legend text.
    pub marked: Option<((f64, f64), String)>,
    /// Where the legend goes.
    pub legend: SeriesLabelPosition,
    /// Empty room below the data, as a fraction of its span (for the legend).
    pub room_below: f64,
}

fn axis(v: f64, log: bool) -> Option<f64> {
    if !v.is_finite() {
        return None;
    }
    if log {
        (v > 0.0).then(|| v.log10())
    } else {
        Some(v)
    }
}

fn tick(v: f64, log: bool) -> String {
    if log {
        if (v - v.round()).abs() < 1e-9 {
            format!("1e{}", v.round() as i64)
        } else {
            String::new()
        }
    } else if v.abs() >= 1e4 || (v != 0.0 && v.abs() < 1e-2) {
        format!("{v:.1e}")
    } else {
        format!("{}", (v * 1000.0).round() / 1000.0)
    }
}

impl Chart {
    /// The plotted points of series `s` (log axes: log10; dropped: not positive).
    fn mapped(&self, pts: &[(f64, f64)]) -> Vec<(f64, f64)> {
        pts.iter()
            .filter_map(|&(x, y)| Some((axis(x, self.x_log)?, axis(y, self.y_log)?)))
            .collect()
    }

    fn ranges(&self) -> ((f64, f64), (f64, f64)) {
        let all: Vec<(f64, f64)> = self
            .series
            .iter()
            .flat_map(|s| self.mapped(&s.points))
            .collect();
        let span = |v: Vec<f64>| {
            let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            if !lo.is_finite() {
                return (0.0, 1.0);
            }
            let pad = ((hi - lo) * 0.06).max(if hi == lo { 0.5 } else { 0.0 });
            (lo - pad, hi + pad)
        };
        let (y0, y1) = span(all.iter().map(|p| p.1).collect());
        (
            span(all.iter().map(|p| p.0).collect()),
            (y0 - (y1 - y0) * self.room_below, y1),
        )
    }

    /// Draws the chart on `root`.
    pub fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), String>
    where
        DB::ErrorType: 'static,
    {
        let e = |e: DrawingAreaErrorKind<DB::ErrorType>| format!("{}: {e}", self.file);
        root.fill(&WHITE).map_err(e)?;
        let ((x0, x1), (y0, y1)) = self.ranges();
        let mut chart = ChartBuilder::on(root)
            .caption(&self.title, ("sans-serif", 20))
            .margin(14)
            .x_label_area_size(50)
            .y_label_area_size(80)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(e)?;
        let (xl, yl) = (self.x_log, self.y_log);
        chart
            .configure_mesh()
            .x_desc(&self.x_label)
            .y_desc(&self.y_label)
            .x_label_formatter(&|v| tick(*v, xl))
            .y_label_formatter(&|v| tick(*v, yl))
            .label_style(("sans-serif", 14))
            .draw()
            .map_err(e)?;
        for (i, s) in self.series.iter().enumerate() {
            let color = Palette99::pick(i).to_rgba();
            let pts = self.mapped(&s.points);
            let mut name = s.name.clone();
            if let Some(twin) = self.series[..i].iter().find(|t| t.points == s.points) {
                name += &format!(" (under {})", twin.name);
            }
            if s.line {
                chart
                    .draw_series(LineSeries::new(pts.clone(), color.stroke_width(2)))
                    .map_err(e)?
                    .label(&s.name)
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
                    });
                chart
                    .draw_series(pts.iter().map(|p| Circle::new(*p, 3, color.filled())))
                    .map_err(e)?;
            } else {
                chart
                    .draw_series(pts.iter().map(|p| Circle::new(*p, 3, color.filled())))
                    .map_err(e)?
                    .label(&name)
                    .legend(move |(x, y)| Circle::new((x + 10, y), 3, color.filled()));
            }
        }
        if let Some((p, label)) = &self.marked {
            if let (Some(x), Some(y)) = (axis(p.0, xl), axis(p.1, yl)) {
                chart
                    .draw_series(std::iter::once(Cross::new((x, y), 9, RED.stroke_width(3))))
                    .map_err(e)?
                    .label(label)
                    .legend(|(x, y)| Cross::new((x + 10, y), 6, RED.stroke_width(3)));
            }
        }
        chart
            .configure_series_labels()
            .label_font(("sans-serif", 14))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .position(self.legend.clone())
            .draw()
            .map_err(e)?;
        root.present().map_err(e)?;
        Ok(())
    }
}
