//! Frames and elementary rotations (docs/math.md §0.3, §0.4, §6.3).
//!
//! Passive elementary rotations map components from the old frame to the frame rotated by +θ
//! about one axis (c = cos θ, s = sin θ):
//!
//! ```text
//! R1(θ) = [[1,0,0],[0,c,s],[0,−s,c]]
//! R2(θ) = [[c,0,−s],[0,1,0],[s,0,c]]
//! R3(θ) = [[c,s,0],[−s,c,0],[0,0,1]]
//! ```
//!
//! `[a×] = [[0,−a3,a2],[a3,0,−a1],[−a2,a1,0]]`, so that `[a×] b = a × b`.
//!
//! Relative-motion frames (§6.3): `RSW` is (r̂, ĥ×r̂, ĥ) and `LVLH_N` is (ĥ×r̂, −ĥ, −r̂), so
//! `C_{LVLH_N←RSW} = [[0,1,0],[0,0,−1],[−1,0,0]]`. Both frames rotate with the same angular
//! velocity, so a 6-D state [position; velocity] maps block-diagonally with no extra term.

use nalgebra::{Matrix3, Vector3, Vector6};

/// Passive rotation about axis 1 by `theta_rad` (§0.4).
pub fn r1(theta_rad: f64) -> Matrix3<f64> {
    let (s, c) = theta_rad.sin_cos();
    Matrix3::new(1.0, 0.0, 0.0, 0.0, c, s, 0.0, -s, c)
}

/// Passive rotation about axis 2 by `theta_rad` (§0.4).
pub fn r2(theta_rad: f64) -> Matrix3<f64> {
    let (s, c) = theta_rad.sin_cos();
    Matrix3::new(c, 0.0, -s, 0.0, 1.0, 0.0, s, 0.0, c)
}

/// Passive rotation about axis 3 by `theta_rad` (§0.4).
pub fn r3(theta_rad: f64) -> Matrix3<f64> {
    let (s, c) = theta_rad.sin_cos();
    Matrix3::new(c, s, 0.0, -s, c, 0.0, 0.0, 0.0, 1.0)
}

/// Cross-product matrix `[a×]` (§0.3): `cross_matrix(a) * b == a.cross(&b)`.
pub fn cross_matrix(a: Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -a.z, a.y, a.z, 0.0, -a.x, -a.y, a.x, 0.0)
}

/// `C_{LVLH_N←RSW}` (§6.3): maps RSW components to LVLH-nadir components.
pub fn c_lvlhn_rsw() -> Matrix3<f64> {
    Matrix3::new(0.0, 1.0, 0.0, 0.0, 0.0, -1.0, -1.0, 0.0, 0.0)
}

/// Maps a relative state `[x, y, z, ẋ, ẏ, ż]` from RSW to LVLH_N (blockwise, §6.3).
pub fn rsw_to_lvlhn_state(x_rsw: Vector6<f64>) -> Vector6<f64> {
    apply_blockwise(&c_lvlhn_rsw(), x_rsw)
}

/// Maps a relative state `[x, y, z, ẋ, ẏ, ż]` from LVLH_N to RSW (blockwise, §6.3).
pub fn lvlhn_to_rsw_state(x_lvlhn: Vector6<f64>) -> Vector6<f64> {
    apply_blockwise(&c_lvlhn_rsw().transpose(), x_lvlhn)
}

fn apply_blockwise(c: &Matrix3<f64>, x: Vector6<f64>) -> Vector6<f64> {
    let p = c * Vector3::new(x[0], x[1], x[2]);
    let v = c * Vector3::new(x[3], x[4], x[5]);
    Vector6::new(p.x, p.y, p.z, v.x, v.y, v.z)
}

/// `v/‖v‖`, or `None` when `v` is zero, subnormal-small or not finite (§0.2).
pub fn normalize(v: Vector3<f64>) -> Option<Vector3<f64>> {
    let norm = v.norm();
    if norm.is_finite() && norm > f64::MIN_POSITIVE {
        Some(v / norm)
    } else {
        None
    }
}

