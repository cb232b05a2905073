//! Covariance, observability and the Cramér–Rao bound of the rate fit (docs/math.md §1.6).
//!
//! With residuals r = w(y − m) and J = w ∂m/∂p at the solution p̂:
//!
//! ```text
//! F = JᵀJ / s²      s² = 1                        (σ given: J is whitened, F is the Fisher
//!                                                  information, Cov = F⁻¹ is the CRB at p̂;
//!                                                  s² = χ²/(N − 3)·τ instead
//!                                                  when χ²/(N − 3) exceeds 1 by 3σ: the
//!                                                  residuals reject the model)
//!                   s² = max(ε/(N − 3), s_min²)·τ
//!                                                 (σ unknown: residual variance in units of Φ̄,
//!                                                  τ = the residuals' correlation time)
//! F = V diag(λ_i) Vᵀ (faer self-adjoint eigendecomposition, λ ascending)
//! bound_i = 1/sqrt(λ_i)  [deg/frame]: the 1σ extent along eigen-direction v_i
//! Cov = V diag(1/λ_i) Vᵀ
//! ```
//!
//! A direction is unobservable when bound_i > threshold (default 0.25 deg/frame, the size of the
//! rates themselves). The whole solution is [`Unobservable`](crate::stage3::RateSolution) when
//! - the light curve has no sensitivity to p: `sqrt(λ_max(JᵀJ)/N)/rms(w) < flat_tol` (relative
//!   flux change per deg/frame; e.g. no facet lit and visible, no glint);
//! - JᵀJ is numerically rank deficient: `λ_min ≤ rank_tol · λ_max`;
//! - or every direction exceeds the threshold.
//!
//! Without σ the residual is mostly model mismatch, smooth in time: N serially correlated
//! residuals carry the evidence of about N/τ independent ones, τ = (1 + ρ)/(1 − ρ) the AR(1)
//! correlation time of the residuals (ρ their lag-1 autocorrelation over frames, pooled over
//! bands, clamped to [0, 0.99]). The variance is inflated by τ. White residuals (ρ ≈ 0) leave
//! it unchanged. (Geyer's initial-positive-sequence estimate of τ was tried: the glint's
//! residuals oscillate, it stops early, and the mismatch still looked like evidence.)
//!
//! CRB helper: `sqrt(diag((JᵀWJ)⁻¹))` at the true p with the observations' σ.

use crate::error::InversionError;
use crate::lm::normal_equations;
use crate::model::RateProblem;
use faer::{Mat, Side};
use serde::{Deserialize, Serialize};
use std::cmp::Ordering;

/// Where the covariance scale comes from.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CovarianceSource {
    /// The observations' σ (whitened residuals; Cov = (JᵀWJ)⁻¹).
    GivenSigma,
    /// The observations' σ, but the residuals reject the model (χ²/(N − 3) above its 3σ
    /// level): Cov = s²(JᵀWJ)⁻¹ with s² = χ²/(N − 3)·τ, so that the reported covariance
    /// covers the model mismatch as well as the noise (Birge ratio with the correlation-time
    /// inflation of the unknown-σ case).
    GivenSigmaScaled {
        /// s² ≥ 1.
        variance_scale: f64,
        /// τ, the residuals' correlation time \[frames\].
        correlation_time: f64,
    },
    /// Residual variance; `sigma_normalised` = s, the fitted 1σ in units of mean Φ_obs.
    ResidualVariance {
        /// s (relative to mean flux), after the floor and the serial-correlation inflation.
        sigma_normalised: f64,
        /// τ, the residuals' correlation time used for the inflation \[frames\].
        #[serde(default)]
        correlation_time: f64,
    },
}

/// Eigen-analysis of the information matrix at the solution.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Observability {
    /// λ_i of F, ascending \[(deg/frame)⁻²\].
    pub information_eigenvalues: [f64; 3],
    /// `eigenvectors[i]` = unit v_i (largest component positive).
    pub eigenvectors: [[f64; 3]; 3],
    /// 1/sqrt(λ_i) \[deg/frame\] (∞ when λ_i ≤ 0; serialised as null).
    pub bounds_1sigma_deg_per_frame: [f64; 3],
    /// bound_i > threshold.
    pub unobservable: [bool; 3],
    /// The threshold used \[deg/frame\].
    pub threshold_deg_per_frame: f64,
    /// λ_max/λ_min of JᵀJ.
    pub condition_number: f64,
    /// sqrt(λ_max(JᵀJ)/N)/rms(w): relative flux change per deg/frame.
    pub rms_sensitivity_per_deg_per_frame: f64,
}

