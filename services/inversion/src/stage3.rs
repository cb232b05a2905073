//! Stage 3: attitude-rate fit p = [w_x, w_y, w_z] \[deg/frame\] by LM with a global start
//! strategy (docs/math.md §1.6).
//!
//! The cost ε(p) of [`RateProblem`] is non-convex: a single start at p = 0 can land in a mirror
//! or shifted-glint minimum (§1.6 findings), and the basin of the true rates can be narrower than
//! any affordable grid spacing across the glint (≈ 0.1 deg/frame for a glint 40 frames in).
//! Ranking grid points by their cost is reliable, picking "distinct local minima" of the grid is
//! not; so the start strategy races many starts cheaply:
//!
//! 1. **Grid**: `points_per_axis`³ points over the box `[−h, h]³` (h = `half_width_deg_per_frame`,
//!    default 0.5 deg/frame, 9 points per axis → 0.125 deg/frame spacing), each costed on every
//!    `⌈T/max_grid_frames⌉`-th frame (values only), brightest frame first. The points are
//!    visited in the order of their cost at the brightest frame, and a point's sum stops once
//!    it passes the `screen_starts`-th best full cost so far: it cannot be a candidate, and the
//!    candidates are those of the full costs, in their order.
//! 2. **Screen**: the `screen_starts` best grid points (default 16) each get `screen_iterations`
//!    LM iterations (default 6) on every `⌈T/max_screen_frames⌉`-th frame.
//! 3. **Polish**: the `polish_starts` best screened points (default 3; duplicates within
//!    1e-2 deg/frame merged) run LM to convergence on all frames with the analytic Jacobian,
//!    best first; a later start is abandoned when it comes within 1e-3 deg/frame of the best
//!    solution so far without a lower cost. The lowest final cost wins.
//!
//! The box must contain the true rates' basin: rates outside ±h are found only if LM walks there.
//! The result is then classified by [`crate::observability`]: a determined fit reports p, its
//! covariance and the eigen-analysis; an unobservable one reports only the bounds.
//!
//! The joint multi-band fit is the same problem with the residuals of several bands stacked
//! (same p), see [`RateProblem::new`].

use crate::error::InversionError;
use crate::lm::{levenberg_marquardt, levenberg_marquardt_with, LmConfig, LmOutcome, StopReason};
use crate::model::RateProblem;
use crate::observability::{
    analyse, widen_to_likelihood_intervals, Analysis, CovarianceSource, Observability,
    UnobservableReason,
};
use serde::{Deserialize, Serialize};

mod bisector;
mod config;
#[cfg(test)]
pub(crate) mod fixtures;
mod neighbours;
mod weak;
use config::validate;
pub use config::{
    LobeRefit, Stage3Config, StartConfig, DEFAULT_LOBE_TEST_CONFIDENCE, DEFAULT_MAX_ROTATION_DEG,
};
pub(crate) use neighbours::off_own_minimum;
pub use neighbours::{neighbouring_minima, Neighbour};
pub(crate) use weak::keep_sense;
pub use weak::{distance, has_sense, mirror, nearest_body_axis, WeakPrior, RATE_NAMES};

/// Frames of the grid's first look at every point (the brightest): the points are then costed
/// in the order of those partial sums, so the best come first and the rest stop early.
const GRID_PROBE_FRAMES: usize = 1;
/// Duplicate screened starts closer than this are merged \[deg/frame\].
const SAME_START_DEG_PER_FRAME: f64 = 1e-2;
/// Two rates this close are the same solution \[deg/frame\]: a later polish that comes this
/// close to the best solution so far is abandoned.
pub(crate) const SAME_SOLUTION_DEG_PER_FRAME: f64 = 1e-3;

