//! A fit's covariance averaged over its own interval: λ*'s (docs/adr/0027) and the joint
//! fit's (docs/adr/0028).
//!
//! The local covariance of a fit is the inverse of the light curve's curvature at p̂. That is
//! the estimator's scatter only where the curvature holds over the region the estimate could
//! have landed in. About Z it does not everywhere: near w_y = 0 a band's information has a
//! ridge, up to 70 × the median run's, and a run that stage 1's noise moves onto the ridge
//! reports the ridge's curvature while its scatter is the region's (docs/adr/0026). About Y
//! the joint fit's information grows away from p₀, where the light curve is flat in w_z to
//! first order.
//!
//! Along each determined eigen-direction v of the fit's covariance (1σ = σ_v), the variance is
//! therefore multiplied by the mean of the local variances along v at p̂ and at
//! p̂ ± [`INTERVAL_SIGMAS`]·σ_v·v over the centre's, when that ratio exceeds 1. The local
//! variances come from the fit's information at each point (on its own problem: one band, or
//! every band) restricted to the fit's determined directions. Where the curvature is the same
//! across the interval (a model linear in p) nothing changes. The decisions read the local
//! covariance: the average is held on the fit ([`RateFit::attach_interval_average`]) and
//! `fit_rates` reports it once they are all taken ([`RateFit::report_interval_average`]).

use super::{RateFit, RateSolution, Stage3Config};
use crate::model::RateProblem;
use crate::observability::{analyse, noise_variance, ObservabilityConfig};
use nalgebra::{DMatrix, Matrix3, Vector3};

/// Half-width of the interval the variance is averaged over, in the fit's own σ (about 95 %).
pub const INTERVAL_SIGMAS: f64 = 2.0;

/// The variance reported along a direction: the mean of the local variances at the centre and
/// at the interval's ends that could be evaluated (`ends`, finite ones only), or the centre's
/// when it is the larger.
pub fn interval_variance(centre: f64, ends: &[f64]) -> f64 {
    let usable: Vec<f64> = ends.iter().copied().filter(|v| v.is_finite()).collect();
    let mean = (centre + usable.iter().sum::<f64>()) / (1 + usable.len()) as f64;
    mean.max(centre)
}

impl RateFit {
    /// Averages the covariance over the fit's interval on `problem` ([`Self::average_over_interval`])
    /// and holds the result on the fit until [`Self::report_interval_average`]: the covariance
    /// the decisions read stays the local one.
    pub fn attach_interval_average(&mut self, problem: &RateProblem, config: &ObservabilityConfig) {
        let mut averaged = self.clone();
        let scale = averaged.average_over_interval(problem, config);
        self.interval_average = Some((averaged.covariance_deg2_per_frame2, scale));
    }

    /// Reports the average [`Self::attach_interval_average`] held: the covariance becomes it and
    /// `interval_variance_scale` records its factor. A no-op when none is held.
    pub fn report_interval_average(&mut self) {
        if let Some((covariance, scale)) = self.interval_average.take() {
            self.covariance_deg2_per_frame2 = covariance;
            self.interval_variance_scale = Some(scale);
        }
    }