/// Why no rate is reported.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum UnobservableReason {
    /// The model light curve does not change with p (no glint, nothing lit and visible).
    FlatLightCurve {
        /// The measured sensitivity.
        rms_sensitivity: f64,
    },
    /// JᵀJ is numerically singular.
    RankDeficient {
        /// λ_max/λ_min.
        condition_number: f64,
    },
    /// Every eigen-direction's 1σ bound exceeds the threshold.
    AllDirectionsAboveThreshold,
    /// No glint: at the fitted rate only the diffuse terms move the light curve (the lobes'
    /// share of its sensitivity is below `min_lobe_share`). The stable window cannot tell
    /// which surface the diffuse light comes from (in the co-orbital geometry the panel's,
    /// the body face's and any Lambertian remainder's columns are nearly collinear), so a rate
    /// read from the diffuse terms alone would rest on an arbitrary split (math.md §1.8: no
    /// solution at phase 40°, "no body or panel glint").
    NoGlint {
        /// ‖J_lobes‖/‖J‖ at the fitted rate.
        lobe_sensitivity_share: f64,
    },
    /// Every start ended far outside the search box (a rate beyond twice its half-width on
    /// some axis): at low SNR LM can chase noise to 5 deg/frame and more, where the body turns
    /// past the fit horizon between two frames and the model no longer describes the data.
    /// The box is the range of rates the search considers; widen it
    /// (`stage3.start.half_width_deg_per_frame`) if faster rates are expected.
    OutsideSearchBox {
        /// Where the best start ended \[deg/frame\].
        rate_deg_per_frame: [f64; 3],
    },
}

impl UnobservableReason {
    /// Wire code of the reason (`SolveResponse::unobservable_reason`; 0 = none).
    pub fn code(&self) -> u32 {
        match self {
            Self::FlatLightCurve { .. } => 1,
            Self::RankDeficient { .. } => 2,
            Self::AllDirectionsAboveThreshold => 3,
            Self::NoGlint { .. } => 4,
            Self::OutsideSearchBox { .. } => 5,
        }
    }
}

/// Thresholds of the classification.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ObservabilityConfig {
    /// A direction with a larger 1σ bound is unobservable \[deg/frame\] (0.25).
    pub unobservable_bound_deg_per_frame: f64,
    /// Flat-light-curve limit on the relative sensitivity \[per deg/frame\] (1e-9).
    pub flat_tol: f64,
    /// Rank-deficiency limit on λ_min/λ_max of JᵀJ (1e-13).
    pub rank_tol: f64,
    /// Floor s_min on the residual σ relative to mean flux when σ is unknown (1e-9).
    pub min_sigma_rel: f64,
    /// No-glint limit on the lobes' share of the sensitivity to p (0.01; 0 disables).
    pub min_lobe_share: f64,
}

impl Default for ObservabilityConfig {
    fn default() -> Self {
        Self {
            unobservable_bound_deg_per_frame: 0.25,
            flat_tol: 1e-9,
            rank_tol: 1e-13,
            min_sigma_rel: 1e-9,
            min_lobe_share: 0.01,
        }
    }
}

/// Eigen-decomposition of a symmetric 3×3 matrix: (λ ascending, v_i as rows).
pub fn symmetric_eigen(a: &[[f64; 3]; 3]) -> Result<([f64; 3], [[f64; 3]; 3]), InversionError> {
    let m = Mat::from_fn(3, 3, |i, j| 0.5 * (a[i][j] + a[j][i]));
    let evd = m
        .self_adjoint_eigen(Side::Lower)
        .map_err(|_| InversionError::LinearAlgebra {
            what: "self-adjoint eigendecomposition",
        })?;
    let (s, u) = (evd.S(), evd.U());
    let mut vals = [0.0; 3];
    let mut vecs = [[0.0; 3]; 3];
    for i in 0..3 {
        vals[i] = s[i];
        let mut v = [u[(0, i)], u[(1, i)], u[(2, i)]];
        let big = v
            .iter()
            .copied()
            .fold(0.0_f64, |m, x| if x.abs() > m.abs() { x } else { m });
        if big < 0.0 {
            v = v.map(|x| -x);
        }
        vecs[i] = v;
    }
    Ok((vals, vecs))
}

