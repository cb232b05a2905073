//! A rectified stereo pair in normalised image coordinates (docs/math.md §5.5, seed 004 eqs
//! 21–25).
//!
//! Camera frame C (CAM_Z, §6.3): z_C the left camera's optical axis, x_C along the baseline
//! toward the right camera, y_C = z_C × x_C. A point at `(x, y, z)` in C, `z > 0`, is seen at
//!
//! ```text
//! z_i = [x/z, y/z, (x − b)/z, y/z]      (left x, left y, right x, right y)
//! ```
//!
//! so `y_l` and `y_r` measure the same quantity and each point gives three independent numbers.

use nalgebra::{Matrix3, Vector3};

/// `C_CO` of a chaser holding its orbit frame O (RSW) and looking along-track (+y_O): rows
/// x_C = x_O, y_C = −z_O, z_C = y_O (math.md §5.1).
pub fn c_co_along_track() -> Matrix3<f64> {
    Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 1.0, 0.0)
}

/// Normalised coordinates `[x_l, y_l, x_r, y_r]` of a point `p_c` [m] in C, for a baseline
/// `baseline_m`; `None` unless the point is in front of the cameras (`z > 0`).
pub fn project(p_c: Vector3<f64>, baseline_m: f64) -> Option<[f64; 4]> {
    if p_c.z.is_nan() || p_c.z <= 0.0 {
        return None;
    }
    let inv_z = 1.0 / p_c.z;
    Some([
        p_c.x * inv_z,
        p_c.y * inv_z,
        (p_c.x - baseline_m) * inv_z,
        p_c.y * inv_z,
    ])
}

/// The point in C [m] seen at `z` (the inverse of [`project`], `y` averaged over both
/// cameras); `None` unless the disparity `x_l − x_r` is positive (the point in front).
pub fn triangulate(z: [f64; 4], baseline_m: f64) -> Option<Vector3<f64>> {
    let disparity = z[0] - z[2];
    if !disparity.is_finite() || disparity <= 0.0 {
        return None;
    }
    let depth = baseline_m / disparity;
    Some(Vector3::new(
        z[0] * depth,
        0.5 * (z[1] + z[3]) * depth,
        depth,
    ))
}

/// 1σ of a triangulated depth [m] at `depth_m` for a per-coordinate noise `sigma_norm`:
/// `z²/b · σ·√2` (the disparity is a difference of two noisy coordinates).
pub fn depth_sigma_m(depth_m: f64, baseline_m: f64, sigma_norm: f64) -> f64 {
    depth_m * depth_m / baseline_m * sigma_norm * std::f64::consts::SQRT_2
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn triangulation_inverts_projection() {
        let p = Vector3::new(0.3, -0.4, 10.0);
        let z = project(p, 0.5).unwrap();
        assert_eq!(z[1], z[3]);
        assert!((z[0] - z[2] - 0.05).abs() < 1e-15);
        let back = triangulate(z, 0.5).unwrap();
        assert!((back - p).norm() < 1e-12);
    }

    #[test]
    fn points_behind_or_at_infinity_are_not_seen() {
        assert!(project(Vector3::new(0.0, 0.0, -1.0), 0.5).is_none());
        assert!(project(Vector3::new(0.0, 0.0, 0.0), 0.5).is_none());
        assert!(triangulate([0.1, 0.0, 0.1, 0.0], 0.5).is_none());
        assert!(triangulate([0.1, 0.0, 0.2, 0.0], 0.5).is_none());
    }
}
