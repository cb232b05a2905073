//! What the data cannot determine: the weak direction held under a stated prior, and the sense
//! of rotation (a rate and its mirror (−w_x, w_y, −w_z) that fit equally well).
//!
//! - [`WeakPrior`] and [`hold_weak_direction`]: an unobservable eigen-direction u (the
//!   sun–observer bisector in the co-orbital geometry, math.md §1.6) is held under the stated
//!   prior and the rest re-fitted, unless the data reject the prior.
//! - [`mirror_if_ambiguous`]: the mirror reported beside a fit it cannot be told from.
//! - [`keep_sense`]: the reweighted joint fit keeps the first fit's sense.

use super::bisector::BisectorHold;
use super::{fit_from_starts, RateSolution, Stage3Config};
use crate::error::InversionError;
use crate::lm::{levenberg_marquardt, levenberg_marquardt_prior, LmOutcome, Prior};
use crate::model::RateProblem;
use crate::observability::{
    analyse, given_sigma_scale, residual_variance, Analysis, Observability,
};
use serde::{Deserialize, Serialize};

/// The mirror (−w_x, w_y, −w_z) of a rate: the same light curve when every geometry vector
/// lies in the body XZ plane.
pub fn mirror(p: [f64; 3]) -> [f64; 3] {
    [-p[0], p[1], -p[2]]
}

/// Whether `p` has a sense of rotation its mirror reverses: the mirror is at least |p| away
/// (w_x, w_z carry at least half the rate). A rate mostly about Y is nearly its own mirror;
/// the two are copies the data hardly tell apart, not two senses.
pub fn has_sense(p: [f64; 3]) -> bool {
    distance(mirror(p), p) >= distance(p, [0.0; 3])
}

/// ‖a − b‖ \[deg/frame\].
pub fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|i| (a[i] - b[i]).powi(2)).sum::<f64>().sqrt()
}

/// The stated prior under which stage 3 holds a direction the data cannot determine.
///
/// Either way the held direction is reported unobservable and only the determined combinations
/// of p come from the data; the prior decides where along u the reported p sits.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum WeakPrior {
    /// The body rate about the body axis e nearest u is zero: e·p = 0 (default). The rate is
    /// assumed to lie in the plane of the other two body axes, a statement about the body, not
    /// about the observing geometry; in the co-orbital geometry u is within a few degrees of
    /// body X and the prior reads w_x = 0.
    #[default]
    BodyAxis,
    /// The component along u itself is zero: u·p = 0 (the minimum-norm choice). A truth with a
    /// component along u (a Z rotation has u·p* = −0.03 deg/frame when u is 7° off body X) is
    /// then biased by that component.
    EigenDirection,
}

/// The rates about the body axes, by index.
pub const RATE_NAMES: [&str; 3] = ["w_x", "w_y", "w_z"];

/// The index of the body axis nearest the direction `u` (its largest component).
pub fn nearest_body_axis(u: &[f64; 3]) -> usize {
    (0..3)
        .max_by(|&a, &b| u[a].abs().total_cmp(&u[b].abs()))
        .unwrap_or(0)
}

impl WeakPrior {
    /// The constraint direction for each held u: u itself, or the body axis nearest u (falling
    /// back to u when two held directions share that axis).
    pub fn directions(self, weak: &[[f64; 3]]) -> Vec<[f64; 3]> {
        let mut out: Vec<[f64; 3]> = Vec::with_capacity(weak.len());
        for u in weak {
            let d = match self {
                WeakPrior::EigenDirection => *u,
                WeakPrior::BodyAxis => {
                    let mut e = [0.0; 3];
                    e[nearest_body_axis(u)] = 1.0;
                    if out.contains(&e) {
                        *u
                    } else {
                        e
                    }
                }
            };
            out.push(d);
        }
        out
    }
}

/// Largest cost increase, in noise variances, at which the data still accept holding the
/// weakest direction at its prior (3σ for one degree of freedom).
const HOLD_MAX_DELTA_CHI2: f64 = 9.0;

/// One noise variance in cost units for likelihood-ratio tests between two fits: with σ given,
/// 1 (whitened residuals) unless the residuals reject the model, then the inflated Birge ratio
/// ([`given_sigma_scale`]); without σ, the residual variance of the fit p̂, inflated for the
/// residuals' serial correlation ([`residual_variance`]). Model mismatch is smooth in time, and
/// counting its N residuals as independent would make any prior look rejected.
pub(super) fn noise_variance(problem: &RateProblem, p: [f64; 3], config: &Stage3Config) -> f64 {
    let mut r = vec![0.0; problem.residual_count()];
    let cost = problem.residuals(p, &mut r);
    if problem.sigma_given() {
        return given_sigma_scale(problem, &r, cost).0;
    }
    residual_variance(problem, &r, cost, &config.observability).0
}

