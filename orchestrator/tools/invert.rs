//! `glint invert OBS.csv`: the three-stage solve on an observation file, no IPC.
//!
//! Prints glint's answer in a few lines — the rate, its 1σ along each Fisher direction, the
//! directions the data leave open and the prior that held them, the sense of rotation, and the
//! error against the file's truth when it states one. `--verbose` adds how the stages got
//! there; `--out DIR` writes the whole result as `inversion.json`.

use std::path::Path;

use anyhow::{anyhow, Result};
use glint_inversion::stage3::{nearest_body_axis, RATE_NAMES};
use glint_inversion::{Answer, AnswerFit, InversionConfig, InversionResult, RateSolution};
use serde_json::json;

use crate::report::inversion::speed_if_own_axis;

/// What `glint invert` asks of the solve.
pub struct InvertOptions<'a> {
    pub joint: bool,
    pub config: Option<&'a Path>,
    pub band_sweep: bool,
    pub verbose: bool,
}

/// Solves `path`; returns the JSON of the result and the text to print.
pub fn invert(path: &Path, options: &InvertOptions) -> Result<(serde_json::Value, String)> {
    let mut config = match options.config {
        Some(p) => read_inversion_config(p)?,
        None => InversionConfig::default(),
    };
    let file = crate::tools::observations::read(path)?;
    config.joint_fit = options.joint;
    let result = glint_inversion::solve_three_stage(&file.set, &config)
        .map_err(|e| anyhow!("{}: {e}", path.display()))?;
    let truth = file.truth_rate_deg_per_frame;
    let mut j = serde_json::to_value(&result)?;
    let err = |p: Option<[f64; 3]>| -> Option<f64> {
        Some(glint_inversion::rate_error_metric(p?, truth?))
    };
    if let Some(t) = truth {
        j["truth_deg_per_frame"] = json!(t);
        j["answer"]["err_paper_metric"] = json!(err(result.answer.rate_deg_per_frame));
        j["stage3_err_paper_metric"] = json!(err(result.rate.fit().map(|f| f.rate_deg_per_frame)));
    }
    let ignored = if file.ignored_columns.is_empty() {
        String::new()
    } else {
        format!(" (columns not read: {})", file.ignored_columns.join(", "))
    };
    let mut text = format!(
        "{}: {} bands, stable {} samples, motion {} frames{ignored}\n",
        path.display(),
        file.set.wavelengths_nm.len(),
        file.set.stable.len(),
        file.set.motion.len(),
    );
    text += &answer_lines(&result.answer, truth);
    if let Some([stable, motion]) = &file.estimated_sigma_w {
        let bands: Vec<String> = (file.set.wavelengths_nm.iter().zip(stable).zip(motion))
            .map(|((w, s), m)| format!("{w} nm {s:.2e} / {m:.2e} W"))
            .collect();
        text += &format!(
            "σ estimated from the data (no sigma_* columns; the light curve's scatter, stable / \
             motion window): {}\n",
            bands.join(", ")
        );
        j["estimated_sigma_w"] = json!({ "stable": stable, "motion": motion });
    }
    if options.verbose {
        text += &stage_lines(&result, truth);
    }
    if options.band_sweep {
        let (rows, summary) = sweep_bands(&file, &result, &config)
            .map_err(|e| anyhow!("{}: band sweep: {e}", path.display()))?;
        j["band_sweep"] = json!(rows);
        text += &summary;
    }
    Ok((j, text))
}

fn vec3(p: [f64; 3]) -> String {
    format!("[{:.5}, {:.5}, {:.5}]", p[0], p[1], p[2])
}

fn axis3(v: [f64; 3]) -> String {
    format!("[{:.3}, {:.3}, {:.3}]", v[0], v[1], v[2])
}

