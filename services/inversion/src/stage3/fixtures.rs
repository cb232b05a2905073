//! Stage-3 results for unit tests: a determined fit at a given rate, with a covariance and a
//! mirror where the test needs them.

use crate::lm::StopReason;
use crate::observability::{CovarianceSource, Observability};
use crate::stage3::{RateFit, RateSolution};

/// A determined fit at `p` (zero covariance, isotropic observability) with `mirror`.
pub(crate) fn solution(p: [f64; 3], mirror: Option<[f64; 3]>) -> RateSolution {
    RateSolution::Determined(RateFit {
        wavelengths_nm: vec![400.0],
        rate_deg_per_frame: p,
        covariance_deg2_per_frame2: [[0.0; 3]; 3],
        covariance_source: CovarianceSource::GivenSigma,
        cost: 1.0,
        iterations: 1,
        total_iterations: 1,
        stop: StopReason::SmallStep,
        grid_points: 0,
        starts_screened: 0,
        starts_polished: 1,
        start_deg_per_frame: p,
        observability: Observability {
            information_eigenvalues: [1.0; 3],
            eigenvectors: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            bounds_1sigma_deg_per_frame: [1.0; 3],
            unobservable: [false; 3],
            threshold_deg_per_frame: 0.25,
            condition_number: 1.0,
            rms_sensitivity_per_deg_per_frame: 1.0,
        },
        held_directions: vec![],
        mirror_deg_per_frame: mirror,
        hold_start_deg_per_frame: None,
        refit: None,
    })
}

/// A determined fit at `p` with covariance `cov`.
pub(crate) fn with_covariance(p: [f64; 3], cov: [[f64; 3]; 3]) -> RateFit {
    let RateSolution::Determined(mut f) = solution(p, None) else {
        unreachable!()
    };
    f.covariance_deg2_per_frame2 = cov;
    f
}

/// "Unobservable: no glint" with the lobes carrying `share` of the sensitivity.
pub(crate) fn no_glint(share: f64) -> RateSolution {
    let RateSolution::Determined(f) = solution([0.0; 3], None) else {
        unreachable!()
    };
    RateSolution::Unobservable {
        reason: crate::observability::UnobservableReason::NoGlint {
            lobe_sensitivity_share: share,
        },
        bounds_deg_per_frame: f.observability.bounds_1sigma_deg_per_frame,
        observability: f.observability,
        wavelengths_nm: f.wavelengths_nm,
    }
}
