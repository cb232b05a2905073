//! The seed-003 static infrared Earth sensor's camera (docs/math.md §4.1): an equidistant
//! fisheye `r = f θ` (eq 1), and the Earth's angular radius from a circular orbit.
//!
//! Pixel convention: (x, y) = (column, row), the first pixel's centre at (0, 0), as the debris
//! camera's. The sensor frame S has X_S along +x, Y_S along +y and Z_S the optical axis.

/// The equidistant fisheye `r = f θ` (eq 1): focal length and principal point [px].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fisheye {
    pub f_px: f64,
    pub x0_px: f64,
    pub y0_px: f64,
}

impl Fisheye {
    /// The unit-sphere direction of pixel (x, y) (eqs 6–9, R = 1).
    pub fn direction(&self, x_px: f64, y_px: f64) -> [f64; 3] {
        let (dx, dy) = (x_px - self.x0_px, y_px - self.y0_px);
        let r = dx.hypot(dy);
        if r == 0.0 {
            return [0.0, 0.0, 1.0];
        }
        let theta = r / self.f_px;
        let (s, c) = theta.sin_cos();
        [s * dx / r, s * dy / r, c]
    }

    /// The pixel a direction images to (the inverse of [`Fisheye::direction`]).
    pub fn pixel(&self, u: [f64; 3]) -> (f64, f64) {
        let rho = u[0].hypot(u[1]);
        let theta = rho.atan2(u[2]);
        if rho == 0.0 {
            return (self.x0_px, self.y0_px);
        }
        let r = self.f_px * theta;
        (self.x0_px + r * u[0] / rho, self.y0_px + r * u[1] / rho)
    }

    /// The angle from the optical axis of pixel (x, y) [rad].
    pub fn theta_rad(&self, x_px: f64, y_px: f64) -> f64 {
        (x_px - self.x0_px).hypot(y_px - self.y0_px) / self.f_px
    }
}

/// ρ_E = arcsin(R_E / (R_E + h)), the Earth's angular radius from altitude h [rad].
pub fn earth_angular_radius_rad(altitude_km: f64) -> f64 {
    // The mean radius, as math.md §4.1 (60.486° at 950 km).
    const EARTH_RADIUS_KM: f64 = 6371.0;
    (EARTH_RADIUS_KM / (EARTH_RADIUS_KM + altitude_km)).asin()
}

#[cfg(test)]
mod tests {
    use super::*;

    const CAM: Fisheye = Fisheye {
        f_px: 150.0,
        x0_px: 255.5,
        y0_px: 255.5,
    };

    #[test]
    fn the_earth_at_950_km_is_60_486_degrees_wide() {
        assert!((earth_angular_radius_rad(950.0).to_degrees() - 60.486).abs() < 5e-4);
    }

    #[test]
    fn a_pixel_and_its_direction_round_trip() {
        for (x, y) in [
            (255.5, 255.5),
            (300.0, 100.25),
            (10.0, 500.0),
            (255.5, 20.0),
        ] {
            let u = CAM.direction(x, y);
            assert!((u[0] * u[0] + u[1] * u[1] + u[2] * u[2] - 1.0).abs() < 1e-15);
            let (px, py) = CAM.pixel(u);
            assert!(
                (px - x).abs() < 1e-9 && (py - y).abs() < 1e-9,
                "({x}, {y}) → ({px}, {py})"
            );
            let theta = CAM.theta_rad(x, y);
            assert!((u[2] - theta.cos()).abs() < 1e-15);
        }
    }
}
