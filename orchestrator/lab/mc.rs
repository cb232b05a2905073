//! Monte-Carlo campaign values (`[campaign] seeds = N > 1`): is the rate estimator efficient
//! and honest at this noise level?
//!
//! Per value: one noise-free deployment (the reference) and N noisy ones (seeds `seed + k`),
//! each a full deployment with its own processes. Then, for the fit at λ* and the joint fit:
//!
//! ```text
//! d_k = p̂_k − p₀                      p₀: the noise-free solution (offline, same solver)
//! CRB = (JᵀWJ − L)⁻¹ at p₀              J over the frames p₀ was fitted on, W = 1/σ²,
//!                                      σ = mean Φ / SNR per band and noisy window
//! L = Σ_b F_pb (S_b + B_bᵀB_b)⁻¹ F_bp   the stage-1 coefficients are unknown too: S_b is the
//!                                      stable window's information about them (stage 1 with
//!                                      that σ, on the coefficients NNLS left free), B_b the
//!                                      motion window's (RateProblem::coefficient_information_loss)
//! observable: CRB eigen-directions v_i with 1σ = sqrt(λ_i) ≤ 0.25 deg/frame
//! other sense: runs nearer mirror(p₀) = (−w_x, w_y, −w_z) than p₀, when that mirror is at least
//!              |p₀| away, counted apart (a global ambiguity the local bound does not describe)
//!              and left out of RMS and NEES
//! HCR_i = sup_h (v_i·h)²/(exp Δ(h) − 1)  Hammersley–Chapman–Robbins, Δ(h) = ‖r(p₀+h) − r(p₀)‖²
//!                                      profiled over the other observable directions and,
//!                                      like the CRB, the stage-1 coefficients
//!                                      (glint_lab::chapman_robbins)
//! copy: a test point ≥ 2 CRB from p₀ with Δ < min(1, ¼(c/CRB)²), coefficients fixed: the
//!       model cannot tell it from p₀ (a Y rotation's mirror, moved off p₀ by the
//!       out-of-plane geometry); runs nearer it than p₀ take d_k = p̂_k − copy
//! efficiency = sqrt(mean_k Σ_obs (d_k·v_i)²) / sqrt(Σ_obs λ_i)     (1 = efficient)
//! NEES_k = Σ_obs' (d_k·u_j)²/μ_j        u_j, μ_j: eigen-pairs of the run's reported covariance
//! lobe test: the joint fit keeps or re-fits stage 1's widest lobes per run; p₀ and the bound
//!            are then computed for each model and d_k is taken from the p₀ of the model the
//!            run reported (the table's bound: the model most runs reported)
//! ```
//!
//! This is the bound of the scenario as run, with both windows noisy. The summary also shows
//! (JᵀWJ)⁻¹, the bound if the coefficients were known exactly.

use std::path::Path;

use anyhow::{anyhow, Context, Result};
use glint_inversion::lm::normal_equations;
use glint_inversion::observability::symmetric_eigen;
use glint_inversion::stage1::{spectral, Stage1Config};
use glint_inversion::stage3::{distance, has_sense, mirror, LobeRefit, RateFit};
use glint_inversion::{
    rate_error_metric, solve_three_stage, InversionConfig, InversionResult, MotionModelConfig,
    Observation, ObservationSet, RateBand, RateProblem, Stage1Band,
};
use glint_lab::chapman_robbins::{chapman_robbins, RateCopy};
use serde_json::{json, Value};
use shared_types::scenario::NoiseWindows;
use shared_types::Scenario;

use crate::run::{self, RunOptions};

/// A direction with a larger 1σ bound is unobservable \[deg/frame\]: stage 3's threshold.
fn observable_bound() -> f64 {
    glint_inversion::observability::ObservabilityConfig::default().unobservable_bound_deg_per_frame
}

