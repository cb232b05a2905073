//! Stage 3 as the solve runs it: the fit horizon, the joint fit over all bands, the fit at λ*
//! and its check against the joint fit (the fallback along stage 2's ranking).

use crate::error::InversionError;
use crate::model::refit::broad_lobe_in_use;
use crate::model::{MotionModelConfig, RateBand, RateProblem};
use crate::observability::UnobservableReason;
use crate::observation::Observation;
use crate::stage1::Stage1Band;
use crate::stage3::{self, LobeRefit, RateFit, RateSolution, Stage3Config, MIRROR_MAX_DELTA_CHI2};

mod horizon;
mod lobe;
use horizon::{horizon_frames, speed, FitSetup};

/// Stage 3 at the first band of stage 2's `ranking` (λ*) and, with `joint`, one p for all
/// bands, each over its fit horizon. A λ* solution the joint fit rejects ([`fit_band`]) is set
/// aside for the next band of the ranking the joint fit accepts. The joint fit uses every
/// band's own coefficients (`stage1`), the single-band fits those of `single_band` (the
/// spectrally pooled ones when stage 1 pooled, [`crate::stage1::Stage1Output`]).
#[allow(clippy::too_many_arguments)]
pub fn fit_rates(
    motion: &[Observation],
    stage1: &[Stage1Band],
    single_band: &[Stage1Band],
    ranking: &[usize],
    model: &MotionModelConfig,
    config: &Stage3Config,
    joint: bool,
) -> Result<RateFits, InversionError> {
    let mut joint_rate = if joint {
        Some(fit_joint(motion, stage1, model, config)?)
    } else {
        None
    };
    let joint_fit = joint_rate.as_ref().map(|j| &j.0);
    let Some((&chosen, others)) = ranking.split_first() else {
        return Err(InversionError::NoSeparableBand);
    };
    let mut fit = fit_band(motion, single_band, chosen, model, config, joint_fit)?;
    let mut band_index = chosen;
    let mut set_aside = Vec::new();
    if fit.rejected_by_joint {
        set_aside.push(chosen);
        for &b in others {
            let next = fit_band(motion, single_band, b, model, config, joint_fit)?;
            if !next.rejected_by_joint {
                fit = next;
                band_index = b;
                break;
            }
            set_aside.push(b);
        }
        // Every candidate rejected: λ*'s own answer stands, flagged.
        if band_index == chosen {
            set_aside = vec![chosen];
        }
    }
    let mut rate = unless_unconfirmed(fit.rate, joint_fit, |kept| {
        confirmed_by_joint(motion, stage1, model, config, kept)
    })?;
    // Every decision on the band is taken: its covariance is the one averaged over its
    // interval, and that covers its distance from the joint fit (measured before the
    // widening, and reported as such) at the joint fit's local covariance.
    rate.report_interval_average();
    let covariance_scale = match (&mut rate, joint_fit.and_then(RateSolution::fit)) {
        (RateSolution::Determined(kept), Some(joint)) if config.widen_to_joint => {
            Some(stage3::widen_to_joint(kept, joint, &config.observability))
        }
        _ => None,
    };
    // Every decision is taken: the answers report their profile-likelihood intervals (when
    // `profile_intervals` attached them) and carry their neighbouring minima (when
    // `cover_neighbours` found them).
    rate.report_profile(covariance_scale.unwrap_or(1.0));
    rate.report_neighbours();
    if let Some((joint, _)) = &mut joint_rate {
        joint.report_interval_average();
        joint.report_profile(1.0);
        joint.report_neighbours();
        if let RateSolution::Determined(fit) = joint {
            if config.cover_lobe_alternative {
                fit.report_lobe_alternative();
            }
        }
    }
    Ok(RateFits {
        rate,
        covariance_scale,
        band_index,
        set_aside,
        fitted_frames: fit.fitted_frames,
        joint_fitted_frames: joint_rate.as_ref().map(|j| j.1),
        joint_rate: joint_rate.map(|j| j.0),
        sense_from_joint: fit.sense_from_joint,
        joint_disagreement_sigma: fit.joint_disagreement_sigma,
    })
}