/// A determined rate estimate.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RateFit {
    /// Bands whose residuals were fitted \[nm\].
    pub wavelengths_nm: Vec<f64>,
    /// p̂ = [w_x, w_y, w_z] \[deg/frame\].
    pub rate_deg_per_frame: [f64; 3],
    /// Cov(p̂) \[(deg/frame)²\], see `covariance_source`.
    pub covariance_deg2_per_frame2: [[f64; 3]; 3],
    /// Given σ or residual variance.
    pub covariance_source: CovarianceSource,
    /// Final cost ε(p̂) (normalised or whitened units).
    pub cost: f64,
    /// LM iterations of the winning start.
    pub iterations: usize,
    /// LM iterations summed over all polished starts.
    pub total_iterations: usize,
    /// Stopping rule of the winning start.
    pub stop: StopReason,
    /// Grid points evaluated (0 for explicit starts).
    pub grid_points: usize,
    /// Starts screened by short LM runs (0 for explicit starts).
    pub starts_screened: usize,
    /// Starts polished to convergence by LM.
    pub starts_polished: usize,
    /// The winning start \[deg/frame\].
    pub start_deg_per_frame: [f64; 3],
    /// Eigen-analysis of the information matrix.
    pub observability: Observability,
    /// The directions e the stated prior held (e·p = 0; [`Stage3Config::weak_prior`]): the body
    /// axis nearest each direction the data could not determine where the fit was made. A
    /// direction `observability` marks unobservable at p̂ but not held here (near the centre of
    /// a mirror pair the light curve is flat to first order) sits where the fit ended.
    #[serde(default)]
    pub held_directions: Vec<[f64; 3]>,
    /// The mirror solution (−w_x, w_y, −w_z) when it fits the data as well as p̂: with every
    /// geometry vector in the body XZ plane the light curve cannot tell a rotation from its
    /// mirror image, so the sense of rotation about X and Z is not observable. `None` when the
    /// data distinguish them (or p̂ is its own mirror).
    #[serde(default)]
    pub mirror_deg_per_frame: Option<[f64; 3]>,
    /// The first start of the polish that held the bisector (the hold is weighted at it);
    /// `None` when no hold applied.
    #[serde(skip)]
    pub hold_start_deg_per_frame: Option<[f64; 3]>,
    /// Which coefficients stage 3 re-estimated from the motion window (the polish of
    /// [`Stage3Config::refit_diffuse`]); `None`: every coefficient from stage 1.
    #[serde(default)]
    pub refit: Option<Refit>,
}

/// The terms a fit re-estimated per band from the motion window, with the body axis it held.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Refit {
    /// Each facet's widest lobe too (besides both diffuse terms and the constant).
    pub widest_lobe: bool,
    /// The lobe re-fitted per facet (panel, body) as a term index, 0 for none.
    #[serde(default)]
    pub lobes: [usize; 2],
    /// The direction held at the prior (the body axis nearest the sun–observer bisector).
    pub held_direction: [f64; 3],
    /// The test that decided `widest_lobe` ([`LobeRefit::WhenNeeded`]); `None` when the
    /// configuration decided it.
    #[serde(default)]
    pub lobe_test: Option<LobeTest>,
    /// The widest-lobe re-fit was asked for, but each facet's widest lobe in use is a glint
    /// lobe ([`crate::model::refit::BROAD_LOBE_MIN_MU`]): its amplitude trades against the
    /// rate, so it stays stage 1's and only the diffuse terms are re-fitted.
    #[serde(default)]
    pub glint_lobes_only: bool,
}

/// The joint fit's test of stage 1's lobes ([`LobeRefit::WhenNeeded`]): the fit re-fitting the
/// widest lobe, seen from the fit keeping it, in the latter's covariance on the plane the
/// bisector hold leaves (2 dof).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LobeTest {
    /// d·C⁻¹·d, d the two rates' difference and C the covariance of the fit keeping the lobe,
    /// both on the plane.
    pub chi2: f64,
    /// The χ²(2) quantile at [`Stage3Config::lobe_test_confidence`]; the lobe is re-fitted
    /// when `chi2` exceeds it, unless `rate_traded`.
    pub threshold: f64,
    /// The re-fit ended below half the kept rate: it traded the rate for the lobe and is not
    /// identifiable, so stage 1's lobes are kept whatever `chi2` says.
    #[serde(default)]
    pub rate_traded: bool,
    /// The fit keeping stage 1's lobes has a minimum a frame's shift away that fits better by
    /// more than Δχ² = 4 ([`RateFit::neighbours`]): it is not its own model's best fit, so its
    /// region is no reference, and the re-fit is reported whatever `chi2` says (unless
    /// `rate_traded`).
    #[serde(default)]
    pub kept_off_minimum: bool,
    /// The rate of the fit not reported: the re-fit's when stage 1's lobes are kept, the
    /// kept fit's when the lobe is re-fitted.
    #[serde(default)]
    pub other_rate_deg_per_frame: Option<[f64; 3]>,
}

