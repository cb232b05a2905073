//! A rigid body's rotation and the tanh parametrisation of its inertia ratios (docs/math.md
//! §5.4, seed 004 eqs 9–20).
//!
//! Euler's equations in the principal frame T, `J ω̇ + ω × (J ω) = τ` (eq 9), depend on J only
//! through the ratios `px = (Jyy − Jzz)/Jxx`, `py = (Jzz − Jxx)/Jyy`, `pz = (Jxx − Jyy)/Jzz`
//! (eq 11). The parametrisation `k = (artanh px, artanh py)` (eq 16) maps every `k ∈ R²` to
//! an inertia that satisfies the triangle inequalities (eq 14):
//!
//! ```text
//! J/λ = diag(e^{−k2} cosh k1, e^{k1} cosh k2, cosh(k1 + k2))          (eq 17)
//! px = tanh k1,  py = tanh k2,  pz = −tanh(k1 + k2)                     (eq 18)
//! ω̇ = f_ω(ω, k) + B(k) ε,  ε = τ / tr J                                 (eq 20)
//! ```
//!
//! Two forms of the same dynamics live here on purpose: [`RigidBody`] integrates eq (9) with
//! the inertia itself (the simulator's truth), [`euler_rate`] is eq (20) in `k` (the
//! estimator's model); tests hold them equal.

use nalgebra::{Matrix3, Matrix3x2, Quaternion, UnitQuaternion, Vector2, Vector3, Vector4};

/// The inertia ratios `p` of eq (11) from principal moments `j` [kg m²].
pub fn inertia_ratios(j: Vector3<f64>) -> Vector3<f64> {
    Vector3::new((j.y - j.z) / j.x, (j.z - j.x) / j.y, (j.x - j.y) / j.z)
}

/// `k` of eq (16) for principal moments `j`; `None` unless every moment is positive and the
/// triangle inequalities (eq 14) hold strictly.
pub fn k_from_inertia(j: Vector3<f64>) -> Option<Vector2<f64>> {
    let (a, b, c) = (j.x + j.y - j.z, j.y + j.z - j.x, j.z + j.x - j.y);
    if !(j.min() > 0.0 && a > 0.0 && b > 0.0 && c > 0.0) {
        return None;
    }
    Some(Vector2::new(0.5 * (a / c).ln(), 0.5 * (b / a).ln()))
}

/// The ratios `p` for a parameter `k` (eq 18).
pub fn p_from_k(k: Vector2<f64>) -> Vector3<f64> {
    Vector3::new(k.x.tanh(), k.y.tanh(), -(k.x + k.y).tanh())
}

/// The principal moments for `k` (eq 17), scaled to unit trace (the scale is unobservable).
pub fn inertia_from_k(k: Vector2<f64>) -> Vector3<f64> {
    let j = unscaled_inertia(k);
    j / j.sum()
}

/// `(e^{−k2} cosh k1, e^{k1} cosh k2, cosh(k1 + k2))`: eq (17) with λ = 1.
fn unscaled_inertia(k: Vector2<f64>) -> Vector3<f64> {
    Vector3::new(
        (-k.y).exp() * k.x.cosh(),
        k.x.exp() * k.y.cosh(),
        (k.x + k.y).cosh(),
    )
}

/// The diagonal of `B(k)` (eq 20): `tr J / J_ii`, which turns the normalised torque `ε = τ/tr J`
/// [rad s⁻²] into `ω̇`.
pub fn torque_gain(k: Vector2<f64>) -> Vector3<f64> {
    let j = unscaled_inertia(k);
    Vector3::new(j.sum() / j.x, j.sum() / j.y, j.sum() / j.z)
}

/// `f_ω(ω, k)` of eq (20): the torque-free `ω̇` [rad s⁻²] in T.
pub fn euler_rate(w: Vector3<f64>, k: Vector2<f64>) -> Vector3<f64> {
    let p = p_from_k(k);
    Vector3::new(p.x * w.y * w.z, p.y * w.z * w.x, p.z * w.x * w.y)
}

