//! Stage 3 as the solve runs it: the fit at λ* (the paper's stage 3) and the joint fit over all
//! bands, each over its fit horizon; the joint fit reweights the bands by their mismatch and
//! tests stage 1's widest lobes.

use crate::answer::{Answer, AnswerFit};
use crate::error::InversionError;
use crate::model::refit::broad_lobe_in_use;
use crate::model::{MotionModelConfig, RateBand, RateProblem};
use crate::observability::UnobservableReason;
use crate::observation::Observation;
use crate::stage1::Stage1Band;
use crate::stage3::{self, LobeRefit, RateFit, RateSolution, Stage3Config};

mod horizon;
mod lobe;
use horizon::{speed, FitSetup};

/// Stage 3 at the first band of stage 2's `ranking` (λ*, the paper's stage 3) and, with
/// `joint`, one p for all bands, each over its fit horizon. λ* uses `single_band`'s
/// coefficients (the spectrally pooled ones when stage 1 pooled,
/// [`crate::stage1::Stage1Output`]); the joint fit every band's own (`stage1`).
pub fn fit_rates(
    motion: &[Observation],
    stage1: &[Stage1Band],
    single_band: &[Stage1Band],
    ranking: &[usize],
    model: &MotionModelConfig,
    config: &Stage3Config,
    joint: bool,
) -> Result<RateFits, InversionError> {
    let Some(&chosen) = ranking.first() else {
        return Err(InversionError::NoSeparableBand);
    };
    let joint_rate = if joint {
        Some(fit_joint(motion, stage1, model, config)?)
    } else {
        None
    };
    let fit = fit_band(motion, single_band, chosen, model, config)?;
    Ok(RateFits {
        rate: fit.rate,
        band_index: chosen,
        fitted_frames: fit.fitted_frames,
        joint_fitted_frames: joint_rate.as_ref().map(|j| j.1),
        joint_rate: joint_rate.map(|j| j.0),
    })
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
}

/// Stage 3 at band `b` over its fit horizon: the search on the stage-1 coefficients, then the
/// polish with the diffuse terms re-fitted ([`Stage3Config::refit_diffuse`]).
pub fn fit_band(
    motion: &[Observation],
    stage1: &[Stage1Band],
    b: usize,
    model: &MotionModelConfig,
    config: &Stage3Config,
) -> Result<BandFit, InversionError> {
    let covariance = vec![stage1[b].coeff_covariance.clone()];
    let bands = [rate_band(stage1, b)];
    let setup = FitSetup::new(motion, &bands, &covariance, None, model);
    let (rate, problem) = horizon::search_and_polish(&setup, config)?;
    Ok(BandFit {
        rate: rate.finalize(&problem, config)?,
        fitted_frames: problem.frame_count(),
    })
}

/// A band's rate below this fraction of another is a different motion: a re-fit of the
/// widest lobe that ends below half the kept rate traded the rate for the lobe.
const SLOW_FRACTION: f64 = 0.5;

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
        let ((joint, frames), problem) = reweighted_joint(&setup, config, &searched)?;
        return Ok((joint.finalize(&problem, config)?, frames));
    }
    let keeping = Stage3Config {
        refit_widest_lobe: LobeRefit::None,
        ..config.clone()
    };
    let ((kept, kept_frames), kept_problem) = reweighted_joint(&setup, &keeping, &searched)?;
    let ((refitted, refitted_frames), refitted_problem) =
        reweighted_joint(&setup, config, &searched)?;
    // The test reads the kept fit's final covariance and mirror.
    let kept = kept.finalize(&kept_problem, config)?;
    let chosen = choose_lobes(
        (kept, kept_frames),
        (refitted, refitted_frames),
        config.lobe_test_confidence,
        |k| stage3::off_own_minimum(&kept_problem, k, config),
    )?;
    Ok(match chosen {
        Lobes::Kept(kept) => kept,
        Lobes::Refitted((joint, frames)) => (joint.finalize(&refitted_problem, config)?, frames),
    })
}