/// Stage-3 outcome: a rate, or the statement that the data do not determine it.
// A handful of these exist per solve, nearly all `Determined`: boxing the fit would only add an
// indirection.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "status", rename_all = "snake_case")]
pub enum RateSolution {
    /// p̂ with covariance.
    Determined(RateFit),
    /// No rate is reported.
    Unobservable {
        /// Why.
        reason: UnobservableReason,
        /// 1σ bounds along the eigen-directions \[deg/frame\].
        bounds_deg_per_frame: [f64; 3],
        /// Full eigen-analysis at the best p found.
        observability: Observability,
        /// Fitted bands \[nm\].
        wavelengths_nm: Vec<f64>,
    },
}

impl RateSolution {
    /// The bands fitted \[nm\].
    pub fn wavelengths_nm(&self) -> &[f64] {
        match self {
            Self::Determined(f) => &f.wavelengths_nm,
            Self::Unobservable { wavelengths_nm, .. } => wavelengths_nm,
        }
    }

    /// The fit, if determined.
    pub fn fit(&self) -> Option<&RateFit> {
        match self {
            Self::Determined(f) => Some(f),
            Self::Unobservable { .. } => None,
        }
    }
}

/// Grid values along one axis.
fn axis_values(start: &StartConfig) -> Vec<f64> {
    let n = start.points_per_axis;
    if n == 1 {
        return vec![0.0];
    }
    let h = start.half_width_deg_per_frame;
    (0..n)
        .map(|k| -h + 2.0 * h * k as f64 / (n - 1) as f64)
        .collect()
}

/// Evaluates the grid; returns the `screen_starts` best points (best first) and the number of
/// grid points evaluated.
pub fn grid_candidates(problem: &RateProblem, start: &StartConfig) -> (Vec<[f64; 3]>, usize) {
    let axis = axis_values(start);
    let stride = problem.frame_count().div_ceil(start.max_grid_frames);
    let mut scored: Vec<(f64, [f64; 3])> = Vec::with_capacity(axis.len().pow(3));
    for &x in &axis {
        for &y in &axis {
            for &z in &axis {
                scored.push((f64::INFINITY, [x, y, z]));
            }
        }
    }
    // Each point's first few frames (the brightest) rank the points for the visit; each
    // point's sum then continues over every frame, stopping once it passes the
    // `screen_starts`-th lowest full cost so far: such a point has `screen_starts` better ones
    // and is not a candidate. The candidates and their order are those of the full costs.
    let frames = problem.brightest_first(stride);
    let probe = &frames[..frames.len().min(GRID_PROBE_FRAMES)];
    let first_look: Vec<f64> = scored
        .iter()
        .map(|(_, p)| problem.cost_over_within(*p, probe, f64::INFINITY))
        .collect();
    let mut visit: Vec<usize> = (0..scored.len()).collect();
    visit.sort_by(|&i, &j| first_look[i].total_cmp(&first_look[j]));
    let mut best: Vec<f64> = Vec::with_capacity(start.screen_starts + 1);
    for i in visit {
        let bound = if best.len() < start.screen_starts {
            f64::INFINITY
        } else {
            best.last().copied().unwrap_or(f64::INFINITY)
        };
        let c = problem.cost_over_within(scored[i].1, &frames, bound);
        let c = if c.is_finite() { c } else { f64::INFINITY };
        if c <= bound {
            let at = best.partition_point(|&b| b <= c);
            best.insert(at, c);
            best.truncate(start.screen_starts);
        }
        scored[i].0 = c;
    }
    let evaluated = scored.len();
    // Stable: equal costs keep the grid's order.
    scored.sort_by(|a, b| a.0.total_cmp(&b.0));
    scored.truncate(start.screen_starts);
    (scored.into_iter().map(|(_, p)| p).collect(), evaluated)
}

/// Short LM runs from each candidate on a subsampled window; returns the `polish_starts` best
/// end points (duplicates merged), best first.
pub fn screen_candidates(
    problem: &RateProblem,
    candidates: &[[f64; 3]],
    config: &Stage3Config,
) -> Result<Vec<[f64; 3]>, InversionError> {
    let start = &config.start;
    let coarse = problem.subsampled(problem.frame_count().div_ceil(start.max_screen_frames));
    let lm = LmConfig {
        max_iterations: start.screen_iterations,
        ..config.lm.clone()
    };
    let mut ends: Vec<(f64, [f64; 3])> = Vec::with_capacity(candidates.len());
    for &p0 in candidates {
        let out = levenberg_marquardt(&coarse, p0, &lm)?;
        ends.push((out.cost, out.p_deg_per_frame));
    }
    ends.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut chosen: Vec<[f64; 3]> = Vec::with_capacity(start.polish_starts);
    for (_, p) in ends {
        if chosen.len() == start.polish_starts {
            break;
        }
        let distinct = chosen.iter().all(|q| {
            let d2: f64 = (0..3).map(|i| (p[i] - q[i]).powi(2)).sum();
            d2.sqrt() > SAME_START_DEG_PER_FRAME
        });
        if distinct {
            chosen.push(p);
        }
    }
    Ok(chosen)
}