/// `∂f_ω/∂ω` and `∂f_ω/∂k` (math.md §5.4).
pub fn euler_rate_jacobians(w: Vector3<f64>, k: Vector2<f64>) -> (Matrix3<f64>, Matrix3x2<f64>) {
    let p = p_from_k(k);
    #[rustfmt::skip]
    let f_ww = Matrix3::new(
        0.0,       p.x * w.z, p.x * w.y,
        p.y * w.z, 0.0,       p.y * w.x,
        p.z * w.y, p.z * w.x, 0.0,
    );
    let dz = -(1.0 - p.z * p.z) * w.x * w.y;
    #[rustfmt::skip]
    let f_wk = Matrix3x2::new(
        (1.0 - p.x * p.x) * w.y * w.z, 0.0,
        0.0,                           (1.0 - p.y * p.y) * w.z * w.x,
        dz,                            dz,
    );
    (f_ww, f_wk)
}

/// A rigid body with principal moments `inertia_kg_m2`, integrating eq (9) directly.
#[derive(Debug, Clone, Copy)]
pub struct RigidBody {
    pub inertia_kg_m2: Vector3<f64>,
}

/// A body's attitude and rate: `q_ab` (Hamilton, `R(q) = C_ab`, b the body frame) and `ω` of b
/// relative to a, in b [rad/s].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spin {
    pub q: UnitQuaternion<f64>,
    pub w_rad_s: Vector3<f64>,
}

impl RigidBody {
    /// `ω̇ = J⁻¹ (τ − ω × J ω)` [rad s⁻²] for a torque `τ` [N m] in the body frame.
    pub fn rate(&self, w: Vector3<f64>, torque_n_m: Vector3<f64>) -> Vector3<f64> {
        let j = self.inertia_kg_m2;
        let h = j.component_mul(&w);
        (torque_n_m - w.cross(&h)).component_div(&j)
    }

    /// Rotational kinetic energy `½ ωᵀ J ω` [J].
    pub fn energy_j(&self, w: Vector3<f64>) -> f64 {
        0.5 * w.dot(&self.inertia_kg_m2.component_mul(&w))
    }

    /// Angular momentum `J ω` in the body frame [kg m² s⁻¹].
    pub fn momentum_body(&self, w: Vector3<f64>) -> Vector3<f64> {
        self.inertia_kg_m2.component_mul(&w)
    }

    /// One classical RK4 step of `h_s` of attitude and rate together (`q̇ = ½ q ⊗ ω`), the
    /// torque held over the step; the quaternion renormalised after it.
    pub fn step(&self, s: Spin, torque_n_m: Vector3<f64>, h_s: f64) -> Spin {
        let deriv = |q: Vector4<f64>, w: Vector3<f64>| (quat_rate(q, w), self.rate(w, torque_n_m));
        let q0 = s.q.into_inner().coords;
        let w0 = s.w_rad_s;
        let (dq1, dw1) = deriv(q0, w0);
        let (dq2, dw2) = deriv(q0 + dq1 * (0.5 * h_s), w0 + dw1 * (0.5 * h_s));
        let (dq3, dw3) = deriv(q0 + dq2 * (0.5 * h_s), w0 + dw2 * (0.5 * h_s));
        let (dq4, dw4) = deriv(q0 + dq3 * h_s, w0 + dw3 * h_s);
        let q = q0 + (dq1 + 2.0 * dq2 + 2.0 * dq3 + dq4) * (h_s / 6.0);
        let w = w0 + (dw1 + 2.0 * dw2 + 2.0 * dw3 + dw4) * (h_s / 6.0);
        Spin {
            q: UnitQuaternion::from_quaternion(Quaternion::from(q)),
            w_rad_s: w,
        }
    }
}