/// Re-fits with the stated prior on `weak` (from p̂ moved onto the prior's plane); returns the
/// held outcome (cost without the prior), the analysis there and the LM iterations used.
fn hold_at_prior(
    problem: &RateProblem,
    best: &LmOutcome,
    weak: &[[f64; 3]],
    analysis: &Analysis,
    config: &Stage3Config,
) -> Result<(LmOutcome, Analysis, usize), InversionError> {
    let strongest = analysis
        .observability
        .information_eigenvalues
        .iter()
        .cloned()
        .filter(|v| v.is_finite())
        .fold(0.0f64, f64::max);
    let directions = config.weak_prior.directions(weak);
    let prior = Prior {
        directions: directions.clone(),
        weight: PRIOR_WEIGHT_FACTOR * strongest.max(1.0),
    };
    let p0 = onto_prior_planes(best.p_deg_per_frame, weak, &directions);
    let refit = levenberg_marquardt_prior(problem, p0, &config.lm, &prior, |_, _, _| false)?;
    let held_analysis = analyse(problem, refit.p_deg_per_frame, &config.observability)?;
    let iterations = refit.iterations;
    let held = LmOutcome {
        cost: problem.cost(refit.p_deg_per_frame),
        ..refit
    };
    Ok((held, held_analysis, iterations))
}

/// `p` moved onto the prior's planes e·p = 0, along each held direction u only (so the
/// determined combinations keep their fitted values): p ← p − u (e·p)/(e·u).
pub(super) fn onto_prior_planes(
    mut p: [f64; 3],
    weak: &[[f64; 3]],
    directions: &[[f64; 3]],
) -> [f64; 3] {
    let dot = |a: &[f64; 3], b: &[f64; 3]| (0..3).map(|i| a[i] * b[i]).sum::<f64>();
    for (u, e) in weak.iter().zip(directions) {
        let t = dot(e, &p) / dot(e, u);
        for i in 0..3 {
            p[i] -= u[i] * t;
        }
    }
    p
}

/// Weight of the prior on unobservable directions, relative to the largest eigenvalue of the
/// information matrix: large enough that the prior decides those components.
pub(super) const PRIOR_WEIGHT_FACTOR: f64 = 1e6;

/// What [`hold_weak_direction`] returns: the (possibly held) outcome, its analysis, the LM
/// iterations spent and the prior's directions e it held (e·p = 0; empty when none).
pub(super) type Held = (LmOutcome, Analysis, usize, Vec<[f64; 3]>);

/// Holds the directions the data cannot determine (math.md §1.6: the sun–observer bisector)
/// under the stated prior ([`WeakPrior`]) and re-fits the rest, instead of reporting wherever
/// LM drifted along them. The returned observability still marks held directions unobservable.
pub(super) fn hold_weak_direction(
    problem: &RateProblem,
    best: LmOutcome,
    analysis: Analysis,
    config: &Stage3Config,
) -> Result<Held, InversionError> {
    let weak: Vec<[f64; 3]> = (0..3)
        .filter(|&i| analysis.observability.unobservable[i])
        .map(|i| analysis.observability.eigenvectors[i])
        .collect();
    if !weak.is_empty() {
        let (mut held, mut held_analysis, mut iterations) =
            hold_at_prior(problem, &best, &weak, &analysis, config)?;
        // Judged where the prior puts the fit: when LM drifted far along the weak directions,
        // their shape there can point at another body axis than at the held solution (about Y
        // at λ*: Z at w_x = −0.11, X at w_x = 0). Then the held solution's own weakest
        // directions are held instead, once.
        let at_held: Vec<[f64; 3]> =
            held_analysis.observability.eigenvectors[..weak.len()].to_vec();
        let mut directions = config.weak_prior.directions(&weak);
        let at_held_directions = config.weak_prior.directions(&at_held);
        if config.weak_prior == WeakPrior::BodyAxis && at_held_directions != directions {
            let again;
            (held, held_analysis, again) =
                hold_at_prior(problem, &best, &at_held, &held_analysis, config)?;
            iterations += again;
            directions = at_held_directions;
        }
        // The classification stays the one at the unconstrained optimum.
        held_analysis.observability.unobservable = analysis.observability.unobservable;
        held_analysis.unobservable = None;
        return Ok((held, held_analysis, iterations, directions));
    }
    // The bisector is invisible to first order only near the prior (the light curve depends
    // on it about quadratically there); a fit that drifted along it sees curvature that is not
    // there at the prior. So the weakest direction is judged where the prior puts it: held if
    // it is unobservable at the held solution and the data do not reject the prior
    // (likelihood ratio: Δχ² ≤ 9, 3σ).
    let u = analysis.observability.eigenvectors[0];
    let (held, held_analysis, iterations) = hold_at_prior(problem, &best, &[u], &analysis, config)?;
    let variance = noise_variance(problem, best.p_deg_per_frame, config);
    let accepted = (held.cost - best.cost) / variance <= HOLD_MAX_DELTA_CHI2;
    if accepted
        && held_analysis.unobservable.is_none()
        && held_analysis.observability.unobservable[0]
    {
        let directions = config.weak_prior.directions(&[u]);
        Ok((held, held_analysis, iterations, directions))
    } else {
        Ok((best, analysis, iterations, vec![]))
    }
}

