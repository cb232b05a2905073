//! From limb pixels to the angle samples: undistortion onto the unit sphere (docs/math.md §4.3,
//! eqs 6–9) and the interval cross product (§4.4, eqs 10–11).
//!
//! Pixel convention: (x, y) = (column, row), the first pixel's centre at (0, 0), as the debris
//! detector's. The sensor frame S has X_S along +x, Y_S along +y and Z_S the optical axis.

use std::f64::consts::PI;

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

/// The β_k and tilt_k samples of one ring.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RingSamples {
    /// β_k = ∠(n̂_k, Z_S) [deg], ≥ 0 (eq 11).
    pub beta_deg: Vec<f64>,
    /// tilt_k = atan2(n̂_x, n̂_z) [deg]: the nadir's angle from Z_S about Y_S, signed.
    pub tilt_deg: Vec<f64>,
    /// azimuth_k = atan2(n̂_y, n̂_x) [deg]: the direction of the nadir's tilt about Z_S.
    pub azimuth_deg: Vec<f64>,
    /// The mean of the oriented unit normals n̂_k (nadir side), normalised.
    pub mean_normal: [f64; 3],
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The interval cross product over ring points on the unit sphere: sorted by azimuth φ about
/// Z_S, cut into thirds A, B, C, and for k = 1..⌊N/3⌋ the normal V_k = (a_k − b_k) × (c_k − b_k)
/// of the plane through a_k, b_k, c_k (eq 10), oriented toward the mean ring point (the nadir
/// side); near-degenerate triples (‖V_k‖ < 1e-9) are dropped.
///
/// Every limb direction u satisfies u·ê = cos ρ_E, so any three of them span a plane with
/// normal ±ê: for exact points every β_k is β exactly, whatever ρ_E and however much of the
/// ring is visible.
pub fn cross_product_samples(points: &[[f64; 3]]) -> RingSamples {
    let mut sorted: Vec<(f64, [f64; 3])> = points.iter().map(|p| (p[1].atan2(p[0]), *p)).collect();
    sorted.sort_by(|a, b| a.0.total_cmp(&b.0));
    let n = sorted.len() / 3;
    let mut mean = [0.0; 3];
    for (_, p) in &sorted {
        for i in 0..3 {
            mean[i] += p[i];
        }
    }
    let mut out = RingSamples::default();
    let mut sum_normal = [0.0; 3];
    for k in 0..n {
        let (a, b, c) = (sorted[k].1, sorted[n + k].1, sorted[2 * n + k].1);
        let v = cross(sub(a, b), sub(c, b));
        let norm = dot(v, v).sqrt();
        if norm.is_nan() || norm < 1e-9 {
            continue;
        }
        let s = if dot(v, mean) < 0.0 { -1.0 } else { 1.0 } / norm;
        let nh = [v[0] * s, v[1] * s, v[2] * s];
        out.beta_deg
            .push(nh[2].clamp(-1.0, 1.0).acos() * 180.0 / PI);
        out.tilt_deg.push(nh[0].atan2(nh[2]) * 180.0 / PI);
        out.azimuth_deg.push(nh[1].atan2(nh[0]) * 180.0 / PI);
        for i in 0..3 {
            sum_normal[i] += nh[i];
        }
    }
    let len = dot(sum_normal, sum_normal).sqrt();
    if len > 0.0 {
        out.mean_normal = sum_normal.map(|v| v / len);
    }
    out
}

/// ρ_E = arcsin(R_E / (R_E + h)), the Earth's angular radius from altitude h [rad].
pub fn earth_angular_radius_rad(altitude_km: f64) -> f64 {
    // The mean radius, as math.md §4.1 (60.486° at 950 km).
    const EARTH_RADIUS_KM: f64 = 6371.0;
    (EARTH_RADIUS_KM / (EARTH_RADIUS_KM + altitude_km)).asin()
}

#[cfg(test)]
#[path = "ring_tests.rs"]
mod tests;
