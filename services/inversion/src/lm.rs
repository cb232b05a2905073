//! Levenberg–Marquardt for the three rate parameters (docs/math.md §1.6 \[REC\], adapted).
//!
//! ```text
//! A = JᵀJ,  g = Jᵀr,  D = diag(max(A_ii, 1e-12·max_j A_jj))
//! (A + λ D) δ = g                         (Marquardt scaling; Cholesky via faer)
//! ε(p + δ) < ε(p) ⇒ accept, λ ← λ/10;   otherwise λ ← 10 λ and re-solve with the same J
//! ```
//!
//! λ starts at `lambda_init` (dimensionless, 1e-3). §1.6 step 2 writes λ₀ = 1e-3·max diag(JᵀJ)
//! *and* multiplies by diag(JᵀJ), mixing Nielsen's and Marquardt's conventions; with Marquardt's
//! scaling the dimensionless λ₀ = 1e-3 is the equivalent choice.
//!
//! Stopping rules (§1.6 step 5, adapted): k = k_max outer iterations (Jacobian evaluations);
//! ε < `cost_tol` (normalised or whitened units); an accepted step with ‖δ‖ < `step_tol`(1 + ‖p‖);
//! an accepted step with relative decrease (ε_old − ε_new)/ε_old < `rel_decrease_tol`; or no
//! decrease possible (λ > `lambda_max`); or the undamped Gauss–Newton step predicts a relative
//! decrease `gᵀ(JᵀJ)⁻¹g/ε < rel_decrease_tol` (stationary; saves the tail of rejected trials).

use crate::error::InversionError;
use crate::model::RateProblem;
use faer::linalg::solvers::Solve;
use faer::{Mat, Side};
use serde::{Deserialize, Serialize};

/// LM settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LmConfig {
    /// k_max, outer iterations (1..=10000; 500). The seed's 5000 only lets LM creep along the
    /// weakly observable bisector direction; a well-posed 3-parameter fit converges in tens.
    pub max_iterations: usize,
    /// Stop when ε < this (seed: 1e-22, in normalised units).
    pub cost_tol: f64,
    /// Stop when ‖δ‖ < step_tol·(1 + ‖p‖) \[deg/frame\] (1e-12).
    pub step_tol: f64,
    /// Stop when the relative cost decrease of an accepted step is below this (1e-15).
    pub rel_decrease_tol: f64,
    /// Initial damping λ₀ (dimensionless, > 0; 1e-3).
    pub lambda_init: f64,
    /// Give up increasing λ beyond this (1e16).
    pub lambda_max: f64,
}

impl Default for LmConfig {
    fn default() -> Self {
        Self {
            max_iterations: 500,
            cost_tol: 1e-22,
            step_tol: 1e-12,
            rel_decrease_tol: 1e-15,
            lambda_init: 1e-3,
            lambda_max: 1e16,
        }
    }
}

/// Why the iteration ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StopReason {
    /// k_max reached.
    MaxIterations,
    /// ε below `cost_tol`.
    CostBelowTolerance,
    /// Step below `step_tol`.
    SmallStep,
    /// Relative decrease below `rel_decrease_tol`.
    SmallDecrease,
    /// No step decreases ε (λ > `lambda_max`).
    NoDecrease,
    /// Even the undamped Gauss–Newton step predicts a relative decrease below
    /// `rel_decrease_tol`: p is stationary.
    Stationary,
    /// Stopped by the caller (e.g. a start that rejoins a known solution).
    Abandoned,
}

/// Result of one LM run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LmOutcome {
    /// Final p \[deg/frame\].
    pub p_deg_per_frame: [f64; 3],
    /// Final ε(p).
    pub cost: f64,
    /// Outer iterations performed.
    pub iterations: usize,
    /// Stopping rule that fired.
    pub stop: StopReason,
}

/// Floor of λ after accepted steps (bounds the climb back after a late rejection).
const LAMBDA_MIN: f64 = 1e-15;

/// Normal matrix `JᵀJ` and gradient `Jᵀr`.
pub fn normal_equations(jac: &[[f64; 3]], r: &[f64]) -> ([[f64; 3]; 3], [f64; 3]) {
    let mut a = [[0.0; 3]; 3];
    let mut g = [0.0; 3];
    for (row, &res) in jac.iter().zip(r) {
        for i in 0..3 {
            g[i] += row[i] * res;
            for j in 0..3 {
                a[i][j] += row[i] * row[j];
            }
        }
    }
    (a, g)
}

/// Solves `(A + λ D) δ = g` by Cholesky; `None` if not positive definite or not finite.
fn damped_step(a: &[[f64; 3]; 3], g: &[f64; 3], lambda: f64) -> Option<[f64; 3]> {
    let max_diag = (0..3).map(|i| a[i][i]).fold(0.0, f64::max);
    let floor = (1e-12 * max_diag).max(f64::MIN_POSITIVE);
    let m = Mat::from_fn(3, 3, |i, j| {
        a[i][j]
            + if i == j {
                lambda * a[i][i].max(floor)
            } else {
                0.0
            }
    });
    let llt = m.llt(Side::Lower).ok()?;
    let rhs = Mat::from_fn(3, 1, |i, _| g[i]);
    let x = llt.solve(rhs);
    let d = [x[(0, 0)], x[(1, 0)], x[(2, 0)]];
    d.iter().all(|v| v.is_finite()).then_some(d)
}

