//! The attitude UKF with generalised Rodrigues parameters (USQUE; docs/math.md §2.8–2.9,
//! Crassidis & Markley 2003). Global state: `q_IB` (Hamilton, body → inertial) and the body
//! rate ω; local error state `[δp, ω]` (n = 6), δp the GRP of `q̂⁻¹ ⊗ q`. One scalar
//! measurement per sample: the apparent magnitude of the identified shape (eq 4-2).
//!
//! Sigma points from `(n + λ)(P + Q̄)`, `λ = 3γ² − n`. The default is γ = 1 (λ = −3, every
//! weight but the centre's positive); the patent's γ = 0.5 (λ = −5.25, centre weights −7 and
//! −4.25) is a setting: over 20 runs started from P₀ (5.7°, 1e-3 rad/s) it ended at a median
//! 1.9° with runs lost, where γ = 1 ended at 0.35° (docs/photometry.md). When `(n + λ)(P + Q̄)`
//! is not positive definite it gets a jitter (1e-12 tr P, growing); a step whose negative centre
//! weight (γ < 1) leaves a predicted covariance or innovation variance that is not positive is
//! taken again with γ = 1, and counted. Each point is propagated exactly for its constant rate,
//! `q ⊗ exp(ω Δt / 2)`; the rate is a random walk of PSD `rate_psd`.

use glint_physics::photometry::{apparent_magnitude, normalised_flux, Shape, SpecularDenominator};
use nalgebra::{Matrix3, Matrix6, UnitQuaternion, Vector3, Vector6};

use crate::grp::Grp;

/// One light-curve sample: time, magnitude and its σ, unit directions from the satellite to
/// the Sun and to the observer (inertial), range [m].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    pub t_s: f64,
    pub mag: f64,
    pub sigma_mag: f64,
    pub sun: Vector3<f64>,
    pub obs: Vector3<f64>,
    pub range_m: f64,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UkfSettings {
    /// The UT's spread γ (0–1; the patent's "usually 0.5", glint's default 1) and its β.
    pub gamma: f64,
    pub beta: f64,
    pub grp: Grp,
    /// PSD of the body rate's random walk [rad² s⁻³].
    pub rate_psd: f64,
    pub den: SpecularDenominator,
}

impl Default for UkfSettings {
    fn default() -> Self {
        UkfSettings {
            gamma: 1.0,
            beta: 2.0,
            grp: Grp::default(),
            rate_psd: 1e-12,
            den: SpecularDenominator::Linares2014,
        }
    }
}

/// What a step did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum StepOutcome {
    /// Updated with the sample: its innovation [mag] and innovation variance [mag²].
    Updated { innovation: f64, variance: f64 },
    /// Propagated only: a sigma point saw no reflected light (the magnitude is undefined).
    NoFlux,
}

/// The filter could not go on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum UkfFailure {
    #[error("the covariance is not positive definite, even with γ = 1 and a jitter")]
    Covariance,
    #[error("the state or covariance is not finite")]
    State,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Ukf {
    pub q: UnitQuaternion<f64>,
    pub w: Vector3<f64>,
    pub p: Matrix6<f64>,
    pub t_s: f64,
    pub settings: UkfSettings,
    /// Steps taken again with γ = 1 (the predicted covariance of γ < 1 was not positive
    /// definite).
    pub fallbacks: u64,
}

const N: f64 = 6.0;
/// A covariance that is not positive definite gets 1e-12 tr P, then 10× more, this many times.
const JITTER_STEPS: i32 = 7;

/// The UT's weights for γ: (λ, W₀ᵐ, W₀ᶜ, Wᵢ).
fn weights(gamma: f64, beta: f64) -> (f64, f64, f64, f64) {
    let lambda = 3.0 * gamma * gamma - N;
    let w0m = lambda / (N + lambda);
    (
        lambda,
        w0m,
        w0m + 1.0 - gamma * gamma + beta,
        1.0 / (2.0 * (N + lambda)),
    )
}

