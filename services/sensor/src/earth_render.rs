//! The [003] infrared Earth frame (docs/math.md §4.1): the Earth seen through an equidistant
//! fisheye from a circular orbit, bright against cold space, the limb blurred by a Gaussian
//! PSF, with read noise; the lens image circle bounds the picture.
//!
//! A pixel of direction u sees the Earth when ∠(u, ê) < ρ_E. Blurred by a PSF of σ px, its
//! brightness is `space + (earth − space) · ½ erfc(d / (σ√2))` with d = (∠(u, ê) − ρ_E) f the
//! distance to the limb in pixels (the limb is locally straight at the PSF's scale). The
//! profile depends on u·ê only, so it is tabulated once over the limb band in u·ê and read per
//! pixel by linear interpolation; each pixel's direction is computed once per camera.

use glint_physics::fisheye::{earth_angular_radius_rad, Fisheye};

use crate::earth_hazards::{HazardFrame, Hazards};
use crate::render::noise::{NormalTable, Xoshiro256pp};

/// PRNG stream offset of the Earth frames' noise (stream = offset + frame index).
const EARTH_STREAM: u64 = 1 << 41;
/// The tabulated band reaches this many PSF σ either side of the limb.
const BAND_SIGMAS: f64 = 8.0;
const PROFILE_LEN: usize = 8192;

/// What the Earth camera sees and how it records it.
#[derive(Clone, Debug, PartialEq)]
pub struct EarthRenderConfig {
    pub width_px: usize,
    pub height_px: usize,
    pub camera: Fisheye,
    /// Orbit altitude [km] (the Earth's angular radius ρ_E).
    pub altitude_km: f64,
    /// Radius of the lens image circle [px]; outside it the detector sees nothing (0 DN).
    pub image_circle_px: f64,
    /// Earth and space radiance as recorded [DN].
    pub earth_dn: f64,
    pub space_dn: f64,
    /// PSF σ [px], > 0.
    pub psf_sigma_px: f64,
    /// Read noise σ [DN], ≥ 0.
    pub noise_dn: f64,
    pub saturation_dn: u16,
    /// Oblateness, a seasonal limb, the Sun in the field: none by default.
    pub hazards: Hazards,
}

/// The renderer: each pixel's direction, the limb profile, the noise table.
pub struct EarthRenderer {
    config: EarthRenderConfig,
    /// Per pixel: its direction, or None outside the image circle.
    directions: Vec<Option<[f32; 3]>>,
    cos_rho_lo: f64,
    cos_rho_hi: f64,
    profile: Vec<f32>,
    normal: NormalTable,
}

/// The nadir direction in the sensor frame for a tilt about Y_S by `tilt_deg` and an azimuth
/// of that tilt about Z_S (0: the tilt is about Y_S, nadir in the XZ plane).
pub fn nadir(tilt_deg: f64, azimuth_deg: f64) -> [f64; 3] {
    let (st, ct) = tilt_deg.to_radians().sin_cos();
    let (sa, ca) = azimuth_deg.to_radians().sin_cos();
    [st * ca, st * sa, ct]
}

impl EarthRenderer {
    pub fn new(config: EarthRenderConfig) -> Self {
        let cam = config.camera;
        let (w, h) = (config.width_px, config.height_px);
        let directions = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f64, (i / w) as f64);
                let r = (x - cam.x0_px).hypot(y - cam.y0_px);
                (r <= config.image_circle_px).then(|| cam.direction(x, y).map(|v| v as f32))
            })
            .collect();
        let rho = earth_angular_radius_rad(config.altitude_km);
        let band = BAND_SIGMAS * config.psf_sigma_px / cam.f_px;
        let (cos_rho_lo, cos_rho_hi) = (
            (rho + band).min(std::f64::consts::PI).cos(),
            (rho - band).max(0.0).cos(),
        );
        let sigma = config.psf_sigma_px * std::f64::consts::SQRT_2;
        let profile = (0..PROFILE_LEN)
            .map(|k| {
                let c =
                    cos_rho_lo + (cos_rho_hi - cos_rho_lo) * k as f64 / (PROFILE_LEN - 1) as f64;
                let d_px = (c.clamp(-1.0, 1.0).acos() - rho) * cam.f_px;
                (0.5 * libm::erfc(d_px / sigma)) as f32
            })
            .collect();
        Self {
            config,
            directions,
            cos_rho_lo,
            cos_rho_hi,
            profile,
            normal: NormalTable::new(),
        }
    }

    pub fn config(&self) -> &EarthRenderConfig {
        &self.config
    }

    /// The Earth's share of a pixel of direction u: the limb profile at u·ê.
    #[inline]
    fn earth_fraction(&self, c: f64) -> f32 {
        if c >= self.cos_rho_hi {
            return 1.0;
        }
        if c <= self.cos_rho_lo {
            return 0.0;
        }
        let t =
            (c - self.cos_rho_lo) / (self.cos_rho_hi - self.cos_rho_lo) * (PROFILE_LEN - 1) as f64;
        let k = (t as usize).min(PROFILE_LEN - 2);
        let f = (t - k as f64) as f32;
        self.profile[k] * (1.0 - f) + self.profile[k + 1] * f
    }

    /// Renders frame `frame_index` with nadir `e` (a unit vector in the sensor frame) into
    /// `out` (width × height pixels, row-major); false if `out` has another length.
    pub fn render(&self, e: [f64; 3], seed: u64, frame_index: u64, out: &mut [u16]) -> bool {
        if out.len() != self.directions.len() {
            return false;
        }
        let c = &self.config;
        let mut rng = Xoshiro256pp::new(seed, EARTH_STREAM + frame_index);
        let (earth, space) = (c.earth_dn as f32, c.space_dn as f32);
        let (noise, sat) = (c.noise_dn as f32, f32::from(c.saturation_dn));
        let mut z = [0.0f32; 4];
        if c.hazards.any() {
            let frame =
                HazardFrame::new(c.hazards, e, c.altitude_km, c.camera.f_px, c.psf_sigma_px);
            for (i, (px, dir)) in out.iter_mut().zip(&self.directions).enumerate() {
                if i % 4 == 0 {
                    z = self.normal.sample4(&mut rng);
                }
                let Some(u) = dir else {
                    *px = 0;
                    continue;
                };
                let u = u.map(f64::from);
                let v = frame.value(u, c.earth_dn, c.space_dn) as f32 + noise * z[i % 4];
                *px = v.round().clamp(0.0, sat) as u16;
            }
            return true;
        }
        for (i, (px, dir)) in out.iter_mut().zip(&self.directions).enumerate() {
            if i % 4 == 0 {
                z = self.normal.sample4(&mut rng);
            }
            let Some(u) = dir else {
                *px = 0;
                continue;
            };
            let dot = f64::from(u[0]) * e[0] + f64::from(u[1]) * e[1] + f64::from(u[2]) * e[2];
            let v = space + (earth - space) * self.earth_fraction(dot) + noise * z[i % 4];
            *px = v.round().clamp(0.0, sat) as u16;
        }
        true
    }
}

#[cfg(test)]
#[path = "earth_render_tests.rs"]
mod tests;
