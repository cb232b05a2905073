//! The filter's model (docs/math.md §5.2–5.6): the rig, the nominal state and its propagation,
//! the error-state dynamics and their discretisation, and the stereo measurement.
//!
//! Conventions (§5.3, §6.4): the attitude is the Hamilton quaternion `q_ct`, scalar first, with
//! `R(q_ct) = C_CT` (T-components → C-components), the error `q_ct = q̂_ct ⊗ exp(δθ)` with δθ
//! in T; ω_t is the target's inertial rate in T; ρ (target CoM relative to the camera) and
//! `v = ρ̇` are in the orbit frame O (RSW: x radial, y along-track, z normal). The chaser holds
//! O, so its inertial rate in C is `ω_c = C_CO (0, 0, n)` and the relative rate is
//! `ω_tc = ω_t − C_TC ω_c`.
//!
//! Error state (14): `δx = [δθ, δω, δk, δρ, δv]` ([`ix`]). Its dynamics split into a rotational
//! block (δθ, δω, δk; time-varying) and a translational block (δρ, δv; CW, constant), so Φ
//! and Q are block-diagonal:
//! - rotation: per substep `h` (at most [`MAX_SUBSTEP_S`]), F taken at the substep's start,
//!   `Φ_h = Σ (F h)ⁿ/n!` and `Q_h = Σ hⁿ/n! Cₙ` with `C₁ = W = G Q_c Gᵀ`, `Cₙ₊₁ = F Cₙ + Cₙ
//!   Fᵀ` (the series of Van Loan's integral, which solves `Q̇ = F Q + Q Fᵀ + W`);
//! - translation: the exact CW STM and Van Loan's `Q` by the matrix exponential, kept for the
//!   last Δt.

use glint_physics::cw::{cw_a_matrix_rsw, cw_stm_rsw};
use glint_physics::frames::cross_matrix;
use glint_physics::rigid_body::{euler_rate, euler_rate_jacobians, quat_rate, torque_gain};
use nalgebra::{
    Matrix3, Matrix6, Quaternion, SMatrix, SVector, UnitQuaternion, Vector2, Vector3, Vector4,
};

/// Error-state dimension.
pub const N_ERR: usize = 14;
pub type ErrVec = SVector<f64, N_ERR>;
pub type ErrMat = SMatrix<f64, N_ERR, N_ERR>;
/// One feature's measurement Jacobian (4 × 14).
pub type FeatureJacobian = SMatrix<f64, 4, N_ERR>;

/// Offsets of the error state's groups.
pub mod ix {
    /// Attitude error δθ [rad] in T.
    pub const TH: usize = 0;
    /// Rate error δω [rad/s] in T.
    pub const W: usize = 3;
    /// Inertia-parameter error δk.
    pub const K: usize = 6;
    /// Position error δρ [m] in O.
    pub const RHO: usize = 8;
    /// Velocity error δv [m/s] in O.
    pub const V: usize = 11;
}

/// The rig and what the filter assumes of the target (the `RIG.toml` of `glint tool relnav`).
#[derive(Debug, Clone, PartialEq)]
pub struct Rig {
    /// Mean motion of the chaser's circular orbit [rad/s].
    pub mean_motion_rad_s: f64,
    /// Right camera at +baseline along x_C [m].
    pub baseline_m: f64,
    /// 1σ of each normalised image coordinate.
    pub sigma_norm: f64,
    /// `C_CO`: O-components → C-components, constant.
    pub c_co: Matrix3<f64>,
    /// Each feature's coordinates in the target principal frame T [m].
    pub features_m: Vec<Vector3<f64>>,
    /// PSD of the normalised torque ε = τ/tr J [rad² s⁻³].
    pub torque_psd: f64,
    /// PSD of the relative acceleration noise [m² s⁻³].
    pub accel_psd: f64,
}

impl Rig {
    /// The chaser's inertial rate in C [rad/s].
    pub fn chaser_rate_c(&self) -> Vector3<f64> {
        self.c_co * Vector3::new(0.0, 0.0, self.mean_motion_rad_s)
    }
}