/// A joint fit with no rate confirms none: `rate` stands only if `confirmed` (the joint cost
/// has a determined minimum near it), else it is unobservable, not confirmed. A joint fit with
/// a rate (or none asked for) leaves `rate` as it is.
fn unless_unconfirmed(
    rate: RateSolution,
    joint: Option<&RateSolution>,
    confirmed: impl FnOnce(&RateFit) -> Result<bool, InversionError>,
) -> Result<RateSolution, InversionError> {
    let (Some(RateSolution::Unobservable { .. }), RateSolution::Determined(kept)) = (joint, &rate)
    else {
        return Ok(rate);
    };
    if confirmed(kept)? {
        return Ok(rate);
    }
    Ok(RateSolution::Unobservable {
        reason: UnobservableReason::NotConfirmedByJoint {
            rate_deg_per_frame: kept.rate_deg_per_frame,
        },
        bounds_deg_per_frame: kept.observability.bounds_1sigma_deg_per_frame,
        observability: kept.observability.clone(),
        wavelengths_nm: kept.wavelengths_nm.clone(),
    })
}

/// Whether the joint cost (every band, each with its own stage-1 coefficients) finds `fit`'s
/// rate: the joint model polished from that rate (with the diffuse terms re-fitted when
/// [`Stage3Config::refit_diffuse`]) ends within [`Stage3Config::joint_gate_sigma`] of it, and
/// so does the joint search (grid, screen, polish) on the frames of that rate's horizon with
/// the rate among its starts: the joint data hold the rate and prefer it. Always true with the
/// gate off.
pub fn confirmed_by_joint(
    motion: &[Observation],
    stage1: &[Stage1Band],
    model: &MotionModelConfig,
    config: &Stage3Config,
    fit: &RateFit,
) -> Result<bool, InversionError> {
    let Some(gate) = config.joint_gate_sigma else {
        return Ok(true);
    };
    let bands: Vec<RateBand> = (0..stage1.len()).map(|b| rate_band(stage1, b)).collect();
    let covs: Vec<Option<Vec<f64>>> = stage1.iter().map(|s| s.coeff_covariance.clone()).collect();
    let setup = FitSetup::new(motion, &bands, &covs, None, model);
    let polished = if config.refit_diffuse {
        let start = RateSolution::Determined(fit.clone());
        match horizon::polish_with_refit(&setup, config, &start)? {
            Some((polished, _)) => polished,
            None => return Ok(false),
        }
    } else {
        horizon::polish_at(&setup, config, fit.rate_deg_per_frame)?
    };
    let near = |sol: &RateSolution| {
        sol.fit()
            .is_some_and(|j| stage3::disagreement_sigma(fit, j, &config.observability) <= gate)
    };
    if !near(&polished) {
        return Ok(false);
    }
    // A minimum the joint cost holds but does not prefer is not confirmed either: the joint
    // search on the same frames, with the band's rate among its starts, must end near it.
    let searched = horizon::search_at(&setup, config, fit.rate_deg_per_frame)?;
    Ok(near(&searched))
}

fn rate_band(stage1: &[Stage1Band], b: usize) -> RateBand {
    RateBand {
        band_index: b,
        wavelength_nm: stage1[b].wavelength_nm,
        coeffs: stage1[b].coeffs,
    }
}

/// Stage 3 at one band ([`fit_band`]).
#[derive(Debug, Clone, PartialEq)]
pub struct BandFit {
    /// The solution.
    pub rate: RateSolution,
    /// Motion frames fitted (the band's fit horizon).
    pub fitted_frames: usize,
    /// p̂ and its mirror fit the band equally well and the joint fit decided the sense.
    pub sense_from_joint: bool,
    /// The joint fit rejects p̂ as another minimum ([`Stage3Config::joint_gate_sigma`]).
    pub rejected_by_joint: bool,
    /// How far p̂ is from the joint solution, in standard deviations of the two covariances
    /// summed over the directions both determine (`stage3::disagreement_sigma`); `None`
    /// without a determined joint solution.
    pub joint_disagreement_sigma: Option<f64>,
}

