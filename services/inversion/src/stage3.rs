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
//!    `⌈T/max_grid_frames⌉`-th frame (values only).
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
    analyse, widen_to_likelihood_intervals, CovarianceSource, Observability, ObservabilityConfig,
    UnobservableReason,
};
use serde::{Deserialize, Serialize};

mod bisector;
#[cfg(test)]
pub(crate) mod fixtures;
mod reported;
mod weak;
pub use weak::{
    disagreement, disagreement_sigma, distance, has_sense, mirror, nearest_body_axis,
    widen_to_joint, WeakPrior, RATE_NAMES,
};
pub(crate) use weak::{keep_sense, sense_from};

/// Multi-start settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct StartConfig {
    /// Box half-width h \[deg/frame\] (> 0; 0.5).
    pub half_width_deg_per_frame: f64,
    /// Grid points per axis (≥ 1; 9). 1 means the single start p = 0.
    pub points_per_axis: usize,
    /// Frames used per grid evaluation, at most (≥ 1; 40).
    pub max_grid_frames: usize,
    /// Best grid points screened by short LM runs (≥ 1; 16).
    pub screen_starts: usize,
    /// LM iterations per screened start (≥ 1; 6).
    pub screen_iterations: usize,
    /// Frames used while screening, at most (≥ 1; 90).
    pub max_screen_frames: usize,
    /// Screened starts polished to convergence (≥ 1; 3).
    pub polish_starts: usize,
}

impl Default for StartConfig {
    fn default() -> Self {
        Self {
            half_width_deg_per_frame: 0.5,
            points_per_axis: 9,
            max_grid_frames: 40,
            screen_starts: 16,
            screen_iterations: 6,
            max_screen_frames: 90,
            polish_starts: 3,
        }
    }
}

/// Duplicate screened starts closer than this are merged \[deg/frame\].
const SAME_START_DEG_PER_FRAME: f64 = 1e-2;
/// Two rates this close are the same solution \[deg/frame\]: a later polish that comes this
/// close to the best solution so far is abandoned.
pub(crate) const SAME_SOLUTION_DEG_PER_FRAME: f64 = 1e-3;

/// Stage-3 settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Stage3Config {
    /// LM stopping rules.
    pub lm: LmConfig,
    /// Start strategy.
    pub start: StartConfig,
    /// Covariance and observability thresholds.
    pub observability: ObservabilityConfig,
    /// Hold unobservable eigen-directions at the stated prior ([`Self::weak_prior`]) and re-fit
    /// the rest (default);
    /// `false` reports the unconstrained optimum.
    pub hold_unobservable_at_prior: bool,
    /// Which prior holds an unobservable direction u (see [`WeakPrior`]).
    pub weak_prior: WeakPrior,
    /// Fit horizon: stage 3 fits the motion frames during which the body has turned at most
    /// this far from its stable attitude at the fitted rate \[deg\] (25; `None` or ∞ = every
    /// frame).
    /// The two-facet model holds only while the observed face and the panel front are the lit
    /// and visible surfaces; turned further, the other faces and the panel back appear.
    pub max_rotation_deg: Option<f64>,
    /// With the joint fit: a λ* solution farther than this many standard deviations (the two
    /// covariances summed, over their determined directions) from the joint solution is
    /// another minimum; stage 3 sets the band aside and fits the next in stage 2's ranking
    /// (`None` or ∞: never).
    pub joint_gate_sigma: Option<f64>,
    /// Polish the searched rate with each band's diffuse terms (panel, body) and a constant
    /// remainder re-estimated from the motion window, the sun–observer bisector held at the
    /// stated prior ([`crate::model::MotionModelConfig::refit_diffuse`]; default `true`, ADR
    /// 0010). The stable window cannot tell the panel's diffuse light from the body's and the
    /// rest's (their columns are nearly collinear there); the motion window can. The search
    /// itself, and so the sense of rotation, stays on the stage-1 coefficients. `false`: the
    /// paper's model throughout.
    pub refit_diffuse: bool,
    /// Which fits also re-estimate each facet's widest lobe in that polish: its stage-1
    /// estimate shares the stable window's diffuse column and carries most of stage 1's noise
    /// (default: the joint fit's when the data ask for it, see [`LobeRefit::WhenNeeded`]; its
    /// bands use their own unpooled stage-1 coefficients).
    pub refit_widest_lobe: LobeRefit,
    /// With [`LobeRefit::WhenNeeded`]: the confidence of the region, in the covariance of the
    /// fit that keeps stage 1's lobes, that the fit re-fitting them must leave for the joint fit
    /// to report it (in (0, 1); 0.99).
    pub lobe_test_confidence: f64,
    /// With the joint fit: widen the covariance of the rate kept at λ* (or the band that
    /// replaced it) by the Birge ratio of its distance from the joint solution, so that it
    /// covers that distance ([`widen_to_joint`]). `false`: the band's own covariance.
    pub widen_to_joint: bool,
    /// Report each answer's determined directions at their profile-likelihood intervals, once
    /// every decision is taken (docs/adr/0017). Off by default: over the SNR campaigns it moved
    /// the mean NEES by 1–20 %, into its interval in one row and out of it in another, for
    /// about 4 % more solve time.
    pub profile_intervals: bool,
}

