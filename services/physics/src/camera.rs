//! Seed-002 pinhole camera in the CAM_X convention (docs/math.md §3.1, §3.2, §3.5, §7.6).
//!
//! Camera frame C: x_c is the boresight, y_c points "up", z_c = x_c × y_c. The focal lengths in
//! pixels are `f_u = (m_u/2)/tan(FOV_x/2)` (columns, m_u = width) and `f_v = (m_v/2)/tan(FOV_y/2)`
//! (rows, m_v = height). The seed's eq (2) gives 1-based continuous pixel coordinates
//!
//! ```text
//! u = f_u z_c/x_c + m_u/2 + 0.5,   v = −f_v y_c/x_c + m_v/2 + 0.5
//! ```
//!
//! with pixel centres at 1..m. This module returns **0-based** coordinates `(x, y) = (u − 1,
//! v − 1)`: column x grows with z_c, row y grows with −y_c (down the image), and the centre of the
//! first pixel is (0, 0), so the principal point is `(m_u/2 − 0.5, m_v/2 − 0.5)`.
//!
//! Angles (eq 10): azimuth `α = atan2(z_c, x_c)`, elevation `β = atan2(y_c, sqrt(x_c² + z_c²))`;
//! from a pixel: `tan α = (x − x_0)/f_u`, `y_c/x_c = −(y − y_0)/f_v`, `β = atan((y_c/x_c) cos α)`;
//! inverse with range r: `(r cos β cos α, r sin β, r cos β sin α)`.

use nalgebra::Vector3;

/// A pinhole camera with square-grid pixels and a centred principal point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PinholeCamera {
    /// Number of columns m_u.
    pub width_px: u32,
    /// Number of rows m_v.
    pub height_px: u32,
    /// Full field of view across the columns \[rad\], in (0, π).
    pub fov_x_rad: f64,
    /// Full field of view across the rows \[rad\], in (0, π).
    pub fov_y_rad: f64,
}

impl PinholeCamera {
    /// The seed-002 camera (Table 1 of §3.9): 1024 × 1024 px, 10° × 10°.
    pub fn zhai2016() -> Self {
        Self {
            width_px: 1024,
            height_px: 1024,
            fov_x_rad: 10f64.to_radians(),
            fov_y_rad: 10f64.to_radians(),
        }
    }

    /// Focal length in column pixels `f/dZ = (m_u/2)/tan(FOV_x/2)` \[px\].
    pub fn focal_px(&self) -> f64 {
        0.5 * f64::from(self.width_px) / (0.5 * self.fov_x_rad).tan()
    }

    /// Focal length in row pixels `f/dY = (m_v/2)/tan(FOV_y/2)` \[px\].
    pub fn focal_y_px(&self) -> f64 {
        0.5 * f64::from(self.height_px) / (0.5 * self.fov_y_rad).tan()
    }

    /// Instantaneous field of view across columns, `FOV_x/m_u` \[rad/px\].
    pub fn ifov_rad(&self) -> f64 {
        self.fov_x_rad / f64::from(self.width_px)
    }

    /// 0-based principal point (x_0, y_0) = (m_u/2 − 0.5, m_v/2 − 0.5) \[px\].
    pub fn principal_point_px(&self) -> (f64, f64) {
        (
            0.5 * f64::from(self.width_px) - 0.5,
            0.5 * f64::from(self.height_px) - 0.5,
        )
    }

    /// Projects a camera-frame point to 0-based continuous pixel coordinates (column x, row y).
    /// `None` if the point is not in front of the camera (x_c ≤ 0). The result may lie outside
    /// the detector; see [`PinholeCamera::contains`].
    pub fn project(&self, r_cam_m: Vector3<f64>) -> Option<(f64, f64)> {
        if r_cam_m.x.is_nan() || r_cam_m.x <= 0.0 {
            return None;
        }
        let (x0, y0) = self.principal_point_px();
        let x_px = self.focal_px() * r_cam_m.z / r_cam_m.x + x0;
        let y_px = -self.focal_y_px() * r_cam_m.y / r_cam_m.x + y0;
        Some((x_px, y_px))
    }

    /// Whether a 0-based continuous pixel coordinate falls on the detector
    /// (`−0.5 ≤ x < m_u − 0.5`, same for y).
    pub fn contains(&self, x_px: f64, y_px: f64) -> bool {
        (-0.5..f64::from(self.width_px) - 0.5).contains(&x_px)
            && (-0.5..f64::from(self.height_px) - 0.5).contains(&y_px)
    }

    /// Line-of-sight angles through a 0-based pixel coordinate: (azimuth α, elevation β) \[rad\]
    /// (§3.5 \[DER\] formulas).
    pub fn angles_from_pixel(&self, x_px: f64, y_px: f64) -> (f64, f64) {
        let (x0, y0) = self.principal_point_px();
        let azimuth_rad = ((x_px - x0) / self.focal_px()).atan();
        let y_over_x = -(y_px - y0) / self.focal_y_px();
        let elevation_rad = (y_over_x * azimuth_rad.cos()).atan();
        (azimuth_rad, elevation_rad)
    }