    /// Averages the covariance over the fit's interval on `problem`, the problem it was made
    /// on (module docs). Directions the fit does not determine are left alone, and the
    /// observability stays the local Fisher analysis at p̂. Returns the largest factor a
    /// variance grew by (1 when none did) and records it on the fit.
    pub fn average_over_interval(
        &mut self,
        problem: &RateProblem,
        config: &ObservabilityConfig,
    ) -> f64 {
        let bound = config.unobservable_bound_deg_per_frame;
        let covariance = Matrix3::from(self.covariance_deg2_per_frame2);
        let eigen = covariance.symmetric_eigen();
        let determined: Vec<(f64, Vector3<f64>)> = (0..3)
            .map(|k| {
                (
                    eigen.eigenvalues[k],
                    eigen.eigenvectors.column(k).into_owned(),
                )
            })
            .filter(|(var, _)| *var > 0.0 && var.sqrt() <= bound)
            .collect();
        let basis: Vec<Vector3<f64>> = determined.iter().map(|(_, v)| *v).collect();
        let p = Vector3::from(self.rate_deg_per_frame);
        let mut out = covariance;
        let mut largest = 1.0f64;
        let Some(centre) = subspace_variances_at(problem, p.into(), &basis, config) else {
            self.interval_variance_scale = Some(largest);
            return largest;
        };
        for (k, (var, v)) in determined.iter().enumerate() {
            let step = INTERVAL_SIGMAS * var.sqrt();
            let ends = [-1.0, 1.0].map(|sign| {
                subspace_variances_at(problem, (p + sign * step * v).into(), &basis, config)
                    .map_or(f64::NAN, |w| w[k])
            });
            let factor = interval_variance(centre[k], &ends) / centre[k];
            let want = var * factor;
            if factor.is_finite() && factor > 1.0 && want.sqrt() <= bound {
                out += (want - var) * v * v.transpose();
                largest = largest.max(factor);
            }
        }
        self.covariance_deg2_per_frame2 = out.into();
        self.interval_variance_scale = Some(largest);
        largest
    }
}

impl RateSolution {
    /// [`RateFit::attach_interval_average`] on a determined answer, when
    /// `config.average_over_interval` asks for it.
    pub(crate) fn attach_interval_average_if_asked(
        &mut self,
        problem: &RateProblem,
        config: &Stage3Config,
    ) {
        if let (true, RateSolution::Determined(fit)) = (config.average_over_interval, self) {
            fit.attach_interval_average(problem, &config.observability);
        }
    }

    /// [`RateFit::report_interval_average`] on a determined answer (a no-op without one held).
    pub(crate) fn report_interval_average(&mut self) {
        if let RateSolution::Determined(fit) = self {
            fit.report_interval_average();
        }
    }
}

/// The variances along the orthonormal `basis` (the fit's determined directions) at `q`, from
/// the band's information there restricted to that subspace: the directions the fit holds
/// under its prior stay held, so their weak information does not leak into the others. At unit
/// noise variance (whatever the analysis at q took it to be): q is off the minimum, and its
/// residuals' excess, or their correlation, is the offset's, not noise.
fn subspace_variances_at(
    problem: &RateProblem,
    q: [f64; 3],
    basis: &[Vector3<f64>],
    config: &ObservabilityConfig,
) -> Option<Vec<f64>> {
    let analysis = analyse(problem, q, config).ok()?;
    let obs = &analysis.observability;
    let mut information = Matrix3::zeros();
    for i in 0..3 {
        let lam = obs.information_eigenvalues[i];
        if lam.is_finite() && lam > 0.0 {
            let u = Vector3::from(obs.eigenvectors[i]);
            information += lam * u * u.transpose();
        }
    }
    let n = basis.len();
    let restricted = DMatrix::from_fn(n, n, |a, b| {
        (basis[a].transpose() * information * basis[b])[0]
    });
    let covariance = restricted.try_inverse()?;
    let scale = noise_variance(&analysis.source);
    let variances: Vec<f64> = (0..n).map(|k| covariance[(k, k)] / scale).collect();
    variances
        .iter()
        .all(|v| v.is_finite() && *v > 0.0)
        .then_some(variances)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_mean_over_the_interval_widens_only() {
        // The curvature holds across the interval: nothing changes.
        assert_eq!(interval_variance(4.0, &[4.0, 4.0]), 4.0);
        // On a ridge: the ends see 9 and 25 times the centre's variance.
        assert_eq!(interval_variance(1.0, &[9.0, 25.0]), 35.0 / 3.0);
        // Sharper at the ends than at the centre: the centre's variance stands.
        assert_eq!(interval_variance(4.0, &[1.0, 2.0]), 4.0);
        // An end that could not be evaluated is left out of the mean.
        assert_eq!(interval_variance(1.0, &[f64::NAN, 7.0]), 4.0);
        assert_eq!(interval_variance(1.0, &[f64::NAN, f64::INFINITY]), 1.0);
    }
}