/// Stage 3 at band `b` over its fit horizon. With a `joint` solution:
/// - when p̂ and its mirror fit this band equally well, the sense of rotation is the joint
///   fit's (`stage3::sense_from`);
/// - p̂ is checked against it ([`Stage3Config::joint_gate_sigma`]): rejected when the two are
///   more than the gate's standard deviations apart *and* the band's own cost has a separate
///   minimum on the joint solution's side (re-polished from the joint solution, LM does not
///   slide back to p̂). A bias of the band — one minimum, shifted — is not rejected.
///
/// With [`Stage3Config::cover_neighbours`] the minima a frame's shift from p̂ are looked for
/// and held on the fit; [`fit_rates`] has its covariance carry them once every decision is
/// taken (docs/adr/0020).
pub fn fit_band(
    motion: &[Observation],
    stage1: &[Stage1Band],
    b: usize,
    model: &MotionModelConfig,
    config: &Stage3Config,
    joint: Option<&RateSolution>,
) -> Result<BandFit, InversionError> {
    let covariance = vec![stage1[b].coeff_covariance.clone()];
    let bands = [rate_band(stage1, b)];
    let joint = joint.zip(joint.and_then(RateSolution::fit));
    let mut setup = FitSetup::new(motion, &bands, &covariance, None, model);
    let (mut rate, mut problem, mut sense_from_joint) =
        search_and_polish_band(&setup, config, joint)?;
    // A rate found slow on the search's first window is judged on frames far beyond a faster
    // rate's horizon, where the model no longer holds for that rate, and stays slow (Z at phase
    // 30°: 0.09 deg/frame over 279 frames, against the joint fit's 0.25 over 100). When the
    // band's rate ends below half the joint's, it is fitted again with its windows no longer
    // than the joint rate's horizon.
    let joint_speed = joint.map_or(0.0, |(_, j)| speed(j.rate_deg_per_frame));
    if rate
        .fit()
        .is_some_and(|f| speed(f.rate_deg_per_frame) < SLOW_FRACTION * joint_speed)
    {
        setup = setup.with_speed_floor(joint_speed);
        (rate, problem, sense_from_joint) = search_and_polish_band(&setup, config, joint)?;
    }
    // Computed on the band's own problem, reported once every decision is taken: the joint
    // gate and the confirmation read the local covariance (docs/adr/0027).
    rate.attach_interval_average_if_asked(&problem, config);
    rate.attach_profile_if_asked(&problem, config);
    rate.attach_neighbours_if_asked(&problem, config)?;
    let mut out = BandFit {
        rate,
        fitted_frames: problem.frame_count(),
        sense_from_joint,
        rejected_by_joint: false,
        joint_disagreement_sigma: None,
    };
    let Some((_, joint_fit)) = joint else {
        return Ok(out);
    };
    out.joint_disagreement_sigma = out
        .rate
        .fit()
        .map(|fit| stage3::disagreement_sigma(fit, joint_fit, &config.observability));
    out.rejected_by_joint = match (config.joint_gate_sigma, out.rate.fit()) {
        (Some(gate), Some(fit)) if out.joint_disagreement_sigma.is_some_and(|d| d > gate) => {
            // Compared on the frames both rates model: the faster one's horizon (often the
            // frames already fitted, then `problem` serves).
            let faster = speed(fit.rate_deg_per_frame).max(speed(joint_fit.rate_deg_per_frame));
            let frames = setup.frames_within(horizon_frames(config, faster));
            let common = if frames.len() == problem.frame_count() {
                None
            } else {
                Some(setup.problem(&frames, problem.refits_diffuse().then_some(config))?)
            };
            separate_minimum(common.as_ref().unwrap_or(&problem), fit, joint_fit, config)
        }
        _ => false,
    };
    Ok(out)
}