/// Runs the reference and the N noisy deployments of one campaign value under `dir`; returns
/// the value's statistics and whether every deployment succeeded.
pub fn run_value(
    variant: &Scenario,
    file: &str,
    dir: &Path,
    seeds: u32,
    progress: bool,
    rescore: bool,
) -> Result<(Value, bool)> {
    let sp = variant
        .spectra
        .as_ref()
        .context("a Monte-Carlo campaign needs a [spectra] section")?;
    let snr = sp
        .snr
        .context("a Monte-Carlo campaign needs spectra.snr (noise)")?;
    let truth = sp.rate_deg_per_frame;
    let mut reference = variant.clone();
    if let Some(x) = reference.spectra.as_mut() {
        x.snr = None;
    }
    let deploy = |scenario: Scenario, sub: &Path| -> Result<(crate::report::Report, bool)> {
        if rescore {
            let path = sub.join("report.json");
            let text = std::fs::read_to_string(&path).with_context(|| {
                format!(
                    "{}: no report to re-score (run the campaign first)",
                    path.display()
                )
            })?;
            let report: crate::report::Report = serde_json::from_str(&text)
                .with_context(|| format!("{}: not a glint report", path.display()))?;
            let ok = report.results.success;
            return Ok((report, ok));
        }
        let (run_dir, ok) = run::run(RunOptions {
            scenario,
            scenario_file: file.to_string(),
            out_dir: Some(sub.to_path_buf()),
            // The campaign owns its directory: a sub-run there replaces the previous one.
            replace: true,
            progress,
            record: false,
            host: None,
        })?;
        run::bail_if_interrupted("campaign")?;
        Ok((
            crate::report::Report::read(&run_dir.join("report.json"))?,
            ok,
        ))
    };
    let ref_dir = dir.join("reference");
    let (_, mut all_ok) = deploy(reference, &ref_dir)?;
    let mut runs = Vec::with_capacity(seeds as usize);
    for k in 0..seeds {
        let mut noisy = variant.clone();
        noisy.seed = variant.seed + k as u64;
        let (report, ok) = deploy(noisy, &dir.join(format!("s{k:03}")))?;
        all_ok &= ok;
        runs.push((report.results.inversion).and_then(|i| i.stage3));
    }
    let stable_noisy = sp.noise_windows == NoiseWindows::Both;
    let reference = Reference::solve(
        &ref_dir.join("observations.csv"),
        snr,
        stable_noisy,
        glint_inversion::service_core::stage3_config(sp),
    )?;
    // λ*'s fit carries its rate (no covariance: its NEES is not scored); the answer is the
    // joint fit, with its covariance.
    let single_fits: Vec<Fit> = runs
        .iter()
        .map(|s3| Fit::lambda_star(s3.as_ref()))
        .collect();
    let joint_fits: Vec<Fit> = runs.iter().map(|s3| Fit::answer(s3.as_ref())).collect();
    let single = Estimator::from_runs(&single_fits, reference.single.clone(), None);
    // The table's bound for the joint fit: that of the model most runs reported.
    let lobe_refits = joint_fits.iter().filter(|f| f.widest_lobe_refit).count();
    let joint_bound = match &reference.joint_models {
        Some(models) => models[usize::from(2 * lobe_refits > runs.len())].clone(),
        None => reference.joint.clone(),
    };
    let joint = Estimator::from_runs(&joint_fits, joint_bound, reference.joint_models.as_ref());
    let median = |fits: &[Fit]| {
        median(
            fits.iter()
                .filter_map(|f| f.p.map(|p| rate_error_metric(p, truth)))
                .collect(),
        )
    };
    let stats = json!({
        "runs": seeds,
        "snr": snr,
        "median_err_paper_metric": median(&single_fits),
        "median_joint_err_paper_metric": median(&joint_fits),
        "reference_err_paper_metric": reference.single.p0.map(|p| rate_error_metric(p, truth)),
        "single": single.json(),
        "joint": joint.json(),
        "joint_widest_lobe_refits": lobe_refits,
    });
    Ok((stats, all_ok))
}

/// A number for JSON: non-finite values become `null`.
pub(crate) fn finite(v: f64) -> Value {
    if v.is_finite() {
        json!(v)
    } else {
        Value::Null
    }
}

pub(crate) fn vec3(v: &Value) -> Option<[f64; 3]> {
    let a = v.as_array()?;
    let p = [
        a.first()?.as_f64()?,
        a.get(1)?.as_f64()?,
        a.get(2)?.as_f64()?,
    ];
    p.iter().all(|x| x.is_finite()).then_some(p)
}

fn median(mut v: Vec<f64>) -> Option<f64> {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    match n {
        0 => None,
        _ if n % 2 == 1 => Some(v[n / 2]),
        _ => Some(0.5 * (v[n / 2 - 1] + v[n / 2])),
    }
}

