//! The frames one stage-3 fit uses (its horizon), the search over them, and the polish with the
//! diffuse terms re-estimated.

use crate::error::InversionError;
use crate::model::{MotionModelConfig, RateBand, RateProblem};
use crate::observation::Observation;
use crate::stage3::{self, RateSolution, Stage3Config};

/// What one stage-3 fit is made of: the motion window, the bands with their stage-1
/// coefficients (and covariance), the bands' weights and the motion model (epoch fixed).
pub(super) struct FitSetup<'a> {
    motion: &'a [Observation],
    bands: &'a [RateBand],
    coefficient_covariance: &'a [Option<Vec<f64>>],
    band_scales: Option<&'a [f64]>,
    model: MotionModelConfig,
}

impl<'a> FitSetup<'a> {
    pub(super) fn new(
        motion: &'a [Observation],
        bands: &'a [RateBand],
        coefficient_covariance: &'a [Option<Vec<f64>>],
        band_scales: Option<&'a [f64]>,
        model: &MotionModelConfig,
    ) -> Self {
        let epoch = model
            .epoch_frame
            .unwrap_or_else(|| motion.iter().map(|o| o.frame_index).min().unwrap_or(0));
        FitSetup {
            motion,
            bands,
            coefficient_covariance,
            band_scales,
            model: MotionModelConfig {
                epoch_frame: Some(epoch),
                ..model.clone()
            },
        }
    }

    fn horizon_of(&self, config: &Stage3Config, speed_deg_per_frame: f64) -> f64 {
        horizon_frames(config, speed_deg_per_frame)
    }

    /// The same fit with the bands weighted by `scales` (the joint fit's reweighting).
    pub(super) fn with_band_scales(&self, scales: &'a [f64]) -> Self {
        FitSetup {
            band_scales: Some(scales),
            model: self.model.clone(),
            ..*self
        }
    }

    /// The problem on `frames`: the search's (the configured model) or, with `polish`, the
    /// polish's (the diffuse terms re-fitted, and the widest lobe where `config` asks).
    pub(super) fn problem(
        &self,
        frames: &[Observation],
        polish: Option<&Stage3Config>,
    ) -> Result<RateProblem, InversionError> {
        let model = match polish {
            Some(config) => MotionModelConfig {
                refit_diffuse: true,
                refit_widest_lobe: config.refit_widest_lobe.applies(self.bands.len()),
                ..self.model.clone()
            },
            None => self.model.clone(),
        };
        let problem = RateProblem::new(frames, self.bands, &model)?
            .with_coefficient_covariance(self.coefficient_covariance.to_vec());
        Ok(match self.band_scales {
            Some(scales) => problem.with_band_scales(scales),
            None => problem,
        })
    }

    /// The motion frames at most `horizon_frames` after the epoch.
    pub(super) fn frames_within(&self, horizon_frames: f64) -> Vec<Observation> {
        let epoch = self.model.epoch_frame.unwrap_or(0);
        self.motion
            .iter()
            .filter(|o| (o.frame_index.saturating_sub(epoch) as f64) <= horizon_frames)
            .cloned()
            .collect()
    }
}

/// ‖p‖ \[deg/frame\].
pub(super) fn speed(p: [f64; 3]) -> f64 {
    p.iter().map(|v| v * v).sum::<f64>().sqrt()
}

/// Frames within the fit horizon of a rate of `speed_deg_per_frame` (every frame without one).
pub(super) fn horizon_frames(config: &Stage3Config, speed_deg_per_frame: f64) -> f64 {
    config
        .max_rotation_deg
        .filter(|d| d.is_finite())
        .map_or(f64::INFINITY, |d| {
            (d / speed_deg_per_frame.max(1e-12)).max(MIN_FIT_FRAMES)
        })
}