/// `V diag(1/λ) Vᵀ` (∞ entries when some λ ≤ 0).
pub fn inverse_from_eigen(vals: &[f64; 3], vecs: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut out = [[0.0; 3]; 3];
    for k in 0..3 {
        let inv = if vals[k] > 0.0 {
            1.0 / vals[k]
        } else {
            f64::INFINITY
        };
        for i in 0..3 {
            for j in 0..3 {
                let prod = vecs[k][i] * vecs[k][j];
                if prod != 0.0 {
                    out[i][j] += prod * inv;
                }
            }
        }
    }
    out
}

/// Analysis at p̂: the covariance, its source and the observability record, or the reason the
/// solution is unobservable (returned with the same record).
pub struct Analysis {
    /// Cov(p) \[(deg/frame)²\].
    pub covariance: [[f64; 3]; 3],
    /// Scale source.
    pub source: CovarianceSource,
    /// Eigen-analysis.
    pub observability: Observability,
    /// `Some` when no rate may be reported.
    pub unobservable: Option<UnobservableReason>,
}

/// Covariance and observability at `p` (usually the LM solution).
pub fn analyse(
    problem: &RateProblem,
    p: [f64; 3],
    config: &ObservabilityConfig,
) -> Result<Analysis, InversionError> {
    let n = problem.residual_count();
    let mut r = vec![0.0; n];
    let mut jac = vec![[0.0; 3]; n];
    let cost = problem.residuals_and_jacobian(p, &mut r, &mut jac);
    let (jtj, _) = normal_equations(&jac, &r);
    let (s2, source) = if problem.sigma_given() {
        given_sigma_scale(problem, &r, cost)
    } else {
        let (s2, correlation_time) = residual_variance(problem, &r, cost, config);
        let sigma_normalised = s2.sqrt();
        (
            s2,
            CovarianceSource::ResidualVariance {
                sigma_normalised,
                correlation_time,
            },
        )
    };
    let (raw_vals, vecs) = symmetric_eigen(&jtj)?;
    let lam_max = raw_vals[2].max(0.0);
    let condition_number = if raw_vals[0] > 0.0 {
        lam_max / raw_vals[0]
    } else {
        f64::INFINITY
    };
    let rms_sensitivity = (lam_max / n as f64).sqrt() / problem.weight_rms();
    let vals = raw_vals.map(|v| v / s2);
    // The stage-1 coefficients are estimates too: with σ given, their covariance is carried
    // into the rates' (F⁻¹ + F⁻¹ C F⁻¹), and the eigen-analysis is of that total.
    let regular = raw_vals.iter().all(|v| *v > config.rank_tol * lam_max);
    let coefficient_term = problem
        .coefficient_term(p, &jac)
        .filter(|_| problem.sigma_given() && regular);
    let (vals, vecs) = match coefficient_term {
        Some(c) => total_information(&raw_vals, &vecs, s2, &c)?,
        None => (vals, vecs),
    };
    let bounds = vals.map(|v| {
        if v > 0.0 {
            v.sqrt().recip()
        } else {
            f64::INFINITY
        }
    });
    let threshold = config.unobservable_bound_deg_per_frame;
    // A numerically singular direction carries no information: its bound is infinite.
    let singular = raw_vals.map(|v| v.is_nan() || v <= config.rank_tol * lam_max);
    let bounds: [f64; 3] = std::array::from_fn(|i| {
        if singular[i] {
            f64::INFINITY
        } else {
            bounds[i]
        }
    });
    let unobservable_dirs = bounds.map(|b| b.is_nan() || b > threshold);
    // Only when no direction is determined is there no rate to report; otherwise the weak
    // directions are flagged (and stage 3 holds them at its prior).
    let reason = if rms_sensitivity.is_nan() || rms_sensitivity < config.flat_tol {
        Some(UnobservableReason::FlatLightCurve { rms_sensitivity })
    } else if unobservable_dirs.iter().all(|&u| u) {
        if singular.iter().any(|&s| s) {
            Some(UnobservableReason::RankDeficient { condition_number })
        } else {
            Some(UnobservableReason::AllDirectionsAboveThreshold)
        }
    } else {
        None
    };
    Ok(Analysis {
        covariance: inverse_from_eigen(&vals, &vecs),
        source,
        observability: Observability {
            information_eigenvalues: vals,
            eigenvectors: vecs,
            bounds_1sigma_deg_per_frame: bounds,
            unobservable: unobservable_dirs,
            threshold_deg_per_frame: threshold,
            condition_number,
            rms_sensitivity_per_deg_per_frame: rms_sensitivity,
        },
        unobservable: reason,
    })
}

