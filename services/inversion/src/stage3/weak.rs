//! What the data cannot determine: the weak direction held under a stated prior, and the sense
//! of rotation (a rate and its mirror (−w_x, w_y, −w_z) that fit equally well).
//!
//! - [`WeakPrior`] and [`hold_weak_direction`]: an unobservable eigen-direction u (the
//!   sun–observer bisector in the co-orbital geometry, math.md §1.6) is held under the stated
//!   prior and the rest re-fitted, unless the data reject the prior.
//! - [`mirror_if_ambiguous`]: the mirror reported beside a fit it cannot be told from.
//! - [`sense_from`] / [`keep_sense`]: which fit's evidence decides the sense when one cannot.

use super::bisector::BisectorHold;
use super::{fit_from_starts, RateFit, RateSolution, Stage3Config};
use crate::error::InversionError;
use crate::lm::{levenberg_marquardt, levenberg_marquardt_prior, LmOutcome, Prior};
use crate::model::RateProblem;
use crate::observability::{
    analyse, given_sigma_scale, residual_variance, Analysis, Observability, ObservabilityConfig,
};
use nalgebra::{Matrix3, Vector3};
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

/// How many standard deviations apart two fits of the same rate are: the Mahalanobis
/// distance of `a − b` under `Cov(a) + Cov(b)`, over the eigen-directions of that sum whose
/// 1σ is within the observability threshold (a direction held under the prior has no
/// evidence to disagree with). The fits share data (λ* is one of the joint fit's bands), so
/// summing the covariances makes the test lenient: it is meant to catch another minimum,
/// not a bias.
pub fn disagreement_sigma(a: &RateFit, b: &RateFit, config: &ObservabilityConfig) -> f64 {
    disagreement(a, b, config).0.sqrt()
}

/// [`disagreement_sigma`] squared, d², and the number k of directions it is taken over
/// (`(NaN, 0)` when a covariance is not finite).
pub fn disagreement(a: &RateFit, b: &RateFit, config: &ObservabilityConfig) -> (f64, usize) {
    let ca = Matrix3::from(a.covariance_deg2_per_frame2);
    let cb = Matrix3::from(b.covariance_deg2_per_frame2);
    let sum = ca + cb;
    if !sum.iter().all(|v| v.is_finite()) {
        return (f64::NAN, 0);
    }
    let d = Vector3::from(a.rate_deg_per_frame) - Vector3::from(b.rate_deg_per_frame);
    let eig = sum.symmetric_eigen();
    let bound = config.unobservable_bound_deg_per_frame;
    let determined: Vec<usize> = (0..3)
        .filter(|&k| eig.eigenvalues[k] > 0.0 && eig.eigenvalues[k].sqrt() <= bound)
        .collect();
    let d2 = determined
        .iter()
        .map(|&k| d.dot(&eig.eigenvectors.column(k)).powi(2) / eig.eigenvalues[k])
        .sum();
    (d2, determined.len())
}

