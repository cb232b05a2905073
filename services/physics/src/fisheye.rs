//! The seed-003 static infrared Earth sensor's camera (docs/math.md §4.1): an equidistant
//! fisheye `r = f θ` (eq 1), and the Earth's angular radius from a circular orbit.
//!
//! Pixel convention: (x, y) = (column, row), the first pixel's centre at (0, 0), as the debris
//! camera's. The sensor frame S has X_S along +x, Y_S along +y and Z_S the optical axis.

/// A fisheye lens: the equidistant `r = f θ` (eq 1) with the Kannala–Brandt distortion of
/// OpenCV's fisheye model, `r = f θ_d`, `θ_d = θ (1 + k₁θ² + k₂θ⁴ + k₃θ⁶ + k₄θ⁸)`; k = 0 is
/// the ideal lens. Focal length and principal point [px].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fisheye {
    pub f_px: f64,
    pub x0_px: f64,
    pub y0_px: f64,
    /// Kannala–Brandt coefficients k₁…k₄ (OpenCV's `D`).
    pub k: [f64; 4],
}

impl Fisheye {
    /// The ideal equidistant lens `r = f θ`.
    pub const fn ideal(f_px: f64, x0_px: f64, y0_px: f64) -> Self {
        Fisheye {
            f_px,
            x0_px,
            y0_px,
            k: [0.0; 4],
        }
    }

    pub fn is_ideal(&self) -> bool {
        self.k == [0.0; 4]
    }