/// The noise-free solution of one estimator and its Cramér–Rao bound.
#[derive(Debug, Clone)]
struct Bound {
    /// p₀ (None when the reference fit was not determined).
    p0: Option<[f64; 3]>,
    /// CRB variances along its eigen-directions \[(deg/frame)²\] and those directions (rows).
    variances: [f64; 3],
    directions: [[f64; 3]; 3],
    /// The bound with the coefficients known, (JᵀWJ)⁻¹: its variances along `directions`.
    known_variances: [f64; 3],
    /// The two-stage bound along `directions`: F⁺ + F⁺ C F⁺ with C the stage-1 coefficients'
    /// covariance propagated (`RateProblem::coefficient_term`), the variance of an efficient
    /// estimator that takes the coefficients from the stable window alone, as this one does
    /// (the CRB lets the motion window inform them too).
    two_stage_variances: [f64; 3],
    /// The Hammersley–Chapman–Robbins bound along each observable direction (coefficients
    /// known; NaN elsewhere) \[(deg/frame)²\].
    hcr_variances: [f64; 3],
    /// A copy of p₀: a rate beyond p₀'s local scatter whose noise-free light curve is within
    /// one noise variance of p₀'s (Δ < 1), and that Δ.
    copy: Option<RateCopy>,
}

impl Bound {
    fn observable(&self) -> [bool; 3] {
        observable(&self.variances)
    }
}

fn observable(variances: &[f64; 3]) -> [bool; 3] {
    variances.map(|v| v.is_finite() && v.sqrt() <= observable_bound())
}

struct Reference {
    single: Bound,
    joint: Bound,
    /// With the joint fit's lobe test ([`LobeRefit::WhenNeeded`]): the noise-free solution and
    /// bound of each of its two models, keeping stage 1's widest lobes (0) and re-fitting them
    /// (1). A run's deviation is taken from the solution of the model it reported: the noisy
    /// stable window is what moves stage 1's lobe, so the noise-free reference mostly keeps it
    /// while the noisy runs about Z mostly re-fit it.
    joint_models: Option<[Bound; 2]>,
}

impl Reference {
    /// p₀, the estimator's noise-free solution: the noise-free run's observations solved
    /// offline with the noisy runs' σ = mean/SNR attached to the windows they make noisy (the
    /// weights, the stage-1 basis test and the joint fit's reweighting all depend on σ, so the
    /// σ-free answer is another estimator's limit), with the scenario's stage-3 settings. Then
    /// the CRB of each fit at p₀ on the frames it used.
    fn solve(
        observations: &Path,
        snr: f64,
        stable_noisy: bool,
        stage3: glint_inversion::stage3::Stage3Config,
    ) -> Result<Reference> {
        let mut file = crate::tools::observations::read(observations)?;
        let mut config = InversionConfig {
            joint_fit: true,
            stage3,
            ..Default::default()
        };
        attach_sigma(&mut file.set.motion, snr);
        if stable_noisy {
            attach_sigma(&mut file.set.stable, snr);
            expected_pooling(&file.set, &mut config.stage1);
        }
        let result = solve_three_stage(&file.set, &config)
            .map_err(|e| anyhow!("{}: {e}", observations.display()))?;
        let mut motion = file.set.motion.clone();
        motion.sort_by_key(|o| o.frame_index);
        let n_bands = file.set.wavelengths_nm.len();
        let epoch_frame = motion.first().map(|o| o.frame_index);
        // The bound of the model each fit ends with (with the polish's re-fitted terms, as p₀'s
        // fit records them).
        let model_for = |fit: Option<&RateFit>| MotionModelConfig {
            epoch_frame,
            refit_diffuse: config.model.refit_diffuse || fit.is_some_and(|f| f.refit.is_some()),
            refit_widest_lobe: fit.is_some_and(|f| f.refit.is_some_and(|r| r.widest_lobe)),
            ..config.model.clone()
        };
        // The coefficients each fit used, with their covariance from the stable window's σ
        // (none when the stable window is noise-free: the coefficients are known).
        let bound = |fit: Option<&RateFit>,
                     frames: usize,
                     stage1: &[Stage1Band],
                     bands: &[usize]|
         -> Result<Bound> {
            let frames: Vec<Observation> = motion.iter().take(frames).cloned().collect();
            let rate_bands: Vec<RateBand> = bands
                .iter()
                .map(|&b| RateBand {
                    band_index: b,
                    wavelength_nm: stage1[b].wavelength_nm,
                    coeffs: stage1[b].coeffs,
                })
                .collect();
            let covariance = bands
                .iter()
                .map(|&b| {
                    stable_noisy
                        .then(|| stage1[b].coeff_covariance.clone())
                        .flatten()
                })
                .collect();
            let problem = RateProblem::new(&frames, &rate_bands, &model_for(fit))?
                .with_coefficient_covariance(covariance);
            crb(&problem, fit.map(|f| f.rate_deg_per_frame))
        };
        let single = bound(
            result.rate.fit(),
            result.fitted_frames,
            result.single_band_stage1(),
            &[result.stage2.chosen_index],
        )?;
        let joint_of = |result: &InversionResult| {
            bound(
                result.joint_rate.as_ref().and_then(|r| r.fit()),
                result.joint_fitted_frames.unwrap_or(result.fitted_frames),
                &result.stage1,
                &(0..n_bands).collect::<Vec<_>>(),
            )
        };
        let joint = joint_of(&result)?;
        let tested =
            config.stage3.refit_diffuse && config.stage3.refit_widest_lobe == LobeRefit::WhenNeeded;
        let joint_models = if tested {
            let model = |lobe: LobeRefit| -> Result<Bound> {
                let mut forced = config.clone();
                forced.stage3.refit_widest_lobe = lobe;
                let result = solve_three_stage(&file.set, &forced)
                    .map_err(|e| anyhow!("{}: {e}", observations.display()))?;
                joint_of(&result)
            };
            Some([model(LobeRefit::None)?, model(LobeRefit::Joint)?])
        } else {
            None
        };
        Ok(Reference {
            single,
            joint,
            joint_models,
        })
    }
}

