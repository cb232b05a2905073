//! Generalised Rodrigues parameters (docs/math.md §2.9, eq 14; Crassidis & Markley 2003): the
//! UKF's local attitude error. `δq = q̂⁻¹ ⊗ q` (Hamilton), `δp = f δq_v / (a + δq_0)`; with
//! a = 1, f = 4 (the defaults) δp ≈ δθ, the rotation vector, for small errors.

use nalgebra::{Quaternion, UnitQuaternion, Vector3};

/// The GRP parameters `a` (0–1) and `f` (= 2(a + 1) so that δp ≈ δθ).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Grp {
    pub a: f64,
    pub f: f64,
}

impl Default for Grp {
    fn default() -> Self {
        Grp { a: 1.0, f: 4.0 }
    }
}

impl Grp {
    /// δp of error quaternion `dq` (taken with δq_0 ≥ 0: the short way round).
    pub fn from_quaternion(&self, dq: &UnitQuaternion<f64>) -> Vector3<f64> {
        let q = dq.quaternion();
        let s = if q.w < 0.0 { -1.0 } else { 1.0 };
        q.imag() * (s * self.f / (self.a + s * q.w))
    }

    /// The error quaternion of δp (eq 14's inverse).
    pub fn to_quaternion(&self, dp: &Vector3<f64>) -> UnitQuaternion<f64> {
        let (a, f) = (self.a, self.f);
        let p2 = dp.norm_squared();
        let w = (-a * p2 + f * (f * f + (1.0 - a * a) * p2).sqrt()) / (f * f + p2);
        let v = dp * ((a + w) / f);
        UnitQuaternion::new_normalize(Quaternion::from_parts(w, v))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// The map and its inverse round-trip (math.md §7.5), for any a in 0–1.
        #[test]
        fn grp_round_trips(x in -1.0..1.0f64, y in -1.0..1.0f64, z in -1.0..1.0f64,
                           angle in 0.0..3.0f64, a in 0.0..=1.0f64) {
            let grp = Grp { a, f: 2.0 * (a + 1.0) };
            let axis = Vector3::new(x, y, z);
            prop_assume!(axis.norm() > 1e-3);
            let dq = UnitQuaternion::from_scaled_axis(axis.normalize() * angle);
            let back = grp.to_quaternion(&grp.from_quaternion(&dq));
            prop_assert!(back.angle_to(&dq) < 1e-12);
        }
    }

    #[test]
    fn small_errors_are_the_rotation_vector() {
        let g = Grp::default();
        let theta = Vector3::new(1e-3, -2e-3, 5e-4);
        let p = g.from_quaternion(&UnitQuaternion::from_scaled_axis(theta));
        assert!((p - theta).norm() < 1e-9, "{p}");
        // the far hemisphere is taken the short way: q and −q give the same δp
        let q = UnitQuaternion::from_scaled_axis(Vector3::new(0.3, 0.1, -0.2));
        let neg = UnitQuaternion::new_unchecked(-q.into_inner());
        assert!((g.from_quaternion(&q) - g.from_quaternion(&neg)).norm() < 1e-15);
    }
}