impl Ukf {
    pub fn new(
        q: UnitQuaternion<f64>,
        w: Vector3<f64>,
        p: Matrix6<f64>,
        t_s: f64,
        settings: UkfSettings,
    ) -> Self {
        Ukf {
            q,
            w,
            p,
            t_s,
            settings,
            fallbacks: 0,
        }
    }

    /// Q̄ over `dt` (math.md §2.9): the rate's random walk and its integral in δp.
    fn process_noise(&self, dt: f64) -> Matrix6<f64> {
        let q = self.settings.rate_psd;
        let mut m = Matrix6::zeros();
        let i3 = Matrix3::identity();
        m.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&(i3 * (q * dt.powi(3) / 3.0)));
        m.fixed_view_mut::<3, 3>(0, 3)
            .copy_from(&(i3 * (q * dt * dt / 2.0)));
        m.fixed_view_mut::<3, 3>(3, 0)
            .copy_from(&(i3 * (q * dt * dt / 2.0)));
        m.fixed_view_mut::<3, 3>(3, 3).copy_from(&(i3 * (q * dt)));
        m
    }

    /// The magnitude `shape` shows at attitude `q` for sample `s`; `None` without flux.
    fn magnitude(&self, shape: &Shape, q: &UnitQuaternion<f64>, s: &Sample) -> Option<f64> {
        let inv = q.inverse();
        let m = normalised_flux(shape, &(inv * s.sun), &(inv * s.obs), self.settings.den);
        apparent_magnitude(m, s.range_m)
    }

    /// Propagates to the sample's time and updates with its magnitude (steps 1–8 of §2.9). A
    /// step whose weights leave a predicted covariance that is not positive definite (a
    /// negative centre weight, γ < 1) is taken again with γ = 1 and counted.
    pub fn step(&mut self, shape: &Shape, s: &Sample) -> Result<StepOutcome, UkfFailure> {
        match self.step_with(shape, s, self.settings.gamma) {
            Err(UkfFailure::Covariance) if self.settings.gamma != 1.0 => {
                self.fallbacks += 1;
                self.step_with(shape, s, 1.0)
            }
            other => other,
        }
    }

    fn step_with(
        &mut self,
        shape: &Shape,
        s: &Sample,
        gamma: f64,
    ) -> Result<StepOutcome, UkfFailure> {
        let dt = (s.t_s - self.t_s).max(0.0);
        let qbar = self.process_noise(dt);
        // 1. Sigma points; a covariance that lost definiteness to rounding gets a jitter.
        let mut base = self.p + qbar;
        let (lambda, w0m, w0c, wi) = weights(gamma, self.settings.beta);
        let jitter = 1e-12 * base.trace().abs().max(f64::MIN_POSITIVE);
        let mut chol = ((N + lambda) * base).cholesky();
        for k in 0..JITTER_STEPS {
            if chol.is_some() {
                break;
            }
            base += Matrix6::identity() * (jitter * 10f64.powi(k));
            chol = ((N + lambda) * base).cholesky();
        }
        let chol = chol.ok_or(UkfFailure::Covariance)?;
        let l = chol.l();
        let grp = self.settings.grp;
        let mut chi: Vec<Vector6<f64>> = Vec::with_capacity(13);
        let mut centre = Vector6::zeros();
        centre.fixed_rows_mut::<3>(3).copy_from(&self.w);
        chi.push(centre);
        for i in 0..6 {
            chi.push(centre + l.column(i));
        }
        for i in 0..6 {
            chi.push(centre - l.column(i));
        }
        // 2–3. Attitudes of the points, each propagated at its own rate.
        let q_pts: Vec<UnitQuaternion<f64>> = chi
            .iter()
            .map(|c| {
                let dq = grp.to_quaternion(&c.fixed_rows::<3>(0).into());
                let w: Vector3<f64> = c.fixed_rows::<3>(3).into();
                self.q * dq * UnitQuaternion::from_scaled_axis(w * dt)
            })
            .collect();
        // 4. Back to local coordinates about the propagated centre.
        let q0_inv = q_pts[0].inverse();
        for (c, q) in chi.iter_mut().zip(&q_pts).skip(1) {
            let dp = grp.from_quaternion(&(q0_inv * q));
            c.fixed_rows_mut::<3>(0).copy_from(&dp);
        }
        chi[0].fixed_rows_mut::<3>(0).fill(0.0);
        // 5. Predicted mean and covariance.
        let weight_m = |i: usize| if i == 0 { w0m } else { wi };
        let weight_c = |i: usize| if i == 0 { w0c } else { wi };
        let x_pred: Vector6<f64> = (chi.iter().enumerate()).map(|(i, c)| c * weight_m(i)).sum();
        let mut p_pred = qbar;
        for (i, c) in chi.iter().enumerate() {
            let d = c - x_pred;
            p_pred += d * d.transpose() * weight_c(i);
        }
        if w0c < 0.0 && p_pred.cholesky().is_none() {
            return Err(UkfFailure::Covariance);
        }
        // 6. Predicted magnitudes.
        let ys: Option<Vec<f64>> = q_pts.iter().map(|q| self.magnitude(shape, q, s)).collect();
        let (x_post, p_post, outcome) = match ys {
            None => (x_pred, p_pred, StepOutcome::NoFlux),
            Some(ys) => {
                let y_hat: f64 = ys.iter().enumerate().map(|(i, y)| y * weight_m(i)).sum();
                let mut p_yy = s.sigma_mag * s.sigma_mag;
                let mut p_xy = Vector6::zeros();
                for (i, (c, y)) in chi.iter().zip(&ys).enumerate() {
                    p_yy += weight_c(i) * (y - y_hat).powi(2);
                    p_xy += (c - x_pred) * (weight_c(i) * (y - y_hat));
                }
                if p_yy.is_nan() || p_yy <= 0.0 {
                    return Err(UkfFailure::Covariance);
                }
                // 7. Update.
                let k = p_xy / p_yy;
                let innovation = s.mag - y_hat;
                (
                    x_pred + k * innovation,
                    p_pred - k * k.transpose() * p_yy,
                    StepOutcome::Updated {
                        innovation,
                        variance: p_yy,
                    },
                )
            }
        };
        // 8. Reset the attitude error into the quaternion.
        let q_new = q_pts[0] * grp.to_quaternion(&x_post.fixed_rows::<3>(0).into());
        let w_new: Vector3<f64> = x_post.fixed_rows::<3>(3).into();
        let p_new = (p_post + p_post.transpose()) * 0.5;
        if !(q_new.coords.iter().all(|v| v.is_finite())
            && w_new.iter().all(|v| v.is_finite())
            && p_new.iter().all(|v| v.is_finite()))
        {
            return Err(UkfFailure::State);
        }
        self.q = q_new;
        self.w = w_new;
        self.p = p_new;
        self.t_s = s.t_s;
        Ok(outcome)
    }

    /// The error against a true attitude and rate as the filter's local state `[δp, δω]`.
    pub fn error_to(&self, q_true: &UnitQuaternion<f64>, w_true: &Vector3<f64>) -> Vector6<f64> {
        let mut e = Vector6::zeros();
        e.fixed_rows_mut::<3>(0).copy_from(
            &self
                .settings
                .grp
                .from_quaternion(&(self.q.inverse() * q_true)),
        );
        e.fixed_rows_mut::<3>(3).copy_from(&(w_true - self.w));
        e
    }

    /// NEES against the truth; `None` if P is not positive definite.
    pub fn nees(&self, q_true: &UnitQuaternion<f64>, w_true: &Vector3<f64>) -> Option<f64> {
        let e = self.error_to(q_true, w_true);
        Some(e.dot(&self.p.cholesky()?.solve(&e)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_patents_weights_and_the_fallback() {
        let (lambda, w0m, w0c, wi) = weights(0.5, 2.0);
        assert_eq!((lambda, w0m, w0c, wi), (-5.25, -7.0, -4.25, 2.0 / 3.0));
        assert!((w0m + 12.0 * wi - 1.0).abs() < 1e-15);
        let (lambda, w0m, w0c, wi) = weights(1.0, 2.0);
        assert_eq!((lambda, w0m, w0c, wi), (-3.0, -1.0, 1.0, 1.0 / 6.0));
    }
}