/// Fixes stage 1's pooling decision to the one the noisy runs take on average: on the
/// noise-free window with σ attached the pooling test's residual is the pooled curves' bias
/// itself ([`spectral::bias_to_noise_noise_free`]), which the runs' test estimates through
/// their noise.
fn expected_pooling(set: &ObservationSet, stage1: &mut Stage1Config) {
    let weights = spectral::local_linear_weights(&set.wavelengths_nm, stage1.spectral_window_nm);
    let rho = spectral::bias_to_noise_noise_free(&set.stable, &weights);
    if rho.is_some_and(|r| r <= stage1.spectral_max_bias_to_noise) {
        stage1.spectral_max_bias_to_noise = f64::INFINITY;
    } else {
        stage1.spectral_window_nm = 0.0;
    }
}

/// Sets every sample's σ to the window's mean flux / SNR, per band: the noise the sensor adds
/// to a noisy window (and publishes with it).
fn attach_sigma(window: &mut [Observation], snr: f64) {
    let n = window.len().max(1) as f64;
    let bands = window.first().map_or(0, |o| o.flux_w.len());
    let sigma: Vec<f64> = (0..bands)
        .map(|b| window.iter().map(|o| o.flux_w[b]).sum::<f64>() / n / snr)
        .collect();
    for o in window {
        o.sigma_w = sigma.clone();
    }
}

