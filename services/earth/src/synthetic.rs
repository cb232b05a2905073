//! Reference frames in closed form, for tests and benchmarks: the Earth seen through `cam`
//! with its nadir tilted by `tilt_deg` about Y_S, the limb blurred by a Gaussian PSF of
//! `psf_px` — brightness `space + contrast · ½ erfc(d / (σ√2))` at d px outside the limb —
//! computed per pixel from the geometry alone, with no table and no noise.

use crate::ring::{earth_angular_radius_rad, Fisheye};

/// A `width`×`height` frame from 950 km: space 20 DN, Earth 3020 DN, PSF 1.2 px.
pub fn blurred_earth(width: usize, height: usize, cam: &Fisheye, tilt_deg: f64) -> Vec<u16> {
    let rho = earth_angular_radius_rad(950.0);
    let (s, c) = tilt_deg.to_radians().sin_cos();
    let e = [s, 0.0, c];
    (0..width * height)
        .map(|i| {
            let u = cam.direction((i % width) as f64, (i / width) as f64);
            let angle = (u[0] * e[0] + u[1] * e[1] + u[2] * e[2])
                .clamp(-1.0, 1.0)
                .acos();
            let d_px = (angle - rho) * cam.f_px;
            (20.0 + 3000.0 * 0.5 * libm::erfc(d_px / (1.2 * std::f64::consts::SQRT_2))) as u16
        })
        .collect()
}
