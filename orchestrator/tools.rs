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
    band_sweep: bool,
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
        "{}: {} bands, stable {} samples, motion {} frames\nstage 1: max reconstruction error {:.3e}; lobes kept {} of 10 (widest μ = {}, Δχ² = {:.1} for k = {})\n{}stage 2: chosen band {} nm (largest σ at {} nm)\n",
        path.display(),
        file.set.wavelengths_nm.len(),
        file.set.stable.len(),
        file.set.motion.len(),
        result.stage1.iter().map(|b| b.recon_err).fold(0.0f64, f64::max),
        result.stage1_basis.lobes_kept,
        result.stage1_basis.widest_lobe_mu,
        result.stage1_basis.delta_chi2,
        result.stage1_basis.dof,
        pooling_line(&result.spectral_pooling),
        result.chosen_wavelength_nm,
        result.stage2.bands[result.stage2.separation_index].wavelength_nm,
    );
    let gate = config.stage3.joint_gate_sigma.unwrap_or(f64::INFINITY);
    if let Some(d) = result.joint_disagreement_sigma.filter(|d| *d > gate) {
        if result.set_aside.is_empty() {
            text += &format!(
                "stage 3: warning: {} nm's rate is {d:.1}σ from the joint fit's and its cost has no minimum near it; use the joint fit\n",
                result.stage1[result.rate_band_index].wavelength_nm
            );
        }
    }
    for (label, sol) in [
        ("the rate", Some(&result.rate)),
        ("the joint fit", result.joint_rate.as_ref()),
    ] {
        if let Some(scale) = sol
            .and_then(|s| s.fit())
            .and_then(|f| f.interval_variance_scale)
            .filter(|s| *s > 1.0)
        {
            text += &format!(
                "stage 3: the curvature changes across {label}'s ±{}σ interval: its covariance is averaged over it (largest variance ×{scale:.2})\n",
                glint_inversion::stage3::INTERVAL_SIGMAS
            );
        }
    }
    if let Some(scale) = result.rate_covariance_scale.filter(|s| *s > 1.0) {
        text += &format!(
            "stage 3: the rate's covariance is widened ×{scale:.1} to cover its distance from the joint fit ({:.1}σ)\n",
            result.joint_disagreement_sigma.unwrap_or(f64::NAN)
        );
    }
    if !result.set_aside.is_empty() {
        let nm = |i: &usize| result.stage1[*i].wavelength_nm;
        let aside: Vec<String> = result
            .set_aside
            .iter()
            .map(|i| format!("{} nm", nm(i)))
            .collect();
        text += &if result.rate_band_index == result.stage2.chosen_index {
            format!(
                "stage 3: the joint fit rejects the solution at every candidate band ({}); λ*'s is reported\n",
                aside.join(", ")
            )
        } else {
            format!(
                "stage 3: the joint fit rejects the solution at {}; fitted at {} nm instead\n",
                aside.join(", "),
                nm(&result.rate_band_index)
            )
        };
    }
    text += &format!(
        "stage 3: fitted {} of {} motion frames (horizon: {})\n",
        result.fitted_frames,
        file.set.motion.len(),
        config
            .stage3
            .max_rotation_deg
            .filter(|d| d.is_finite())
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
                if let Some(refit) = fit.refit {
                    let e = refit.held_direction;
                    text += &format!(
                        "; polished with each band's diffuse terms{} re-fitted, [{}, {}, {}]·p held at 0",
                        if refit.widest_lobe { " and widest lobe" } else { "" },
                        e[0], e[1], e[2]
                    );
                    if refit.held_coefficients {
                        text += "; stage 1's other coefficients held by their stable-window prior";
                    }
                    if refit.glint_lobes_only {
                        text += " (no broad lobe to re-fit: each facet's widest lobe in use is a glint lobe, kept from stage 1)";
                    } else if let Some(t) = refit.lobe_test.filter(|t| t.rate_traded) {
                        text += &format!(
                            " (lobe test: the re-fit traded the rate for the lobe, ending below half this rate; stage 1's lobes kept, χ² {:.1} not used)",
                            t.chi2
                        );
                    } else if let Some(t) = refit.lobe_test.filter(|t| t.kept_off_minimum) {
                        text += &format!(
                            " (lobe test: the fit keeping stage 1's lobes has a clearly better minimum a frame's shift away, so it is not its model's best fit; re-fitted, χ² {:.1} not used)",
                            t.chi2
                        );
                    } else if let Some(t) = refit.lobe_test {
                        text += &format!(
                            " (lobe test χ² {:.1} {} {:.2}: stage 1's lobes {})",
                            t.chi2,
                            if refit.widest_lobe { ">" } else { "≤" },
                            t.threshold,
                            if refit.widest_lobe {
                                "rejected"
                            } else {
                                "kept"
                            }
                        );
                    }
                    let carried = refit.lobe_test.filter(|t| t.other_weight > 0.0);
                    if let Some(t) = carried {
                        if let Some(q) = t.other_rate_deg_per_frame {
                            text += &format!(
                                "; the other lobe model's rate [{:.5}, {:.5}, {:.5}] carried in the covariance at weight {:.2}",
                                q[0], q[1], q[2], t.other_weight
                            );
                        }
                    }
                }
                if let Some(m) = fit.mirror_deg_per_frame {
                    let sense = if label == "stage 3" && result.sense_from_joint {
                        "at this band alone; the sense of rotation is the joint fit's"
                    } else {
                        "the sense of rotation is not determined"
                    };
                    text += &format!(
                        "; its mirror [{:.5}, {:.5}, {:.5}] fits as well ({sense}",
                        m[0], m[1], m[2]
                    );
                    if let Some(t) = file.truth_rate_deg_per_frame {
                        let e = glint_inversion::rate_error_metric(m, t);
                        text += &format!(", error {e:.3}");
                    }
                    text += ")";
                }
                text += "\n";
                text += &bounds_line(
                    label,
                    &fit.observability,
                    &fit.held_directions,
                    fit.rate_deg_per_frame,
                );
                text += &neighbour_line(label, fit);
            }
            None => {
                let why = match sol {
                    glint_inversion::RateSolution::Unobservable { reason, .. } => {
                        shared_types::SolveResponse::reason_name(reason.code())
                    }
                    _ => "unknown",
                };
                text += &format!("{label}: unobservable ({why}) — no rate reported");
                if let glint_inversion::RateSolution::Unobservable {
                    reason:
                        glint_inversion::observability::UnobservableReason::NotConfirmedByJoint {
                            rate_deg_per_frame: p,
                        },
                    ..
                } = sol
                {
                    text += &format!(
                        " (the band alone fits [{:.5}, {:.5}, {:.5}])",
                        p[0], p[1], p[2]
                    );
                }
                text += "\n";
            }
        }
    }
    if let Some(t) = file.truth_rate_deg_per_frame {
        j["truth_deg_per_frame"] = json!(t);
    }
    if band_sweep {
        let (rows, summary) = sweep_bands(&file, &result, &config)
            .map_err(|e| anyhow!("{}: band sweep: {e}", path.display()))?;
        j["band_sweep"] = json!(rows);
        text += &summary;
    }
    Ok((j, text))
}

