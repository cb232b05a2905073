//! The inversion part of the report ([000]): stage 1 reconstruction error per band, stage 2
//! separation degree and the chosen band, stage 3 rates against truth with the paper's error
//! metric, the Fisher-information eigen-directions, and the windows every figure depends on.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::Result;
use glint_inversion::rate_error_metric;
use glint_inversion::stage3::{nearest_body_axis, RATE_NAMES};
use serde_json::{json, Value};
use shared_types::scenario::SpectraScenario;
use shared_types::{SolveResponse, SolveStatus};

use crate::plots::{line_chart, Series, BLUE, GREEN, RED};

mod decisions;
use decisions::{
    disagreement_phrase, lobe_other_text, lobe_test_text, set_aside_phrase, widened_phrase,
    HELD_SENTENCE,
};

/// A number for JSON: non-finite values become `null`.
pub(crate) fn finite(v: f64) -> Value {
    if v.is_finite() {
        json!(v)
    } else {
        Value::Null
    }
}

fn status(r: &SolveResponse) -> &'static str {
    SolveStatus::from_u32(r.status).map_or("unknown", |s| s.name())
}

/// The reason name of an unobservable answer, null for none.
fn reason(code: u32) -> Value {
    if code == 0 {
        Value::Null
    } else {
        json!(SolveResponse::reason_name(code))
    }
}

