//! The Cramér–Rao bound against the covariance the fit reports at the truth (noise-free, no
//! prior: the two are the same matrix), and its refusal without σ.

#[path = "../../services/inversion/tests/common/mod.rs"]
mod common;

use common::*;
use glint_inversion::stage3::{fit_single_start, Stage3Config};
use glint_inversion::{rate_error_metric, InversionError, MotionModelConfig, RateProblem};
use glint_lab::cramer_rao_bound;

#[test]
fn cramer_rao_bound_equals_the_covariance_at_the_truth() {
    let p_true = [0.0, 0.25, 0.0];
    let obs = with_noise(y_window(120), 20.0, None);
    let problem = RateProblem::new(&obs, &[band()], &MotionModelConfig::default()).expect("p");
    let crb = cramer_rao_bound(&problem, p_true).expect("crb");
    // The CRB bounds the unconstrained estimator: no prior on the weak direction here.
    let unconstrained = Stage3Config {
        hold_unobservable_at_prior: false,
        ..Default::default()
    };
    let sol = fit_single_start(&problem, p_true, &unconstrained).expect("fit");
    let fit = sol.fit().expect("determined");
    assert!(rate_error_metric(fit.rate_deg_per_frame, p_true) < 1e-8);
    for (i, &bound) in crb.iter().enumerate() {
        let sd = fit.covariance_deg2_per_frame2[i][i].sqrt();
        assert!((sd - bound).abs() <= 1e-6 * bound, "{i}: {sd} vs {bound}");
    }
    // Without σ there is no CRB.
    let bare = y_window(120);
    let problem = RateProblem::new(&bare, &[band()], &MotionModelConfig::default()).expect("p");
    assert_eq!(
        cramer_rao_bound(&problem, p_true),
        Err(InversionError::MissingSigma {
            what: "the Cramér–Rao bound"
        })
    );
}
