//! Fit plots of the attitude solve: the stage-1 reconstruction of the stable window and the
//! stage-3 model against the motion window, with its residuals, at the chosen band.
//!
//! The curves are not on the wire (a solve response carries figures, not series), so they are
//! recomputed from the run's `observations.csv` with the same solver; `glint invert` on that
//! file reproduces the service's answer to the bit (tested), so these are the service's fits.

use std::path::Path;

use anyhow::{anyhow, Result};
use glint_inversion::stage1::{coefficients_to_array, design_matrix};
use glint_inversion::{
    solve_three_stage, InversionConfig, MotionModelConfig, RateBand, RateProblem,
};
use nalgebra::Vector3;
use shared_types::scenario::SpectraScenario;

use crate::plots::{line_chart, Series, BLUE, RED};

/// Writes `stage1-fit.svg`, `stage3-fit.svg` and `stage3-residuals.svg` from the run's
/// observation file. Returns whether the stage-3 plots were drawn (a determined rate).
pub fn plots(dir: &Path, sp: &SpectraScenario) -> Result<bool> {
    let path = dir.join("observations.csv");
    let file = crate::observations::read(&path)?;
    // As the service solves (the orchestrator always asks for the joint fit, which can decide
    // the sense of rotation at λ*).
    let config = InversionConfig {
        joint_fit: true,
        stage3: glint_inversion::node::stage3_config(sp),
        ..Default::default()
    };
    let result =
        solve_three_stage(&file.set, &config).map_err(|e| anyhow!("{}: {e}", path.display()))?;
    let chosen = result.stage2.chosen_index;
    let nm = result.chosen_wavelength_nm;

    // Stage 1: Φ_rec,j = G_j x / ‖T0_j‖² over the stable window.
    let stable = &file.set.stable;
    let g = design_matrix(stable, Vector3::from(config.model.body_normal));
    let x = coefficients_to_array(&result.stage1[chosen].coeffs);
    let observed: Vec<(f64, f64)> = stable
        .iter()
        .enumerate()
        .map(|(j, o)| (j as f64, o.flux_w[chosen]))
        .collect();
    let rebuilt: Vec<(f64, f64)> = stable
        .iter()
        .enumerate()
        .map(|(j, o)| {
            let q: f64 = x.iter().enumerate().map(|(m, v)| g[(j, m)] * v).sum();
            (j as f64, q / o.range_m.powi(2))
        })
        .collect();
    observed_and_model(
        &dir.join("stage1-fit.svg"),
        &format!(
            "Stage 1 at {nm} nm: stable window (dots) and its NNLS reconstruction (line), ε_rec = {:.2e}",
            result.stage1[chosen].recon_err
        ),
        "stable-window sample",
        observed,
        ("two-facet reconstruction", rebuilt),
    )?;

    // Stage 3: the model at p̂ over the frames it was fitted on.
    let Some(fit) = result.rate.fit() else {
        return Ok(false);
    };
    // The band stage 3 fitted: λ*, unless the joint fit rejected its solution.
    let chosen = result.rate_band_index;
    let nm = result.stage1[chosen].wavelength_nm;
    let mut motion = file.set.motion.clone();
    motion.sort_by_key(|o| o.frame_index);
    motion.truncate(result.fitted_frames);
    let epoch = motion.first().map_or(0, |o| o.frame_index);
    // The model the fit ended with: with the polish's re-fitted terms, if it was polished.
    let model = MotionModelConfig {
        epoch_frame: Some(epoch),
        refit_diffuse: config.model.refit_diffuse || fit.refit.is_some(),
        refit_widest_lobe: fit.refit.is_some_and(|r| r.widest_lobe),
        ..config.model.clone()
    };
    // The coefficients stage 3 used there (the spectrally pooled ones when stage 1 pooled).
    let band = RateBand {
        band_index: chosen,
        wavelength_nm: nm,
        coeffs: result.single_band_stage1()[chosen].coeffs,
    };
    let problem = RateProblem::new(&motion, &[band], &model)?;
    let p = fit.rate_deg_per_frame;
    let curve = problem.model_flux_w(p).remove(0);
    let frame = |o: &glint_inversion::Observation| (o.frame_index - epoch) as f64;
    let observed: Vec<(f64, f64)> = motion
        .iter()
        .map(|o| (frame(o), o.flux_w[chosen]))
        .collect();
    let modelled: Vec<(f64, f64)> = motion
        .iter()
        .zip(&curve)
        .map(|(o, m)| (frame(o), *m))
        .collect();
    let mean = observed.iter().map(|(_, f)| f).sum::<f64>() / observed.len().max(1) as f64;
    let residuals: Vec<(f64, f64)> = observed
        .iter()
        .zip(&curve)
        .map(|((t, f), m)| (*t, (f - m) / mean))
        .collect();
    observed_and_model(
        &dir.join("stage3-fit.svg"),
        &format!(
            "Stage 3 at {nm} nm: motion window (dots) and the model at p = [{:.4}, {:.4}, {:.4}] deg/frame (line)",
            p[0], p[1], p[2]
        ),
        "frame after the motion start",
        observed,
        (if fit.refit.is_some() { "two-facet model at p̂, diffuse terms re-fitted" } else { "two-facet model at p̂" }, modelled),
    )?;
    line_chart(
        &dir.join("stage3-residuals.svg"),
        &format!("Stage 3 residuals at {nm} nm, relative to the mean flux"),
        "frame after the motion start",
        "(Φ_obs − Φ_model) / mean Φ_obs",
        &[Series {
            label: "residual",
            points: residuals,
            color: BLUE,
            markers: true,
        }],
    )?;
    Ok(true)
}

/// Observed flux as dots and a model as a line, on one chart.
fn observed_and_model(
    path: &Path,
    title: &str,
    x_label: &str,
    observed: Vec<(f64, f64)>,
    (label, model): (&str, Vec<(f64, f64)>),
) -> Result<()> {
    line_chart(
        path,
        title,
        x_label,
        "flux [W]",
        &[
            Series {
                label: "observed",
                points: observed,
                color: RED,
                markers: true,
            },
            Series {
                label,
                points: model,
                color: BLUE,
                markers: false,
            },
        ],
    )
}
