//! A band fit's covariance averaged over its own interval (docs/adr/0027): unchanged where the
//! curvature holds across the interval, widened where it changes across it.

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
fn an_interval_over_which_the_curvature_changes_widens_the_covariance() {
    let (mut fit, problem) = fit_and_problem();
    // Stated 100 × wider (σ ≈ 0.003–0.03 deg/frame), its ±2σ ends reach where the light curve
    // turns differently with p: the mean variance there exceeds the centre's.
    let wide = fit
        .covariance_deg2_per_frame2
        .map(|row| row.map(|x| x * 1e4));
    fit.covariance_deg2_per_frame2 = wide;
    let largest = fit.average_over_interval(&problem, &ObservabilityConfig::default());
    assert!(largest > 1.1 && largest < 10.0, "largest ×{largest:.3}");
    let mut grew = 0;
    for (var, v) in determined(&wide) {
        let ratio = variance_along(&fit.covariance_deg2_per_frame2, &v) / var;
        assert!(ratio >= 1.0 - 1e-12, "narrowed ×{ratio:.4}");
        assert!(
            ratio <= largest * (1.0 + 1e-9),
            "×{ratio:.4} beyond the recorded ×{largest:.4}"
        );
        grew += usize::from(ratio > 1.0);
    }
    assert!(grew >= 1);
}