/// The noise variance estimated from residuals `r` (cost ε = Σ r²) when σ is unknown:
/// max(ε/(N − 3), s_min²)·τ, and τ (see the module docs).
pub fn residual_variance(
    problem: &RateProblem,
    r: &[f64],
    cost: f64,
    config: &ObservabilityConfig,
) -> (f64, f64) {
    let dof = r.len().saturating_sub(3).max(1) as f64;
    let tau = correlation_time(r, problem.wavelengths_nm().len());
    let s2 = (cost / dof).max(config.min_sigma_rel.powi(2));
    (s2 * tau, tau)
}

/// With σ given: 1 while χ²/(N − 3) is within 3σ of 1 (the model explains the data to the
/// noise), else the inflated Birge ratio (see [`CovarianceSource::GivenSigmaScaled`]).
pub fn given_sigma_scale(problem: &RateProblem, r: &[f64], chi2: f64) -> (f64, CovarianceSource) {
    let dof = r.len().saturating_sub(3).max(1) as f64;
    let birge = chi2 / dof;
    if birge <= 1.0 + 3.0 * (2.0 / dof).sqrt() {
        return (1.0, CovarianceSource::GivenSigma);
    }
    let correlation_time = correlation_time(r, problem.wavelengths_nm().len());
    let variance_scale = birge * correlation_time;
    (
        variance_scale,
        CovarianceSource::GivenSigmaScaled {
            variance_scale,
            correlation_time,
        },
    )
}

/// Correlation time τ = (1 + ρ)/(1 − ρ) of frame-major residuals (`r[t·bands + b]`) under an
/// AR(1) model, ρ the lag-1 autocorrelation pooled over bands and clamped to [0, 0.99]
/// (τ ≤ 199); 1 when undefined (no bands, fewer than two frames, zero residuals).
pub fn correlation_time(r: &[f64], bands: usize) -> f64 {
    let energy: f64 = r.iter().map(|v| v * v).sum();
    if bands == 0 || r.len() <= bands || energy <= 0.0 {
        return 1.0;
    }
    let lagged: f64 = r.iter().zip(&r[bands..]).map(|(a, b)| a * b).sum();
    let rho = (lagged / energy).clamp(0.0, MAX_SERIAL_CORRELATION);
    (1.0 + rho) / (1.0 - rho)
}

/// Largest lag-1 autocorrelation [`correlation_time`] uses.
const MAX_SERIAL_CORRELATION: f64 = 0.99;