    /// 0-based pixel coordinate of the direction (α, β) \[rad\]; `None` if it points behind.
    pub fn pixel_from_angles(&self, azimuth_rad: f64, elevation_rad: f64) -> Option<(f64, f64)> {
        self.project(position_from_angles(azimuth_rad, elevation_rad, 1.0))
    }
}

/// Azimuth α = atan2(z_c, x_c) and elevation β = atan2(y_c, sqrt(x_c² + z_c²)) \[rad\] (eq 10).
pub fn angles_from_position(r_cam_m: Vector3<f64>) -> (f64, f64) {
    let azimuth_rad = r_cam_m.z.atan2(r_cam_m.x);
    let elevation_rad = r_cam_m
        .y
        .atan2((r_cam_m.x * r_cam_m.x + r_cam_m.z * r_cam_m.z).sqrt());
    (azimuth_rad, elevation_rad)
}

/// Camera-frame position from (α, β) \[rad\] and range \[m\] (§3.5 inverse).
pub fn position_from_angles(azimuth_rad: f64, elevation_rad: f64, range_m: f64) -> Vector3<f64> {
    let (s_az, c_az) = azimuth_rad.sin_cos();
    let (s_el, c_el) = elevation_rad.sin_cos();
    Vector3::new(range_m * c_el * c_az, range_m * s_el, range_m * c_el * s_az)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn focal_length_and_ifov_match_reference() {
        let cam = PinholeCamera::zhai2016();
        assert!((cam.focal_px() - 5852.18677901).abs() < 1e-8);
        assert!((cam.focal_y_px() - 5852.18677901).abs() < 1e-8);
        assert!((cam.ifov_rad() - 1.70442310e-4).abs() < 1e-12);
    }

    #[test]
    fn boresight_hits_principal_point_and_axes_orientation() {
        let cam = PinholeCamera::zhai2016();
        let (x, y) = cam
            .project(Vector3::new(1000.0, 0.0, 0.0))
            .expect("in front");
        assert_eq!((x, y), (511.5, 511.5));
        // +z_c moves right (larger column), +y_c moves up (smaller row).
        let (x, y) = cam
            .project(Vector3::new(1000.0, 1.0, 1.0))
            .expect("in front");
        assert!(x > 511.5 && y < 511.5);
        assert!(cam.project(Vector3::new(0.0, 1.0, 1.0)).is_none());
        assert!(cam.project(Vector3::new(-1.0, 0.0, 0.0)).is_none());
        assert!(cam.contains(-0.5, 1023.49) && !cam.contains(1023.5, 0.0));
    }

    #[test]
    fn table4_debris_initial_angles() {
        // §3.9 [DER]: (α, β, range) in degrees and metres.
        let cases = [
            ([9000.0, 600.0, -500.0], -3.1798, 3.8082, 9033.83),
            ([8000.0, -600.0, 500.0], 3.5763, -4.2808, 8038.03),
            ([6000.0, 300.0, 400.0], 3.8141, 2.8561, 6020.80),
            ([10000.0, 600.0, 700.0], 4.0042, 3.4253, 10042.41),
        ];
        let cam = PinholeCamera::zhai2016();
        for (r, az_deg, el_deg, range_m) in cases {
            let r = Vector3::from(r);
            let (az, el) = angles_from_position(r);
            assert!((az.to_degrees() - az_deg).abs() < 5e-5, "{az_deg}");
            assert!((el.to_degrees() - el_deg).abs() < 5e-5, "{el_deg}");
            assert!((r.norm() - range_m).abs() < 5e-3);
            let (x, y) = cam.project(r).expect("in front");
            assert!(cam.contains(x, y), "inside the ±5° field");
        }
    }

    proptest! {
        #[test]
        fn pixel_angle_position_round_trips(
            az in -0.08..0.08f64,
            el in -0.08..0.08f64,
            range_m in 10.0..1e7f64,
        ) {
            let cam = PinholeCamera::zhai2016();
            let r = position_from_angles(az, el, range_m);
            prop_assert!((r.norm() - range_m).abs() < 1e-9 * range_m);
            let (az2, el2) = angles_from_position(r);
            prop_assert!((az2 - az).abs() < 1e-14 && (el2 - el).abs() < 1e-14);
            let (x, y) = cam.pixel_from_angles(az, el).expect("in front");
            let (xp, yp) = cam.project(r).expect("in front");
            prop_assert!((x - xp).abs() < 1e-8 && (y - yp).abs() < 1e-8);
            let (az3, el3) = cam.angles_from_pixel(x, y);
            prop_assert!((az3 - az).abs() < 1e-14 && (el3 - el).abs() < 1e-14);
        }

        #[test]
        fn non_square_camera_round_trips(x in -0.5..639.5f64, y in -0.5..479.5f64) {
            let cam = PinholeCamera {
                width_px: 640,
                height_px: 480,
                fov_x_rad: 0.6,
                fov_y_rad: 0.45,
            };
            let (az, el) = cam.angles_from_pixel(x, y);
            let (x2, y2) = cam.pixel_from_angles(az, el).expect("in front");
            prop_assert!((x2 - x).abs() < 1e-9 && (y2 - y).abs() < 1e-9);
        }
    }
}