/// The answer in at most four lines.
pub fn answer_lines(answer: &Answer, truth: Option<[f64; 3]>) -> String {
    let from = match answer.from {
        AnswerFit::Joint { bands } => format!("joint fit over {bands} bands"),
        AnswerFit::Band { wavelength_nm } => format!("fit at λ* = {wavelength_nm} nm"),
    };
    let Some(p) = answer.rate_deg_per_frame else {
        let why = answer.unobservable.map_or("unknown", |r| {
            shared_types::SolveResponse::reason_name(r.code())
        });
        let bounds: Vec<String> = answer
            .directions
            .iter()
            .rev()
            .map(|d| format!("{:.2e} along {}", d.sigma_deg_per_frame, axis3(d.axis)))
            .collect();
        return format!(
            "answer: no rate — {why} ({from})\n1σ bounds [deg/frame]: {}\n",
            bounds.join("; ")
        );
    };
    let error = truth.map_or(String::new(), |t| {
        format!(
            "; error {:.3} against the file's truth (100·|Δp|)",
            glint_inversion::rate_error_metric(p, t)
        )
    });
    let mut s = format!(
        "answer: p = {} deg/frame ({from}, {} frames){error}\n",
        vec3(p),
        answer.fitted_frames
    );
    let mut determined = vec![];
    let mut open = vec![];
    for d in answer.directions.iter().rev() {
        if d.determined {
            let speed = speed_if_own_axis(&d.axis, p)
                .map_or_else(String::new, |v| format!(" (the spin rate |p| = {v:.5})"));
            determined.push(format!(
                "{:.2e} along {}{speed}",
                d.sigma_deg_per_frame,
                axis3(d.axis)
            ));
            continue;
        }
        let k = nearest_body_axis(&d.axis);
        let held = answer
            .held_axes
            .iter()
            .any(|e| e[k] == 1.0 || (0..3).map(|i| e[i] * d.axis[i]).sum::<f64>().abs() > 0.99);
        open.push(if held {
            format!("{} held by the prior {} = 0", axis3(d.axis), RATE_NAMES[k])
        } else {
            format!(
                "{} (1σ {:.2e}; p sits where the fit ended)",
                axis3(d.axis),
                d.sigma_deg_per_frame
            )
        });
    }
    s += &format!("1σ [deg/frame]: {}\n", determined.join("; "));
    if !open.is_empty() {
        s += &format!("not determined by the data: {}\n", open.join("; "));
    }
    s += &match answer.mirror_deg_per_frame {
        Some(m) => format!(
            "sense of rotation: NOT determined — the mirror {} fits within the noise{}\n",
            vec3(m),
            truth.map_or(String::new(), |t| format!(
                " (error {:.3})",
                glint_inversion::rate_error_metric(m, t)
            ))
        ),
        None => "sense of rotation: determined\n".to_string(),
    };
    s
}

/// `--verbose`: how the three stages got there.
fn stage_lines(result: &InversionResult, truth: Option<[f64; 3]>) -> String {
    let basis = &result.stage1_basis;
    let mut s = format!(
        "stage 1: max reconstruction error {:.3e}; lobes kept {} of 10 (widest μ = {}, Δχ² = {:.1} for k = {})\n",
        result.stage1.iter().map(|b| b.recon_err).fold(0.0f64, f64::max),
        basis.lobes_kept,
        basis.widest_lobe_mu,
        basis.delta_chi2,
        basis.dof,
    );
    let pooling = &result.spectral_pooling;
    if let Some(rho) = pooling.bias_to_noise {
        s += &if pooling.applied {
            format!(
                "stage 1: stage 2 and λ* use the stable window pooled over ±{} nm (bias/noise ρ = {rho:.2})\n",
                pooling.window_nm
            )
        } else {
            format!(
                "stage 1: every band on its own (pooling over ±{} nm would smear ρ = {rho:.2} of the noise)\n",
                pooling.window_nm
            )
        };
    }
    s += &format!(
        "stage 2: λ* = {} nm (largest σ at {} nm)\n",
        result.chosen_wavelength_nm,
        result.stage2.bands[result.stage2.separation_index].wavelength_nm,
    );
    let fits = [
        ("stage 3 at λ*", Some(&result.rate), result.fitted_frames),
        (
            "stage 3 joint",
            result.joint_rate.as_ref(),
            result.joint_fitted_frames.unwrap_or(0),
        ),
    ];
    for (label, sol, frames) in fits {
        let Some(sol) = sol else { continue };
        s += &match sol {
            RateSolution::Determined(fit) => {
                let refit = match fit.refit {
                    Some(r) if r.widest_lobe => "; diffuse terms and widest lobe re-fitted",
                    Some(_) => "; diffuse terms re-fitted",
                    None => "",
                };
                let lobe = fit
                    .refit
                    .and_then(|r| r.lobe_test)
                    .map_or(String::new(), |t| {
                        format!("; lobe test χ² {:.1} against {:.2}", t.chi2, t.threshold)
                    });
                format!(
                    "{label}: p = {}{} over {frames} frames, {} LM iterations from {} starts{refit}{lobe}\n",
                    vec3(fit.rate_deg_per_frame),
                    truth.map_or(String::new(), |t| format!(
                        ", error {:.3}",
                        glint_inversion::rate_error_metric(fit.rate_deg_per_frame, t)
                    )),
                    fit.total_iterations,
                    fit.starts_polished,
                )
            }
            RateSolution::Unobservable { reason, .. } => format!(
                "{label}: no rate ({})\n",
                shared_types::SolveResponse::reason_name(reason.code())
            ),
        };
    }
    s
}