/// The nominal (whole) state.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Nominal {
    pub q_ct: UnitQuaternion<f64>,
    /// ω_t [rad/s] in T.
    pub w_t: Vector3<f64>,
    /// Inertia parameters k (eq 16).
    pub k: Vector2<f64>,
    /// ρ [m] in O.
    pub rho_o: Vector3<f64>,
    /// v [m/s] in O.
    pub v_o: Vector3<f64>,
}

impl Nominal {
    /// The state with the error `dx` injected (multiplicative attitude, additive rest).
    pub fn inject(&self, dx: &ErrVec) -> Nominal {
        let dth = Vector3::new(dx[ix::TH], dx[ix::TH + 1], dx[ix::TH + 2]);
        Nominal {
            q_ct: self.q_ct * UnitQuaternion::from_scaled_axis(dth),
            w_t: self.w_t + dx.fixed_rows::<3>(ix::W),
            k: self.k + dx.fixed_rows::<2>(ix::K),
            rho_o: self.rho_o + dx.fixed_rows::<3>(ix::RHO),
            v_o: self.v_o + dx.fixed_rows::<3>(ix::V),
        }
    }

    /// The error `δx` that takes `self` to `other` (`other = self.inject(δx)`).
    pub fn error_to(&self, other: &Nominal) -> ErrVec {
        let dq = self.q_ct.inverse() * other.q_ct;
        let mut dx = ErrVec::zeros();
        dx.fixed_rows_mut::<3>(ix::TH).copy_from(&dq.scaled_axis());
        dx.fixed_rows_mut::<3>(ix::W)
            .copy_from(&(other.w_t - self.w_t));
        dx.fixed_rows_mut::<2>(ix::K).copy_from(&(other.k - self.k));
        dx.fixed_rows_mut::<3>(ix::RHO)
            .copy_from(&(other.rho_o - self.rho_o));
        dx.fixed_rows_mut::<3>(ix::V)
            .copy_from(&(other.v_o - self.v_o));
        dx
    }

    pub fn is_finite(&self) -> bool {
        let q = self.q_ct.coords;
        q.iter()
            .chain(self.w_t.iter())
            .chain(self.k.iter())
            .chain(self.rho_o.iter())
            .chain(self.v_o.iter())
            .all(|v| v.is_finite())
    }
}

/// Longest substep of the rotational propagation [s].
pub const MAX_SUBSTEP_S: f64 = 1.0;
/// Terms of the series for Φ and Q of a substep (|F h| ≲ 1: the last term is below 1e-5 of
/// the first).
const SERIES_TERMS: usize = 8;

/// Propagates the nominal attitude and rate over `h_s` by one RK4 step of (q_ct, ω_t) together.
fn rotation_rk4(x: &Nominal, w_c: Vector3<f64>, h_s: f64) -> (UnitQuaternion<f64>, Vector3<f64>) {
    let k = x.k;
    let deriv = |q: Vector4<f64>, w: Vector3<f64>| {
        let r = Quaternion::from(q);
        // C_TC ω_c with the (not yet unit) quaternion's rotation: q* ω q / |q|².
        let w_c_t = (r.conjugate() * Quaternion::from_imag(w_c) * r).imag() / r.norm_squared();
        (quat_rate(q, w - w_c_t), euler_rate(w, k))
    };
    let q0 = x.q_ct.into_inner().coords;
    let w0 = x.w_t;
    let (dq1, dw1) = deriv(q0, w0);
    let (dq2, dw2) = deriv(q0 + dq1 * (0.5 * h_s), w0 + dw1 * (0.5 * h_s));
    let (dq3, dw3) = deriv(q0 + dq2 * (0.5 * h_s), w0 + dw2 * (0.5 * h_s));
    let (dq4, dw4) = deriv(q0 + dq3 * h_s, w0 + dw3 * h_s);
    let q = q0 + (dq1 + 2.0 * dq2 + 2.0 * dq3 + dq4) * (h_s / 6.0);
    let w = w0 + (dw1 + 2.0 * dw2 + 2.0 * dw3 + dw4) * (h_s / 6.0);
    (UnitQuaternion::from_quaternion(Quaternion::from(q)), w)
}