/// Eigen-pairs of the total information, the inverse of the covariance s² G⁻¹ + G⁻¹ C G⁻¹
/// (G = JᵀJ whitened; the coefficients' covariance C comes from stage 1's own σ and is not
/// rescaled), ascending with their directions like the Fisher analysis.
///
/// Near the bisector G spans many decades: the covariance is formed in G's eigenbasis
/// (s² Λ⁻¹ + Λ⁻¹ C' Λ⁻¹, C' = Vᵀ C V, exact scaling) and rotated back. Its eigen-decomposition
/// resolves the large variances (the weak directions, the ones that matter); a small variance
/// lost to round-off is floored at the noise-only s²/λ_max(G), since C only adds variance.
fn total_information(
    raw_vals: &[f64; 3],
    vecs: &[[f64; 3]; 3],
    s2: f64,
    c: &[[f64; 3]; 3],
) -> Result<([f64; 3], [[f64; 3]; 3]), InversionError> {
    let dot3 = |a: &[f64; 3], b: &[f64; 3]| (0..3).map(|i| a[i] * b[i]).sum::<f64>();
    let c_v: [[f64; 3]; 3] =
        std::array::from_fn(|i| std::array::from_fn(|j| dot3(&c[i], &vecs[j])));
    let inner: [[f64; 3]; 3] = std::array::from_fn(|k| {
        std::array::from_fn(|l| {
            let c_kl: f64 = (0..3).map(|i| vecs[k][i] * c_v[i][l]).sum();
            let noise = if k == l { s2 / raw_vals[k] } else { 0.0 };
            noise + c_kl / (raw_vals[k] * raw_vals[l])
        })
    });
    let total: [[f64; 3]; 3] = std::array::from_fn(|i| {
        std::array::from_fn(|j| {
            (0..3)
                .flat_map(|k| (0..3).map(move |l| (k, l)))
                .map(|(k, l)| vecs[k][i] * inner[k][l] * vecs[l][j])
                .sum()
        })
    });
    let (var, dirs) = symmetric_eigen(&total)?;
    let floor = s2 / raw_vals.iter().cloned().fold(0.0f64, f64::max);
    let var = var.map(|v| v.max(floor));
    // Variance ascending = information descending: reverse.
    Ok((
        [var[2], var[1], var[0]].map(|v| 1.0 / v),
        [dirs[2], dirs[1], dirs[0]],
    ))
}

/// Widens the bounds of the determined directions to their likelihood intervals: along each
/// eigen-direction v_i, the half-width δ_i where the cost has risen by one noise variance,
/// `ε(p ± δ v_i) − ε(p) = s²` (the larger side). For a quadratic cost δ_i is the linearised
/// bound 1/sqrt(λ_i); near the mirror-symmetric geometry (math.md §1.6) the cost is flatter
/// than its curvature at p̂ says, and the linearised covariance would be overconfident. The
/// covariance is rebuilt as V diag(δ²) Vᵀ; the classification is left as it is.
pub fn widen_to_likelihood_intervals(problem: &RateProblem, p: [f64; 3], analysis: &mut Analysis) {
    let s2 = noise_variance(&analysis.source);
    let obs = &mut analysis.observability;
    let cap = INTERVAL_CAP_FACTOR * obs.threshold_deg_per_frame;
    let c0 = problem.cost(p);
    for i in 0..3 {
        let linear = obs.bounds_1sigma_deg_per_frame[i];
        if obs.unobservable[i] || !(linear > 0.0 && linear.is_finite()) {
            continue;
        }
        let v = obs.eigenvectors[i];
        let rise = |d: f64| problem.cost([p[0] + d * v[0], p[1] + d * v[1], p[2] + d * v[2]]) - c0;
        let width = [1.0, -1.0]
            .map(|side| half_width(|d| rise(side * d), linear, cap, s2))
            .into_iter()
            .fold(0.0f64, f64::max);
        if width > linear {
            obs.bounds_1sigma_deg_per_frame[i] = width;
            obs.information_eigenvalues[i] = width.powi(-2);
        }
    }
    analysis.covariance = inverse_from_eigen(&obs.information_eigenvalues, &obs.eigenvectors);
}

/// The noise variance s² in the cost's units: one unit of whitened χ², or the variance the
/// covariance was scaled by.
pub(crate) fn noise_variance(source: &CovarianceSource) -> f64 {
    match *source {
        CovarianceSource::GivenSigma => 1.0,
        CovarianceSource::GivenSigmaScaled { variance_scale, .. } => variance_scale,
        CovarianceSource::ResidualVariance {
            sigma_normalised, ..
        } => sigma_normalised.powi(2),
    }
}

/// Bisection steps of a likelihood half-width (2⁻⁸ of its bracket: the bound is a 1σ figure).
const INTERVAL_BISECTIONS: usize = 8;

/// Likelihood intervals are not searched beyond this multiple of the threshold.
const INTERVAL_CAP_FACTOR: f64 = 4.0;

