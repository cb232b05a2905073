//! A band fit's covariance averaged over its own interval (docs/adr/0027): unchanged where the
//! curvature holds across the interval, widened to the interval's mean where the covariance is
//! sharper than the curvature around it.

mod common;

use common::*;
use glint_inversion::observability::{symmetric_eigen, ObservabilityConfig};
use glint_inversion::stage3::{fit_multistart, Stage3Config};
use glint_inversion::{MotionModelConfig, RateFit, RateProblem, RateSolution};

/// The paper's Y case, noise-free, σ = mean flux / 20: a fit at the exact rate with its local
/// covariance.
fn fit_and_problem() -> (RateFit, RateProblem) {
    let obs = with_noise(y_window(360), 20.0, None);
    let problem =
        RateProblem::new(&obs, &[band()], &MotionModelConfig::default()).expect("problem");
    let RateSolution::Determined(fit) =
        fit_multistart(&problem, &Stage3Config::default()).expect("fit")
    else {
        panic!("the Y case is determined");
    };
    (fit, problem)
}

/// The determined eigen-directions of `cov` (1σ within the observability threshold) with
/// their variances.
fn determined(cov: &[[f64; 3]; 3]) -> Vec<(f64, [f64; 3])> {
    let bound = ObservabilityConfig::default().unobservable_bound_deg_per_frame;
    let (vals, vecs) = symmetric_eigen(cov).expect("eigen");
    (0..3)
        .filter(|&k| vals[k] > 0.0 && vals[k].sqrt() <= bound)
        .map(|k| (vals[k], vecs[k]))
        .collect()
}

fn variance_along(cov: &[[f64; 3]; 3], v: &[f64; 3]) -> f64 {
    (0..3)
        .map(|i| (0..3).map(|j| v[i] * cov[i][j] * v[j]).sum::<f64>())
        .sum()
}

#[test]
fn a_covariance_the_curvature_holds_across_is_kept() {
    let (mut fit, problem) = fit_and_problem();
    let local = fit.covariance_deg2_per_frame2;
    let directions = determined(&local);
    assert_eq!(directions.len(), 2, "Y: two determined directions, X held");
    let largest = fit.average_over_interval(&problem, &ObservabilityConfig::default());
    assert_eq!(fit.interval_variance_scale, Some(largest));
    for (var, v) in &directions {
        let after = variance_along(&fit.covariance_deg2_per_frame2, v);
        // Never narrowed; widened by no more than the curvature's variation over ±2σ.
        assert!(after >= var * (1.0 - 1e-12), "{after:e} < {var:e}");
        assert!(after <= var * 1.05, "widened {:.3}×", after / var);
    }
}

#[test]
fn a_covariance_sharper_than_the_curvature_around_it_is_widened_to_the_mean() {
    let (mut fit, problem) = fit_and_problem();
    let local = fit.covariance_deg2_per_frame2;
    // A hundred times too sharp: its ±2σ ends are a tenth of the local σ from p̂, where the
    // local variance is the centre's own, so the mean is (1/100 + 1 + 1)/3 of it.
    fit.covariance_deg2_per_frame2 = local.map(|row| row.map(|x| x / 100.0));
    let largest = fit.average_over_interval(&problem, &ObservabilityConfig::default());
    let want = (0.01 + 2.0) / 3.0;
    for (var, v) in determined(&local) {
        let ratio = variance_along(&fit.covariance_deg2_per_frame2, &v) / var;
        assert!(
            (ratio - want).abs() < 0.02 * want,
            "{ratio:.4} against {want:.4}"
        );
    }
    assert!(
        (largest - 100.0 * want).abs() < 2.0 * want,
        "largest ×{largest:.1}"
    );
}
