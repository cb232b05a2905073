//! Position–velocity Kalman filter on the line-of-sight angles (docs/math.md §3.6, eqs 11–15,
//! with the FIXED Φ and H).
//!
//! State `X = [α, α̇, β, β̇]ᵀ` (rad, rad/s). For a step T (variable; T = t_ep + t_in = 0.04 s per
//! frame in the seed):
//!
//! ```text
//! Φ = [[1,T,0,0],[0,1,0,0],[0,0,1,T],[0,0,0,1]]     (row 3 fixed: the seed prints [1,0,1,T])
//! Γ = [[0,0],[T,0],[0,0],[0,T]]                     (seed; or the piecewise-constant-
//!                                                     acceleration [[T²/2,0],[T,0],[0,T²/2],[0,T]])
//! H = [[1,0,0,0],[0,0,1,0]]                         (fixed: the seed says "identity")
//! Q = q_a I₂ (angular-acceleration noise),  R = σ² I₂
//! P⁻ = Φ P Φᵀ + Γ Q Γᵀ,   K = P⁻Hᵀ(H P⁻ Hᵀ + R)⁻¹,   X⁺ = X⁻ + K (Z − H X⁻)
//! P⁺ = (I − KH) P⁻ (I − KH)ᵀ + K R Kᵀ               (Joseph form, then symmetrised)
//! ```
//!
//! Initialisation from the first two frames (t₁ < t₂): `α̂ = Z₂`, `α̇ = (Z₂ − Z₁)/(t₂ − t₁)`, and
//! likewise for β, with the covariance of that map: `var α = σ²`, `cov(α, α̇) = σ²/T`,
//! `var α̇ = 2σ²/T²`. The azimuth innovation is wrapped to (−π, π].

use nalgebra::{Matrix2, Matrix2x4, Matrix4, Matrix4x2, Vector2, Vector4};

/// Which Γ maps the angular-acceleration noise into the state.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GammaModel {
    /// `[[0,0],[T,0],[0,0],[0,T]]` (the seed's eq 11).
    #[default]
    Seed,
    /// `[[T²/2,0],[T,0],[0,T²/2],[0,T]]`.
    PiecewiseConstantAcceleration,
}

/// Noise model of the angle filter.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AngleFilterConfig {
    /// q_a: variance of the angular acceleration noise per axis \[rad²/s⁴\], ≥ 0.
    /// Default (1e-3)² (§3.6 \[ASSUMP\]).
    pub accel_noise_var_rad2_s4: f64,
    /// σ of each angle measurement \[rad\], > 0. Default 1.7e-4 (≈ 1 px, §3.5).
    pub measurement_sigma_rad: f64,
    pub gamma: GammaModel,
}

impl Default for AngleFilterConfig {
    fn default() -> Self {
        Self {
            accel_noise_var_rad2_s4: 1e-6,
            measurement_sigma_rad: 1.7e-4,
            gamma: GammaModel::Seed,
        }
    }
}

impl AngleFilterConfig {
    pub fn validate(&self) -> Result<(), crate::ConfigError> {
        let q = self.accel_noise_var_rad2_s4;
        if !(q.is_finite() && q >= 0.0) {
            return Err(crate::ConfigError::new("accel_noise_var_rad2_s4", q, "≥ 0"));
        }
        let s = self.measurement_sigma_rad;
        if !(s.is_finite() && s > 0.0) {
            return Err(crate::ConfigError::new("measurement_sigma_rad", s, "> 0"));
        }
        Ok(())
    }
}

/// One (α, β) measurement.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AngleMeasurement {
    pub t_s: f64,
    pub azimuth_rad: f64,
    pub elevation_rad: f64,
}