/// The rotational block of F (8 × 8: δθ, δω, δk) at rate `w_t` and parameter `k` (eq 36).
pub fn f_rotation(w_t: Vector3<f64>, k: Vector2<f64>) -> SMatrix<f64, 8, 8> {
    let (f_ww, f_wk) = euler_rate_jacobians(w_t, k);
    let mut f = SMatrix::<f64, 8, 8>::zeros();
    f.fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&(-cross_matrix(w_t)));
    f.fixed_view_mut::<3, 3>(0, 3)
        .copy_from(&Matrix3::identity());
    f.fixed_view_mut::<3, 3>(3, 3).copy_from(&f_ww);
    f.fixed_view_mut::<3, 2>(3, 6).copy_from(&f_wk);
    f
}

/// The whole error-state F (14 × 14) of eq (36), for tests and the linearised analysis.
pub fn f_matrix(x: &Nominal, n_rad_s: f64) -> ErrMat {
    let mut f = ErrMat::zeros();
    f.fixed_view_mut::<8, 8>(0, 0)
        .copy_from(&f_rotation(x.w_t, x.k));
    f.fixed_view_mut::<6, 6>(ix::RHO, ix::RHO)
        .copy_from(&cw_a_matrix_rsw(n_rad_s));
    f
}

/// Φ and Q of the translational block for a step, with Van Loan's integral.
#[derive(Debug, Clone, Copy)]
struct TranslationStep {
    dt_s: f64,
    phi: Matrix6<f64>,
    q: Matrix6<f64>,
}

/// Propagation of the nominal state and the covariance (its cache is not state: a restored
/// filter recomputes it).
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Propagator {
    #[serde(skip)]
    last: Option<TranslationStep>,
}

impl Default for Propagator {
    fn default() -> Self {
        Self::new()
    }
}

impl Propagator {
    pub fn new() -> Self {
        Propagator { last: None }
    }