/// The band's search, its sense from the joint fit when the band cannot tell (decided on the
/// stage-1 coefficients, before any diffuse re-fit), and the polish.
fn search_and_polish_band(
    setup: &FitSetup,
    config: &Stage3Config,
    joint: Option<(&RateSolution, &RateFit)>,
) -> Result<(RateSolution, RateProblem, bool), InversionError> {
    let (mut rate, mut problem) = horizon::search(setup, config)?;
    let mut sense_from_joint = false;
    if let Some((joint, joint_fit)) = joint {
        if let Some(flipped) = flip_to_joint(&problem, &rate, joint, joint_fit, config) {
            rate = RateSolution::Determined(flipped);
            sense_from_joint = true;
        }
    }
    if let Some((polished, refit_problem)) = horizon::polish_with_refit(setup, config, &rate)? {
        (rate, problem) = (polished, refit_problem);
    }
    Ok((rate, problem, sense_from_joint))
}

/// A band's rate below this fraction of the joint rate is fitted again within the joint
/// rate's horizon ([`fit_band`]).
const SLOW_FRACTION: f64 = 0.5;

/// When p̂ and its mirror fit equally well, the fit re-polished from the mirror on the joint
/// fit's side (if it does end there).
fn flip_to_joint(
    problem: &RateProblem,
    rate: &RateSolution,
    joint: &RateSolution,
    joint_fit: &RateFit,
    config: &Stage3Config,
) -> Option<RateFit> {
    let first = rate.fit()?;
    let start = stage3::sense_from(rate, joint)?;
    let to_joint = |p: [f64; 3]| stage3::distance(p, joint_fit.rate_deg_per_frame);
    let RateSolution::Determined(mut flipped) =
        stage3::fit_from_starts(problem, &[start], config).ok()?
    else {
        return None;
    };
    if to_joint(flipped.rate_deg_per_frame) >= to_joint(first.rate_deg_per_frame) {
        return None;
    }
    // The record covers the whole search: the first multi-start and the re-polish.
    flipped.total_iterations += first.total_iterations;
    flipped.starts_polished += first.starts_polished;
    flipped.grid_points = first.grid_points;
    flipped.starts_screened = first.starts_screened;
    Some(flipped)
}

/// Whether the band's cost (over `problem`'s frames) has a minimum apart from p̂ near the joint
/// solution: LM from the joint solution ends nearer it than half-way back to p̂.
fn separate_minimum(
    problem: &RateProblem,
    fit: &RateFit,
    joint_fit: &RateFit,
    config: &Stage3Config,
) -> bool {
    let (p, pj) = (fit.rate_deg_per_frame, joint_fit.rate_deg_per_frame);
    match stage3::fit_from_starts(problem, &[pj], config) {
        Ok(RateSolution::Determined(local)) => {
            stage3::distance(local.rate_deg_per_frame, p) > 0.5 * stage3::distance(pj, p)
        }
        _ => false,
    }
}

/// One p for all bands over its fit horizon; returns the solution and the frames fitted.
///
/// Feasible weighted least squares: a first fit weights every band by its σ (or, without σ,
/// equally, in units of its mean flux). Each band's noise is then re-estimated from its own
/// residual level at that solution, with its correlation time, floored at σ when σ is given
/// ([`RateProblem::band_mismatch_scales`]), and the fit is run again. The bands the two-facet
/// model explains worst (the diffuse-heavy ones, whose mismatch exceeds their noise) then stop
/// pulling the common p. Down-weighting them also weakens the evidence for the sense of
/// rotation, so the reweighted fit keeps the first fit's sense (`stage3::keep_sense`).
///
/// With [`LobeRefit::WhenNeeded`] this runs twice from the same search, once keeping stage 1's
/// widest lobes and once re-fitting them, and reports the first unless the second lies outside
/// its confidence region (`choose_lobes`).
pub fn fit_joint(
    motion: &[Observation],
    stage1: &[Stage1Band],
    model: &MotionModelConfig,
    config: &Stage3Config,
) -> Result<(RateSolution, usize), InversionError> {
    let bands: Vec<RateBand> = (0..stage1.len()).map(|b| rate_band(stage1, b)).collect();
    let covs: Vec<Option<Vec<f64>>> = stage1.iter().map(|s| s.coeff_covariance.clone()).collect();
    let setup = FitSetup::new(motion, &bands, &covs, None, model);
    let searched = horizon::search(&setup, config)?;
    // With glint lobes only, the fit "re-fitting" them is the fit keeping them: run it once.
    let tested = config.refit_diffuse
        && config.refit_widest_lobe == LobeRefit::WhenNeeded
        && config.refit_widest_lobe.applies(bands.len())
        && broad_lobe_in_use(&bands);
    if !tested {
        return reweighted_joint(&setup, config, &searched);
    }
    let keeping = Stage3Config {
        refit_widest_lobe: LobeRefit::None,
        ..config.clone()
    };
    let kept = reweighted_joint(&setup, &keeping, &searched)?;
    let refitted = reweighted_joint(&setup, config, &searched)?;
    Ok(choose_lobes(kept, refitted, config.lobe_test_confidence))
}