/// Angle-filter failure.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FilterError {
    #[error("time goes backwards: filter at {filter_t_s} s, asked for {t_s} s")]
    TimeReversed { filter_t_s: f64, t_s: f64 },
    #[error("the two initial measurements need t₂ > t₁ (got {t1_s} s and {t2_s} s)")]
    BadInitialStep { t1_s: f64, t2_s: f64 },
    #[error("non-finite {what}")]
    NonFinite { what: &'static str },
    #[error("innovation covariance is not positive definite")]
    SingularInnovation,
    #[error("invalid configuration: {0}")]
    Config(#[from] crate::ConfigError),
}

/// Result of one update.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AngleUpdate {
    /// `Z − H X⁻` \[rad\] (azimuth wrapped).
    pub innovation_rad: Vector2<f64>,
    /// Normalised innovation squared `νᵀ S⁻¹ ν` (χ² with 2 dof when consistent).
    pub nis: f64,
    /// The gain K used.
    pub gain: Matrix4x2<f64>,
}

/// Filter output for reports.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AngleEstimate {
    pub t_s: f64,
    pub azimuth_rad: f64,
    pub azimuth_rate_rad_s: f64,
    pub elevation_rad: f64,
    pub elevation_rate_rad_s: f64,
    /// Diagonal of P: var α, var α̇, var β, var β̇ \[rad², rad²/s², …\].
    pub covariance_diag: [f64; 4],
}

/// `Φ(T)` of eq 11 (fixed row 3).
pub fn transition(dt_s: f64) -> Matrix4<f64> {
    let mut phi = Matrix4::identity();
    phi[(0, 1)] = dt_s;
    phi[(2, 3)] = dt_s;
    phi
}

/// `Γ Q Γᵀ` for a step T.
pub fn process_noise(config: &AngleFilterConfig, dt_s: f64) -> Matrix4<f64> {
    let t = dt_s;
    let gamma = match config.gamma {
        GammaModel::Seed => Matrix4x2::new(0.0, 0.0, t, 0.0, 0.0, 0.0, 0.0, t),
        GammaModel::PiecewiseConstantAcceleration => {
            Matrix4x2::new(0.5 * t * t, 0.0, t, 0.0, 0.0, 0.5 * t * t, 0.0, t)
        }
    };
    gamma * gamma.transpose() * config.accel_noise_var_rad2_s4
}

/// `H` of eq 11 (fixed).
pub fn observation() -> Matrix2x4<f64> {
    Matrix2x4::new(1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0)
}

/// Wraps an angle to (−π, π].
pub fn wrap_pi(a: f64) -> f64 {
    let w = (a + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI;
    if w == -std::f64::consts::PI {
        std::f64::consts::PI
    } else {
        w
    }
}

/// The §3.6 angle filter.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AngleFilter {
    config: AngleFilterConfig,
    t_s: f64,
    x: Vector4<f64>,
    p: Matrix4<f64>,
}

impl AngleFilter {
    /// A filter from an explicit state and covariance at `t_s`.
    pub fn from_state(
        config: AngleFilterConfig,
        t_s: f64,
        x: Vector4<f64>,
        p: Matrix4<f64>,
    ) -> Result<Self, FilterError> {
        config.validate()?;
        if !t_s.is_finite() || x.iter().chain(p.iter()).any(|v| !v.is_finite()) {
            return Err(FilterError::NonFinite {
                what: "initial state",
            });
        }
        Ok(Self { config, t_s, x, p })
    }

    /// Two-frame initialisation (§3.6).
    pub fn initialize(
        config: AngleFilterConfig,
        first: &AngleMeasurement,
        second: &AngleMeasurement,
    ) -> Result<Self, FilterError> {
        let dt = second.t_s - first.t_s;
        if !(dt > 0.0 && dt.is_finite()) {
            return Err(FilterError::BadInitialStep {
                t1_s: first.t_s,
                t2_s: second.t_s,
            });
        }
        let d_az = wrap_pi(second.azimuth_rad - first.azimuth_rad);
        let d_el = second.elevation_rad - first.elevation_rad;
        let x = Vector4::new(
            second.azimuth_rad,
            d_az / dt,
            second.elevation_rad,
            d_el / dt,
        );
        let s2 = config.measurement_sigma_rad.powi(2);
        let block = Matrix2::new(s2, s2 / dt, s2 / dt, 2.0 * s2 / (dt * dt));
        let mut p = Matrix4::zeros();
        p.fixed_view_mut::<2, 2>(0, 0).copy_from(&block);
        p.fixed_view_mut::<2, 2>(2, 2).copy_from(&block);
        Self::from_state(config, second.t_s, x, p)
    }

