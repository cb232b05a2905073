//! Fit plots of the attitude solve: the stage-1 reconstruction of the stable window and the
//! answer's model against the motion window, with its residuals, at λ*.
//!
//! The curves are not on the wire (a solve response carries the answer, not series): they are
//! the model evaluated on the run's `observations.csv` at the service's answer — its rate and
//! the two-facet coefficients at λ* it carries. Nothing is solved again.

use std::path::Path;

use anyhow::{anyhow, Result};
use glint_inversion::stage1::{coefficients_from_slice, design_matrix};
use glint_inversion::{MotionModelConfig, RateBand, RateProblem};
use nalgebra::Vector3;
use shared_types::scenario::SpectraScenario;
use shared_types::{SolveResponse, SolveStatus};

use crate::plots::{line_chart, Series, BLUE, RED};

/// Writes `stage1-fit.svg`, `stage3-fit.svg` and `stage3-residuals.svg` from the run's
/// observation file and the service's answer. Returns whether the stage-3 plots were drawn (a
/// determined rate).
pub fn plots(dir: &Path, sp: &SpectraScenario, responses: &[SolveResponse]) -> Result<bool> {
    let Some(answer) = responses.iter().rev().find(|r| r.stage == 3) else {
        return Ok(false);
    };
    let path = dir.join("observations.csv");
    let file = crate::tools::observations::read(&path)?;
    let model = glint_inversion::service_core::model_config(sp);
    let body_normal = Vector3::from(model.body_normal);
    let chosen = answer.chosen_band as usize;
    let nm = *file.set.wavelengths_nm.get(chosen).ok_or_else(|| {
        anyhow!(
            "{}: the answer's band {chosen} is not among the file's {} bands",
            path.display(),
            file.set.wavelengths_nm.len()
        )
    })?;
    if answer.recon_coefficients.iter().any(|c| c.is_nan()) {
        return Ok(false);
    }

    // Stage 1: Φ_rec,j = G_j x / ‖T0_j‖² over the stable window.
    let stable = &file.set.stable;
    let g = design_matrix(stable, body_normal);
    let x = answer.recon_coefficients;
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
            "Stage 1 at λ* = {nm} nm: stable window (dots) and its NNLS reconstruction (line), ε_rec = {:.2e}",
            answer.recon_err[chosen]
        ),
        "stable-window sample",
        observed,
        ("two-facet reconstruction", rebuilt),
    )?;

    // Stage 3: the answer's model at λ*, over the frames the answer fitted. The joint fit
    // evaluates every band with its own coefficients and re-fitted diffuse terms at p̂, each
    // band on its own (a per-band weight does not move a band's re-fitted terms), so λ*'s curve
    // is λ* alone with the coefficients the answer used there and the lobes it re-fitted (chosen
    // over every band, so carried in the answer).
    if answer.status != SolveStatus::Ok as u32 {
        return Ok(false);
    }
    let p = answer.rate_deg_per_frame;
    let joint = answer.flags & SolveResponse::JOINT != 0;
    let mut motion = file.set.motion.clone();
    motion.sort_by_key(|o| o.frame_index);
    motion.truncate(answer.fitted_frames as usize);
    let epoch = motion.first().map_or(0, |o| o.frame_index);
    let model = MotionModelConfig {
        epoch_frame: Some(epoch),
        refit_diffuse: true,
        refit_widest_lobe: answer.flags & SolveResponse::LOBE_REFIT != 0,
        widest_lobes: Some(answer.refit_lobes.map(|k| k as usize)),
        ..model
    };
    let coefficients = if joint {
        &answer.recon_coefficients
    } else {
        &answer.rate_coefficients
    };
    let band = RateBand {
        band_index: chosen,
        wavelength_nm: nm,
        coeffs: coefficients_from_slice(coefficients),
    };
    let problem = RateProblem::new(&motion, &[band], &model)?;
    let curve = problem.model_flux_w(p).swap_remove(0);
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
            "glint's answer at λ* = {nm} nm: motion window (dots) and the model at p = [{:.4}, {:.4}, {:.4}] deg/frame (line)",
            p[0], p[1], p[2]
        ),
        "frame after the motion start",
        observed,
        ("two-facet model at p̂, diffuse terms re-fitted", modelled),
    )?;
    line_chart(
        &dir.join("stage3-residuals.svg"),
        &format!("Residuals of the answer at λ* = {nm} nm, relative to the mean flux"),
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