pub fn json(sp: &SpectraScenario, responses: &[SolveResponse]) -> Value {
    let windows = json!({
        "stable_samples": sp.stable_samples,
        "stable_start_phase_deg": sp.stable_start_phase_deg,
        "motion_frames": sp.motion_frames,
        "frame_interval_s": sp.frame_interval_s,
        "start_phase_deg": sp.start_phase_deg,
        "materials": format!("{:?}", sp.materials).to_lowercase(),
        "body_shape": format!("{:?}", sp.body_shape).to_lowercase(),
        "snr": sp.snr,
    });
    let truth = sp.rate_deg_per_frame;
    let get = |stage: u32| responses.iter().find(|r| r.stage == stage);
    let bands =
        |r: &SolveResponse, f: &dyn Fn(&SolveResponse, usize) -> Value, key: &str| -> Vec<Value> {
            (0..r.n_bands as usize)
                .map(|i| json!({ "wavelength_nm": r.wavelength_nm[i], key: f(r, i) }))
                .collect()
        };
    let stage1 = get(1).map_or(Value::Null, |r| {
        json!({
            "status": status(r),
            "bands": bands(r, &|r, i| finite(r.recon_err[i]), "recon_err"),
            "basis": {
                "lobes_kept": r.stage1_lobes_kept,
                "widest_lobe_mu": finite(r.stage1_widest_lobe_mu),
                "delta_chi2": finite(r.stage1_basis_delta_chi2),
                "dof": r.stage1_basis_dof,
            },
            "spectral_pooling": {
                "window_nm": r.stage1_spectral_window_nm,
                "bias_to_noise": finite(r.stage1_spectral_bias_to_noise),
            },
        })
    });
    let stage2 = get(2).map_or(Value::Null, |r| {
        json!({
            "status": status(r),
            "sigma": bands(r, &|r, i| finite(r.separation[i]), "sigma"),
            "specular_share": bands(r, &|r, i| finite(r.specular_share[i]), "specular_share"),
            "chosen_nm": r.wavelength_nm[r.chosen_band as usize],
            "max_sigma_nm": r.wavelength_nm[r.separation_band as usize],
        })
    });
    let stage3 = get(3).map_or(Value::Null, |r| {
        let p = r.p_deg_per_frame;
        let determined = r.status == SolveStatus::Ok as u32;
        let pj = r.p_joint_deg_per_frame;
        let joint_ok = pj.iter().all(|v| v.is_finite());
        let mirror_ok = r.p_mirror_deg_per_frame.iter().all(|v| v.is_finite());
        let joint_mirror = r.p_joint_mirror_deg_per_frame;
        let joint_mirror_ok = joint_ok && joint_mirror.iter().all(|v| v.is_finite());
        let neighbour = r.p_joint_neighbour_deg_per_frame;
        let neighbour_ok = joint_ok && neighbour.iter().all(|v| v.is_finite());
        let own_neighbour = r.p_neighbour_deg_per_frame;
        let own_neighbour_ok = determined && own_neighbour.iter().all(|v| v.is_finite());
        let lobe_other = r.p_joint_lobe_other_deg_per_frame;
        let lobe_other_ok = joint_ok && lobe_other.iter().all(|v| v.is_finite());
        json!({
            "status": status(r),
            "unobservable_reason": reason(r.unobservable_reason),
            "band_nm": r.wavelength_nm[r.stage3_band as usize],
            "fitted_frames": r.fitted_frames,
            "sense_from_joint": r.stage3_flags & SolveResponse::SENSE_FROM_JOINT != 0,
            "lambda_rejected_by_joint": r.stage3_flags & SolveResponse::LAMBDA_REJECTED != 0,
            "held_coefficients": r.stage3_flags & SolveResponse::HELD_COEFFICIENTS != 0,
            "bands_set_aside": r.stage3_set_aside,
            "joint_disagreement_sigma": finite(r.stage3_joint_disagreement_sigma),
            "covariance_scale": finite(r.stage3_covariance_scale),
            "fit_horizon_deg": glint_inversion::stage3::DEFAULT_MAX_ROTATION_DEG,
            "p_deg_per_frame": if determined { json!(p) } else { Value::Null },
            "truth_deg_per_frame": truth,
            "err_paper_metric": if determined { finite(rate_error_metric(p, truth)) } else { Value::Null },
            "covariance": r.p_covariance.iter().map(|v| finite(*v)).collect::<Vec<_>>(),
            "mirror_deg_per_frame": if mirror_ok { json!(r.p_mirror_deg_per_frame) } else { Value::Null },
            "err_paper_metric_mirror": if mirror_ok { finite(rate_error_metric(r.p_mirror_deg_per_frame, truth)) } else { Value::Null },
            "neighbour_deg_per_frame": if own_neighbour_ok { json!(own_neighbour) } else { Value::Null },
            "neighbour_delta_chi2": if own_neighbour_ok { finite(r.stage3_neighbour_delta_chi2) } else { Value::Null },
            "err_paper_metric_neighbour": if own_neighbour_ok { finite(rate_error_metric(own_neighbour, truth)) } else { Value::Null },
            "joint": {
                "unobservable_reason": reason(r.joint_unobservable_reason),
                "p_deg_per_frame": if joint_ok { json!(pj) } else { Value::Null },
                "err_paper_metric": if joint_ok { finite(rate_error_metric(pj, truth)) } else { Value::Null },
                "covariance": r.p_joint_covariance.iter().map(|v| finite(*v)).collect::<Vec<_>>(),
                "widest_lobe_refit": r.stage3_flags & SolveResponse::JOINT_LOBE_REFIT != 0,
                "lobe_test_chi2": finite(r.stage3_joint_lobe_test_chi2),
                "lobe_rate_traded": r.stage3_flags & SolveResponse::JOINT_LOBE_RATE_TRADED != 0,
                "lobe_kept_off_minimum": r.stage3_flags & SolveResponse::JOINT_LOBE_KEPT_OFF_MINIMUM != 0,
                "glint_lobes_only": r.stage3_flags & SolveResponse::JOINT_GLINT_LOBES_ONLY != 0,
                "held_coefficients": r.stage3_flags & SolveResponse::JOINT_HELD_COEFFICIENTS != 0,
                "lobe_other_deg_per_frame": if lobe_other_ok { json!(lobe_other) } else { Value::Null },
                "lobe_other_weight": if lobe_other_ok { finite(r.stage3_joint_lobe_other_weight) } else { Value::Null },
                "err_paper_metric_lobe_other": if lobe_other_ok { finite(rate_error_metric(lobe_other, truth)) } else { Value::Null },
                "mirror_deg_per_frame": if joint_mirror_ok { json!(joint_mirror) } else { Value::Null },
                "err_paper_metric_mirror": if joint_mirror_ok { finite(rate_error_metric(joint_mirror, truth)) } else { Value::Null },
                "neighbour_deg_per_frame": if neighbour_ok { json!(neighbour) } else { Value::Null },
                "neighbour_delta_chi2": if neighbour_ok { finite(r.stage3_joint_neighbour_delta_chi2) } else { Value::Null },
                "err_paper_metric_neighbour": if neighbour_ok { finite(rate_error_metric(neighbour, truth)) } else { Value::Null },
            },
            "fisher": {
                "eigenvalues": r.fisher_eigenvalues.iter().map(|v| finite(*v)).collect::<Vec<_>>(),
                "eigenvectors_columns": r.fisher_eigenvectors.iter().map(|v| finite(*v)).collect::<Vec<_>>(),
                "bound_1sigma_deg_per_frame": r.bound_1sigma_deg_per_frame.iter().map(|v| finite(*v)).collect::<Vec<_>>(),
                "observable": (0..3).map(|i| r.observable_mask & (1 << i) != 0).collect::<Vec<_>>(),
                "held_at_prior": held_names(r.stage3_held_axes),
                "covariance_source": SolveResponse::COVARIANCE_SOURCE_NAMES.get(r.stage3_covariance_source as usize).copied(),
            },
            "cost": finite(r.cost),
            "iterations": r.iterations,
            "starts": r.starts,
        })
    });
    json!({ "windows": windows, "stage1": stage1, "stage2": stage2, "stage3": stage3 })
}