/// Polishes every start with LM, keeps the lowest cost and classifies the result: the raw
/// polish, without the likelihood intervals and the mirror ([`RateSolution::finalize`]), as
/// the solve's intermediate fits need it.
pub fn fit_from_starts(
    problem: &RateProblem,
    starts: &[[f64; 3]],
    config: &Stage3Config,
) -> Result<RateSolution, InversionError> {
    polish(problem, starts, (0, 0), config)
}

/// Whether every |p_i| is within twice the start box's half-width: a credible answer.
fn near_box(p: &[f64; 3], start: &StartConfig) -> bool {
    p.iter()
        .all(|v| v.abs() <= 2.0 * start.half_width_deg_per_frame)
}

/// Whether every |p_i| is within the start box (`half_width_deg_per_frame`).
fn in_box(p: &[f64; 3], start: &StartConfig) -> bool {
    p.iter().all(|v| v.abs() <= start.half_width_deg_per_frame)
}

/// Polishes `starts`; `counts` = (grid points, screened starts) for the record.
fn polish(
    problem: &RateProblem,
    starts: &[[f64; 3]],
    (grid_points, starts_screened): (usize, usize),
    config: &Stage3Config,
) -> Result<RateSolution, InversionError> {
    validate(config)?;
    let hold = match (problem.refits_diffuse(), starts.first()) {
        (true, Some(&p0)) => Some(bisector::BisectorHold::new(problem, p0, config)),
        _ => None,
    };
    let mut best: Option<(LmOutcome, [f64; 3])> = None;
    let mut total_iterations = 0;
    for &p0 in starts {
        // A later start is dropped once it rejoins the best solution or stays clearly worse.
        let known = best.map(|(b, _)| (b.p_deg_per_frame, b.cost));
        let abandon = |p: &[f64; 3], cost: f64, _k: usize| match known {
            Some((q, c)) => weak::distance(*p, q) < SAME_SOLUTION_DEG_PER_FRAME && cost >= c,
            None => false,
        };
        let out = match &hold {
            Some(hold) => hold.fit(problem, p0, config, abandon)?,
            None => levenberg_marquardt_with(problem, p0, &config.lm, abandon)?,
        };
        total_iterations += out.iterations;
        if out.stop == StopReason::Abandoned {
            continue;
        }
        // An end point inside the search box beats one outside it; then the lower cost wins.
        let inside = in_box(&out.p_deg_per_frame, &config.start);
        let better = best.as_ref().is_none_or(|(b, _)| {
            let b_inside = in_box(&b.p_deg_per_frame, &config.start);
            (inside && !b_inside) || (inside == b_inside && out.cost < b.cost)
        });
        if better {
            best = Some((out, p0));
        }
    }
    let Some((best, start)) = best else {
        return Err(InversionError::InvalidConfig {
            field: "starts",
            reason: "at least one start is required",
        });
    };
    let mut analysis = analyse(problem, best.p_deg_per_frame, &config.observability)?;
    let wavelengths_nm = problem.wavelengths_nm().to_vec();
    let mut best = best;
    // Directions the data cannot determine are held under the stated prior.
    let mut held_directions = vec![];
    if let Some(hold) = &hold {
        hold.restate(&mut analysis, config)?;
        held_directions = vec![hold.held_direction()];
    } else if analysis.unobservable.is_none() && config.hold_unobservable_at_prior {
        let iterations;
        (best, analysis, iterations, held_directions) =
            weak::hold_weak_direction(problem, best, analysis, config)?;
        total_iterations += iterations;
    }
    if analysis.unobservable.is_none() && !near_box(&best.p_deg_per_frame, &config.start) {
        analysis.unobservable = Some(UnobservableReason::OutsideSearchBox {
            rate_deg_per_frame: best.p_deg_per_frame,
        });
    }
    if analysis.unobservable.is_none() {
        let share = problem.lobe_sensitivity_share(best.p_deg_per_frame);
        if share < config.observability.min_lobe_share {
            analysis.unobservable = Some(UnobservableReason::NoGlint {
                lobe_sensitivity_share: share,
            });
        }
    }
    if let Some(reason) = analysis.unobservable {
        return Ok(RateSolution::Unobservable {
            reason,
            bounds_deg_per_frame: analysis.observability.bounds_1sigma_deg_per_frame,
            observability: analysis.observability,
            wavelengths_nm,
        });
    }
    Ok(RateSolution::Determined(RateFit {
        wavelengths_nm,
        rate_deg_per_frame: best.p_deg_per_frame,
        covariance_deg2_per_frame2: analysis.covariance,
        covariance_source: analysis.source,
        cost: best.cost,
        iterations: best.iterations,
        total_iterations,
        stop: best.stop,
        grid_points,
        starts_screened,
        starts_polished: starts.len(),
        start_deg_per_frame: start,
        observability: analysis.observability,
        held_directions,
        mirror_deg_per_frame: None,
        hold_start_deg_per_frame: hold.as_ref().and(starts.first().copied()),
        refit: hold.as_ref().map(|h| Refit {
            widest_lobe: problem.refits_widest_lobe(),
            lobes: problem.refit_lobes(),
            held_direction: h.held_direction(),
            lobe_test: None,
            glint_lobes_only: problem.keeps_glint_lobes(),
        }),
    }))
}