/// [`LobeRefit::WhenNeeded`]: the fit keeping stage 1's lobes unless the fit re-fitting them
/// lies outside its confidence region ([`lobe::lobe_test`]); the test goes on the record of
/// the fit reported. When either has no rate, or the re-fit's polish was not taken (so it
/// re-fitted nothing), the re-fit's answer stands, as with [`LobeRefit::Joint`].
fn choose_lobes(
    kept: (RateSolution, usize),
    refitted: (RateSolution, usize),
    confidence: f64,
) -> (RateSolution, usize) {
    // Stage 1's lobes show no glint in the motion window: a re-fitted widest lobe cannot
    // supply one. Its amplitude trades against the rate (ADR 0011), and with the paper-like
    // materials at phase 30° the re-fit made a glint of a 0.15 % drift (24.2, confidently).
    let no_glint = matches!(
        kept.0,
        RateSolution::Unobservable {
            reason: UnobservableReason::NoGlint { .. },
            ..
        }
    );
    if no_glint {
        return kept;
    }
    let (Some(k), Some(r)) = (kept.0.fit(), refitted.0.fit()) else {
        return refitted;
    };
    let Some(held) = r.refit.filter(|x| x.widest_lobe).map(|x| x.held_direction) else {
        return refitted;
    };
    let mut test = lobe::lobe_test(k, r, held, confidence);
    // A re-fit that ends below half the kept rate traded the rate for the lobe: with only narrow
    // lobes a brighter widest lobe lengthens the glint as a slower rate does, and the re-fit is
    // not identifiable (paper-like materials at phase 20°: 0.10 against 0.25 deg/frame).
    test.rate_traded = speed(r.rate_deg_per_frame) < SLOW_FRACTION * speed(k.rate_deg_per_frame);
    // A kept fit with a clearly better neighbouring minimum is not its model's best fit: its
    // region is no reference for the test (docs/adr/0022).
    test.kept_off_minimum = test.chi2 <= test.threshold
        && k.neighbours
            .iter()
            .any(|n| n.delta_chi2 < -MIRROR_MAX_DELTA_CHI2);
    let refit_wins = test.chi2 > test.threshold || test.kept_off_minimum;
    let reports_refit = refit_wins && !test.rate_traded;
    test.other_rate_deg_per_frame = Some(if reports_refit {
        k.rate_deg_per_frame
    } else {
        r.rate_deg_per_frame
    });
    let (mut chosen, frames) = if reports_refit { refitted } else { kept };
    if let RateSolution::Determined(fit) = &mut chosen {
        if let Some(refit) = &mut fit.refit {
            refit.lobe_test = Some(test);
        }
    }
    (chosen, frames)
}