/// Widens `fit`'s covariance so that it covers its distance from `joint`, the fit of the same
/// rate on every band: by the Birge ratio s² = max(1, d²/k) of the two fits
/// ([`disagreement`]), as [`crate::observability::CovarianceSource::GivenSigmaScaled`] does
/// for residuals that reject the model. Two fits that agree within their errors keep their
/// covariance (s² = 1); a band whose own mismatch or stage-1 noise moves its answer further
/// than its covariance says gets error bars that cover the move. Returns s².
pub fn widen_to_joint(fit: &mut RateFit, joint: &RateFit, config: &ObservabilityConfig) -> f64 {
    let (d2, k) = disagreement(fit, joint, config);
    if k == 0 || !d2.is_finite() || d2 <= k as f64 {
        return 1.0;
    }
    let scale = d2 / k as f64;
    for row in &mut fit.covariance_deg2_per_frame2 {
        for v in row.iter_mut() {
            *v *= scale;
        }
    }
    scale
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

/// When the λ* data fit p̂ and its mirror equally well (the sense of rotation about X and Z is
/// not observable in that band), the start for the other sense if the joint fit prefers it:
/// the joint cost holds λ*'s own data and every other band's, so its sense is the likelier one
/// even where it cannot exclude its own mirror at Δχ² ≤ 4 either (at SNR 50 about Z, 18 of 50
/// λ* fits took the wrong sense while the joint fit, ambiguous by that test, had it right).
/// Compared through the exact mirror (−w_x, w_y, −w_z) of p̂: the polished mirror can drift
/// along the weak direction. `None` to keep p̂.
pub(crate) fn sense_from(rate: &RateSolution, joint: &RateSolution) -> Option<[f64; 3]> {
    let (fit, joint) = (rate.fit()?, joint.fit()?);
    fit.mirror_deg_per_frame?;
    let p = fit.rate_deg_per_frame;
    let m = mirror(p);
    if distance(m, p) <= SAME_SENSE_DEG_PER_FRAME {
        return None;
    }
    let to_joint = |a: [f64; 3]| distance(a, joint.rate_deg_per_frame);
    (to_joint(m) < to_joint(p)).then_some(m)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stage3::fixtures::{solution as fit, with_covariance};

    #[test]
    fn the_joint_fit_decides_the_sense_when_lambda_star_cannot() {
        let p = [0.0, -0.006, -0.25];
        let m = [0.0, -0.006, 0.25];
        let joint = fit([0.0, -0.001, 0.249], None);
        // λ* ambiguous, joint not: start from the mirror, the one nearer the joint fit.
        assert_eq!(sense_from(&fit(p, Some(m)), &joint), Some(m));
        // λ* already on the joint's side: keep it.
        assert_eq!(sense_from(&fit(m, Some(p)), &joint), None);
        // λ* not ambiguous: its own answer stands.
        assert_eq!(sense_from(&fit(p, None), &joint), None);
        // The joint fit ambiguous too: its preferred sense still carries all bands' evidence.
        let joint_ambiguous = fit([0.0, -0.001, 0.249], Some([0.0, -0.001, -0.249]));
        assert_eq!(sense_from(&fit(p, Some(m)), &joint_ambiguous), Some(m));
        // The start is the exact mirror of p̂, not a polished mirror that drifted along X.
        assert_eq!(
            sense_from(&fit(p, Some([0.56, 0.0, 0.18])), &joint),
            Some(m)
        );
        // No sense to flip: p̂ is its own mirror.
        let flat = [0.0, 0.25, 0.001];
        assert_eq!(sense_from(&fit(flat, Some(flat)), &joint), None);
    }

    #[test]
    fn widening_covers_the_distance_from_the_joint_fit_and_only_beyond_its_errors() {
        let config = ObservabilityConfig::default();
        // X held (1σ 3 ≫ 0.25): Y and Z are the k = 2 directions compared.
        let cov = [[9.0, 0.0, 0.0], [0.0, 1e-6, 0.0], [0.0, 0.0, 1e-6]];
        let joint = with_covariance(
            [0.0, 0.25, 0.0],
            [[0.0; 3], [0.0, 1e-8, 0.0], [0.0, 0.0, 1e-8]],
        );
        // 0.001 along Y and Z: d² = 2e-6 / 1.01e-6 < k, kept as it is.
        let mut near = with_covariance([0.0, 0.251, 0.001], cov);
        assert_eq!(widen_to_joint(&mut near, &joint, &config), 1.0);
        assert_eq!(near.covariance_deg2_per_frame2, cov);
        // 0.004 along Z: d² = 16e-6 / 1.01e-6 = 15.84, widened by d²/k = 7.92 …
        let mut far = with_covariance([0.0, 0.25, 0.004], cov);
        let scale = widen_to_joint(&mut far, &joint, &config);
        let want = 16e-6 / 1.01e-6 / 2.0;
        assert!((scale - want).abs() < 1e-9 * want, "{scale} vs {want}");
        assert_eq!(far.covariance_deg2_per_frame2[2][2], 1e-6 * scale);
        assert_eq!(far.covariance_deg2_per_frame2[0][0], 9.0 * scale);
        // … after which its covariance covers the distance: d² ≈ k (the joint fit's own 1 %
        // of the sum leaves it 16 / (7.92 + 0.01) = 2.017).
        let (d2, k) = disagreement(&far, &joint, &config);
        assert_eq!(k, 2);
        assert!((d2 - 2.0).abs() < 0.03, "{d2}");
    }

    #[test]
    fn disagreement_is_the_mahalanobis_distance_over_the_determined_directions() {
        let config = ObservabilityConfig::default();
        // Diagonal: variances 1e-6 + 3e-6 along Y, 2e-6 + 2e-6 along Z; X held (1σ 3 ≫ 0.25).
        let a = with_covariance(
            [0.1, 0.25, 0.004],
            [[9.0, 0.0, 0.0], [0.0, 1e-6, 0.0], [0.0, 0.0, 2e-6]],
        );
        let b = with_covariance(
            [-0.3, 0.248, 0.0],
            [[0.0, 0.0, 0.0], [0.0, 3e-6, 0.0], [0.0, 0.0, 2e-6]],
        );
        let expected = (0.002f64.powi(2) / 4e-6 + 0.004f64.powi(2) / 4e-6).sqrt();
        let d = disagreement_sigma(&a, &b, &config);
        assert!((d - expected).abs() < 1e-9 * expected, "{d} vs {expected}");
        assert_eq!(disagreement_sigma(&b, &a, &config), d);
        // Rotated frame: the same distance (the test is coordinate-free).
        let (c, s) = (0.6f64, 0.8f64);
        let rot = |v: [f64; 3]| [v[0], c * v[1] - s * v[2], s * v[1] + c * v[2]];
        let rot_cov = |d: [f64; 3]| {
            let r = nalgebra::Matrix3::new(1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c);
            let m = r * nalgebra::Matrix3::from_diagonal(&Vector3::from(d)) * r.transpose();
            [
                [m[(0, 0)], m[(0, 1)], m[(0, 2)]],
                [m[(1, 0)], m[(1, 1)], m[(1, 2)]],
                [m[(2, 0)], m[(2, 1)], m[(2, 2)]],
            ]
        };
        let ar = with_covariance(rot(a.rate_deg_per_frame), rot_cov([9.0, 1e-6, 2e-6]));
        let br = with_covariance(rot(b.rate_deg_per_frame), rot_cov([0.0, 3e-6, 2e-6]));
        let dr = disagreement_sigma(&ar, &br, &config);
        assert!(
            (dr - expected).abs() < 1e-6 * expected,
            "{dr} vs {expected}"
        );
    }
}
