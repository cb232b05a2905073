//! A satellite spinning about an inertially fixed axis (docs/math.md §2.5, eqs 5–8): the
//! attitude `q_IB = q(v, φ)` (rotation about unit axis v by φ; body components → inertial),
//! the database's axes on a Fibonacci sphere and its rotation angles.

use nalgebra::{Unit, UnitQuaternion, Vector3};
use std::f64::consts::PI;

/// `q(v, φ)`: the rotation about `axis` by `phi_rad` (eqs 7–8: q0 = cos φ/2, μ = v sin φ/2).
pub fn spin_attitude(axis: &Unit<Vector3<f64>>, phi_rad: f64) -> UnitQuaternion<f64> {
    UnitQuaternion::from_axis_angle(axis, phi_rad)
}

/// `n` axes on the Fibonacci sphere (eq 5), the whole sphere: the FFT gives |w| only and
/// (v, w) ≡ (−v, −w).
pub fn fibonacci_axes(n: usize) -> Vec<Unit<Vector3<f64>>> {
    let golden = (1.0 + 5f64.sqrt()) / 2.0;
    (0..n)
        .map(|i| {
            let z = 1.0 - (2 * i + 1) as f64 / n as f64;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = (2.0 * PI * i as f64 / golden).rem_euclid(2.0 * PI);
            Unit::new_normalize(Vector3::new(r * phi.cos(), r * phi.sin(), z))
        })
        .collect()
}

/// The `m` rotation angles `φ_j = j 2π/m` (eq 6) [rad].
pub fn rotation_angles(m: usize) -> Vec<f64> {
    (0..m).map(|j| j as f64 * 2.0 * PI / m as f64).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fibonacci_axes_cover_the_sphere_evenly() {
        let axes = fibonacci_axes(200);
        assert_eq!(axes.len(), 200);
        // mean of the axes ≈ 0 and every direction within ~15° of an axis
        let mean: Vector3<f64> = axes.iter().map(|a| a.into_inner()).sum::<Vector3<f64>>() / 200.0;
        assert!(mean.norm() < 0.01, "{mean}");
        for probe in fibonacci_axes(997) {
            let nearest = axes.iter().map(|a| a.dot(&probe)).fold(-1.0, f64::max);
            assert!(nearest.acos().to_degrees() < 15.0);
        }
    }

    #[test]
    fn the_spin_attitude_is_eq_7_and_8() {
        let v = Unit::new_normalize(Vector3::new(1.0, 2.0, 2.0));
        let q = spin_attitude(&v, 1.2);
        assert!((q.w - 0.6f64.cos()).abs() < 1e-15);
        assert!((q.imag() - v.into_inner() * 0.6f64.sin()).norm() < 1e-15);
        assert_eq!(rotation_angles(8)[2], PI / 2.0);
    }
}