/// The bound of the fit whose plug-in model is `problem` (with the stage-1 covariance), at its
/// noise-free answer p0.
fn crb(problem: &RateProblem, p0: Option<[f64; 3]>) -> Result<Bound> {
    let Some(p) = p0 else {
        return Ok(Bound {
            p0: None,
            variances: [f64::NAN; 3],
            directions: [[f64::NAN; 3]; 3],
            known_variances: [f64::NAN; 3],
            two_stage_variances: [f64::NAN; 3],
            hcr_variances: [f64::NAN; 3],
            copy: None,
        });
    };
    let information = |problem: &RateProblem| {
        let n = problem.residual_count();
        let (mut r, mut jac) = (vec![0.0; n], vec![[0.0; 3]; n]);
        problem.residuals_and_jacobian(p, &mut r, &mut jac);
        (normal_equations(&jac, &r).0, jac)
    };
    let (fisher, jac) = information(problem);
    let loss = problem
        .coefficient_information_loss(p, &jac)
        .unwrap_or([[0.0; 3]; 3]);
    let reduced: [[f64; 3]; 3] =
        std::array::from_fn(|i| std::array::from_fn(|j| fisher[i][j] - loss[i][j]));
    let (info, vecs) = symmetric_eigen(&reduced)?;
    let (known_info, known_vecs) = symmetric_eigen(&fisher)?;
    // (JᵀWJ)⁺ along each direction v of the scenario's bound: Σ_k (v·u_k)²/λ_k over the
    // determined eigen-pairs of JᵀWJ. The estimator holds the undetermined one under its prior,
    // so its variance does not leak into the others (the full inverse would add (v·u₁)²/λ₁
    // with λ₁ ≈ 0).
    let determined = |l: f64| l > 0.0 && l.sqrt().recip() <= observable_bound();
    // F⁺v over the determined eigen-pairs of F = JᵀWJ: v·F⁺v is the bound with the
    // coefficients known, v·F⁺v + (F⁺v)ᵀC(F⁺v) the two-stage bound.
    let pinv_v = vecs.map(|v| -> [f64; 3] {
        std::array::from_fn(|i| {
            known_info
                .iter()
                .zip(&known_vecs)
                .filter(|(l, _)| determined(**l))
                .map(|(l, u)| (0..3).map(|k| v[k] * u[k]).sum::<f64>() / l * u[i])
                .sum()
        })
    });
    let known_variances: [f64; 3] =
        std::array::from_fn(|d| (0..3).map(|i| vecs[d][i] * pinv_v[d][i]).sum());
    let coefficients = problem.coefficient_term(p, &jac).unwrap_or([[0.0; 3]; 3]);
    let two_stage_variances: [f64; 3] = std::array::from_fn(|d| {
        let w = pinv_v[d];
        let quad: f64 = (0..3)
            .flat_map(|i| (0..3).map(move |j| (i, j)))
            .map(|(i, j)| w[i] * coefficients[i][j] * w[j])
            .sum();
        known_variances[d] + quad
    });
    let variances = info.map(|l| if l > 0.0 { 1.0 / l } else { f64::INFINITY });
    let (hcr_variances, copy) = chapman_robbins_variances(problem, p, &variances, &vecs)?;
    Ok(Bound {
        p0,
        variances,
        directions: vecs,
        known_variances,
        two_stage_variances,
        hcr_variances,
        copy,
    })
}

/// The HCR bound along each observable direction, profiled over the other observable ones (and
/// over the stage-1 coefficients when `problem` carries their covariance), searching offsets
/// from a tenth of the CRB out to the observability threshold (and, when the mirror of p₀ is
/// another sense of rotation, to half-way there: runs beyond it are counted apart, not as
/// scatter); and the copy of p₀ with the smallest Δ, the coefficients fixed, if any.
fn chapman_robbins_variances(
    problem: &RateProblem,
    p0: [f64; 3],
    variances: &[f64; 3],
    directions: &[[f64; 3]; 3],
) -> Result<([f64; 3], Option<RateCopy>)> {
    let observable = observable(variances);
    let m0 = mirror(p0);
    let mut reach = observable_bound();
    if has_sense(p0) {
        reach = reach.min(0.5 * distance(m0, p0));
    }
    // A copy is a second rate of the model itself (the mirror, ADR 0005): judged with the
    // coefficients fixed. The bound lets the stage-1 coefficients move too, as the CRB does.
    let fixed = problem.clone().with_coefficient_covariance(vec![]);
    let mut out = [f64::NAN; 3];
    let mut copy: Option<RateCopy> = None;
    for i in (0..3).filter(|&i| observable[i]) {
        let free: Vec<[f64; 3]> = (0..3)
            .filter(|&k| k != i && observable[k])
            .map(|k| directions[k])
            .collect();
        let search = |problem: &RateProblem| {
            chapman_robbins(
                problem,
                p0,
                directions[i],
                &free,
                variances[i].sqrt(),
                reach,
            )
        };
        out[i] = search(problem)?.variance;
        if let Some(c) = search(&fixed)?
            .copy
            .filter(|c| copy.is_none_or(|b| c.divergence < b.divergence))
        {
            copy = Some(c);
        }
    }
    Ok((out, copy))
}

#[path = "mc/estimator.rs"]
mod estimator;
use estimator::{Estimator, Fit};

#[cfg(test)]
#[path = "mc/tests.rs"]
mod tests;