impl Default for Stage3Config {
    fn default() -> Self {
        Stage3Config {
            lm: LmConfig::default(),
            start: StartConfig::default(),
            observability: ObservabilityConfig::default(),
            hold_unobservable_at_prior: true,
            weak_prior: WeakPrior::default(),
            max_rotation_deg: Some(DEFAULT_MAX_ROTATION_DEG),
            joint_gate_sigma: Some(DEFAULT_JOINT_GATE_SIGMA),
            refit_diffuse: true,
            refit_widest_lobe: LobeRefit::WhenNeeded,
            lobe_test_confidence: DEFAULT_LOBE_TEST_CONFIDENCE,
            widen_to_joint: true,
            profile_intervals: false,
        }
    }
}

/// Which stage-3 fits re-estimate the widest lobe ([`Stage3Config::refit_widest_lobe`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LobeRefit {
    /// None: every lobe comes from stage 1.
    None,
    /// The joint fit polishes twice, keeping stage 1's lobes and re-fitting them, and reports
    /// the re-fit only when it lies outside the other's confidence region
    /// ([`Stage3Config::lobe_test_confidence`]; default). Where stage 1's lobes explain the
    /// motion window (about Y) the re-fit only adds variance; where they do not (about Z, the
    /// noisy stable window's lobe is off by several of the fit's σ) the re-fit removes the bias.
    #[default]
    WhenNeeded,
    /// The fits of more than one band: the joint fit, always.
    Joint,
    /// Every fit.
    All,
}

impl LobeRefit {
    /// Whether a fit of `bands` bands may re-estimate the widest lobe.
    pub fn applies(self, bands: usize) -> bool {
        match self {
            LobeRefit::None => false,
            LobeRefit::WhenNeeded | LobeRefit::Joint => bands > 1,
            LobeRefit::All => true,
        }
    }
}

/// Default [`Stage3Config::lobe_test_confidence`].
pub const DEFAULT_LOBE_TEST_CONFIDENCE: f64 = 0.99;

/// Default [`Stage3Config::joint_gate_sigma`]: far beyond any scatter of the two fits (they share
/// data), near nothing a second minimum can hide in.
pub const DEFAULT_JOINT_GATE_SIGMA: f64 = 6.0;

/// Default fit horizon \[deg of rotation\]. The noise-free Z error at λ* grows steadily with
/// it (0.10 / 0.13 / 0.18 / 0.24 / 0.39 / 0.58 at 22 / 24 / 25 / 26 / 28 / 30°): the longer
/// the window, the more light from surfaces outside the two-facet model. 25° keeps 100 frames
/// at 0.25 deg/frame for the noise.
pub const DEFAULT_MAX_ROTATION_DEG: f64 = 25.0;

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
    /// Which coefficients stage 3 re-estimated from the motion window (the polish of
    /// [`Stage3Config::refit_diffuse`]); `None`: every coefficient from stage 1.
    #[serde(default)]
    pub refit: Option<Refit>,
    /// The determined directions' profile-likelihood half-widths \[deg/frame\]
    /// ([`RateFit::attach_profile`]), held until every decision is taken
    /// ([`RateFit::report_profile`]); `None` once reported.
    #[serde(skip)]
    pub profiled_bounds_deg_per_frame: Option<[f64; 3]>,
}