/// "fits {what}better by Δχ² = …" (or worse) for a minimum `delta_chi2` noise variances above
/// or below the answer's cost.
pub(crate) fn fits_by(delta_chi2: f64, what: &str) -> String {
    let sense = if delta_chi2 < 0.0 { "better" } else { "worse" };
    format!("fits {what}{sense} by Δχ² = {:.1}", delta_chi2.abs())
}

/// The summary's sentence on a fit's neighbouring minimum `q`, Δχ² `delta_chi2` from the
/// answer (the joint fit's when `joint`); empty without one (NaN).
fn neighbour_sentence(q: [f64; 3], delta_chi2: f64, truth: [f64; 3], joint: bool) -> String {
    if !(q.iter().all(|v| v.is_finite()) && delta_chi2.is_finite()) {
        return String::new();
    }
    let (cost, fits, covariance, adr) = if joint {
        let fits = fits_by(delta_chi2, "all bands ");
        ("joint cost", fits, "joint covariance", "0019")
    } else {
        ("fit's cost", fits_by(delta_chi2, ""), "covariance", "0020")
    };
    format!(
        "\nA second minimum of the {cost} a frame's shift away, [{:.5}, {:.5}, {:.5}] (error {:.3}), {fits}: the two-facet model's glint moves to the next sample there, and which minimum is deeper can be decided by the stable window's noise. The {covariance} carries it, weighted by its likelihood (docs/adr/{adr}).\n",
        q[0],
        q[1],
        q[2],
        rate_error_metric(q, truth)
    )
}