/// [`LobeRefit::WhenNeeded`]: the fit keeping stage 1's lobes unless the fit re-fitting them
/// lies outside its confidence region ([`lobe::lobe_test`]); the test goes on the record of
/// the fit reported. When either has no rate, or the re-fit's polish was not taken (so it
/// re-fitted nothing), the re-fit's answer stands, as with [`LobeRefit::Joint`].
fn choose_lobes(
    kept: (RateSolution, usize),
    refitted: (RateSolution, usize),
    confidence: f64,
    kept_off_own_minimum: impl FnOnce(&RateFit) -> Result<bool, InversionError>,
) -> Result<Lobes, InversionError> {
    // Stage 1's lobes show no glint in the motion window: a re-fitted widest lobe cannot
    // supply one. Its amplitude trades against the rate, and with the paper-like
    // materials at phase 30° the re-fit made a glint of a 0.15 % drift (24.2, confidently).
    let no_glint = matches!(
        kept.0,
        RateSolution::Unobservable {
            reason: UnobservableReason::NoGlint { .. },
            ..
        }
    );
    if no_glint {
        return Ok(Lobes::Kept(kept));
    }
    let (Some(k), Some(r)) = (kept.0.fit(), refitted.0.fit()) else {
        return Ok(Lobes::Refitted(refitted));
    };
    let Some(held) = r.refit.filter(|x| x.widest_lobe).map(|x| x.held_direction) else {
        return Ok(Lobes::Refitted(refitted));
    };
    let mut test = lobe::lobe_test(k, r, held, confidence);
    // A re-fit that ends below half the kept rate traded the rate for the lobe: with only narrow
    // lobes a brighter widest lobe lengthens the glint as a slower rate does, and the re-fit is
    // not identifiable (paper-like materials at phase 20°: 0.10 against 0.25 deg/frame).
    test.rate_traded = speed(r.rate_deg_per_frame) < SLOW_FRACTION * speed(k.rate_deg_per_frame);
    // A kept fit with a clearly better neighbouring minimum is not its model's best fit: its
    // region is no reference for the test.
    test.kept_off_minimum = test.chi2 <= test.threshold && kept_off_own_minimum(k)?;
    let refit_wins = test.chi2 > test.threshold || test.kept_off_minimum;
    let reports_refit = refit_wins && !test.rate_traded;
    test.other_rate_deg_per_frame = Some(if reports_refit {
        k.rate_deg_per_frame
    } else {
        r.rate_deg_per_frame
    });
    let mut chosen = if reports_refit {
        Lobes::Refitted(refitted)
    } else {
        Lobes::Kept(kept)
    };
    let (Lobes::Kept((solution, _)) | Lobes::Refitted((solution, _))) = &mut chosen;
    if let RateSolution::Determined(fit) = solution {
        if let Some(refit) = &mut fit.refit {
            refit.lobe_test = Some(test);
        }
    }
    Ok(chosen)
}

/// The joint fit [`choose_lobes`] reports, with its frames.
#[derive(Debug)]
enum Lobes {
    /// Stage 1's lobes kept.
    Kept((RateSolution, usize)),
    /// Each facet's widest lobe re-fitted.
    Refitted((RateSolution, usize)),
}

impl Lobes {
    #[cfg(test)]
    fn into_inner(self) -> (RateSolution, usize) {
        match self {
            Lobes::Kept(x) | Lobes::Refitted(x) => x,
        }
    }
}

/// The joint fit from the search on the stage-1 coefficients: the polish, each band's noise
/// re-estimated from the polished model's residuals, the search again with those weights
/// (keeping the first fit's sense), and its polish.
fn reweighted_joint(
    setup: &FitSetup,
    config: &Stage3Config,
    (searched, searched_problem): &(RateSolution, RateProblem),
) -> Result<((RateSolution, usize), RateProblem), InversionError> {
    // The bands' mismatch is measured with the model the fit ends with.
    let (j, problem) = horizon::polish_with_refit(setup, config, searched)?
        .unwrap_or_else(|| (searched.clone(), searched_problem.clone()));
    let Some(first) = j.fit().map(|f| f.rate_deg_per_frame) else {
        let frames = problem.frame_count();
        return Ok(((j, frames), problem));
    };
    let scales = problem.band_mismatch_scales(first);
    let reweighted_setup = setup.with_band_scales(&scales);
    let (reweighted, reweighted_problem) = horizon::search(&reweighted_setup, config)?;
    let (searched, problem, setup) =
        match stage3::keep_sense(reweighted, &reweighted_problem, first, config) {
            Some(j2) => (j2, reweighted_problem, &reweighted_setup),
            None => (j, problem, setup),
        };
    let (joint, problem) =
        horizon::polish_with_refit(setup, config, &searched)?.unwrap_or((searched, problem));
    let frames = problem.frame_count();
    Ok(((joint, frames), problem))
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
pub fn fit_within_horizon(
    motion: &[Observation],
    bands: &[RateBand],
    coefficient_covariance: &[Option<Vec<f64>>],
    model: &MotionModelConfig,
    config: &Stage3Config,
) -> Result<(RateSolution, usize), InversionError> {
    let setup = FitSetup::new(motion, bands, coefficient_covariance, None, model);
    let (rate, problem) = horizon::search_and_polish(&setup, config)?;
    Ok((rate.finalize(&problem, config)?, problem.frame_count()))
}

impl RateFits {
    /// glint's answer: the joint fit when it ran, else the fit at λ* (`wavelength_nm`).
    pub fn answer(&self, wavelength_nm: f64) -> Answer {
        match (&self.joint_rate, self.joint_fitted_frames) {
            (Some(joint), Some(frames)) => {
                let bands = joint.wavelengths_nm().len();
                Answer::of(AnswerFit::Joint { bands }, joint, frames)
            }
            _ => Answer::of(
                AnswerFit::Band { wavelength_nm },
                &self.rate,
                self.fitted_frames,
            ),
        }
    }
}

/// Stage-3 results and the windows they were fitted on.
#[derive(Debug, Clone, PartialEq)]
pub struct RateFits {
    /// At λ* (`band_index`): the paper's stage 3.
    pub rate: RateSolution,
    /// The band `rate` was fitted at: λ*.
    pub band_index: usize,
    /// All bands jointly, when asked.
    pub joint_rate: Option<RateSolution>,
    /// Motion frames fitted at λ* (those within its horizon).
    pub fitted_frames: usize,
    /// Motion frames of the joint fit.
    pub joint_fitted_frames: Option<usize>,
}

#[cfg(test)]
mod tests;
