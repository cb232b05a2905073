//! Charts for the run directory, as SVG (no font files needed: text is emitted as SVG text).
//! One generic line/scatter chart, one histogram and one stacked bar chart; the report decides
//! what to draw.

use std::path::Path;

use anyhow::{anyhow, Result};
use plotters::prelude::*;

/// One series of a line chart.
pub struct Series<'a> {
    pub label: &'a str,
    pub points: Vec<(f64, f64)>,
    pub color: RGBColor,
    /// Draw markers instead of a line.
    pub markers: bool,
}

/// Drops every other element of a series (the first is kept): how a long run's series
/// stay bounded while spanning the whole run.
pub fn thin_by_half<T>(v: &mut Vec<T>) {
    let mut k = 0;
    v.retain(|_| {
        k += 1;
        k % 2 == 1
    });
}

pub const BLUE: RGBColor = RGBColor(31, 119, 180);
pub const GREEN: RGBColor = RGBColor(44, 160, 44);
pub const RED: RGBColor = RGBColor(214, 39, 40);
pub const ORANGE: RGBColor = RGBColor(255, 127, 14);
pub const PURPLE: RGBColor = RGBColor(148, 103, 189);
pub const GREY: RGBColor = RGBColor(190, 190, 190);

fn bounds(series: &[Series]) -> ((f64, f64), (f64, f64)) {
    let mut x = (f64::INFINITY, f64::NEG_INFINITY);
    let mut y = (f64::INFINITY, f64::NEG_INFINITY);
    for s in series {
        for &(px, py) in &s.points {
            if px.is_finite() && py.is_finite() {
                x = (x.0.min(px), x.1.max(px));
                y = (y.0.min(py), y.1.max(py));
            }
        }
    }
    let pad = |(lo, hi): (f64, f64)| {
        if !lo.is_finite() {
            return (0.0, 1.0);
        }
        let span = (hi - lo)
            .abs()
            .max(hi.abs().max(lo.abs()) * 1e-9)
            .max(1e-300);
        (lo - 0.05 * span, hi + 0.05 * span)
    };
    (pad(x), pad(y))
}

/// A tick label readable at any scale: scientific notation for very small or large axes
/// (fluxes are ~1e-14 W).
fn tick_label(v: f64, axis_scale: f64) -> String {
    if axis_scale > 0.0 && !(1e-2..1e5).contains(&axis_scale) {
        format!("{v:.2e}")
    } else {
        format!("{v:.3}")
    }
}

/// Writes a line chart to `path`.
pub fn line_chart(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
) -> Result<()> {
    let root = SVGBackend::new(path, (900, 500)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| anyhow!("{e:?}"))?;
    let ((x0, x1), (y0, y1)) = bounds(series);
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(80)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(|e| anyhow!("{e:?}"))?;
    let y_scale = y0.abs().max(y1.abs());
    chart
        .configure_mesh()
        .x_desc(x_label)
        .y_desc(y_label)
        .y_label_formatter(&|v| tick_label(*v, y_scale))
        .draw()
        .map_err(|e| anyhow!("{e:?}"))?;
    for s in series {
        let color = s.color;
        let pts: Vec<(f64, f64)> = s
            .points
            .iter()
            .copied()
            .filter(|(a, b)| a.is_finite() && b.is_finite())
            .collect();
        if s.markers {
            chart
                .draw_series(pts.iter().map(|&p| Circle::new(p, 2, color.filled())))
                .map_err(|e| anyhow!("{e:?}"))?
                .label(s.label)
                .legend(move |(x, y)| Circle::new((x + 10, y), 3, color.filled()));
        } else {
            chart
                .draw_series(LineSeries::new(pts, color.stroke_width(2)))
                .map_err(|e| anyhow!("{e:?}"))?
                .label(s.label)
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
                });
        }
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(|e| anyhow!("{e:?}"))?;
    root.present().map_err(|e| anyhow!("{e:?}"))?;
    Ok(())
}

