//! The debris part of the report: `detection` and `tracking` sections, the summary table, and
//! the pictures — α/β measured vs filtered vs truth, EKF position error with its 3σ bound, and
//! one annotated frame.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::Result;
use glint_physics::camera::PinholeCamera;
use nalgebra::Vector3;
use shared_types::{Detections, Truth};

use crate::plots::{line_chart, Series, BLUE, GREEN, RED};
use crate::report::score_debris::{DebrisScore, SeriesPoint};

pub fn markdown(score: &DebrisScore) -> String {
    let d = &score.detection;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "\n## Debris detection and tracking ([002])\n\nDetections vs truth (gate {} px, frames after the first): precision {:.3}, recall {:.3} ({} true, {} false, {} missed over {} frames); false targets rejected: {} of {}.\n",
        crate::report::score_debris::GATE_PX,
        d.precision,
        d.recall,
        d.true_positives,
        d.false_positives,
        d.missed,
        d.frames_scored,
        d.false_targets_rejected,
        d.false_targets
    );
    // Without a laser (`camera.tracker.laser = false`) there is no range: no direct fix,
    // no EKF, and their columns would hold only NaN.
    let ranged = score.targets.iter().any(|t| t.laser_shots > 0);
    if ranged {
        s.push_str("| debris | track | frames | α err RMS meas / filt [deg] | β err RMS meas / filt [deg] | direct fix RMS [m] | EKF pos err final [m] | EKF vel err final [m/s] | NEES mean (95 % bounds) | laser hits |\n|---|---|---|---|---|---|---|---|---|---|\n");
    } else {
        s.push_str("No laser ranges in this run: angles only (the direct fix and the EKF need a range).\n\n| debris | track | frames | α err RMS meas / filt [deg] | β err RMS meas / filt [deg] |\n|---|---|---|---|---|\n");
    }
    for t in &score.targets {
        let _ = write!(
            s,
            "| {} | {} | {} | {:.2e} / {:.2e} | {:.2e} / {:.2e} |",
            t.id,
            t.track_id.map_or("—".into(), |v| v.to_string()),
            t.frames_tracked,
            t.azimuth_err_deg_rms_measured,
            t.azimuth_err_deg_rms_filtered,
            t.elevation_err_deg_rms_measured,
            t.elevation_err_deg_rms_filtered,
        );
        if ranged {
            let _ = write!(
                s,
                " {:.3} | {:.3} | {:.3} | {:.2} ({:.2}–{:.2}) | {}/{} |",
                t.pos_err_m_rms_direct,
                t.pos_err_m_final,
                t.vel_err_mps_final,
                t.nees_mean,
                t.nees_bounds[0],
                t.nees_bounds[1],
                t.laser_hits,
                t.laser_shots
            );
        }
        s.push('\n');
    }
    s.push_str("\n![angle errors](debris-angles.svg)\n\n");
    if ranged {
        s.push_str("![EKF position error](debris-ekf.svg)\n\n");
    }
    s.push_str("![annotated frame](frame-annotated.svg)\n");
    s
}

/// Writes the debris pictures into `dir`.
pub fn plots(
    dir: &Path,
    score: &DebrisScore,
    camera: &PinholeCamera,
    snapshot: Option<&crate::run::taps::Snapshot>,
    detections: &[Detections],
    truths: &[Truth],
) -> Result<()> {
    let colors = [BLUE, GREEN, RED, crate::plots::ORANGE];
    let labels: Vec<(String, String)> = score
        .targets
        .iter()
        .map(|t| (format!("#{} measured", t.id), format!("#{} filtered", t.id)))
        .collect();
    let mut series = vec![];
    for (i, s) in score.series.iter().enumerate() {
        let c = colors[i % colors.len()];
        let err = |a: fn(&SeriesPoint) -> f64, b: fn(&SeriesPoint) -> f64| -> Vec<(f64, f64)> {
            (s.points.iter())
                .map(|p| (p.t_s, (a(p) - b(p)) * 3600.0))
                .collect()
        };
        series.push(Series {
            label: &labels[i].0,
            points: err(|p| p.azimuth_meas_deg, |p| p.azimuth_true_deg),
            color: c,
            markers: true,
        });
        series.push(Series {
            label: &labels[i].1,
            points: err(|p| p.azimuth_filt_deg, |p| p.azimuth_true_deg),
            color: c,
            markers: false,
        });
    }
    line_chart(
        &dir.join("debris-angles.svg"),
        "Azimuth minus truth: measured (dots) and after the angle filter (lines)",
        "time [s]",
        "α − α_true [arcsec]",
        &series,
    )?;
    let bound_labels: Vec<(String, String)> = score
        .targets
        .iter()
        .map(|t| (format!("#{} |Δr|", t.id), format!("#{} 3σ", t.id)))
        .collect();
    let mut series = vec![];
    for (i, s) in score.series.iter().enumerate() {
        let c = colors[i % colors.len()];
        let ekf: Vec<(f64, (f64, f64))> = (s.points.iter())
            .filter_map(|p| Some((p.t_s, p.pos_err_m?)))
            .collect();
        series.push(Series {
            label: &bound_labels[i].0,
            points: ekf.iter().map(|(t, (e, _))| (*t, *e)).collect(),
            color: c,
            markers: false,
        });
        series.push(Series {
            label: &bound_labels[i].1,
            points: ekf.iter().map(|(t, (_, b))| (*t, *b)).collect(),
            color: c,
            markers: true,
        });
    }
    // No EKF without laser ranges: no picture of it (the summary says why).
    if series.iter().any(|s| !s.points.is_empty()) {
        line_chart(
            &dir.join("debris-ekf.svg"),
            "EKF position error and its 3σ bound",
            "time [s]",
            "position error [m]",
            &series,
        )?;
    }
    if let Some(snap) = snapshot {
        let (k, w, h) = (snap.frame_index, snap.width_px, snap.height_px);
        annotated_frame(dir, camera, k, w, h, &snap.pixels, detections, truths)?;
    }
    Ok(())
}

