//! Extended Kalman filter with Clohessy–Wiltshire dynamics (docs/math.md §3.8, eqs 17–28,
//! with the FIXED innovation of eq 21).
//!
//! State `X = [x, y, z, ẋ, ẏ, ż]ᵀ` (m, m/s) of the debris relative to the observer in LVLH_N
//! (x along-track, y = −orbit normal, z nadir), camera frame C ≡ O (§3.1). Over a step Δt:
//!
//! ```text
//! X⁻ = Φ(Δt) X                  Φ = the exact CW STM of eq 25 (glint_physics::cw)
//! P⁻ = Φ P Φᵀ + Q_d,            Q_d = σ_a² [[Δt³/3 I₃, Δt²/2 I₃], [Δt²/2 I₃, Δt I₃]]
//! z = h(X) + v = [α, β, r]ᵀ + v,  α = atan2(z, x), β = atan2(y, d), r = ‖(x, y, z)‖, d = √(x²+z²)
//! H = [∂h/∂(x,y,z) | 0₃ₓ₃]   (eq 28):
//!     ∂α = (−z/d², 0, x/d²),  ∂β = (−x y/(r² d), d/r², −z y/(r² d)),  ∂r = (x, y, z)/r
//! K = P⁻Hᵀ(H P⁻ Hᵀ + R)⁻¹,   X⁺ = X⁻ + K (z − h(X⁻))  (α residual wrapped to (−π, π])
//! P⁺ = (I − KH) P⁻ (I − KH)ᵀ + K R Kᵀ, symmetrised;   R = diag(σ_α², σ_β², σ_r²)
//! ```
//!
//! When the range reply is missing, [`CwEkf::update_angles`] uses the α, β rows only.
//!
//! Initialisation (§3.8 \[ASSUMP\], made exact for CW): two fixes give positions
//! `p_i = r_i (cos β_i cos α_i, sin β_i, cos β_i sin α_i)`; the velocity at t₁ solves the CW
//! boundary problem `p₂ = Φ_rr p₁ + Φ_rv v₁` (Δt = t₂ − t₁), and the state at t₂ is
//! `[p₂; Φ_vr p₁ + Φ_vv v₁]`. For Δt ≪ 1/n this is the finite difference `(p₂ − p₁)/Δt`, but it
//! is exact on noise-free data. P₀ is `M diag(J₁RJ₁ᵀ, J₂RJ₂ᵀ) Mᵀ`, the covariance of that linear
//! map M of (p₁, p₂), with `J_i = ∂p/∂(α, β, r)` at fix i.
//! NEES `(X − X_true)ᵀ P⁻¹ (X − X_true)` is χ² with 6 dof for a consistent filter.

use crate::angle_filter::{wrap_pi, AngleMeasurement};
use glint_physics::camera::position_from_angles;
use glint_physics::cw::cw_stm_lvlhn;
use nalgebra::{Matrix2, Matrix3, Matrix3x6, Matrix6, SMatrix, SVector, Vector3, Vector6};

/// Mean motion of a GEO observer (§3.9, §7.1) \[rad/s\].
pub const GEO_MEAN_MOTION_RAD_S: f64 = 7.292115864164384e-05;

/// Noise and dynamics settings of the CW EKF.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CwEkfConfig {
    /// Mean motion n of the observer's circular orbit \[rad/s\], ≥ 0. Default GEO.
    pub mean_motion_rad_s: f64,
    /// σ_a of the white acceleration noise \[m s^-3/2\], ≥ 0. Default 1e-3.
    pub accel_noise_m_s_3_2: f64,
    /// σ_α \[rad\], > 0. Default 1.7e-4.
    pub sigma_azimuth_rad: f64,
    /// σ_β \[rad\], > 0. Default 1.7e-4.
    pub sigma_elevation_rad: f64,
    /// σ_r \[m\], > 0. Default 0.1/3 (0.1 m at 3σ).
    pub sigma_range_m: f64,
}

impl Default for CwEkfConfig {
    fn default() -> Self {
        Self {
            mean_motion_rad_s: GEO_MEAN_MOTION_RAD_S,
            accel_noise_m_s_3_2: 1e-3,
            sigma_azimuth_rad: 1.7e-4,
            sigma_elevation_rad: 1.7e-4,
            sigma_range_m: 0.1 / 3.0,
        }
    }
}