/// Stage 3 at every band (the stage-2 check: is λ* the band with the lowest error?).
fn sweep_bands(
    file: &crate::tools::observations::ObservationFile,
    result: &InversionResult,
    config: &InversionConfig,
) -> Result<(Vec<serde_json::Value>, String)> {
    let mut rows = Vec::with_capacity(result.stage1.len());
    let mut text = String::from("band sweep (stage 3 at each band):\n");
    let mut errors = Vec::new();
    for (b, band) in result.stage1.iter().enumerate() {
        let glint_inversion::BandFit {
            rate,
            fitted_frames,
        } = glint_inversion::fit_band(
            &file.set.motion,
            result.single_band_stage1(),
            b,
            &config.model,
            &config.stage3,
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
            p.map_or("unobservable".into(), |p| format!("p = {}", vec3(p))),
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
    }
    Ok((rows, text))
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

/// Reads solver settings for `glint invert --config` (TOML; unknown fields are errors).
fn read_inversion_config(path: &Path) -> Result<InversionConfig> {
    let text =
        shared_types::input::read_text_capped(path, shared_types::input::MAX_TEXT_FILE_BYTES)
            .map_err(|e| anyhow!("{}: {e}", path.display()))?;
    let config: InversionConfig = toml::from_str(&text).map_err(|e| toml_error(path, &text, &e))?;
    config
        .stage1
        .validate()
        .map_err(|e| anyhow!("{}: {e}", path.display()))?;
    config
        .stage3
        .validate()
        .map_err(|e| anyhow!("{}: {e}", path.display()))?;
    config
        .stage2
        .validate()
        .map_err(|e| anyhow!("{}: {e}", path.display()))?;
    Ok(config)
}

/// `glint invert OBS.csv …`.
pub fn command(args: crate::cli::InvertArgs) -> std::process::ExitCode {
    use std::process::ExitCode;
    let crate::cli::InvertArgs {
        observations,
        out,
        no_joint,
        config,
        band_sweep,
        verbose,
    } = args;
    match invert(
        &observations,
        &InvertOptions {
            joint: !no_joint,
            config: config.as_deref(),
            band_sweep,
            verbose,
        },
    ) {
        Ok((json, text)) => {
            print!("{text}");
            if let Some(dir) = out {
                let written = std::fs::create_dir_all(&dir).and_then(|_| {
                    std::fs::write(
                        dir.join("inversion.json"),
                        serde_json::to_string_pretty(&json).unwrap_or_default() + "\n",
                    )
                });
                if let Err(e) = written {
                    eprintln!("error: {}: {e}", dir.display());
                    return ExitCode::from(1);
                }
            }
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glint_inversion::Direction;

    fn answer(mirror: Option<[f64; 3]>) -> Answer {
        Answer {
            from: AnswerFit::Joint { bands: 36 },
            rate_deg_per_frame: Some([0.0, 0.25, -0.002]),
            covariance_deg2_per_frame2: Some([[0.0; 3]; 3]),
            // Least informed first: Z (not determined), X (held), Y (determined).
            directions: [
                Direction {
                    axis: [0.0, 0.008, 1.0],
                    sigma_deg_per_frame: 2.7,
                    determined: false,
                },
                Direction {
                    axis: [1.0, 0.0, 0.0],
                    sigma_deg_per_frame: 0.5,
                    determined: false,
                },
                Direction {
                    axis: [0.0, 1.0, -0.008],
                    sigma_deg_per_frame: 1.455e-4,
                    determined: true,
                },
            ],
            held_axes: vec![[1.0, 0.0, 0.0]],
            mirror_deg_per_frame: mirror,
            unobservable: None,
            fitted_frames: 101,
        }
    }

    #[test]
    fn the_answer_names_what_was_determined_what_was_held_and_the_sense() {
        let text = answer_lines(&answer(None), Some([0.0, 0.25, 0.0]));
        let lines: Vec<&str> = text.lines().collect();
        assert!(lines.len() <= 4, "{text}");
        assert!(
            lines[0].starts_with("answer: p = [0.00000, 0.25000, -0.00200] deg/frame (joint fit over 36 bands, 101 frames); error 0.200"),
            "{text}"
        );
        assert!(
            lines[1].contains("1.46e-4 along [0.000, 1.000, -0.008] (the spin rate |p| = 0.25001)"),
            "{text}"
        );
        assert!(
            lines[2].contains("[1.000, 0.000, 0.000] held by the prior w_x = 0"),
            "{text}"
        );
        assert!(
            lines[2].contains("[0.000, 0.008, 1.000] (1σ 2.70e0"),
            "{text}"
        );
        assert_eq!(lines[3], "sense of rotation: determined");
        let text = answer_lines(&answer(Some([0.0, 0.25, 0.002])), Some([0.0, 0.25, 0.0]));
        assert!(
            text.contains("sense of rotation: NOT determined — the mirror [0.00000, 0.25000, 0.00200] fits within the noise (error 0.200)"),
            "{text}"
        );
    }
}
