//! Offline tools: every algorithm stage on files, without any IPC.
//!
//! - `glint tool detect FRAME.pgm [--threshold DN]`: detections of one 16-bit PGM as JSON.
//! - `glint tool render SCENARIO --frame K --out FRAME.pgm`: one frame of a scenario's camera,
//!   rendered by the sensor's renderer (the same pixels a run publishes for that seed).

use std::path::Path;

use anyhow::{anyhow, Context, Result};
use glint_detector::pgm::{read_pgm, write_pgm, PgmImage};
use glint_detector::{Detector, DetectorConfig, Threshold};
use serde_json::json;
use shared_types::Scenario;

/// Detections of one frame as JSON (pixel convention: x = column, y = row, the first pixel's
/// centre at (0, 0); θ from +x toward +y).
pub fn detect(path: &Path, threshold_dn: Option<u16>) -> Result<String> {
    let img = read_pgm(path).map_err(|e| anyhow!("{}: {e}", path.display()))?;
    let mut cfg = DetectorConfig::default();
    if let Some(t) = threshold_dn {
        cfg.threshold = Threshold::AbsoluteDn { threshold_dn: t };
    }
    let mut detector = Detector::new(cfg).map_err(|e| anyhow!("{e}"))?;
    let found = detector
        .detect(&img.pixels, img.width, img.height)
        .map_err(|e| anyhow!("{}: {e}", path.display()))?;
    let blobs: Vec<_> = found
        .blobs
        .iter()
        .map(|b| {
            json!({
                "x": b.weighted.x_px, "y": b.weighted.y_px,
                "area": b.area_px,
                "a": b.a_px, "b": b.b_px,
                "theta_rad": b.theta_rad,
                "eccentricity": b.eccentricity,
                "flux_dn": b.flux_dn,
                "peak_dn": b.peak_dn,
                "touches_border": b.touches_border,
            })
        })
        .collect();
    let out = json!({
        "file": path.display().to_string(),
        "width": img.width,
        "height": img.height,
        "background_dn": found.background.background_dn,
        "sigma_dn": found.background.sigma_dn,
        "threshold_dn": found.threshold_dn,
        "detections": blobs,
    });
    Ok(serde_json::to_string_pretty(&out)?)
}

/// Renders frame `k` of a scenario into a 16-bit PGM.
pub fn render(scenario: &Scenario, k: u64, out: &Path) -> Result<()> {
    let cam = scenario
        .camera
        .as_ref()
        .context("the scenario has no [camera] section")?;
    if k >= cam.frames {
        return Err(anyhow!(
            "--frame {k} is out of range 0..={}",
            cam.frames - 1
        ));
    }
    let scene = glint_sensor::debris_scene::DebrisScene::new(cam, scenario.seed)
        .map_err(|e| anyhow!("{e}"))?;
    let mut pixels = vec![0u16; cam.pixels()];
    scene.render(k, &mut pixels);
    let img = PgmImage {
        width: cam.width_px as usize,
        height: cam.height_px as usize,
        maxval: 65535,
        pixels,
    };
    write_pgm(out, &img).map_err(|e| anyhow!("{}: {e}", out.display()))
}

/// `glint invert OBS.csv`: the three-stage solve on an observation file; returns the JSON of the
/// result (with the paper's error metric when the file states the truth) and a text summary.
pub fn invert(
    path: &Path,
    joint: bool,
    config_path: Option<&Path>,
) -> Result<(serde_json::Value, String)> {
    let mut config = match config_path {
        Some(p) => read_inversion_config(p)?,
        None => glint_inversion::InversionConfig::default(),
    };
    let file = crate::observations::read(path)?;
    config.joint_fit = joint;
    let result = glint_inversion::solve_three_stage(&file.set, &config)
        .map_err(|e| anyhow!("{}: {e}", path.display()))?;
    let mut j = serde_json::to_value(&result)?;
    let mut text = format!(
        "{}: {} bands, stable {} samples, motion {} frames\nstage 1: max reconstruction error {:.3e}\nstage 2: chosen band {} nm\n",
        path.display(),
        file.set.wavelengths_nm.len(),
        file.set.stable.len(),
        file.set.motion.len(),
        result.stage1.iter().map(|b| b.recon_err).fold(0.0f64, f64::max),
        result.chosen_wavelength_nm
    );
    text += &format!(
        "stage 3: fitted {} of {} motion frames (horizon: {})\n",
        result.fitted_frames,
        file.set.motion.len(),
        config
            .stage3
            .max_rotation_deg
            .map_or("every frame".to_string(), |d| format!("{d}° of rotation")),
    );
    for (label, sol) in [
        ("stage 3", Some(&result.rate)),
        ("joint", result.joint_rate.as_ref()),
    ] {
        let Some(sol) = sol else { continue };
        match sol.fit() {
            Some(fit) => {
                let p = fit.rate_deg_per_frame;
                text += &format!(
                    "{label}: p = [{:.5}, {:.5}, {:.5}] deg/frame",
                    p[0], p[1], p[2]
                );
                if let Some(t) = file.truth_rate_deg_per_frame {
                    let e = glint_inversion::rate_error_metric(p, t);
                    text += &format!(", error {e:.3} (100·|Δp|)");
                    j[format!("{}_err_paper_metric", label.replace(' ', ""))] = json!(e);
                }
                text += "\n";
            }
            None => text += &format!("{label}: unobservable — no rate reported\n"),
        }
    }
    if let Some(t) = file.truth_rate_deg_per_frame {
        j["truth_deg_per_frame"] = json!(t);
    }
    Ok((j, text))
}

/// Reads solver settings for `glint invert --config` (TOML; unknown fields are errors).
fn read_inversion_config(path: &Path) -> Result<glint_inversion::InversionConfig> {
    let text = std::fs::read_to_string(path).map_err(|e| anyhow!("{}: {e}", path.display()))?;
    let config: glint_inversion::InversionConfig =
        toml::from_str(&text).map_err(|e| anyhow!("{}: {}", path.display(), e.message()))?;
    config
        .stage3
        .validate()
        .map_err(|e| anyhow!("{}: [stage3] {e}", path.display()))?;
    Ok(config)
}