/// Histogram of `values` over log10-spaced bins, drawn as bars (x in log10 units).
pub fn log_histogram(path: &Path, title: &str, x_label: &str, values: &[(f64, u64)]) -> Result<()> {
    let logs: Vec<(f64, u64)> = values
        .iter()
        .filter(|(v, _)| *v > 0.0)
        .map(|(v, n)| (v.log10(), *n))
        .collect();
    if logs.is_empty() {
        return Ok(());
    }
    let lo = logs
        .iter()
        .map(|l| l.0)
        .fold(f64::INFINITY, f64::min)
        .floor();
    let hi = logs
        .iter()
        .map(|l| l.0)
        .fold(f64::NEG_INFINITY, f64::max)
        .ceil()
        .max(lo + 1.0);
    let bins = ((hi - lo) * 10.0).round().max(1.0) as usize;
    let width = (hi - lo) / bins as f64;
    let mut counts = vec![0u64; bins];
    for (l, n) in &logs {
        let i = (((l - lo) / width) as usize).min(bins - 1);
        counts[i] += n;
    }
    let max = *counts.iter().max().unwrap_or(&1) as f64;
    let root = SVGBackend::new(path, (900, 400)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| anyhow!("{e:?}"))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(lo..hi, 0.0..max * 1.1)
        .map_err(|e| anyhow!("{e:?}"))?;
    chart
        .configure_mesh()
        .x_desc(x_label)
        .y_desc("count")
        .x_label_formatter(&|v| format!("{:.3}", 10f64.powf(*v)))
        .draw()
        .map_err(|e| anyhow!("{e:?}"))?;
    chart
        .draw_series(counts.iter().enumerate().map(|(i, c)| {
            let x0 = lo + i as f64 * width;
            Rectangle::new([(x0, 0.0), (x0 + width * 0.9, *c as f64)], BLUE.filled())
        }))
        .map_err(|e| anyhow!("{e:?}"))?;
    root.present().map_err(|e| anyhow!("{e:?}"))?;
    Ok(())
}

/// One bar of a stacked bar chart: its name and its segments' lengths, in the parts' order.
pub struct Bar<'a> {
    pub name: &'a str,
    pub lengths: Vec<f64>,
}

/// Horizontal bars, one per row, each the sum of `parts` (name, color) laid end to end.
pub fn stacked_bars(
    path: &Path,
    title: &str,
    x_label: &str,
    parts: &[(&str, RGBColor)],
    bars: &[Bar],
) -> Result<()> {
    let total = |b: &Bar| b.lengths.iter().filter(|v| v.is_finite()).sum::<f64>();
    let x1 = bars.iter().map(total).fold(0.0, f64::max).max(1e-12) * 1.05;
    let n = bars.len().max(1);
    let root = SVGBackend::new(path, (900, 120 + 60 * n as u32)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| anyhow!("{e:?}"))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(110)
        .build_cartesian_2d(0.0..x1, 0.0..n as f64)
        .map_err(|e| anyhow!("{e:?}"))?;
    let names: Vec<&str> = bars.iter().map(|b| b.name).collect();
    chart
        .configure_mesh()
        .disable_y_mesh()
        .x_desc(x_label)
        .y_labels(n * 2 + 1)
        .y_label_formatter(&|v| {
            // Labels at the bars' middles (k + 0.5), none elsewhere.
            let k = v.floor();
            match (v - k - 0.5).abs() < 1e-6 {
                true => names
                    .get(k as usize)
                    .map_or(String::new(), |s| s.to_string()),
                false => String::new(),
            }
        })
        .draw()
        .map_err(|e| anyhow!("{e:?}"))?;
    for (j, &(label, color)) in parts.iter().enumerate() {
        let rects = bars.iter().enumerate().map(|(k, b)| {
            let start: f64 = b.lengths[..j].iter().filter(|v| v.is_finite()).sum();
            let len = b
                .lengths
                .get(j)
                .copied()
                .filter(|v| v.is_finite())
                .unwrap_or(0.0);
            let y = k as f64;
            Rectangle::new([(start, y + 0.2), (start + len, y + 0.8)], color.filled())
        });
        chart
            .draw_series(rects)
            .map_err(|e| anyhow!("{e:?}"))?
            .label(label)
            .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 14, y + 5)], color.filled()));
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::LowerRight)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(|e| anyhow!("{e:?}"))?;
    root.present().map_err(|e| anyhow!("{e:?}"))?;
    Ok(())
}