impl CwEkfConfig {
    pub fn validate(&self) -> Result<(), crate::ConfigError> {
        let nonneg = [
            ("mean_motion_rad_s", self.mean_motion_rad_s),
            ("accel_noise_m_s_3_2", self.accel_noise_m_s_3_2),
        ];
        for (field, v) in nonneg {
            if !(v.is_finite() && v >= 0.0) {
                return Err(crate::ConfigError::new(field, v, "≥ 0"));
            }
        }
        let positive = [
            ("sigma_azimuth_rad", self.sigma_azimuth_rad),
            ("sigma_elevation_rad", self.sigma_elevation_rad),
            ("sigma_range_m", self.sigma_range_m),
        ];
        for (field, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(crate::ConfigError::new(field, v, "> 0"));
            }
        }
        Ok(())
    }

    /// `R = diag(σ_α², σ_β², σ_r²)`.
    pub fn measurement_covariance(&self) -> Matrix3<f64> {
        Matrix3::from_diagonal(&Vector3::new(
            self.sigma_azimuth_rad.powi(2),
            self.sigma_elevation_rad.powi(2),
            self.sigma_range_m.powi(2),
        ))
    }
}

/// An angles-and-range measurement (a camera fix with its laser range).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RangeFix {
    pub t_s: f64,
    pub azimuth_rad: f64,
    pub elevation_rad: f64,
    pub range_m: f64,
}

impl RangeFix {
    /// The direct position solution `r (cos β cos α, sin β, cos β sin α)` \[m\] (§3.5).
    pub fn position_m(&self) -> Vector3<f64> {
        position_from_angles(self.azimuth_rad, self.elevation_rad, self.range_m)
    }
}

/// EKF failure. A failed call leaves the filter unchanged.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EkfError {
    #[error("time goes backwards: filter at {filter_t_s} s, asked for {t_s} s")]
    TimeReversed { filter_t_s: f64, t_s: f64 },
    #[error("the two initial fixes need t₂ > t₁ (got {t1_s} s and {t2_s} s)")]
    BadInitialStep { t1_s: f64, t2_s: f64 },
    #[error("non-finite {what}")]
    NonFinite { what: &'static str },
    #[error(
        "the measurement is singular at the estimated position (on the y axis or at the origin)"
    )]
    SingularGeometry,
    #[error("innovation covariance is not positive definite")]
    SingularInnovation,
    #[error("the CW position-velocity block is singular over the initial step")]
    SingularInitialStep,
    #[error("invalid configuration: {0}")]
    Config(#[from] crate::ConfigError),
}

/// Result of one update.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct EkfUpdate {
    pub innovation_azimuth_rad: f64,
    pub innovation_elevation_rad: f64,
    /// `None` for an angles-only update.
    pub innovation_range_m: Option<f64>,
    /// Normalised innovation squared (χ² with 3 or 2 dof when consistent).
    pub nis: f64,
}

/// EKF output for reports.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct EkfEstimate {
    pub t_s: f64,
    /// LVLH_N position \[m\].
    pub position_m: [f64; 3],
    /// LVLH_N velocity \[m/s\].
    pub velocity_m_s: [f64; 3],
    /// √diag(P) of the position \[m\].
    pub position_sigma_m: [f64; 3],
    /// √diag(P) of the velocity \[m/s\].
    pub velocity_sigma_m_s: [f64; 3],
}

/// `h(X) = [α, β, r]` (eqs 26–27).
pub fn measurement(x: &Vector6<f64>) -> Vector3<f64> {
    let d = x[0].hypot(x[2]);
    Vector3::new(x[2].atan2(x[0]), x[1].atan2(d), d.hypot(x[1]))
}

/// `H = ∂h/∂X` (eq 28); `None` where d = √(x² + z²) = 0.
pub fn measurement_jacobian(x: &Vector6<f64>) -> Option<Matrix3x6<f64>> {
    let (px, py, pz) = (x[0], x[1], x[2]);
    let d2 = px * px + pz * pz;
    let r2 = d2 + py * py;
    if d2 <= 0.0 || !d2.is_finite() {
        return None;
    }
    let (d, r) = (d2.sqrt(), r2.sqrt());
    let mut h = Matrix3x6::zeros();
    h[(0, 0)] = -pz / d2;
    h[(0, 2)] = px / d2;
    h[(1, 0)] = -px * py / (r2 * d);
    h[(1, 1)] = d / r2;
    h[(1, 2)] = -pz * py / (r2 * d);
    h[(2, 0)] = px / r;
    h[(2, 1)] = py / r;
    h[(2, 2)] = pz / r;
    Some(h)
}

/// `Q_d` for a step Δt and white acceleration noise σ_a.
pub fn process_noise(accel_noise_m_s_3_2: f64, dt_s: f64) -> Matrix6<f64> {
    let q = accel_noise_m_s_3_2.powi(2);
    let (pp, pv, vv) = (dt_s.powi(3) / 3.0, dt_s.powi(2) / 2.0, dt_s);
    let mut m = Matrix6::zeros();
    for i in 0..3 {
        m[(i, i)] = q * pp;
        m[(i, i + 3)] = q * pv;
        m[(i + 3, i)] = q * pv;
        m[(i + 3, i + 3)] = q * vv;
    }
    m
}