/// The multi-start search over the fit horizon, on the stage-1 coefficients (see
/// [`super::fit_within_horizon`]); returns the solution and the problem of the frames fitted.
pub(super) fn search(
    setup: &FitSetup,
    config: &Stage3Config,
) -> Result<(RateSolution, RateProblem), InversionError> {
    if !config.max_rotation_deg.is_some_and(f64::is_finite) {
        let problem = setup.problem(setup.motion, None)?;
        return Ok((stage3::fit_multistart_with(&problem, config, &[])?, problem));
    }
    let fastest = 3f64.sqrt() * config.start.half_width_deg_per_frame;
    let mut frames = setup.frames_within(horizon_frames(config, fastest));
    let mut problem = setup.problem(&frames, None)?;
    let mut rate = stage3::fit_multistart_with(&problem, config, &[])?;
    let mut fastest_fitted_deg_per_frame = 0.0f64;
    for _ in 0..HORIZON_ROUNDS {
        let Some(fit) = rate.fit() else { break };
        let p = fit.rate_deg_per_frame;
        fastest_fitted_deg_per_frame = fastest_fitted_deg_per_frame.max(speed(p));
        let next = setup.frames_within(setup.horizon_of(config, fastest_fitted_deg_per_frame));
        if next.len() == frames.len() {
            break;
        }
        frames = next;
        problem = setup.problem(&frames, None)?;
        // A fresh global search on the longer window (it can rank the minima the short one
        // could not), with the short window's solution as one more start.
        rate = stage3::fit_multistart_with(&problem, config, &[p])?;
    }
    Ok((rate, problem))
}

/// [`search`], then [`polish_with_refit`] when it polishes.
pub(super) fn search_and_polish(
    setup: &FitSetup,
    config: &Stage3Config,
) -> Result<(RateSolution, RateProblem), InversionError> {
    let (rate, problem) = search(setup, config)?;
    Ok(polish_with_refit(setup, config, &rate)?.unwrap_or((rate, problem)))
}

/// Polishes `searched` with the diffuse terms re-estimated ([`Stage3Config::refit_diffuse`]; the
/// bisector held, see `stage3`) on the horizon of the polished rate, until the fitted frames stop
/// changing.
///
/// The sense of rotation stays the search's. A model that re-fits the diffuse light has little
/// left to tell a rate from its mirror: a polish that ends on the mirror's side is
/// re-polished from the mirror of where it ended. A searched rate mostly about Y is nearly its
/// own mirror and has no side: the polish then goes where its model leads. `None` (keep the search's solution) when the
/// model does not re-fit, the search found no rate, or the polish has no minimum on the search's
/// side.
pub(super) fn polish_with_refit(
    setup: &FitSetup,
    config: &Stage3Config,
    searched: &RateSolution,
) -> Result<Option<(RateSolution, RateProblem)>, InversionError> {
    let Some(first) = searched.fit().filter(|_| config.refit_diffuse) else {
        return Ok(None);
    };
    let sense = first.rate_deg_per_frame;
    // A rate mostly about Y has no side to keep.
    let sided = stage3::has_sense(sense);
    let wrong_side = |p: [f64; 3]| {
        sided && stage3::distance(p, stage3::mirror(sense)) < stage3::distance(p, sense)
    };
    let mut p = sense;
    let mut frames: Vec<Observation> = Vec::new();
    let mut last = None;
    for _ in 0..=HORIZON_ROUNDS {
        let next = setup.frames_within(setup.horizon_of(config, speed(p)));
        if next.len() == frames.len() {
            break;
        }
        frames = next;
        let problem = setup.problem(&frames, Some(config))?;
        let mut polished = stage3::fit_from_starts(&problem, &[p], config)?;
        if polished
            .fit()
            .is_some_and(|f| wrong_side(f.rate_deg_per_frame))
        {
            let q = polished.fit().map_or(p, |f| f.rate_deg_per_frame);
            polished = stage3::fit_from_starts(&problem, &[stage3::mirror(q)], config)?;
            if polished
                .fit()
                .is_none_or(|f| wrong_side(f.rate_deg_per_frame))
            {
                return Ok(None);
            }
        }
        let Some(fit) = polished.fit() else {
            // The re-fit cannot determine the rate here: that is its answer.
            return Ok(Some((polished, problem)));
        };
        p = fit.rate_deg_per_frame;
        last = Some((polished, problem));
    }
    let Some((mut rate, problem)) = last else {
        return Ok(None);
    };
    if let RateSolution::Determined(fit) = &mut rate {
        // The record covers the search and the polish.
        fit.total_iterations += first.total_iterations;
        fit.starts_polished += first.starts_polished;
        fit.grid_points = first.grid_points;
        fit.starts_screened = first.starts_screened;
    }
    Ok(Some((rate, problem)))
}

/// The fit horizon never shrinks below this many frames.
const MIN_FIT_FRAMES: f64 = 24.0;
/// Re-fits while the horizon grows, at most.
const HORIZON_ROUNDS: usize = 4;