/// Stage 3 at every band (the stage-2 check: is λ* the band with the lowest error?).
fn sweep_bands(
    file: &crate::observations::ObservationFile,
    result: &glint_inversion::InversionResult,
    config: &glint_inversion::InversionConfig,
) -> Result<(Vec<serde_json::Value>, String)> {
    let mut rows = Vec::with_capacity(result.stage1.len());
    let mut text = String::from("band sweep (stage 3 at each band):\n");
    let mut errors = Vec::new();
    // The sweep reports rates, not covariances: no neighbouring minima looked for.
    let stage3 = glint_inversion::stage3::Stage3Config {
        cover_neighbours: false,
        ..config.stage3.clone()
    };
    for (b, band) in result.stage1.iter().enumerate() {
        // Each band as λ* would be fitted: with the joint fit (when run) deciding the sense of
        // rotation where the band alone cannot.
        let glint_inversion::BandFit {
            rate,
            fitted_frames,
            ..
        } = glint_inversion::fit_band(
            &file.set.motion,
            result.single_band_stage1(),
            b,
            &config.model,
            &stage3,
            result.joint_rate.as_ref(),
        )?;
        let p = rate.fit().map(|f| f.rate_deg_per_frame);
        // Fit quality at the band: RMS residual relative to the band's mean flux.
        let rms_residual = rate
            .fit()
            .map(|f| (f.cost / fitted_frames.max(1) as f64).sqrt());
        let err = match (p, file.truth_rate_deg_per_frame) {
            (Some(p), Some(t)) => Some(glint_inversion::rate_error_metric(p, t)),
            _ => None,
        };
        if let Some(e) = err {
            errors.push((band.wavelength_nm, e));
        }
        let sigma = result.stage2.bands.get(b).map(|s| s.sigma);
        let share = result.stage2.bands.get(b).map(|s| s.specular_share);
        text += &format!(
            "  {:>5.0} nm  σ = {:>8.4}  specular {:>5.3}  rms residual {:>9.3e}  {}{}\n",
            band.wavelength_nm,
            sigma.unwrap_or(f64::NAN),
            share.unwrap_or(f64::NAN),
            rms_residual.unwrap_or(f64::NAN),
            p.map_or("unobservable".into(), |p| format!(
                "p = [{:.5}, {:.5}, {:.5}]",
                p[0], p[1], p[2]
            )),
            err.map_or(String::new(), |e| format!("  error {e:.3}")),
        );
        rows.push(json!({
            "wavelength_nm": band.wavelength_nm,
            "sigma": sigma,
            "specular_share": share,
            "p_deg_per_frame": p,
            "err_paper_metric": err,
            "rms_residual": rms_residual,
        }));
    }
    let chosen = result.chosen_wavelength_nm;
    if let (Some(best), Some(own)) = (
        errors.iter().map(|e| e.1).reduce(f64::min),
        errors.iter().find(|e| e.0 == chosen).map(|e| e.1),
    ) {
        text += &format!(
            "chosen band {chosen} nm: error {own:.3}; lowest over the sweep {best:.3} ({}).\n",
            if own <= 1.1 * best {
                "λ* is the lowest or within 10 %"
            } else {
                "λ* is NOT within 10 % of the lowest"
            }
        );
        let fitted = result.stage1[result.rate_band_index].wavelength_nm;
        if let Some(e) = errors.iter().find(|e| e.0 == fitted && fitted != chosen) {
            text += &format!(
                "stage 3 set λ* aside and fitted {fitted} nm: error {:.3}.\n",
                e.1
            );
        }
    }
    Ok((rows, text))
}