/// `frame-NNNN.png` (2× max-pooled, contrast stretched) and `frame-annotated.svg` drawing the
/// detections (circles, track ids) and the truth positions (crosses) over it.
#[allow(clippy::too_many_arguments)]
fn annotated_frame(
    dir: &Path,
    camera: &PinholeCamera,
    k: u64,
    w: u32,
    h: u32,
    px: &[u16],
    detections: &[Detections],
    truths: &[Truth],
) -> Result<()> {
    let (w, h) = (w as usize, h as usize);
    let (ow, oh) = (w.div_ceil(2), h.div_ceil(2));
    let mut sorted: Vec<u16> = px.iter().step_by(7).copied().collect();
    sorted.sort_unstable();
    let lo = sorted[sorted.len() / 2] as f64;
    let hi = (lo + 12.0 * (sorted[sorted.len() * 84 / 100] as f64 - lo).max(1.0)).max(lo + 1.0);
    let mut img = vec![0u8; ow * oh];
    for y in 0..h {
        for x in 0..w {
            let v = ((px[y * w + x] as f64 - lo) / (hi - lo)).clamp(0.0, 1.0);
            let v = (v.sqrt() * 255.0) as u8;
            let o = &mut img[(y / 2) * ow + x / 2];
            *o = (*o).max(v);
        }
    }
    let png_name = format!("frame-{k:04}.png");
    std::fs::write(dir.join(&png_name), crate::png::encode_gray8(ow, oh, &img)?)?;
    let mut svg = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" xmlns:xlink=\"http://www.w3.org/1999/xlink\" width=\"{ow}\" height=\"{}\" viewBox=\"0 0 {ow} {}\">\n<image href=\"{png_name}\" xlink:href=\"{png_name}\" x=\"0\" y=\"0\" width=\"{ow}\" height=\"{oh}\"/>\n",
        oh + 24,
        oh + 24
    );
    if let Some(t) = truths
        .iter()
        .find(|t| t.kind == Truth::KIND_FRAME && t.frame_index == k)
    {
        for i in 0..t.n_debris as usize {
            let s = t.debris_state_lvlh[i];
            if let Some((x, y)) = camera.project(Vector3::new(s[0], s[1], s[2])) {
                let (x, y) = (x / 2.0, y / 2.0);
                let _ = writeln!(svg, "<path d=\"M{} {} l8 8 M{} {} l-8 8\" stroke=\"#2ca02c\" stroke-width=\"1.5\"/>", x - 4.0, y - 4.0, x + 4.0, y - 4.0);
            }
        }
    }
    if let Some(d) = detections.iter().find(|d| d.frame_index == k) {
        for det in &d.items[..d.n as usize] {
            let (x, y) = (det.x_px / 2.0, det.y_px / 2.0);
            let r = (det.a_px / 2.0).max(6.0);
            let _ = writeln!(svg, "<circle cx=\"{x:.1}\" cy=\"{y:.1}\" r=\"{r:.1}\" fill=\"none\" stroke=\"#d62728\" stroke-width=\"1.5\"/>\n<text x=\"{:.1}\" y=\"{:.1}\" fill=\"#d62728\" font-family=\"sans-serif\" font-size=\"12\">track {}</text>", x + r + 2.0, y - r, det.track_id);
        }
    }
    let _ = writeln!(
        svg,
        "<text x=\"4\" y=\"{}\" font-family=\"sans-serif\" font-size=\"13\">frame {k}: detections (red circles, track ids) and truth (green crosses); 2× max-pooled</text>\n</svg>",
        oh + 17
    );
    std::fs::write(dir.join("frame-annotated.svg"), svg)?;
    Ok(())
}