/// `J = ∂p/∂(α, β, r)` of the direct position solution.
pub fn fix_jacobian(azimuth_rad: f64, elevation_rad: f64, range_m: f64) -> Matrix3<f64> {
    let (sa, ca) = azimuth_rad.sin_cos();
    let (sb, cb) = elevation_rad.sin_cos();
    let r = range_m;
    Matrix3::new(
        -r * cb * sa,
        -r * sb * ca,
        cb * ca,
        0.0,
        r * cb,
        sb,
        r * cb * ca,
        -r * sb * sa,
        cb * sa,
    )
}

/// The §3.8 CW EKF.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CwEkf {
    config: CwEkfConfig,
    t_s: f64,
    x: Vector6<f64>,
    p: Matrix6<f64>,
}

mod update;

impl CwEkf {
    /// A filter from an explicit state and covariance at `t_s`.
    pub fn from_state(
        config: CwEkfConfig,
        t_s: f64,
        x: Vector6<f64>,
        p: Matrix6<f64>,
    ) -> Result<Self, EkfError> {
        config.validate()?;
        if !t_s.is_finite() || x.iter().chain(p.iter()).any(|v| !v.is_finite()) {
            return Err(EkfError::NonFinite {
                what: "initial state",
            });
        }
        Ok(Self { config, t_s, x, p })
    }

    /// Two-fix initialisation (see the module doc), each fix's angles measured with the
    /// configured σ_α, σ_β.
    pub fn initialize(
        config: CwEkfConfig,
        first: &RangeFix,
        second: &RangeFix,
    ) -> Result<Self, EkfError> {
        let angles = config
            .measurement_covariance()
            .fixed_view::<2, 2>(0, 0)
            .into_owned();
        Self::initialize_with_angle_covariances(config, first, second, [angles; 2])
    }

