//! `glint bench scaling`: the pipeline bench swept over frame size (at four debris) and over
//! the number of debris (at 1024²), each point a deployment beside its in-process baseline.
//!
//! The answer is how each stage's cost grows: the exponent of a log–log least-squares fit of
//! the in-process core time per frame against pixels (the detector should be ≈ 1) and against
//! targets (the tracker). The frames per point scale inversely with the pixels, so every point
//! does about the same work.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde::Serialize;
use serde_json::json;
use shared_types::scenario::Clock;

use super::pipeline::{self, PipelineOptions};
use crate::plots::{self, Series};

/// Options of `glint bench scaling`.
pub struct ScalingOptions {
    pub out: PathBuf,
    /// Frames of a 1024² point; other sizes get frames ∝ 1/pixels (20 to 4× this).
    pub frames: u64,
    pub sizes: Vec<(u32, u32)>,
    pub targets: Vec<usize>,
    pub laser: bool,
}

/// Debris of the size sweep, frame side of the targets sweep: the paper's scene.
const SIZE_SWEEP_TARGETS: usize = 4;
const TARGET_SWEEP_SIDE_PX: u32 = 1024;

/// One point of a sweep.
#[derive(Serialize)]
pub struct ScalingPoint {
    /// `size` or `targets`: the sweep the point belongs to.
    pub sweep: &'static str,
    pub width_px: u32,
    pub height_px: u32,
    pub pixels: u64,
    pub targets: usize,
    pub frames: u64,
    pub fps: f64,
    pub in_process_fps: f64,
    pub dropped: u64,
    /// CPU per frame of each process of the deployment [ms].
    pub cpu_ms_per_frame: serde_json::Map<String, serde_json::Value>,
    /// Mean in-process time per frame of each core [µs].
    pub core_us: serde_json::Map<String, serde_json::Value>,
}

impl ScalingPoint {
    fn core(&self, name: &str) -> f64 {
        self.core_us
            .get(name)
            .and_then(|v| v.as_f64())
            .unwrap_or(f64::NAN)
    }
}

/// Frames of a point: the 1024² count scaled by 1024²/pixels, 20 to 4× the 1024² count.
pub fn frames_for(frames_1024: u64, pixels: u64) -> u64 {
    let scaled = frames_1024 as f64 * (1024.0 * 1024.0) / pixels.max(1) as f64;
    (scaled.round() as u64).clamp(20.min(frames_1024), frames_1024.saturating_mul(4))
}