/// A mirror this far from p̂ is distinct whatever p̂'s bounds \[deg/frame\].
const MIRROR_MIN_DISTANCE_DEG_PER_FRAME: f64 = 1e-2;
/// A nearer mirror is distinct when it lies this many 1σ bounds from p̂ along the determined
/// directions (closer, it is inside p̂'s own error bars).
const MIRROR_MIN_SEPARATION_SIGMA: f64 = 2.0;
/// The mirror is reported when its cost exceeds p̂'s by at most this many noise variances
/// (Δχ² ≤ 4: the data cannot tell them apart at 2σ).
pub(crate) const MIRROR_MAX_DELTA_CHI2: f64 = 4.0;

/// The mirror solution of p̂ when the data cannot tell them apart: LM polished from
/// (−w_x, w_y, −w_z) (an exact minimum when every geometry vector lies in the body XZ plane, a
/// nearby one otherwise), reported if it is distinct from p̂ and its cost is within Δχ² ≤ 4 of
/// p̂'s, in units of the noise variance ([`noise_variance`]).
///
/// Distinct: at least 1e-2 deg/frame away, or at least 2σ along the directions `observability`
/// determines. A rate about Y is nearly its own mirror: the Sun's fraction of a degree off the
/// body XZ plane moves the mirror of [0, 0.25, 0] to w_z ≈ −0.004, several σ
/// away at SNR 10 over all bands, and the data cannot choose between the two.
pub(super) fn mirror_if_ambiguous(
    problem: &RateProblem,
    p: [f64; 3],
    cost: f64,
    observability: &Observability,
    config: &Stage3Config,
    hold: Option<&BisectorHold>,
) -> Result<Option<[f64; 3]>, InversionError> {
    let out = match hold {
        Some(hold) => hold.fit(problem, mirror(p), config, |_, _, _| false)?,
        None => levenberg_marquardt(problem, mirror(p), &config.lm)?,
    };
    let m = out.p_deg_per_frame;
    let separation2: f64 = (0..3)
        .filter(|&k| !observability.unobservable[k])
        .map(|k| {
            let v = observability.eigenvectors[k];
            let along: f64 = (0..3).map(|i| v[i] * (m[i] - p[i])).sum();
            (along / observability.bounds_1sigma_deg_per_frame[k]).powi(2)
        })
        .sum();
    let distinct = distance(m, p) >= MIRROR_MIN_DISTANCE_DEG_PER_FRAME
        || separation2 >= MIRROR_MIN_SEPARATION_SIGMA.powi(2);
    if !distinct || !out.cost.is_finite() {
        return Ok(None);
    }
    let dof = problem.residual_count().saturating_sub(3).max(1) as f64;
    let variance = noise_variance(problem, p, config);
    // Noise-free data fitted exactly (cost ≈ 0): only an equally exact mirror qualifies.
    let tie = (out.cost - cost).abs() <= 1e-6 * cost.abs().max(1e-12 * dof);
    Ok(((out.cost - cost) / variance <= MIRROR_MAX_DELTA_CHI2 || tie).then_some(m))
}

/// The reweighted joint solution with the sense of rotation of `first`: as it is when it is
/// nearer `first` than its mirror (−w_x, w_y, −w_z) is (or the two are too close to tell),
/// else re-polished from the mirror; `None` (keep the first fit) when that fails or does not
/// hold the sense.
pub(crate) fn keep_sense(
    reweighted: RateSolution,
    problem: &RateProblem,
    first: [f64; 3],
    config: &Stage3Config,
) -> Option<RateSolution> {
    let q = reweighted.fit()?.rate_deg_per_frame;
    let wrong_side = |p: [f64; 3]| {
        distance(p, mirror(p)) > SAME_SENSE_DEG_PER_FRAME
            && distance(mirror(p), first) < distance(p, first)
    };
    if !wrong_side(q) {
        return Some(reweighted);
    }
    let flipped = fit_from_starts(problem, &[mirror(q)], config).ok()?;
    let p = flipped.fit()?.rate_deg_per_frame;
    (!wrong_side(p)).then_some(flipped)
}

/// A rate closer than this to its own mirror has no sense of rotation to keep \[deg/frame\].
const SAME_SENSE_DEG_PER_FRAME: f64 = 1e-2;