    /// Two-fix initialisation where each fix's (α, β) carry their own covariance, e.g. angles
    /// an angle filter predicted to a delayed range's time: P₀ must hold the prediction's
    /// uncertainty, not the measurement's, or the filter starts (and stays) over-confident.
    pub fn initialize_with_angle_covariances(
        config: CwEkfConfig,
        first: &RangeFix,
        second: &RangeFix,
        angle_covariances: [Matrix2<f64>; 2],
    ) -> Result<Self, EkfError> {
        let dt = second.t_s - first.t_s;
        if !(dt > 0.0 && dt.is_finite()) {
            return Err(EkfError::BadInitialStep {
                t1_s: first.t_s,
                t2_s: second.t_s,
            });
        }
        let phi = cw_stm_lvlhn(config.mean_motion_rad_s, dt);
        let rr = phi.fixed_view::<3, 3>(0, 0).into_owned();
        let rv = phi.fixed_view::<3, 3>(0, 3).into_owned();
        let vr = phi.fixed_view::<3, 3>(3, 0).into_owned();
        let vv = phi.fixed_view::<3, 3>(3, 3).into_owned();
        let rv_inv = rv.try_inverse().ok_or(EkfError::SingularInitialStep)?;
        let (p1, p2) = (first.position_m(), second.position_m());
        let v1 = rv_inv * (p2 - rr * p1);
        let v2 = vr * p1 + vv * v1;
        let x = Vector6::new(p2[0], p2[1], p2[2], v2[0], v2[1], v2[2]);
        // x₂ = M [p₁; p₂], M = [[0, I], [Φ_vr − Φ_vv Φ_rv⁻¹ Φ_rr, Φ_vv Φ_rv⁻¹]].
        let mut m = Matrix6::zeros();
        m.fixed_view_mut::<3, 3>(0, 3)
            .copy_from(&Matrix3::identity());
        m.fixed_view_mut::<3, 3>(3, 0)
            .copy_from(&(vr - vv * rv_inv * rr));
        m.fixed_view_mut::<3, 3>(3, 3).copy_from(&(vv * rv_inv));
        let cov = |f: &RangeFix, angles: &Matrix2<f64>| {
            let mut r = config.measurement_covariance();
            r.fixed_view_mut::<2, 2>(0, 0).copy_from(angles);
            let j = fix_jacobian(f.azimuth_rad, f.elevation_rad, f.range_m);
            j * r * j.transpose()
        };
        let mut c = Matrix6::zeros();
        c.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&cov(first, &angle_covariances[0]));
        c.fixed_view_mut::<3, 3>(3, 3)
            .copy_from(&cov(second, &angle_covariances[1]));
        let p = m * c * m.transpose() + process_noise(config.accel_noise_m_s_3_2, dt);
        Self::from_state(config, second.t_s, x, 0.5 * (p + p.transpose()))
    }

    pub fn config(&self) -> &CwEkfConfig {
        &self.config
    }

    /// Time of the current estimate \[s\].
    pub fn t_s(&self) -> f64 {
        self.t_s
    }

    pub fn state(&self) -> &Vector6<f64> {
        &self.x
    }

    pub fn covariance(&self) -> &Matrix6<f64> {
        &self.p
    }

    /// State and covariance predicted to `t_s` (no change to the filter).
    pub fn predicted(&self, t_s: f64) -> Result<(Vector6<f64>, Matrix6<f64>), EkfError> {
        let dt = t_s - self.t_s;
        if !dt.is_finite() || dt < -crate::SAME_INSTANT_S {
            return Err(EkfError::TimeReversed {
                filter_t_s: self.t_s,
                t_s,
            });
        }
        let dt = dt.max(0.0);
        let phi = cw_stm_lvlhn(self.config.mean_motion_rad_s, dt);
        let p = phi * self.p * phi.transpose() + process_noise(self.config.accel_noise_m_s_3_2, dt);
        Ok((phi * self.x, 0.5 * (p + p.transpose())))
    }

    /// Propagates to `t_s` (eq 24 and the covariance prediction).
    pub fn predict(&mut self, t_s: f64) -> Result<(), EkfError> {
        let (x, p) = self.predicted(t_s)?;
        self.x = x;
        self.p = p;
        self.t_s = self.t_s.max(t_s);
        Ok(())
    }

    /// NEES `(X − X_true)ᵀ P⁻¹ (X − X_true)`; `None` if P is not positive definite.
    pub fn nees(&self, x_true: &Vector6<f64>) -> Option<f64> {
        let e = self.x - x_true;
        let chol = self.p.cholesky()?;
        Some(e.dot(&chol.solve(&e)))
    }

    /// The current estimate for reports.
    pub fn estimate(&self) -> EkfEstimate {
        let s = |i: usize| self.p[(i, i)].max(0.0).sqrt();
        EkfEstimate {
            t_s: self.t_s,
            position_m: [self.x[0], self.x[1], self.x[2]],
            velocity_m_s: [self.x[3], self.x[4], self.x[5]],
            position_sigma_m: [s(0), s(1), s(2)],
            velocity_sigma_m_s: [s(3), s(4), s(5)],
        }
    }

    /// Predicts to the fix time and applies α, β and r (eq 21, Joseph form).
    pub fn update(&mut self, fix: &RangeFix) -> Result<EkfUpdate, EkfError> {
        let z = Vector3::new(fix.azimuth_rad, fix.elevation_rad, fix.range_m);
        let r = self.config.measurement_covariance();
        let nu = self.apply::<3>(fix.t_s, z, r)?;
        Ok(EkfUpdate {
            innovation_azimuth_rad: nu.0[0],
            innovation_elevation_rad: nu.0[1],
            innovation_range_m: Some(nu.0[2]),
            nis: nu.1,
        })
    }

    /// Predicts to the measurement time and applies α and β only (no range reply).
    pub fn update_angles(&mut self, m: &AngleMeasurement) -> Result<EkfUpdate, EkfError> {
        self.update_angles_with_sigma(m, None)
    }

    /// As [`CwEkf::update_angles`] with this measurement's own 1σ \[rad\] for α and β.
    pub fn update_angles_with_sigma(
        &mut self,
        m: &AngleMeasurement,
        sigma_rad: Option<f64>,
    ) -> Result<EkfUpdate, EkfError> {
        let z = SVector::<f64, 2>::new(m.azimuth_rad, m.elevation_rad);
        let sigma = sigma_rad.filter(|v| v.is_finite() && *v > 0.0);
        let r = SMatrix::<f64, 2, 2>::new(
            sigma.unwrap_or(self.config.sigma_azimuth_rad).powi(2),
            0.0,
            0.0,
            sigma.unwrap_or(self.config.sigma_elevation_rad).powi(2),
        );
        let nu = self.apply::<2>(m.t_s, z, r)?;
        Ok(EkfUpdate {
            innovation_azimuth_rad: nu.0[0],
            innovation_elevation_rad: nu.0[1],
            innovation_range_m: None,
            nis: nu.1,
        })
    }
}

/// The residual `z − h` with the azimuth (row 0) wrapped.
fn residual<const M: usize>(z: &SVector<f64, M>, h: &Vector3<f64>) -> SVector<f64, M> {
    let mut nu = SVector::<f64, M>::zeros();
    for i in 0..M {
        nu[i] = z[i] - h[i];
    }
    nu[0] = wrap_pi(nu[0]);
    nu
}

#[cfg(test)]
mod tests;