fn norm(v: &[f64; 3]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// Undamped Gauss–Newton predicted decrease `gᵀA⁻¹g` (∞ when A is singular).
fn gauss_newton_decrease(a: &[[f64; 3]; 3], g: &[f64; 3]) -> f64 {
    match damped_step(a, g, 0.0) {
        Some(d) => (0..3).map(|i| d[i] * g[i]).sum(),
        None => f64::INFINITY,
    }
}

/// Runs LM from `p0` \[deg/frame\].
pub fn levenberg_marquardt(
    problem: &RateProblem,
    p0: [f64; 3],
    config: &LmConfig,
) -> Result<LmOutcome, InversionError> {
    levenberg_marquardt_with(problem, p0, config, |_, _, _| false)
}

/// LM with a caller test `abandon(p, cost, k)` checked after every accepted step.
pub fn levenberg_marquardt_with(
    problem: &RateProblem,
    p0: [f64; 3],
    config: &LmConfig,
    abandon: impl FnMut(&[f64; 3], f64, usize) -> bool,
) -> Result<LmOutcome, InversionError> {
    levenberg_marquardt_prior(problem, p0, config, &Prior::default(), abandon)
}

/// A point prior `u·p = 0` on given unit directions u, as pseudo-measurements of weight
/// `weight` [cost units per (deg/frame)²]: the way a direction the data cannot determine is
/// held at a stated value instead of drifting (math.md §1.6 on the sun–observer bisector).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Prior {
    pub directions: Vec<[f64; 3]>,
    pub weight: f64,
}

impl Prior {
    fn cost(&self, p: &[f64; 3]) -> f64 {
        self.directions
            .iter()
            .map(|u| self.weight * (0..3).map(|i| u[i] * p[i]).sum::<f64>().powi(2))
            .sum()
    }

    /// Adds the pseudo-measurements to the normal equations (A += w u uᵀ, g −= w u (u·p)).
    fn add(&self, p: &[f64; 3], a: &mut [[f64; 3]; 3], g: &mut [f64; 3]) {
        for u in &self.directions {
            let up: f64 = (0..3).map(|i| u[i] * p[i]).sum();
            for i in 0..3 {
                g[i] -= self.weight * u[i] * up;
                for j in 0..3 {
                    a[i][j] += self.weight * u[i] * u[j];
                }
            }
        }
    }
}

/// LM on the data cost plus a [`Prior`].
pub fn levenberg_marquardt_prior(
    problem: &RateProblem,
    p0: [f64; 3],
    config: &LmConfig,
    prior: &Prior,
    mut abandon: impl FnMut(&[f64; 3], f64, usize) -> bool,
) -> Result<LmOutcome, InversionError> {
    let n = problem.residual_count();
    let mut r = vec![0.0; n];
    let mut jac = vec![[0.0; 3]; n];
    let (mut r_try, mut jac_try) = (r.clone(), jac.clone());
    let mut p = p0;
    let mut cost = problem.residuals_and_jacobian(p, &mut r, &mut jac) + prior.cost(&p);
    if !cost.is_finite() {
        return Err(InversionError::Diverged {
            iterations: 0,
            cost,
        });
    }
    let mut lambda = config.lambda_init;
    let outcome = |p, cost, iterations, stop| LmOutcome {
        p_deg_per_frame: p,
        cost,
        iterations,
        stop,
    };
    for k in 1..=config.max_iterations {
        if cost < config.cost_tol {
            return Ok(outcome(p, cost, k - 1, StopReason::CostBelowTolerance));
        }
        let (mut a, mut g) = normal_equations(&jac, &r);
        prior.add(&p, &mut a, &mut g);
        if gauss_newton_decrease(&a, &g) < config.rel_decrease_tol * cost {
            return Ok(outcome(p, cost, k - 1, StopReason::Stationary));
        }
        loop {
            let step = damped_step(&a, &g, lambda);
            let Some(delta) = step else {
                lambda *= 10.0;
                if lambda > config.lambda_max {
                    return Ok(outcome(p, cost, k, StopReason::NoDecrease));
                }
                continue;
            };
            let p_new = [p[0] + delta[0], p[1] + delta[1], p[2] + delta[2]];
            // Value and Jacobian cost the same (the lobes dominate), so trials carry J along.
            // A non-finite trial cost compares false and counts as a rejection.
            // A trial stops once its partial cost passes ε(p): rejected either way.
            let cost_new =
                problem.residuals_and_jacobian_within(p_new, &mut r_try, &mut jac_try, cost)
                    + prior.cost(&p_new);
            if cost_new < cost {
                let rel = (cost - cost_new) / cost;
                let small_step = norm(&delta) < config.step_tol * (1.0 + norm(&p));
                p = p_new;
                cost = cost_new;
                std::mem::swap(&mut r, &mut r_try);
                std::mem::swap(&mut jac, &mut jac_try);
                lambda = (lambda / 10.0).max(LAMBDA_MIN);
                if small_step {
                    return Ok(outcome(p, cost, k, StopReason::SmallStep));
                }
                if rel < config.rel_decrease_tol {
                    return Ok(outcome(p, cost, k, StopReason::SmallDecrease));
                }
                if abandon(&p, cost, k) {
                    return Ok(outcome(p, cost, k, StopReason::Abandoned));
                }
                break;
            }
            if norm(&delta) < config.step_tol * (1.0 + norm(&p)) {
                return Ok(outcome(p, cost, k, StopReason::SmallStep));
            }
            lambda *= 10.0;
            if lambda > config.lambda_max {
                return Ok(outcome(p, cost, k, StopReason::NoDecrease));
            }
        }
    }
    Ok(outcome(
        p,
        cost,
        config.max_iterations,
        StopReason::MaxIterations,
    ))
}