    /// Propagates `x` and `p` over `dt_s` > 0 (math.md §5.6 step 2): attitude and rate by RK4
    /// in substeps of at most [`MAX_SUBSTEP_S`], k held, (ρ, v) by the CW STM.
    pub fn propagate(
        &mut self,
        rig: &Rig,
        x: &Nominal,
        p: &ErrMat,
        dt_s: f64,
    ) -> (Nominal, ErrMat) {
        let w_c = rig.chaser_rate_c();
        let substeps = (dt_s / MAX_SUBSTEP_S).ceil().max(1.0) as usize;
        let h = dt_s / substeps as f64;
        let mut xr = *x;
        let mut phi_r = SMatrix::<f64, 8, 8>::identity();
        let mut q_r = SMatrix::<f64, 8, 8>::zeros();
        for _ in 0..substeps {
            let f = f_rotation(xr.w_t, xr.k);
            let b = torque_gain(xr.k);
            let mut c = SMatrix::<f64, 8, 8>::zeros();
            for i in 0..3 {
                c[(3 + i, 3 + i)] = b[i] * b[i] * rig.torque_psd;
            }
            // Φ_h = Σ (F h)ⁿ/n!, Q_h = Σ hⁿ/n! Cₙ with C₁ = W, Cₙ₊₁ = F Cₙ + Cₙ Fᵀ.
            let mut phi_h = SMatrix::<f64, 8, 8>::identity();
            let mut term = phi_h;
            let mut q_h = SMatrix::<f64, 8, 8>::zeros();
            let mut coef = 1.0;
            for n in 1..=SERIES_TERMS {
                let step = h / n as f64;
                term = term * f * step;
                phi_h += term;
                coef *= step;
                q_h += c * coef;
                if n < SERIES_TERMS {
                    c = f * c + c * f.transpose();
                }
            }
            phi_r = phi_h * phi_r;
            q_r = phi_h * q_r * phi_h.transpose() + q_h;
            let (q, w_t) = rotation_rk4(&xr, w_c, h);
            xr.q_ct = q;
            xr.w_t = w_t;
        }
        let tr = self.translation(rig, dt_s);
        let mut s = SVector::<f64, 6>::zeros();
        s.fixed_rows_mut::<3>(0).copy_from(&x.rho_o);
        s.fixed_rows_mut::<3>(3).copy_from(&x.v_o);
        let s = tr.phi * s;
        xr.rho_o = s.fixed_rows::<3>(0).into();
        xr.v_o = s.fixed_rows::<3>(3).into();

        // Φ P Φᵀ + Q block by block (Φ and Q are block-diagonal: rotation 8, translation 6).
        let p_rr = p.fixed_view::<8, 8>(0, 0);
        let p_rt = p.fixed_view::<8, 6>(0, 8);
        let p_tt = p.fixed_view::<6, 6>(8, 8);
        let rr = phi_r * p_rr * phi_r.transpose() + q_r;
        let rt = phi_r * p_rt * tr.phi.transpose();
        let tt = tr.phi * p_tt * tr.phi.transpose() + tr.q;
        let mut p1 = ErrMat::zeros();
        p1.fixed_view_mut::<8, 8>(0, 0).copy_from(&rr);
        p1.fixed_view_mut::<8, 6>(0, 8).copy_from(&rt);
        p1.fixed_view_mut::<6, 8>(8, 0).copy_from(&rt.transpose());
        p1.fixed_view_mut::<6, 6>(8, 8).copy_from(&tt);
        symmetrise(&mut p1);
        (xr, p1)
    }

    fn translation(&mut self, rig: &Rig, dt_s: f64) -> TranslationStep {
        if let Some(t) = self.last {
            if t.dt_s == dt_s {
                return t;
            }
        }
        let a = cw_a_matrix_rsw(rig.mean_motion_rad_s);
        let mut w = Matrix6::zeros();
        for i in 3..6 {
            w[(i, i)] = rig.accel_psd;
        }
        // Van Loan: expm([[−A, W], [0, Aᵀ]] Δt) = [[·, Φ⁻¹Q], [0, Φᵀ]].
        let mut m = SMatrix::<f64, 12, 12>::zeros();
        m.fixed_view_mut::<6, 6>(0, 0).copy_from(&(-a * dt_s));
        m.fixed_view_mut::<6, 6>(0, 6).copy_from(&(w * dt_s));
        m.fixed_view_mut::<6, 6>(6, 6)
            .copy_from(&(a.transpose() * dt_s));
        let e = expm(&m);
        let phi = cw_stm_rsw(rig.mean_motion_rad_s, dt_s);
        let mut q: Matrix6<f64> = phi * e.fixed_view::<6, 6>(0, 6);
        q = (q + q.transpose()) * 0.5;
        let t = TranslationStep { dt_s, phi, q };
        self.last = Some(t);
        t
    }
}

/// Makes `p` exactly symmetric.
pub fn symmetrise(p: &mut ErrMat) {
    *p = (*p + p.transpose()) * 0.5;
}

/// The matrix exponential by scaling and squaring of a degree-16 Taylor series (ample for
/// the small, well-conditioned matrices of a discretisation).
pub fn expm<const D: usize>(m: &SMatrix<f64, D, D>) -> SMatrix<f64, D, D> {
    let norm = m.abs().row_sum().max();
    let squarings = if norm > 0.5 {
        (norm / 0.5).log2().ceil() as i32
    } else {
        0
    };
    let a = m / 2f64.powi(squarings);
    let mut term = SMatrix::<f64, D, D>::identity();
    let mut sum = term;
    for i in 1..=16 {
        term = term * a / i as f64;
        sum += term;
    }
    for _ in 0..squarings {
        sum = sum * sum;
    }
    sum
}