pub fn markdown(sp: &SpectraScenario, responses: &[SolveResponse]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "\n## Three-stage attitude solve ([000])\n\nWindows: stable {} samples from phase {}° through the pass; motion {} frames, {} s apart, from phase {}°; materials `{:?}`, body `{:?}`, SNR {}.\n",
        sp.stable_samples,
        sp.stable_start_phase_deg,
        sp.motion_frames,
        sp.frame_interval_s,
        sp.start_phase_deg,
        sp.materials,
        sp.body_shape,
        sp.snr.map_or("∞ (noise-free)".to_string(), |v| v.to_string())
    );
    let get = |stage: u32| responses.iter().find(|r| r.stage == stage);
    if let (Some(r1), Some(r2)) = (get(1), get(2)) {
        let worst = r1.recon_err[..r1.n_bands as usize]
            .iter()
            .cloned()
            .fold(0.0f64, f64::max);
        let _ = writeln!(
            s,
            "Stage 1: reconstruction error ≤ {:.2e} over {} bands; {}. Stage 2: chosen band {} nm (σ = {:.4}, specular share {:.3}); the largest σ is at {} nm (σ = {:.4}, the paper's rule). λ* is the band with the largest specular share among those with σ ≥ ½ max σ: the diffuse light is what the two-facet model misplaces.\n\n![separation](inversion-sigma.svg)\n",
            worst,
            r1.n_bands,
            [basis_phrase(r1), pooling_phrase(r1)]
                .into_iter()
                .filter(|p| !p.is_empty())
                .collect::<Vec<_>>()
                .join("; "),
            r2.wavelength_nm[r2.chosen_band as usize],
            r2.separation[r2.chosen_band as usize],
            r2.specular_share[r2.chosen_band as usize],
            r2.wavelength_nm[r2.separation_band as usize],
            r2.separation[r2.separation_band as usize],
        );
    }
    if let Some(r) = get(3) {
        let truth = sp.rate_deg_per_frame;
        if r.status == SolveStatus::Ok as u32 {
            let p = r.p_deg_per_frame;
            let _ = writeln!(
                s,
                "Stage 3 at {} nm: p = [{:.5}, {:.5}, {:.5}] deg/frame (truth [{}, {}, {}]), **error {:.3}** (paper metric 100·‖Δp‖); fitted on the first {} of {} motion frames (fit horizon: {}° of rotation at the fitted rate); {} LM iterations over {} polished starts.",
                r.wavelength_nm[r.stage3_band as usize], p[0], p[1], p[2], truth[0], truth[1], truth[2],
                rate_error_metric(p, truth), r.fitted_frames, r.motion_samples,
                glint_inversion::stage3::DEFAULT_MAX_ROTATION_DEG, r.iterations, r.starts
            );
            if r.stage3_flags & SolveResponse::LAMBDA_REJECTED != 0 {
                let _ = writeln!(s, "\n{}", set_aside_phrase(r));
            } else if let Some(phrase) = disagreement_phrase(r) {
                let _ = writeln!(s, "\n{phrase}");
            } else if r.stage3_joint_disagreement_sigma.is_finite() {
                let _ = writeln!(
                    s,
                    "\nThe joint fit (all bands) is {:.1}σ from this rate (the two covariances summed, over the directions both determine){}.",
                    r.stage3_joint_disagreement_sigma,
                    widened_phrase(r)
                );
            }
            if r.stage3_flags & SolveResponse::SENSE_FROM_JOINT != 0 {
                let _ = writeln!(
                    s,
                    "\nAt {} nm alone this rate and its mirror fit equally well; the sense of rotation is the joint fit's (all bands).",
                    r.wavelength_nm[r.stage3_band as usize]
                );
            }
            if r.stage3_flags & SolveResponse::HELD_COEFFICIENTS != 0 {
                let _ = writeln!(s, "\n{HELD_SENTENCE}");
            }
            let _ = writeln!(
                s,
                "\n![stage-1 fit](stage1-fit.svg)\n\n![stage-3 fit](stage3-fit.svg)\n\n![stage-3 residuals](stage3-residuals.svg)\n"
            );
        } else {
            let _ = writeln!(
                s,
                "Stage 3 at {} nm: **{}** ({}) — no rate is reported.",
                r.wavelength_nm[r.stage3_band as usize],
                status(r),
                SolveResponse::reason_name(r.unobservable_reason)
            );
        }
        let m = r.p_mirror_deg_per_frame;
        if m.iter().all(|v| v.is_finite()) {
            let _ = writeln!(
                s,
                "\n**The mirror solution [{:.5}, {:.5}, {:.5}] fits the data equally well** (error {:.3}): its cost is within Δχ² ≤ 4 of the fit's. With the Sun within a fraction of a degree of the orbit plane, the geometry is (nearly) symmetric about the body XZ plane: the light curves of a rate and of its mirror image (−w_x, w_y, −w_z) differ only through that fraction of a degree, so the data cannot choose between them (for a rate with components about X or Z, the sense of rotation).",
                m[0], m[1], m[2], rate_error_metric(m, truth)
            );
        }
        s += &neighbour_sentence(
            r.p_neighbour_deg_per_frame,
            r.stage3_neighbour_delta_chi2,
            truth,
            false,
        );
        let pj = r.p_joint_deg_per_frame;
        if pj.iter().all(|v| v.is_finite()) {
            let _ = writeln!(
                s,
                "Joint fit over all bands: p = [{:.5}, {:.5}, {:.5}], error {:.3}.{}{}{}",
                pj[0],
                pj[1],
                pj[2],
                rate_error_metric(pj, truth),
                lobe_test_text(r),
                lobe_other_text(r, truth),
                if r.stage3_flags & SolveResponse::JOINT_HELD_COEFFICIENTS != 0 {
                    format!(" {HELD_SENTENCE}")
                } else {
                    String::new()
                }
            );
            let m = r.p_joint_mirror_deg_per_frame;
            if m.iter().all(|v| v.is_finite()) {
                let _ = writeln!(
                    s,
                    "\n**The joint fit's mirror [{:.5}, {:.5}, {:.5}] fits all bands equally well** (error {:.3}): the data cannot tell the two apart (for a rate with components about X or Z, its sense of rotation), and the covariance describes the scatter about the one reported.",
                    m[0], m[1], m[2], rate_error_metric(m, truth)
                );
            }
            s += &neighbour_sentence(
                r.p_joint_neighbour_deg_per_frame,
                r.stage3_joint_neighbour_delta_chi2,
                truth,
                true,
            );
        }
        let b = r.bound_1sigma_deg_per_frame;
        let _ = writeln!(s, "\nFisher information eigen-directions (columns) and 1σ bounds [deg/frame]:\n\n| direction | x | y | z | 1σ | observable |\n|---|---|---|---|---|---|");
        for (i, bound) in b.iter().enumerate() {
            let _ = writeln!(
                s,
                "| {} | {:.3} | {:.3} | {:.3} | {:.3e} | {} |",
                i + 1,
                r.fisher_eigenvectors[i],
                r.fisher_eigenvectors[3 + i],
                r.fisher_eigenvectors[6 + i],
                bound,
                if r.observable_mask & (1 << i) != 0 {
                    "yes"
                } else {
                    "**no**"
                }
            );
        }
        if r.status == SolveStatus::Ok as u32 {
            s.push_str(&speed_sentence(r));
            s.push_str(&held_sentences(r));
        }
    }
    s
}