    pub fn config(&self) -> &AngleFilterConfig {
        &self.config
    }

    /// Time of the current estimate \[s\].
    pub fn t_s(&self) -> f64 {
        self.t_s
    }

    pub fn state(&self) -> &Vector4<f64> {
        &self.x
    }

    pub fn covariance(&self) -> &Matrix4<f64> {
        &self.p
    }

    /// State and covariance predicted to `t_s` (no change to the filter).
    pub fn predicted(&self, t_s: f64) -> Result<(Vector4<f64>, Matrix4<f64>), FilterError> {
        let dt = t_s - self.t_s;
        if !dt.is_finite() || dt < -crate::SAME_INSTANT_S {
            return Err(FilterError::TimeReversed {
                filter_t_s: self.t_s,
                t_s,
            });
        }
        let dt = dt.max(0.0);
        let phi = transition(dt);
        let p = phi * self.p * phi.transpose() + process_noise(&self.config, dt);
        Ok((phi * self.x, 0.5 * (p + p.transpose())))
    }

    /// Predicts to `t_s` (eq 14, first half).
    pub fn predict(&mut self, t_s: f64) -> Result<(), FilterError> {
        let (x, p) = self.predicted(t_s)?;
        self.x = x;
        self.p = p;
        self.t_s = self.t_s.max(t_s);
        Ok(())
    }

    /// Predicts to the measurement time and applies it (eqs 13–15, Joseph form).
    pub fn update(&mut self, z: &AngleMeasurement) -> Result<AngleUpdate, FilterError> {
        self.update_with_sigma(z, None)
    }

    /// As [`AngleFilter::update`] with this measurement's own 1σ \[rad\] (e.g. from the
    /// detection's centroid uncertainty) instead of the configured one.
    pub fn update_with_sigma(
        &mut self,
        z: &AngleMeasurement,
        sigma_rad: Option<f64>,
    ) -> Result<AngleUpdate, FilterError> {
        if !(z.azimuth_rad.is_finite() && z.elevation_rad.is_finite()) {
            return Err(FilterError::NonFinite {
                what: "measurement",
            });
        }
        let (x, p) = self.predicted(z.t_s)?;
        let h = observation();
        let sigma = sigma_rad
            .filter(|v| v.is_finite() && *v > 0.0)
            .unwrap_or(self.config.measurement_sigma_rad);
        let r = Matrix2::identity() * sigma.powi(2);
        let s = h * p * h.transpose() + r;
        let s_inv = s
            .cholesky()
            .ok_or(FilterError::SingularInnovation)?
            .inverse();
        let k = p * h.transpose() * s_inv;
        let nu = Vector2::new(wrap_pi(z.azimuth_rad - x[0]), z.elevation_rad - x[2]);
        let mut x_new = x + k * nu;
        x_new[0] = wrap_pi(x_new[0]);
        let i_kh = Matrix4::identity() - k * h;
        let p_new = i_kh * p * i_kh.transpose() + k * r * k.transpose();
        let p_new = 0.5 * (p_new + p_new.transpose());
        if x_new.iter().chain(p_new.iter()).any(|v| !v.is_finite()) {
            return Err(FilterError::NonFinite { what: "update" });
        }
        self.x = x_new;
        self.p = p_new;
        self.t_s = self.t_s.max(z.t_s);
        Ok(AngleUpdate {
            innovation_rad: nu,
            nis: (nu.transpose() * s_inv * nu)[0],
            gain: k,
        })
    }

    /// The current estimate for reports.
    pub fn estimate(&self) -> AngleEstimate {
        AngleEstimate {
            t_s: self.t_s,
            azimuth_rad: self.x[0],
            azimuth_rate_rad_s: self.x[1],
            elevation_rad: self.x[2],
            elevation_rate_rad_s: self.x[3],
            covariance_diag: [
                self.p[(0, 0)],
                self.p[(1, 1)],
                self.p[(2, 2)],
                self.p[(3, 3)],
            ],
        }
    }
}

#[cfg(test)]
mod tests;