/// Smallest δ in (0, cap] with `rise(δ) ≥ s2` (doubling from `start`, then bisection); `cap`
/// if the cost never rises that far.
fn half_width(rise: impl Fn(f64) -> f64, start: f64, cap: f64, s2: f64) -> f64 {
    let (mut lo, mut hi) = (0.0, start.min(cap));
    // Each point once: `!(r >= s2)` also carries on past a NaN.
    while !matches!(
        rise(hi).partial_cmp(&s2),
        Some(Ordering::Greater | Ordering::Equal)
    ) {
        if hi >= cap {
            return cap;
        }
        lo = hi;
        hi = (2.0 * hi).min(cap);
    }
    for _ in 0..INTERVAL_BISECTIONS {
        let mid = 0.5 * (lo + hi);
        if rise(mid) >= s2 {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    hi
}

#[cfg(test)]
mod tests {
    use super::*;

    fn eigen_of_diag(d: [f64; 3]) -> ([f64; 3], [[f64; 3]; 3]) {
        (d, [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    }

    #[test]
    fn total_information_matches_the_inverse_of_the_total_covariance() {
        // Well conditioned: compare with inverting s² G⁻¹ + G⁻¹ C G⁻¹ directly.
        let (g, v) = eigen_of_diag([2.0, 5.0, 11.0]);
        let c = [[0.3, 0.1, 0.0], [0.1, 0.4, 0.05], [0.0, 0.05, 0.2]];
        let s2 = 1.7;
        let (info, dirs) = total_information(&g, &v, s2, &c).unwrap();
        let g_inv = [1.0 / 2.0, 1.0 / 5.0, 1.0 / 11.0];
        let cov: [[f64; 3]; 3] = std::array::from_fn(|i| {
            std::array::from_fn(|j| {
                let noise = if i == j { s2 * g_inv[i] } else { 0.0 };
                noise + g_inv[i] * c[i][j] * g_inv[j]
            })
        });
        let (var, _) = symmetric_eigen(&cov).unwrap();
        for k in 0..3 {
            let want = 1.0 / var[2 - k];
            assert!(
                (info[k] - want).abs() <= 1e-12 * want,
                "{info:?} vs {var:?}"
            );
        }
        assert!(dirs.iter().flatten().all(|x| x.is_finite()));
    }

    #[test]
    fn total_information_stays_finite_when_g_spans_many_decades() {
        // The co-orbital bisector: G's eigenvalues 1e-4 … 1e12. Inverting G first loses the
        // strongest direction to round-off (a zero or negative variance, infinite information).
        let g = [1e-4, 1.0, 1e12];
        // Eigenvectors: the body axes turned by a generic rotation (rows are unit, orthogonal).
        let r = nalgebra::Rotation3::from_euler_angles(0.3, -0.7, 1.1);
        let v: [[f64; 3]; 3] = std::array::from_fn(|k| std::array::from_fn(|i| r[(i, k)]));
        let c = [[1e-3, 2e-4, 1e-4], [2e-4, 1e-3, 3e-4], [1e-4, 3e-4, 1e-3]];
        let (info, dirs) = total_information(&g, &v, 1.0, &c).unwrap();
        assert!(info.iter().all(|x| x.is_finite() && *x > 0.0), "{info:?}");
        // Information never exceeds the noise-only Fisher information.
        assert!(info[2] <= 1e12 * (1.0 + 1e-9), "{info:?}");
        // The weak direction, the one that matters, is exact: v₀ with variance
        // 1/g₀ + v₀ᵀ C v₀ / g₀².
        let c00: f64 = (0..3)
            .flat_map(|i| (0..3).map(move |j| (i, j)))
            .map(|(i, j)| v[0][i] * c[i][j] * v[0][j])
            .sum();
        let want = 1.0 / (1.0 / g[0] + c00 / (g[0] * g[0]));
        assert!((info[0] / want - 1.0).abs() < 1e-9, "{} vs {want}", info[0]);
        let along: f64 = (0..3).map(|i| dirs[0][i] * v[0][i]).sum();
        assert!(along.abs() > 1.0 - 1e-9, "{along}");
    }
}