/// `q̇ = ½ q ⊗ [0; ω]` for a quaternion stored as nalgebra's coords `[x, y, z, w]`.
pub fn quat_rate(q: Vector4<f64>, w: Vector3<f64>) -> Vector4<f64> {
    let p = Quaternion::from(q) * Quaternion::from_imag(w);
    p.coords * 0.5
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// math.md §7.6: J = diag(10, 12, 15) ↔ k = (−0.309519604, 0.443651598).
    #[test]
    fn the_reference_inertia_maps_to_the_reference_k() {
        let j = Vector3::new(10.0, 12.0, 15.0);
        let k = k_from_inertia(j).unwrap();
        assert!((k.x + 0.309519604).abs() < 1e-9 && (k.y - 0.443651598).abs() < 1e-9);
        let p = p_from_k(k);
        let p_ref = Vector3::new(-0.3, 0.416666667, -0.133333333);
        assert!((p - p_ref).amax() < 1e-9);
        assert!((p - inertia_ratios(j)).amax() < 1e-12);
        let jn = inertia_from_k(k);
        assert!((jn - j / 37.0).amax() < 1e-12);
        let p2 = p_from_k(Vector2::new(0.3, -0.2));
        assert!((p2 - Vector3::new(0.291312612, -0.197375320, -0.0996679946)).amax() < 1e-9);
    }

    #[test]
    fn an_inertia_outside_the_triangle_has_no_k() {
        assert!(k_from_inertia(Vector3::new(1.0, 1.0, 2.0)).is_none());
        assert!(k_from_inertia(Vector3::new(-1.0, 1.0, 1.0)).is_none());
    }

    proptest! {
        /// Eqs (12), (14), (15) hold for every k, and k → J → k is the identity.
        #[test]
        fn every_k_is_a_physical_inertia(k1 in -4.0f64..4.0, k2 in -4.0f64..4.0) {
            let k = Vector2::new(k1, k2);
            let p = p_from_k(k);
            prop_assert!((p.x + p.y + p.z + p.x * p.y * p.z).abs() < 1e-12);
            prop_assert!(p.iter().all(|v| v.abs() < 1.0));
            let j = inertia_from_k(k);
            prop_assert!(j.x + j.y > j.z && j.y + j.z > j.x && j.z + j.x > j.y);
            prop_assert!((inertia_ratios(j) - p).amax() < 1e-9);
            let back = k_from_inertia(j).unwrap();
            prop_assert!((back - k).amax() < 1e-8);
            // eq (20) in k is eq (9) in J, torque included.
            let w = Vector3::new(0.02, -0.03, 0.05);
            let eps = Vector3::new(1e-4, -2e-4, 3e-4);
            let body = RigidBody { inertia_kg_m2: j * 7.5 };
            let tau = eps * body.inertia_kg_m2.sum();
            let lhs = euler_rate(w, k) + torque_gain(k).component_mul(&eps);
            prop_assert!((lhs - body.rate(w, tau)).amax() < 1e-12);
        }
    }

    /// The analytic Jacobians of f_ω against central differences.
    #[test]
    fn euler_rate_jacobians_match_finite_differences() {
        let w = Vector3::new(0.02, -0.03, 0.05);
        let k = Vector2::new(-0.31, 0.44);
        let (f_ww, f_wk) = euler_rate_jacobians(w, k);
        let h = 1e-6;
        for i in 0..3 {
            let mut d = Vector3::zeros();
            d[i] = h;
            let col = (euler_rate(w + d, k) - euler_rate(w - d, k)) / (2.0 * h);
            assert!((col - f_ww.column(i)).amax() < 1e-10, "∂f/∂ω{i}");
        }
        for i in 0..2 {
            let mut d = Vector2::zeros();
            d[i] = h;
            let col = (euler_rate(w, k + d) - euler_rate(w, k - d)) / (2.0 * h);
            assert!((col - f_wk.column(i)).amax() < 1e-10, "∂f/∂k{i}");
        }
    }

    /// Torque-free: energy and the inertial angular momentum are conserved over 2000 s.
    #[test]
    fn torque_free_motion_conserves_energy_and_momentum() {
        let body = RigidBody {
            inertia_kg_m2: Vector3::new(10.0, 12.0, 15.0),
        };
        let mut s = Spin {
            q: UnitQuaternion::identity(),
            w_rad_s: Vector3::new(0.02, -0.03, 0.05),
        };
        let e0 = body.energy_j(s.w_rad_s);
        let h0 = s.q * body.momentum_body(s.w_rad_s);
        for _ in 0..200_000 {
            s = body.step(s, Vector3::zeros(), 0.01);
        }
        let e1 = body.energy_j(s.w_rad_s);
        let h1 = s.q * body.momentum_body(s.w_rad_s);
        assert!(((e1 - e0) / e0).abs() < 1e-10, "energy {e0} → {e1}");
        assert!((h1 - h0).norm() / h0.norm() < 1e-9, "momentum {h0} → {h1}");
        // and the body did tumble: the rate vector moved in the body frame.
        assert!((s.w_rad_s - Vector3::new(0.02, -0.03, 0.05)).norm() > 1e-3);
    }
}