/// Where feature `r_t` (in T) is in C [m]: `C_CO ρ + C_CT r_t` (eqs 22–23).
pub fn feature_in_camera(rig: &Rig, x: &Nominal, r_t: &Vector3<f64>) -> Vector3<f64> {
    rig.c_co * x.rho_o + x.q_ct * r_t
}

/// The error-state components a stereo measurement depends on: δθ and δρ (eq 39: H is zero in
/// the columns of δω, δk and δv).
pub const OBSERVED: [usize; 6] = [
    ix::TH,
    ix::TH + 1,
    ix::TH + 2,
    ix::RHO,
    ix::RHO + 1,
    ix::RHO + 2,
];

/// A feature's measurement Jacobian on the [`OBSERVED`] components (4 × 6).
pub type ObservedJacobian = SMatrix<f64, 4, 6>;

/// The predicted normalised coordinates of feature `r_t` and their Jacobian on the
/// [`OBSERVED`] components (eqs 38–39); `None` when the feature would be behind the cameras.
pub fn measure_observed(
    rig: &Rig,
    x: &Nominal,
    r_t: &Vector3<f64>,
) -> Option<(Vector4<f64>, ObservedJacobian)> {
    let p = feature_in_camera(rig, x, r_t);
    let z = glint_physics::stereo::project(p, rig.baseline_m)?;
    let (px, py, pz) = (p.x, p.y, p.z);
    let iz = 1.0 / pz;
    let iz2 = iz * iz;
    #[rustfmt::skip]
    let jp = SMatrix::<f64, 4, 3>::new(
        iz,  0.0, -px * iz2,
        0.0, iz,  -py * iz2,
        iz,  0.0, -(px - rig.baseline_m) * iz2,
        0.0, iz,  -py * iz2,
    );
    let c_ct = x.q_ct.to_rotation_matrix().into_inner();
    let mut h = ObservedJacobian::zeros();
    h.fixed_view_mut::<4, 3>(0, 0)
        .copy_from(&(jp * (-c_ct * cross_matrix(*r_t))));
    h.fixed_view_mut::<4, 3>(0, 3).copy_from(&(jp * rig.c_co));
    Some((Vector4::from(z), h))
}