impl RateSolution {
    /// The answer's last word on a fit of `problem`: each determined direction's 1σ widened to
    /// its likelihood interval where the cost rises slower than its curvature says
    /// ([`widen_to_likelihood_intervals`]), and the mirror (−w_x, w_y, −w_z) named when it fits
    /// as well ([`RateFit::mirror_deg_per_frame`]). Run once per reported fit (and on the fit a
    /// decision reads), not on every intermediate polish.
    pub fn finalize(
        mut self,
        problem: &RateProblem,
        config: &Stage3Config,
    ) -> Result<Self, InversionError> {
        if let RateSolution::Determined(fit) = &mut self {
            fit.finalize(problem, config)?;
        }
        Ok(self)
    }
}

impl RateFit {
    /// [`RateSolution::finalize`] of a determined fit.
    pub fn finalize(
        &mut self,
        problem: &RateProblem,
        config: &Stage3Config,
    ) -> Result<(), InversionError> {
        let mut analysis = Analysis {
            covariance: self.covariance_deg2_per_frame2,
            source: self.covariance_source,
            observability: self.observability.clone(),
            unobservable: None,
        };
        widen_to_likelihood_intervals(problem, self.rate_deg_per_frame, &mut analysis);
        self.covariance_deg2_per_frame2 = analysis.covariance;
        self.observability = analysis.observability;
        let hold = self
            .hold_start_deg_per_frame
            .map(|p0| bisector::BisectorHold::new(problem, p0, config));
        self.mirror_deg_per_frame = weak::mirror_if_ambiguous(
            problem,
            self.rate_deg_per_frame,
            self.cost,
            &self.observability,
            config,
            hold.as_ref(),
        )?;
        Ok(())
    }
}

/// LM from one explicit start (e.g. the seed's p₀ = 0), no grid; the fit as reported
/// ([`RateSolution::finalize`]).
pub fn fit_single_start(
    problem: &RateProblem,
    p0_deg_per_frame: [f64; 3],
    config: &Stage3Config,
) -> Result<RateSolution, InversionError> {
    fit_from_starts(problem, &[p0_deg_per_frame], config)?.finalize(problem, config)
}

/// Grid → screen → polish (the default stage-3 solve on one problem); the fit as reported
/// ([`RateSolution::finalize`]).
pub fn fit_multistart(
    problem: &RateProblem,
    config: &Stage3Config,
) -> Result<RateSolution, InversionError> {
    fit_multistart_with(problem, config, &[])?.finalize(problem, config)
}

/// Grid → screen → polish, with `extra` starts (e.g. a solution on a shorter window) polished
/// after the screened ones; the raw polish ([`fit_from_starts`]).
pub fn fit_multistart_with(
    problem: &RateProblem,
    config: &Stage3Config,
    extra: &[[f64; 3]],
) -> Result<RateSolution, InversionError> {
    validate(config)?;
    let (candidates, grid_points) = grid_candidates(problem, &config.start);
    let mut starts = screen_candidates(problem, &candidates, config)?;
    starts.extend_from_slice(extra);
    polish(problem, &starts, (grid_points, candidates.len()), config)
}
