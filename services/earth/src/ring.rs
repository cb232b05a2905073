//! From limb pixels to the angle samples: undistortion onto the unit sphere (docs/math.md §4.3,
//! eqs 6–9) and the interval cross product (§4.4, eqs 10–11).
//!
//! The camera ([`Fisheye`]) is glint-physics', shared with the sensor that renders the frames.

use std::f64::consts::PI;

pub use glint_physics::fisheye::{earth_angular_radius_rad, Fisheye};

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

#[cfg(test)]
#[path = "ring_tests.rs"]
mod tests;