/// The predicted normalised coordinates of feature `r_t` and their whole Jacobian (eqs
/// 38–39); `None` when the feature would be behind the cameras.
pub fn measure(
    rig: &Rig,
    x: &Nominal,
    r_t: &Vector3<f64>,
) -> Option<(Vector4<f64>, FeatureJacobian)> {
    let (z, h6) = measure_observed(rig, x, r_t)?;
    let mut h = FeatureJacobian::zeros();
    for (c, &j) in OBSERVED.iter().enumerate() {
        h.set_column(j, &h6.column(c));
    }
    Some((z, h))
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    pub(crate) fn rig() -> Rig {
        Rig {
            mean_motion_rad_s: 1.1068e-3,
            baseline_m: 0.5,
            sigma_norm: 1e-5,
            c_co: Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 1.0, 0.0),
            features_m: vec![
                Vector3::new(0.5, 0.0, 0.0),
                Vector3::new(-0.5, 0.0, 0.0),
                Vector3::new(0.0, 0.5, 0.0),
                Vector3::new(0.0, -0.5, 0.0),
            ],
            torque_psd: 1e-10,
            accel_psd: 1e-10,
        }
    }

    pub(crate) fn state() -> Nominal {
        Nominal {
            q_ct: UnitQuaternion::from_scaled_axis(Vector3::new(0.3, -0.5, 0.8)),
            w_t: Vector3::new(0.02, -0.03, 0.05),
            k: Vector2::new(-0.31, 0.44),
            rho_o: Vector3::new(0.4, 10.0, -0.2),
            v_o: Vector3::new(1e-3, -8e-4, 2e-4),
        }
    }

    /// H against central differences of h over every error-state component (math.md §7.6: to
    /// 7e-12).
    #[test]
    fn h_matches_finite_differences() {
        let (rig, x) = (rig(), state());
        let r = Vector3::new(0.3, -0.2, 0.4);
        let (_, h) = measure(&rig, &x, &r).unwrap();
        let d = 1e-6;
        for j in 0..N_ERR {
            let mut dx = ErrVec::zeros();
            dx[j] = d;
            let (zp, _) = measure(&rig, &x.inject(&dx), &r).unwrap();
            let (zm, _) = measure(&rig, &x.inject(&-dx), &r).unwrap();
            let col = (zp - zm) / (2.0 * d);
            assert!(
                (col - h.column(j)).amax() < 1e-9,
                "column {j}: {col} vs {}",
                h.column(j)
            );
        }
    }

    /// F against the numerical error-state Jacobian: propagate x and x ⊕ δx over a short Δt
    /// and difference (math.md §7.6: agree to O(Δt)).
    #[test]
    fn f_matches_the_propagated_error() {
        let (rig, x) = (rig(), state());
        let f = f_matrix(&x, rig.mean_motion_rad_s);
        let dt = 1e-3;
        let mut prop = Propagator::new();
        let p0 = ErrMat::zeros();
        let (x1, _) = prop.propagate(&rig, &x, &p0, dt);
        let d = 1e-6;
        for j in 0..N_ERR {
            let mut dx = ErrVec::zeros();
            dx[j] = d;
            let (xp, _) = prop.propagate(&rig, &x.inject(&dx), &p0, dt);
            let (xm, _) = prop.propagate(&rig, &x.inject(&-dx), &p0, dt);
            let e = (x1.error_to(&xp) - x1.error_to(&xm)) / (2.0 * d);
            // (Φ − I)/Δt → F
            let mut col = e / dt;
            col[j] -= 1.0 / dt;
            assert!(
                (col - f.column(j)).amax() < 1e-3,
                "column {j}: {col} vs {}",
                f.column(j)
            );
        }
    }

    /// The propagated covariance against the Van Loan exponential of the whole 28 × 28 system,
    /// over one 1 s step with constant F (the second method).
    #[test]
    fn q_matches_van_loan() {
        let rig = rig();
        let mut x = state();
        // a rate about a principal axis keeps ω (and so F) constant over the step
        x.w_t = Vector3::new(0.0, 0.0, 0.05);
        let dt = 1.0; // one substep
        let f = f_matrix(&x, rig.mean_motion_rad_s);
        let mut g = SMatrix::<f64, N_ERR, 6>::zeros();
        let b = torque_gain(x.k);
        for i in 0..3 {
            g[(ix::W + i, i)] = b[i];
            g[(ix::V + i, 3 + i)] = 1.0;
        }
        let qc = SMatrix::<f64, 6, 6>::from_diagonal(&SVector::<f64, 6>::from_column_slice(&[
            rig.torque_psd,
            rig.torque_psd,
            rig.torque_psd,
            rig.accel_psd,
            rig.accel_psd,
            rig.accel_psd,
        ]));
        let w = g * qc * g.transpose();
        let mut m = SMatrix::<f64, 28, 28>::zeros();
        m.fixed_view_mut::<14, 14>(0, 0).copy_from(&(-f * dt));
        m.fixed_view_mut::<14, 14>(0, 14).copy_from(&(w * dt));
        m.fixed_view_mut::<14, 14>(14, 14)
            .copy_from(&(f.transpose() * dt));
        let e = expm(&m);
        let phi: ErrMat = e.fixed_view::<14, 14>(14, 14).transpose();
        let q_ref: ErrMat = phi * e.fixed_view::<14, 14>(0, 14);
        let (_, q) = Propagator::new().propagate(&rig, &x, &ErrMat::zeros(), dt);
        let scale = q_ref.amax();
        assert!(
            (q - q_ref).amax() < 1e-8 * scale,
            "{}",
            (q - q_ref).amax() / scale
        );
    }
}