/// The terms a fit re-estimated per band from the motion window, with the body axis it held.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Refit {
    /// Each facet's widest lobe too (besides both diffuse terms and the constant).
    pub widest_lobe: bool,
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
    /// The fit, if determined.
    pub fn fit(&self) -> Option<&RateFit> {
        match self {
            Self::Determined(f) => Some(f),
            Self::Unobservable { .. } => None,
        }
    }
}

impl Stage3Config {
    /// Checks every setting (the error names the field).
    pub fn validate(&self) -> Result<(), InversionError> {
        validate(self)
    }
}

fn validate(config: &Stage3Config) -> Result<(), InversionError> {
    let s = &config.start;
    let bad = |field, reason| Err(InversionError::InvalidConfig { field, reason });
    if !(s.half_width_deg_per_frame > 0.0 && s.half_width_deg_per_frame.is_finite()) {
        return bad("start.half_width_deg_per_frame", "must be > 0 and finite");
    }
    let counts = [
        s.points_per_axis,
        s.max_grid_frames,
        s.screen_starts,
        s.screen_iterations,
        s.max_screen_frames,
        s.polish_starts,
    ];
    if counts.contains(&0) {
        return bad("start", "every count must be ≥ 1");
    }
    if let Some(deg) = config.max_rotation_deg {
        if !(deg > 0.0 && (deg <= 360.0 || deg == f64::INFINITY)) {
            return bad(
                "max_rotation_deg",
                "must be in (0, 360], or inf for every frame",
            );
        }
    }
    if config
        .joint_gate_sigma
        .is_some_and(|g| g.is_nan() || g <= 0.0)
    {
        return bad("joint_gate_sigma", "must be > 0 (inf: never set λ* aside)");
    }
    let confidence = config.lobe_test_confidence;
    if !(confidence > 0.0 && confidence < 1.0) {
        return bad("lobe_test_confidence", "must be in (0, 1)");
    }
    if !(0.0..=1.0).contains(&config.observability.min_lobe_share) {
        return bad("observability.min_lobe_share", "must be in [0, 1]");
    }
    let lambda_ok = config.lm.lambda_init > 0.0 && config.lm.lambda_init.is_finite();
    if config.lm.max_iterations == 0 || !lambda_ok {
        return bad("lm", "max_iterations ≥ 1 and lambda_init > 0 required");
    }
    Ok(())
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
                let c = problem.cost_strided([x, y, z], stride);
                scored.push((if c.is_finite() { c } else { f64::INFINITY }, [x, y, z]));
            }
        }
    }
    let evaluated = scored.len();
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

/// Polishes every start with LM, keeps the lowest cost and classifies the result.
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
    if analysis.unobservable.is_none() {
        widen_to_likelihood_intervals(problem, best.p_deg_per_frame, &mut analysis);
    }
    if let Some(reason) = analysis.unobservable {
        return Ok(RateSolution::Unobservable {
            reason,
            bounds_deg_per_frame: analysis.observability.bounds_1sigma_deg_per_frame,
            observability: analysis.observability,
            wavelengths_nm,
        });
    }
    let mirror_deg_per_frame = weak::mirror_if_ambiguous(
        problem,
        best.p_deg_per_frame,
        best.cost,
        &analysis.observability,
        config,
        hold.as_ref(),
    )?;
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
        mirror_deg_per_frame,
        refit: hold.as_ref().map(|h| Refit {
            widest_lobe: problem.refits_widest_lobe(),
            held_direction: h.held_direction(),
            lobe_test: None,
            glint_lobes_only: problem.keeps_glint_lobes(),
        }),
        profiled_bounds_deg_per_frame: None,
    }))
}

/// LM from one explicit start (e.g. the seed's p₀ = 0), no grid.
pub fn fit_single_start(
    problem: &RateProblem,
    p0_deg_per_frame: [f64; 3],
    config: &Stage3Config,
) -> Result<RateSolution, InversionError> {
    fit_from_starts(problem, &[p0_deg_per_frame], config)
}

/// Grid → screen → polish (the default stage-3 solve).
pub fn fit_multistart(
    problem: &RateProblem,
    config: &Stage3Config,
) -> Result<RateSolution, InversionError> {
    fit_multistart_with(problem, config, &[])
}

/// Grid → screen → polish, with `extra` starts (e.g. a solution on a shorter window) polished
/// after the screened ones.
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