/// The minima a frame's shift from a fit that its covariance carries (docs/adr/0019): the best
/// one, how much better or worse it fits, and how many there are; empty when none was found.
fn neighbour_line(label: &str, fit: &glint_inversion::RateFit) -> String {
    let Some(best) = fit.neighbours.first() else {
        return String::new();
    };
    let q = best.rate_deg_per_frame;
    let fits = crate::report_inversion::fits_by(best.delta_chi2, "");
    let others = match fit.neighbours.len() {
        1 => String::new(),
        n => format!(" ({} more, less likely)", n - 1),
    };
    format!(
        "{label}: a minimum a frame's shift away, [{:.5}, {:.5}, {:.5}], {fits}{others}; the 1σ above carries it, weighted by its likelihood\n",
        q[0], q[1], q[2]
    )
}

/// One fit's uncertainty, per eigen-direction of its information: the 1σ of each determined
/// one, and for each undetermined one whether the stated prior held it or p sits where the
/// fit ended along it.
fn bounds_line(
    label: &str,
    obs: &glint_inversion::observability::Observability,
    held: &[[f64; 3]],
    p: [f64; 3],
) -> String {
    let fmt_v = |v: &[f64; 3]| format!("[{:.3}, {:.3}, {:.3}]", v[0], v[1], v[2]);
    let parts: Vec<String> = (0..3)
        .rev()
        .map(|k| {
            let v = &obs.eigenvectors[k];
            let sigma = obs.bounds_1sigma_deg_per_frame[k];
            if !obs.unobservable[k] {
                let speed = crate::report_inversion::speed_if_own_axis(v, p)
                    .map_or_else(String::new, |s| format!(" (the spin rate |p| = {s:.5})"));
                return format!("{sigma:.2e} along {}{speed}", fmt_v(v));
            }
            // Held: the prior's direction is v itself or the body axis nearest v.
            let axis = glint_inversion::stage3::nearest_body_axis(v);
            let is_held = held
                .iter()
                .any(|e| e[axis] == 1.0 || (0..3).map(|i| e[i] * v[i]).sum::<f64>().abs() > 0.99);
            if is_held {
                format!(
                    "{} held by the prior ({} = 0)",
                    fmt_v(v),
                    glint_inversion::stage3::RATE_NAMES[axis]
                )
            } else {
                format!(
                    "{} not determined (1σ {sigma:.2e}; p sits where the fit ended)",
                    fmt_v(v)
                )
            }
        })
        .collect();
    format!("{label}: 1σ [deg/frame]: {}\n", parts.join("; "))
}