/// The joint fit from the search on the stage-1 coefficients: the polish, each band's noise
/// re-estimated from the polished model's residuals, the search again with those weights
/// (keeping the first fit's sense), and its polish.
fn reweighted_joint(
    setup: &FitSetup,
    config: &Stage3Config,
    (searched, searched_problem): &(RateSolution, RateProblem),
) -> Result<(RateSolution, usize), InversionError> {
    // The bands' mismatch is measured with the model the fit ends with.
    let (j, problem) = horizon::polish_with_refit(setup, config, searched)?
        .unwrap_or_else(|| (searched.clone(), searched_problem.clone()));
    let Some(first) = j.fit().map(|f| f.rate_deg_per_frame) else {
        return Ok((j, problem.frame_count()));
    };
    let scales = problem.band_mismatch_scales(first);
    let reweighted_setup = setup.with_band_scales(&scales);
    let (reweighted, reweighted_problem) = horizon::search(&reweighted_setup, config)?;
    let (searched, problem, setup) =
        match stage3::keep_sense(reweighted, &reweighted_problem, first, config) {
            Some(j2) => (j2, reweighted_problem, &reweighted_setup),
            None => (j, problem, setup),
        };
    let (mut joint, problem) =
        horizon::polish_with_refit(setup, config, &searched)?.unwrap_or((searched, problem));
    // Held until every decision is taken: the lobe test, λ*'s gate and its widening read the
    // local covariance (docs/adr/0028).
    joint.attach_interval_average_if_asked(&problem, config);
    joint.attach_neighbours_if_asked(&problem, config)?;
    joint.attach_profile_if_asked(&problem, config);
    Ok((joint, problem.frame_count()))
}

/// Multi-start fit on the frames within the fit horizon: the first window is valid for every
/// rate in the start box (the fastest turns `max_rotation_deg` in it); it then grows to the
/// horizon of the fastest rate fitted so far, searching again (with the previous solution as
/// an extra start), until the fitted frames stop changing. With
/// [`MotionModelConfig::refit_diffuse`] the solution is then polished with the diffuse terms
/// re-estimated, on its own horizon. Returns the solution and the number of frames fitted.
///
/// The search's horizon never grows past that of a rate already fitted: frames beyond the
/// model's validity pull the fit towards slower rates, a slower rate would admit more such
/// frames, and the window would run away (the Z case at phase 20° crept from 0.21 to 0.11
/// deg/frame over 184 frames that way).
///
/// With [`Stage3Config::profile_intervals`] the answer reports its profile-likelihood intervals
/// ([`RateFit::report_profile`]).
pub fn fit_within_horizon(
    motion: &[Observation],
    bands: &[RateBand],
    coefficient_covariance: &[Option<Vec<f64>>],
    model: &MotionModelConfig,
    config: &Stage3Config,
) -> Result<(RateSolution, usize), InversionError> {
    let setup = FitSetup::new(motion, bands, coefficient_covariance, None, model);
    let (mut rate, problem) = horizon::search_and_polish(&setup, config)?;
    rate.attach_profile_if_asked(&problem, config);
    rate.report_profile(1.0);
    Ok((rate, problem.frame_count()))
}

/// Stage-3 results and the window they were fitted on.
#[derive(Debug, Clone, PartialEq)]
pub struct RateFits {
    /// At λ* (or the band that replaced it, `band_index`).
    pub rate: RateSolution,
    /// The band `rate` was fitted at: λ*, unless the joint fit rejected λ*'s solution.
    pub band_index: usize,
    /// Bands whose solution the joint fit rejected, in the order tried
    /// ([`Stage3Config::joint_gate_sigma`]); when it holds every candidate, `rate` is λ*'s
    /// and this is `[λ*]`.
    pub set_aside: Vec<usize>,
    /// All bands jointly, when asked.
    pub joint_rate: Option<RateSolution>,
    /// Motion frames fitted at λ* (those within its horizon).
    pub fitted_frames: usize,
    /// Motion frames of the joint fit.
    pub joint_fitted_frames: Option<usize>,
    /// The λ* data could not tell p̂ from its mirror and the joint fit decided the sense of
    /// rotation (see [`fit_rates`]).
    pub sense_from_joint: bool,
    /// `rate`'s distance from the joint solution in σ ([`BandFit::joint_disagreement_sigma`]).
    /// Beyond the gate with `rate` kept, the band has no minimum near the joint solution, and
    /// its own covariance does not cover the difference.
    pub joint_disagreement_sigma: Option<f64>,
    /// The factor `rate`'s covariance was widened by to cover its distance from the joint
    /// solution ([`Stage3Config::widen_to_joint`]; 1 when the two agree within their errors);
    /// `None` without a determined joint solution or with the widening off.
    pub covariance_scale: Option<f64>,
}

#[cfg(test)]
mod tests;