/// A determined direction this close to the rate's own axis is its speed \[cos 1°\].
const SPEED_DIRECTION_MIN_COS: f64 = 0.999_85;

/// When a determined eigen-direction is the rate's own axis (within 1°), what the light curve
/// fixes is the spin rate |p|, the angle the body turns through per frame (docs/adr/0025):
/// named, with its 1σ, so that a reader does not take it for a rate about a body axis.
fn speed_sentence(r: &SolveResponse) -> String {
    let p = r.p_deg_per_frame;
    (0..3)
        .filter(|&i| r.observable_mask & (1 << i) != 0)
        .find_map(|i| {
            let v = [0, 1, 2].map(|k| r.fisher_eigenvectors[3 * k + i]);
            speed_if_own_axis(&v, p).map(|speed| (i, speed))
        })
        .map_or_else(String::new, |(i, speed)| {
            format!(
                "\nDirection {} is the rate's own axis: the light curve fixes the spin rate |p| = {:.5} ± {:.1e} deg/frame (1σ), the angle the body turns through per frame.\n",
                i + 1,
                speed,
                r.bound_1sigma_deg_per_frame[i]
            )
        })
}

/// |p| \[deg/frame\] when the unit direction `v` is p's own axis (within 1°), else `None`.
pub(crate) fn speed_if_own_axis(v: &[f64; 3], p: [f64; 3]) -> Option<f64> {
    let speed = glint_inversion::stage3::distance(p, [0.0; 3]);
    if !(speed > 0.0 && speed.is_finite()) {
        return None;
    }
    let cos: f64 = (0..3).map(|k| v[k] * p[k] / speed).sum();
    (cos.abs() >= SPEED_DIRECTION_MIN_COS).then_some(speed)
}

/// The rates `SolveResponse::stage3_held_axes` says the prior held at zero.
fn held_names(bits: u32) -> Vec<&'static str> {
    let mut held: Vec<&str> = (0..3)
        .filter(|k| bits & (1 << k) != 0)
        .map(|k| RATE_NAMES[k])
        .collect();
    if bits & SolveResponse::HELD_OTHER != 0 {
        held.push("the weak direction itself");
    }
    held
}