/// A TOML error as `FILE:LINE: message (in `the line`)`, so that errors whose message does not
/// name the key (an unknown enum variant, a wrong type) still point at the field.
fn toml_error(path: &Path, text: &str, e: &toml::de::Error) -> anyhow::Error {
    let Some(span) = e.span() else {
        return anyhow!("{}: {}", path.display(), e.message());
    };
    let line_no = text[..span.start.min(text.len())].matches('\n').count() + 1;
    let line = text.lines().nth(line_no - 1).unwrap_or("").trim();
    anyhow!(
        "{}:{line_no}: {} (in `{line}`)",
        path.display(),
        e.message()
    )
}

/// What stage 1 decided about spectral pooling, one line (empty when it was not tested).
fn pooling_line(pooling: &glint_inversion::SpectralPooling) -> String {
    match pooling.bias_to_noise {
        None => String::new(),
        Some(rho) if pooling.applied => format!(
            "stage 1: stage 2 and λ* use the stable window pooled over ±{} nm (bias/noise ρ = {rho:.2})\n",
            pooling.window_nm
        ),
        Some(rho) => format!(
            "stage 1: every band on its own (pooling over ±{} nm would smear ρ = {rho:.2} of the noise)\n",
            pooling.window_nm
        ),
    }
}

/// Reads solver settings for `glint invert --config` (TOML; unknown fields are errors).
fn read_inversion_config(path: &Path) -> Result<glint_inversion::InversionConfig> {
    let text = std::fs::read_to_string(path).map_err(|e| anyhow!("{}: {e}", path.display()))?;
    let config: glint_inversion::InversionConfig =
        toml::from_str(&text).map_err(|e| toml_error(path, &text, &e))?;
    config
        .stage1
        .validate()
        .map_err(|e| anyhow!("{}: {e}", path.display()))?;
    config
        .stage3
        .validate()
        .map_err(|e| anyhow!("{}: [stage3] {e}", path.display()))?;
    config
        .stage2
        .validate()
        .map_err(|e| anyhow!("{}: {e}", path.display()))?;
    Ok(config)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glint_inversion::observability::Observability;

    #[test]
    fn the_bounds_line_names_what_was_held_and_what_was_not() {
        // Eigen-directions ≈ Z (undetermined), X (held), Y (determined), ascending.
        let obs = Observability {
            information_eigenvalues: [0.14, 4.0, 4.7e7],
            eigenvectors: [[0.0, 0.008, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, -0.008]],
            bounds_1sigma_deg_per_frame: [2.7, 0.5, 1.455e-4],
            unobservable: [true, true, false],
            threshold_deg_per_frame: 0.25,
            condition_number: 1e9,
            rms_sensitivity_per_deg_per_frame: 1.0,
        };
        let line = bounds_line("stage 3", &obs, &[[1.0, 0.0, 0.0]], [0.0, 0.25, -0.002]);
        assert!(
            line.starts_with(
                "stage 3: 1σ [deg/frame]: 1.46e-4 along [0.000, 1.000, -0.008] (the spin rate |p| = 0.25001)"
            ),
            "{line}"
        );
        assert!(
            line.contains("[1.000, 0.000, 0.000] held by the prior (w_x = 0)"),
            "{line}"
        );
        assert!(
            line.contains("[0.000, 0.008, 1.000] not determined (1σ 2.70e0"),
            "{line}"
        );
        // Both held: nothing is left where the fit ended.
        let both = bounds_line(
            "joint",
            &obs,
            &[[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]],
            [0.0, 0.0, 0.25],
        );
        // A rate off the determined direction's axis: no spin rate named.
        assert!(!both.contains("spin rate"), "{both}");
        assert!(!both.contains("not determined"), "{both}");
        assert!(both.contains("(w_z = 0)"), "{both}");
    }
}