/// Angle between two non-zero vectors \[rad\], computed with `atan2(‖a×b‖, a·b)` so that it stays
/// accurate near 0 and π (acos loses half the digits there). Returns 0 if either vector is zero.
pub fn angle_between_rad(a: Vector3<f64>, b: Vector3<f64>) -> f64 {
    a.cross(&b).norm().atan2(a.dot(&b))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::f64::consts::FRAC_PI_2;

    fn close(a: &Matrix3<f64>, b: &Matrix3<f64>, tol: f64) -> bool {
        (a - b).abs().max() <= tol
    }

    #[test]
    fn elementary_rotations_are_passive() {
        // Rotating the frame by +90° about z: the old x axis appears at −y in the new frame.
        let v = r3(FRAC_PI_2) * Vector3::x();
        assert!((v - Vector3::new(0.0, -1.0, 0.0)).norm() < 1e-15);
        let v = r1(FRAC_PI_2) * Vector3::y();
        assert!((v - Vector3::new(0.0, 0.0, -1.0)).norm() < 1e-15);
        let v = r2(FRAC_PI_2) * Vector3::z();
        assert!((v - Vector3::new(-1.0, 0.0, 0.0)).norm() < 1e-15);
    }

    #[test]
    fn lvlhn_rsw_map_matches_axis_definitions() {
        let c = c_lvlhn_rsw();
        // RSW x = r̂ is −z in LVLH_N; RSW y = ĥ×r̂ is +x; RSW z = ĥ is −y.
        assert_eq!(c * Vector3::x(), Vector3::new(0.0, 0.0, -1.0));
        assert_eq!(c * Vector3::y(), Vector3::new(1.0, 0.0, 0.0));
        assert_eq!(c * Vector3::z(), Vector3::new(0.0, -1.0, 0.0));
        assert!((c.determinant() - 1.0).abs() < 1e-15);
    }

    #[test]
    fn case_a_states_correspond() {
        // §7.1 case A is given in both frames.
        let x_lvlhn = Vector6::new(10000.0, 600.0, 700.0, -60.0, -10.0, -100.0);
        let x_rsw = Vector6::new(-700.0, 10000.0, -600.0, 100.0, -60.0, 10.0);
        assert_eq!(lvlhn_to_rsw_state(x_lvlhn), x_rsw);
        assert_eq!(rsw_to_lvlhn_state(x_rsw), x_lvlhn);
    }

    #[test]
    fn normalize_rejects_zero_and_nan() {
        assert!(normalize(Vector3::zeros()).is_none());
        assert!(normalize(Vector3::new(f64::NAN, 0.0, 1.0)).is_none());
        let n = normalize(Vector3::new(3.0, 0.0, 4.0)).expect("non-zero");
        assert!((n - Vector3::new(0.6, 0.0, 0.8)).norm() < 1e-16);
    }

    #[test]
    fn angle_between_is_accurate_near_zero() {
        let a = Vector3::new(1.0, 0.0, 0.0);
        let b = Vector3::new(1.0, 1e-9, 0.0);
        assert!((angle_between_rad(a, b) - 1e-9).abs() < 1e-22);
    }

    proptest! {
        #[test]
        fn rotations_are_orthonormal_and_compose(t1 in -7.0..7.0f64, t2 in -7.0..7.0f64) {
            for r in [r1, r2, r3] {
                let m = r(t1);
                prop_assert!(close(&(m * m.transpose()), &Matrix3::identity(), 1e-14));
                prop_assert!((m.determinant() - 1.0).abs() < 1e-14);
                prop_assert!(close(&(r(t1) * r(t2)), &r(t1 + t2), 1e-13));
            }
        }

        #[test]
        fn cross_matrix_is_cross_product(
            a in prop::array::uniform3(-10.0..10.0f64),
            b in prop::array::uniform3(-10.0..10.0f64),
        ) {
            let a = Vector3::from(a);
            let b = Vector3::from(b);
            prop_assert!((cross_matrix(a) * b - a.cross(&b)).norm() < 1e-12);
        }
    }
}
