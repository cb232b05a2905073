//! Line-of-sight angles of a pixel (docs/math.md §3.5, eq 10), via the seed-002 pinhole camera
//! of glint-physics (C ≡ O, §3.1).
//!
//! `α = atan2(z_c, x_c)` (azimuth, in-plane), `β = atan2(y_c, sqrt(x_c² + z_c²))` (elevation).
//! From a 0-based pixel (x, y) with principal point (x_0, y_0) and focal lengths (f_u, f_v) in
//! pixels: `tan α = (x − x_0)/f_u`, `y_c/x_c = −(y − y_0)/f_v`, `β = atan((y_c/x_c) cos α)`.
//! A centroid error of σ_px pixels is an angle error of about `σ_px / f` (§3.5: 1 px ≈ 1.7e-4
//! rad for the 1024 px, 10° camera).

use crate::matching::MatchedDetection;
use glint_physics::camera::PinholeCamera;

/// Direction of a pixel as seen from the camera.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LineOfSight {
    /// α \[rad\].
    pub azimuth_rad: f64,
    /// β \[rad\].
    pub elevation_rad: f64,
}

/// Eq 10 for a 0-based continuous pixel coordinate.
pub fn line_of_sight(camera: &PinholeCamera, x_px: f64, y_px: f64) -> LineOfSight {
    let (azimuth_rad, elevation_rad) = camera.angles_from_pixel(x_px, y_px);
    LineOfSight {
        azimuth_rad,
        elevation_rad,
    }
}

/// Eq 10 at a matched detection's end point (eq 9), i.e. the direction at the end of the
/// current exposure.
pub fn detection_line_of_sight(camera: &PinholeCamera, d: &MatchedDetection) -> LineOfSight {
    line_of_sight(camera, d.end_point_px[0], d.end_point_px[1])
}

/// Angle error \[rad\] of a centroid error of `sigma_px` pixels at the image centre.
pub fn angle_sigma_rad(camera: &PinholeCamera, sigma_px: f64) -> f64 {
    sigma_px / camera.focal_px()
}

#[cfg(test)]
mod tests {
    use super::*;
    use glint_physics::camera::position_from_angles;

    #[test]
    fn principal_point_is_boresight_and_signs_follow_eq_10() {
        let cam = PinholeCamera::zhai2016();
        let los = line_of_sight(&cam, 511.5, 511.5);
        assert_eq!((los.azimuth_rad, los.elevation_rad), (0.0, 0.0));
        // Right of centre: +z_c ⇒ α > 0. Above centre (smaller row): +y_c ⇒ β > 0.
        assert!(line_of_sight(&cam, 600.0, 511.5).azimuth_rad > 0.0);
        assert!(line_of_sight(&cam, 511.5, 400.0).elevation_rad > 0.0);
        assert!((angle_sigma_rad(&cam, 1.0) - 1.70877e-4).abs() < 1e-8);
    }

    #[test]
    fn table4_debris_round_trips_through_the_pixel() {
        let cam = PinholeCamera::zhai2016();
        // Debris #4 of Table 4 (§3.9 [DER]): α = 4.0042°, β = 3.4253°, 10042.41 m.
        let (az, el) = (4.0042f64.to_radians(), 3.4253f64.to_radians());
        let r = position_from_angles(az, el, 10042.41);
        let (x, y) = cam.project(r).expect("in front");
        assert!(x > 511.5 && y < 511.5 && cam.contains(x, y));
        let los = line_of_sight(&cam, x, y);
        assert!((los.azimuth_rad - az).abs() < 1e-14);
        assert!((los.elevation_rad - el).abs() < 1e-14);
    }
}