/// What the stated prior held at λ*, which undetermined directions it did not hold, and where
/// the bounds' noise level came from.
fn held_sentences(r: &SolveResponse) -> String {
    let mut parts: Vec<String> = vec![];
    let weak: Vec<[f64; 3]> = (0..3)
        .filter(|i| r.observable_mask & (1 << i) == 0)
        .map(|i| [0, 3, 6].map(|row| r.fisher_eigenvectors[row + i]))
        .collect();
    let held = held_names(r.stage3_held_axes);
    if !weak.is_empty() {
        parts.push("The data do not determine the direction(s) marked **no**.".into());
        if !held.is_empty() {
            parts.push(format!(
                "p is reported under the stated prior {} = 0 (the rate about the body axis nearest a direction the data could not determine is zero); only the determined combinations come from the light curve.",
                held.join(", ")
            ));
        }
        // A weak direction whose nearest body axis the prior did not hold.
        let free: Vec<&str> = weak
            .iter()
            .map(nearest_body_axis)
            .filter(|&k| r.stage3_held_axes & (1 << k) == 0)
            .map(|k| RATE_NAMES[k])
            .collect();
        if !free.is_empty() {
            parts.push(format!(
                "Along {} the fit held nothing: the light curve is flat there to first order at this p (as at the centre between a rate and its near-mirror (−w_x, w_y, −w_z), where it rises only quadratically), and p sits where the fit ended.",
                free.join(", ")
            ));
        }
    }
    if let Some(source) = SolveResponse::COVARIANCE_SOURCE_NAMES
        .get(r.stage3_covariance_source as usize)
        .filter(|_| r.stage3_covariance_source > 0)
    {
        parts.push(format!("The bounds use {source}."));
    }
    if parts.is_empty() {
        return String::new();
    }
    format!("\n{}\n", parts.join(" "))
}

pub fn plots(dir: &Path, responses: &[SolveResponse]) -> Result<()> {
    let (Some(r1), Some(r2)) = (
        responses.iter().find(|r| r.stage == 1),
        responses.iter().find(|r| r.stage == 2),
    ) else {
        return Ok(());
    };
    let n = r2.n_bands as usize;
    let sigma: Vec<(f64, f64)> = (0..n)
        .map(|i| (r2.wavelength_nm[i], r2.separation[i]))
        .collect();
    let recon: Vec<(f64, f64)> = (0..n)
        .map(|i| (r1.wavelength_nm[i], r1.recon_err[i] * 100.0))
        .collect();
    let specular: Vec<(f64, f64)> = (0..n)
        .map(|i| (r2.wavelength_nm[i], r2.specular_share[i]))
        .collect();
    line_chart(
        &dir.join("inversion-sigma.svg"),
        "Stage 2: separation degree σ(λ), specular share, stage-1 reconstruction error ×100",
        "wavelength [nm]",
        "σ(λ); specular share; 100·ε_rec",
        &[
            Series {
                label: "σ(λ)",
                points: sigma,
                color: BLUE,
                markers: false,
            },
            Series {
                label: "specular share",
                points: specular,
                color: GREEN,
                markers: false,
            },
            Series {
                label: "100·ε_rec",
                points: recon,
                color: RED,
                markers: true,
            },
        ],
    )
}

/// How stage 1's basis test ended, in words.
fn basis_phrase(r: &SolveResponse) -> String {
    if r.stage1_lobes_kept >= 10 || !r.stage1_widest_lobe_mu.is_finite() {
        return "basis: diffuse + all 10 lobes (the data support each of them)".to_string();
    }
    format!(
        "basis: diffuse + the {} narrowest lobes (μ ≤ {}); the broader ones, which the stable window cannot tell from diffuse light, add nothing the data support (Δχ² = {:.1} for k = {} parameters)",
        r.stage1_lobes_kept, r.stage1_widest_lobe_mu, r.stage1_basis_delta_chi2, r.stage1_basis_dof
    )
}

