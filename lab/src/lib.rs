//! glint-lab: how good the attitude solve's estimator is, beside the solve itself.
//!
//! The product (`glint run`, `glint invert`, the inversion service) reports one answer with its
//! covariance; this crate holds the analyses `glint lab` scores that answer with over many noisy
//! runs: the Cramér–Rao bound of the rates ([`cramer_rao_bound`]) and the
//! Hammersley–Chapman–Robbins bound where the light curve is not linear over the scatter the
//! noise allows ([`chapman_robbins`]). Nothing here runs on the default path.

pub mod chapman_robbins;

use glint_inversion::lm::normal_equations;
use glint_inversion::observability::{inverse_from_eigen, symmetric_eigen};
use glint_inversion::{InversionError, RateProblem};

/// Cramér–Rao bound `sqrt(diag((JᵀWJ)⁻¹))` \[deg/frame\] at the true rates, using the
/// observations' σ (which the problem must carry).
pub fn cramer_rao_bound(
    problem: &RateProblem,
    p_true_deg_per_frame: [f64; 3],
) -> Result<[f64; 3], InversionError> {
    if !problem.sigma_given() {
        return Err(InversionError::MissingSigma {
            what: "the Cramér–Rao bound",
        });
    }
    let n = problem.residual_count();
    let mut r = vec![0.0; n];
    let mut jac = vec![[0.0; 3]; n];
    problem.residuals_and_jacobian(p_true_deg_per_frame, &mut r, &mut jac);
    let (fisher, _) = normal_equations(&jac, &r);
    let (vals, vecs) = symmetric_eigen(&fisher)?;
    let cov = inverse_from_eigen(&vals, &vecs);
    Ok([0, 1, 2].map(|i| cov[i][i].sqrt()))
}