/// Slope of the least-squares line through (log x, log y): the exponent of y ∝ x^b.
pub fn log_log_slope(points: &[(f64, f64)]) -> f64 {
    let pts: Vec<(f64, f64)> = (points.iter())
        .filter(|(x, y)| *x > 0.0 && *y > 0.0 && x.is_finite() && y.is_finite())
        .map(|(x, y)| (x.ln(), y.ln()))
        .collect();
    let n = pts.len() as f64;
    if pts.len() < 2 {
        return f64::NAN;
    }
    let (mx, my) = (
        pts.iter().map(|p| p.0).sum::<f64>() / n,
        pts.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let sxy: f64 = pts.iter().map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = pts.iter().map(|(x, _)| (x - mx).powi(2)).sum();
    if sxx > 0.0 {
        sxy / sxx
    } else {
        f64::NAN
    }
}

/// Runs both sweeps, prints the exponents and the tables, writes bench.json's `scaling`
/// section, `scaling.csv` and the plots.
pub fn run(o: &ScalingOptions) -> Result<()> {
    std::fs::create_dir_all(&o.out).with_context(|| format!("creating {}", o.out.display()))?;
    let mut plan: Vec<(&'static str, (u32, u32), usize)> = (o.sizes.iter())
        .map(|&s| ("size", s, SIZE_SWEEP_TARGETS))
        .collect();
    plan.extend(
        (o.targets.iter()).map(|&k| ("targets", (TARGET_SWEEP_SIDE_PX, TARGET_SWEEP_SIDE_PX), k)),
    );
    let bar = crate::progress::points_bar(plan.len() as u64);
    let mut points = vec![];
    for (i, (sweep, (w, h), k)) in plan.into_iter().enumerate() {
        bar.set_message(format!("{w}×{h}, {k} debris"));
        let po = PipelineOptions {
            out: o.out.clone(),
            frames: frames_for(o.frames, u64::from(w) * u64::from(h)),
            width_px: w,
            height_px: h,
            targets: k,
            clock: Clock::Sim,
            laser: o.laser,
        };
        let sc =
            pipeline::scenario(&po).map_err(|e| anyhow::anyhow!("{w}×{h}, {k} debris: {e}"))?;
        let p = super::measure(sc, o.out.join(format!("run-{i:02}")), false)?;
        points.push(point(sweep, &po, &p));
        bar.inc(1);
    }
    bar.finish_and_clear();
    let slopes = Slopes::of(&points);
    print(&points, &slopes);
    write_outputs(&o.out, &points, &slopes)?;
    println!("\n{}", o.out.join("bench.json").display());
    Ok(())
}

fn point(sweep: &'static str, po: &PipelineOptions, p: &super::Point) -> ScalingPoint {
    let d = &p.deployed;
    let ip = &p.in_process;
    let per_frame = d.frames.max(1) as f64;
    ScalingPoint {
        sweep,
        width_px: po.width_px,
        height_px: po.height_px,
        pixels: u64::from(po.width_px) * u64::from(po.height_px),
        targets: po.targets,
        frames: d.frames,
        fps: d.fps,
        in_process_fps: ip.frames as f64 / ip.wall_s.max(1e-9),
        dropped: d.dropped,
        cpu_ms_per_frame: (d.cpu_s.iter())
            .map(|(n, c)| (n.clone(), json!(c * 1e3 / per_frame)))
            .collect(),
        core_us: (ip.stages.iter())
            .map(|(n, ns)| (n.to_string(), json!(pipeline::stats_us(ns).0)))
            .collect(),
    }
}

/// The growth exponents, each from one sweep.
#[derive(Serialize)]
pub struct Slopes {
    pub render_vs_pixels: f64,
    pub detect_vs_pixels: f64,
    pub track_vs_targets: f64,
    pub detect_vs_targets: f64,
}

impl Slopes {
    fn of(points: &[ScalingPoint]) -> Self {
        let fit = |sweep: &str, x: &dyn Fn(&ScalingPoint) -> f64, core: &str| {
            let pts: Vec<(f64, f64)> = (points.iter().filter(|p| p.sweep == sweep))
                .map(|p| (x(p), p.core(core)))
                .collect();
            log_log_slope(&pts)
        };
        let px = |p: &ScalingPoint| p.pixels as f64;
        let k = |p: &ScalingPoint| p.targets as f64;
        Slopes {
            render_vs_pixels: fit("size", &px, "render"),
            detect_vs_pixels: fit("size", &px, "detect"),
            track_vs_targets: fit("targets", &k, "track"),
            detect_vs_targets: fit("targets", &k, "detect"),
        }
    }
}

fn print(points: &[ScalingPoint], s: &Slopes) {
    println!(
        "scaling: detector cost ∝ pixels^{:.2}, render ∝ pixels^{:.2}; tracker cost ∝ \
         targets^{:.2} (detector ∝ targets^{:.2})",
        s.detect_vs_pixels, s.render_vs_pixels, s.track_vs_targets, s.detect_vs_targets
    );
    for sweep in ["size", "targets"] {
        let rows: Vec<&ScalingPoint> = points.iter().filter(|p| p.sweep == sweep).collect();
        if rows.is_empty() {
            continue;
        }
        println!("\nagainst {sweep}\n");
        println!(
            "{:<11} {:>7} {:>6} {:>9} {:>9} {:>8} {:>11} {:>11} {:>10} {:>9}",
            "frame",
            "debris",
            "frames",
            "frames/s",
            "in-proc/s",
            "dropped",
            "render [µs]",
            "detect [µs]",
            "track [µs]",
            "ns/px det"
        );
        for p in rows {
            println!(
                "{:<11} {:>7} {:>6} {:>9.0} {:>9.0} {:>8} {:>11.1} {:>11.1} {:>10.2} {:>9.3}",
                format!("{}×{}", p.width_px, p.height_px),
                p.targets,
                p.frames,
                p.fps,
                p.in_process_fps,
                p.dropped,
                p.core("render"),
                p.core("detect"),
                p.core("track"),
                p.core("detect") * 1e3 / p.pixels as f64,
            );
        }
    }
}

fn write_outputs(dir: &Path, points: &[ScalingPoint], s: &Slopes) -> Result<()> {
    super::merge_bench_json(
        dir,
        json!({
            "glint_version": env!("CARGO_PKG_VERSION"),
            "host": super::host(),
            "scaling": {
                "method": "each point a `glint bench pipeline` deployment (sim clock) and its \
                           in-process baseline; core_us = mean in-process time per frame; \
                           exponents = slope of a least-squares line through (ln x, ln core_us)",
                "exponents": s,
                "points": points,
            }
        }),
    )?;
    let mut csv = csv::Writer::from_path(dir.join("scaling.csv"))?;
    csv.write_record([
        "sweep",
        "width_px",
        "height_px",
        "targets",
        "frames",
        "fps",
        "in_process_fps",
        "dropped",
        "render_us",
        "checksum_us",
        "detect_us",
        "track_us",
        "laser_us",
    ])?;
    for p in points {
        let mut rec = vec![
            p.sweep.to_string(),
            p.width_px.to_string(),
            p.height_px.to_string(),
            p.targets.to_string(),
            p.frames.to_string(),
            format!("{:.1}", p.fps),
            format!("{:.1}", p.in_process_fps),
            p.dropped.to_string(),
        ];
        for core in ["render", "checksum", "detect", "track", "laser"] {
            rec.push(format!("{:.3}", p.core(core)));
        }
        csv.write_record(rec)?;
    }
    csv.flush()?;
    plot(dir, points)
}

fn plot(dir: &Path, points: &[ScalingPoint]) -> Result<()> {
    type Pick = fn(&ScalingPoint) -> f64;
    let series = |sweep: &str, x: Pick, ys: &[(&'static str, Pick, plotters::style::RGBColor)]| {
        (ys.iter())
            .map(|&(label, y, color)| Series {
                label,
                points: (points.iter().filter(|p| p.sweep == sweep))
                    .map(|p| (x(p).log10(), y(p).log10()))
                    .collect(),
                color,
                markers: false,
            })
            .collect::<Vec<_>>()
    };
    let px: Pick = |p| p.pixels as f64;
    let k: Pick = |p| p.targets as f64;
    let fps: [(&str, Pick, _); 2] = [
        ("processes", |p| p.fps, plots::BLUE),
        ("one process", |p| p.in_process_fps, plots::ORANGE),
    ];
    let cores: [(&str, Pick, _); 3] = [
        ("render", |p| p.core("render"), plots::BLUE),
        ("detect", |p| p.core("detect"), plots::GREEN),
        ("track", |p| p.core("track"), plots::RED),
    ];
    let charts = [
        (
            "scaling-fps-vs-size.svg",
            "frames/s against frame size (4 debris)",
            "log10 pixels",
            "log10 frames/s",
            series("size", px, &fps),
        ),
        (
            "scaling-cost-vs-size.svg",
            "core time per frame against frame size",
            "log10 pixels",
            "log10 µs per frame",
            series("size", px, &cores),
        ),
        (
            "scaling-fps-vs-targets.svg",
            "frames/s against debris (1024²)",
            "log10 debris",
            "log10 frames/s",
            series("targets", k, &fps),
        ),
        (
            "scaling-cost-vs-targets.svg",
            "core time per frame against debris",
            "log10 debris",
            "log10 µs per frame",
            series("targets", k, &cores),
        ),
    ];
    for (file, title, x, y, s) in charts {
        if s.iter().any(|s| !s.points.is_empty()) {
            plots::line_chart(&dir.join(file), title, x, y, &s)?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_slope_of_a_power_law_is_its_exponent() {
        let pts: Vec<(f64, f64)> = (1..=5)
            .map(|i| (i as f64 * 10.0, 3.0 * (i as f64 * 10.0).powf(1.5)))
            .collect();
        assert!((log_log_slope(&pts) - 1.5).abs() < 1e-12);
        assert!(log_log_slope(&pts[..1]).is_nan());
    }

    #[test]
    fn frames_scale_inversely_with_pixels_within_bounds() {
        assert_eq!(frames_for(500, 1024 * 1024), 500);
        assert_eq!(frames_for(500, 512 * 512), 2000);
        assert_eq!(frames_for(500, 256 * 256), 2000);
        assert_eq!(frames_for(500, 2048 * 2048), 125);
        assert_eq!(frames_for(500, 4096 * 4096), 31);
        assert_eq!(frames_for(100, 4096 * 4096), 20);
        assert_eq!(frames_for(5, 4096 * 4096), 5);
    }
}