/// Stage 1's spectral pooling decision, in words (empty when it was not tested).
fn pooling_phrase(r: &SolveResponse) -> String {
    let rho = r.stage1_spectral_bias_to_noise;
    if !rho.is_finite() {
        return String::new();
    }
    if r.stage1_spectral_window_nm > 0.0 {
        format!(
            "stage 2 and λ* use the stable window pooled over ±{} nm (the pooled curves' bias is {rho:.2} of the noise; the joint fit keeps every band's own)",
            r.stage1_spectral_window_nm
        )
    } else {
        format!(
            "every band on its own (pooling neighbouring bands would smear {rho:.2} of the noise)"
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn response(disagreement_sigma: f64, flags: u32) -> SolveResponse {
        let mut r = SolveResponse {
            stage3_joint_disagreement_sigma: disagreement_sigma,
            stage3_covariance_scale: (disagreement_sigma.powi(2) / 2.0).max(1.0),
            stage3_flags: flags,
            stage3_band: 1,
            ..SolveResponse::default()
        };
        r.wavelength_nm[1] = 410.0;
        r
    }

    #[test]
    fn a_kept_rate_beyond_the_gate_is_flagged_and_one_within_it_is_not() {
        let gate = glint_inversion::stage3::DEFAULT_JOINT_GATE_SIGMA;
        let warned = disagreement_phrase(&response(gate + 2.0, 0)).expect("beyond the gate");
        assert!(
            warned.contains("8.0σ apart") && warned.contains("410 nm"),
            "{warned}"
        );
        // 8σ over two directions: widened by 64 / 2.
        assert!(warned.contains("widened ×32.0"), "{warned}");
        assert!(widened_phrase(&response(1.2, 0)).is_empty());
        assert!(disagreement_phrase(&response(gate - 0.5, 0)).is_none());
        assert!(disagreement_phrase(&response(f64::NAN, 0)).is_none());
    }

    /// Eigen-directions Z, X, Y (ascending), only Y determined; `held` axes held by the prior.
    fn weak_response(held: u32, source: u32) -> SolveResponse {
        let mut r = SolveResponse {
            observable_mask: 0b100,
            stage3_held_axes: held,
            stage3_covariance_source: source,
            fisher_eigenvectors: [0.0; 9],
            ..SolveResponse::default()
        };
        for (i, axis) in [2, 0, 1].into_iter().enumerate() {
            r.fisher_eigenvectors[3 * axis + i] = 1.0;
        }
        r
    }

    #[test]
    fn a_determined_direction_along_the_rate_is_named_its_speed() {
        // Y determined (direction 3) and the rate along Y, 0.5° off: the spin rate.
        let mut r = weak_response(1, 1);
        let tilt = 0.5f64.to_radians();
        r.p_deg_per_frame = [0.0, 0.25 * tilt.cos(), 0.25 * tilt.sin()];
        r.bound_1sigma_deg_per_frame = [0.5, 0.5, 3e-5];
        let text = speed_sentence(&r);
        assert!(
            text.contains("Direction 3 is the rate's own axis")
                && text.contains("|p| = 0.25000 ± 3.0e-5"),
            "{text}"
        );
        // 2° off, or along an undetermined direction: not the speed.
        let tilt = 2f64.to_radians();
        r.p_deg_per_frame = [0.0, 0.25 * tilt.cos(), 0.25 * tilt.sin()];
        assert!(speed_sentence(&r).is_empty());
        r.p_deg_per_frame = [0.0, 0.0, 0.25];
        assert!(speed_sentence(&r).is_empty());
        r.p_deg_per_frame = [0.0; 3];
        assert!(speed_sentence(&r).is_empty());
    }

    #[test]
    fn the_summary_says_which_undetermined_directions_the_prior_held() {
        // The bisector hold held w_x; Z is flat to first order at p̂ but was not held.
        let text = held_sentences(&weak_response(1, 1));
        assert!(text.contains("stated prior w_x = 0"), "{text}");
        assert!(!text.contains("w_z = 0"), "{text}");
        assert!(text.contains("Along w_z the fit held nothing"), "{text}");
        assert!(
            text.contains("The bounds use the observations' σ."),
            "{text}"
        );
        // Both held: nothing is left where the fit ended.
        let text = held_sentences(&weak_response(1 | 4, 3));
        assert!(text.contains("stated prior w_x, w_z = 0"), "{text}");
        assert!(!text.contains("held nothing"), "{text}");
        assert!(text.contains("residual variance"), "{text}");
        // Every direction determined: only the noise level's source.
        let mut all = weak_response(0, 2);
        all.observable_mask = 0b111;
        let text = held_sentences(&all);
        assert!(!text.contains("do not determine"), "{text}");
        assert!(text.contains("Birge ratio"), "{text}");
    }
}