    /// θ_d of θ [rad].
    pub fn distort(&self, theta: f64) -> f64 {
        let t2 = theta * theta;
        let [k1, k2, k3, k4] = self.k;
        theta * (1.0 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4))))
    }

    /// dθ_d/dθ.
    fn distort_slope(&self, theta: f64) -> f64 {
        let t2 = theta * theta;
        let [k1, k2, k3, k4] = self.k;
        1.0 + t2 * (3.0 * k1 + t2 * (5.0 * k2 + t2 * (7.0 * k3 + t2 * 9.0 * k4)))
    }

    /// θ of θ_d [rad], the first root: bracketed by marching from 0 in 0.05 rad steps while
    /// θ_d(θ) grows, then Newton's method kept inside the bracket (bisection where a step
    /// would leave it), to 1e-12 rad. NaN where no angle before the lens's fold (θ_d stops
    /// growing) or π images to θ_d. θ_d itself for the ideal lens.
    pub fn undistort(&self, theta_d: f64) -> f64 {
        if self.is_ideal() {
            return theta_d;
        }
        if theta_d.is_nan() || theta_d < 0.0 {
            return f64::NAN;
        }
        const STEP: f64 = 0.05;
        let (mut lo, mut hi) = (0.0, f64::NAN);
        let mut t = 0.0;
        while t < std::f64::consts::PI {
            let next = (t + STEP).min(std::f64::consts::PI);
            if self.distort_slope(next) <= 0.0 {
                break;
            }
            if self.distort(next) >= theta_d {
                (lo, hi) = (t, next);
                break;
            }
            t = next;
        }
        if hi.is_nan() {
            return f64::NAN;
        }
        let mut theta = 0.5 * (lo + hi);
        for _ in 0..60 {
            let f = self.distort(theta) - theta_d;
            if f > 0.0 {
                hi = theta;
            } else {
                lo = theta;
            }
            let newton = theta - f / self.distort_slope(theta);
            let next = if newton > lo && newton < hi {
                newton
            } else {
                0.5 * (lo + hi)
            };
            if (next - theta).abs() < 1e-12 {
                return next;
            }
            theta = next;
        }
        theta
    }

    /// The first angle up to `up_to_deg` [deg] (0.1° steps) at which θ_d stops growing, if
    /// any: beyond it the lens would image two angles to one radius.
    pub fn fold_deg(&self, up_to_deg: f64) -> Option<f64> {
        (1..=(up_to_deg * 10.0).round() as u32)
            .map(|s| f64::from(s) / 10.0)
            .find(|d| self.distort(d.to_radians()) <= self.distort((d - 0.1).to_radians()))
    }

    /// The image radius of the angle θ from the axis [px].
    pub fn radius_px(&self, theta: f64) -> f64 {
        self.f_px * self.distort(theta)
    }

    /// The unit-sphere direction of pixel (x, y) (eqs 6–9, R = 1).
    pub fn direction(&self, x_px: f64, y_px: f64) -> [f64; 3] {
        let (dx, dy) = (x_px - self.x0_px, y_px - self.y0_px);
        let r = dx.hypot(dy);
        if r == 0.0 {
            return [0.0, 0.0, 1.0];
        }
        let theta = self.undistort(r / self.f_px);
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
        let r = self.radius_px(theta);
        (self.x0_px + r * u[0] / rho, self.y0_px + r * u[1] / rho)
    }

    /// Where pixel (x, y) lies in the ideal lens's image (`r = f θ`, same f and principal
    /// point): the undistorted pixel. The identity for the ideal lens.
    pub fn to_equidistant(&self, x_px: f64, y_px: f64) -> (f64, f64) {
        let (dx, dy) = (x_px - self.x0_px, y_px - self.y0_px);
        let r = dx.hypot(dy);
        if self.is_ideal() || r == 0.0 {
            return (x_px, y_px);
        }
        let s = self.undistort(r / self.f_px) * self.f_px / r;
        (self.x0_px + s * dx, self.y0_px + s * dy)
    }

    /// An edge's unit normal (ux, uy) at pixel (x, y), carried into the ideal lens's image
    /// ([`Fisheye::to_equidistant`]): a normal is a covector, so its radial part is divided by
    /// the map's radial stretch dr'/dr and its tangential part by r'/r.
    pub fn normal_to_equidistant(&self, x_px: f64, y_px: f64, (ux, uy): (f64, f64)) -> (f64, f64) {
        let (dx, dy) = (x_px - self.x0_px, y_px - self.y0_px);
        let r = dx.hypot(dy);
        if self.is_ideal() || r == 0.0 {
            return (ux, uy);
        }
        let (ex, ey) = (dx / r, dy / r);
        let theta_d = r / self.f_px;
        let theta = self.undistort(theta_d);
        let radial_stretch = 1.0 / self.distort_slope(theta);
        let tangential_stretch = theta / theta_d;
        let radial = (ux * ex + uy * ey) / radial_stretch;
        let tangential = (-ux * ey + uy * ex) / tangential_stretch;
        let (vx, vy) = (radial * ex - tangential * ey, radial * ey + tangential * ex);
        let n = vx.hypot(vy);
        (vx / n, vy / n)
    }

    /// The angle from the optical axis of pixel (x, y) [rad].
    pub fn theta_rad(&self, x_px: f64, y_px: f64) -> f64 {
        self.undistort((x_px - self.x0_px).hypot(y_px - self.y0_px) / self.f_px)
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

    const CAM: Fisheye = Fisheye::ideal(150.0, 255.5, 255.5);
    /// A strongly distorted lens (OpenCV's fisheye calibrations give |k| of this order).
    const KB: Fisheye = Fisheye {
        k: [0.05, -0.01, 0.002, -0.0005],
        ..CAM
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
            // within the distorted lens's field (θ ≤ 90°: r ≤ 240 px)
            if CAM.theta_rad(x, y) < 1.5 {
                let (kx, ky) = KB.pixel(KB.direction(x, y));
                assert!(
                    (kx - x).abs() < 1e-9 && (ky - y).abs() < 1e-9,
                    "KB ({x}, {y})"
                );
            }
        }
    }

    #[test]
    fn the_kannala_brandt_polynomial_and_its_inverse() {
        // θ_d = θ (1 + k₁θ² + k₂θ⁴ + k₃θ⁶ + k₄θ⁸) written out at θ = 1 rad and π/2.
        assert!((KB.distort(1.0) - (1.0 + 0.05 - 0.01 + 0.002 - 0.0005)).abs() < 1e-15);
        let t = std::f64::consts::FRAC_PI_2;
        let want = t
            * (1.0 + 0.05 * t.powi(2) - 0.01 * t.powi(4) + 0.002 * t.powi(6) - 0.0005 * t.powi(8));
        assert!((KB.distort(t) - want).abs() < 1e-14);
        for deg in [0.0, 1.0, 30.0, 60.0, 90.0, 110.0] {
            let theta = f64::to_radians(deg);
            assert!(
                (KB.undistort(KB.distort(theta)) - theta).abs() < 1e-12,
                "{deg}"
            );
        }
        // A lens that folds at θ ≈ 1.97 rad: a θ_d below the fold's finds its angle before the
        // fold, though Newton from θ_d itself (2.4, past the fold) would run the wrong way.
        let steep = Fisheye {
            k: [0.3, -0.06, 0.0, 0.0],
            ..CAM
        };
        let fold = steep.fold_deg(180.0).unwrap().to_radians();
        assert!((1.9..2.0).contains(&fold), "{fold}");
        let theta = steep.undistort(2.4);
        assert!(
            theta < fold && (steep.distort(theta) - 2.4).abs() < 1e-12,
            "{theta}"
        );
        // beyond the fold's θ_d, no angle
        assert!(steep.undistort(steep.distort(fold) + 0.1).is_nan());
        assert_eq!(KB.fold_deg(90.0), None);
        assert_eq!(CAM.radius_px(1.0), 150.0);
    }

    #[test]
    fn an_edge_normal_follows_the_undistortion() {
        // A circle about the axis stays one (its normal radial); the ideal lens changes nothing.
        let (x, y) = (255.5 + 100.0, 255.5 + 50.0);
        assert_eq!(CAM.to_equidistant(x, y), (x, y));
        let r = (100f64).hypot(50.0);
        let (ux, uy) = KB.normal_to_equidistant(x, y, (100.0 / r, 50.0 / r));
        assert!((ux - 100.0 / r).abs() < 1e-12 && (uy - 50.0 / r).abs() < 1e-12);
        // A straight line's image through the lens, mapped back: its normal there is the
        // normal of the mapped curve, found by mapping two nearby points of the curve.
        let (p, q) = ((300.0, 100.0), (300.0, 100.0 + 1e-4));
        let (pe, qe) = (KB.to_equidistant(p.0, p.1), KB.to_equidistant(q.0, q.1));
        let (tx, ty) = (qe.0 - pe.0, qe.1 - pe.1);
        let t = tx.hypot(ty);
        let (nx, ny) = KB.normal_to_equidistant(p.0, p.1, (1.0, 0.0));
        assert!(
            (nx * tx + ny * ty).abs() / t < 1e-6,
            "normal ⟂ the mapped tangent"
        );
        let (px, py) =
            KB.to_equidistant(KB.pixel([0.3, 0.4, 0.866]).0, KB.pixel([0.3, 0.4, 0.866]).1);
        let (ix, iy) = CAM.pixel([0.3, 0.4, 0.866]);
        assert!((px - ix).abs() < 1e-9 && (py - iy).abs() < 1e-9);
    }
}
