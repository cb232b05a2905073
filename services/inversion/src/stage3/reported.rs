//! The profile-likelihood intervals a fit reports once the solve's decisions are taken
//! (docs/adr/0017; the walk itself is [`crate::observability::profiled_bounds`]).

use super::{RateFit, RateSolution, Stage3Config};
use crate::model::RateProblem;
use crate::observability::profiled_bounds;
use std::cmp::Ordering;

impl RateFit {
    /// Computes the profile-likelihood half-widths on `problem`, the one this fit was made on
    /// (docs/adr/0017), and holds them for [`RateFit::report_profile`]. Costs a few dozen
    /// Jacobians, so the solve calls it on the answers it may report, not on every fit.
    pub fn attach_profile(&mut self, problem: &RateProblem) {
        self.profiled_bounds_deg_per_frame = profiled_bounds(
            problem,
            self.rate_deg_per_frame,
            &self.observability,
            &self.covariance_source,
        );
    }

    /// Reports the profile-likelihood half-widths (docs/adr/0017): along each determined
    /// direction v_i whose profile interval δ_i is wider than the reported 1σ, the bound becomes
    /// δ_i and the covariance's variance along v_i becomes δ_i² (the covariance is diagonal in
    /// the v_i, `variance_scale` times their bounds² after [`widen_to_joint`](super::widen_to_joint)). The decisions
    /// read the local covariance, so the solve calls this once they are all taken. Returns
    /// whether anything widened.
    pub fn report_profile(&mut self, variance_scale: f64) -> bool {
        let Some(profiled) = self.profiled_bounds_deg_per_frame.take() else {
            return false;
        };
        let obs = &mut self.observability;
        let mut widened = false;
        for (i, &width) in profiled.iter().enumerate() {
            let variance = variance_scale * obs.bounds_1sigma_deg_per_frame[i].powi(2);
            let wider = matches!(
                (width * width).partial_cmp(&variance),
                Some(Ordering::Greater)
            );
            if obs.unobservable[i] || !wider {
                continue;
            }
            let v = obs.eigenvectors[i];
            let added = width * width - variance;
            for (row, vr) in self.covariance_deg2_per_frame2.iter_mut().zip(v) {
                for (c, vc) in row.iter_mut().zip(v) {
                    *c += added * vr * vc;
                }
            }
            obs.bounds_1sigma_deg_per_frame[i] = obs.bounds_1sigma_deg_per_frame[i].max(width);
            obs.information_eigenvalues[i] = obs.bounds_1sigma_deg_per_frame[i].powi(-2);
            // An interval this wide no longer determines the direction.
            obs.unobservable[i] = obs.bounds_1sigma_deg_per_frame[i] > obs.threshold_deg_per_frame;
            widened = true;
        }
        widened
    }
}

impl RateSolution {
    /// [`RateFit::attach_profile`] on a determined answer, when `config.profile_intervals`
    /// asks for it.
    pub(crate) fn attach_profile_if_asked(&mut self, problem: &RateProblem, config: &Stage3Config) {
        if let (true, RateSolution::Determined(fit)) = (config.profile_intervals, self) {
            fit.attach_profile(problem);
        }
    }

    /// [`RateFit::report_profile`] on a determined answer (a no-op without an attached profile).
    pub(crate) fn report_profile(&mut self, variance_scale: f64) {
        if let RateSolution::Determined(fit) = self {
            fit.report_profile(variance_scale);
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::stage3::fixtures::with_covariance;

    #[test]
    fn reporting_the_profile_sets_each_wider_direction_s_variance_and_keeps_the_rest() {
        let (b, scale) = ([0.01, 0.002, 0.001], 2.0);
        let cov = [
            [scale * b[0] * b[0], 0.0, 0.0],
            [0.0, scale * b[1] * b[1], 0.0],
            [0.0, 0.0, scale * b[2] * b[2]],
        ];
        let mut fit = with_covariance([0.0, 0.25, 0.0], cov);
        fit.observability.bounds_1sigma_deg_per_frame = b;
        fit.observability.information_eigenvalues = b.map(|x| x.powi(-2));
        // x: narrower than its widened variance (kept); y: 3 × its bound; z: beyond the
        // threshold (no longer determined).
        fit.profiled_bounds_deg_per_frame = Some([0.012, 0.006, 0.4]);
        assert!(fit.report_profile(scale));
        let c = fit.covariance_deg2_per_frame2;
        assert_eq!(c[0][0], scale * b[0] * b[0]);
        assert!((c[1][1] - 0.006f64.powi(2)).abs() < 1e-18, "{c:?}");
        assert!((c[2][2] - 0.4f64.powi(2)).abs() < 1e-15, "{c:?}");
        assert_eq!(c[0][1], 0.0);
        let obs = &fit.observability;
        assert_eq!(obs.bounds_1sigma_deg_per_frame, [0.01, 0.006, 0.4]);
        assert_eq!(obs.unobservable, [false, false, true]);
        // Reported once: the held widths are gone.
        assert!(fit.profiled_bounds_deg_per_frame.is_none());
        assert!(!fit.report_profile(scale));
    }
}
