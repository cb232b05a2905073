//! The `[earth]` section: the [003] static infrared Earth sensor — an equidistant fisheye
//! staring at the Earth from a circular orbit, turned on a one-axis turntable (docs/math.md §4).

use serde::{Deserialize, Serialize};

use super::*;

/// The Earth sensor, its orbit and its attitude sweep.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EarthScenario {
    /// Image width and height [px], 64–2048.
    pub width_px: u32,
    pub height_px: u32,
    /// Fisheye focal length [px/rad] (`r = f θ`, eq 1), 10–10000.
    pub f_px: f64,
    /// The lens's Kannala–Brandt distortion k₁…k₄ (OpenCV's fisheye `D`): `r = f θ_d`,
    /// `θ_d = θ (1 + k₁θ² + k₂θ⁴ + k₃θ⁶ + k₄θ⁸)`, each −1–1, θ_d growing with θ across the
    /// image circle; 0 (default) is the ideal `r = f θ`.
    pub lens_k: [f64; 4],
    /// The distortion the earth service is told (its calibration), each −1–1; absent: the
    /// lens's own (a perfect calibration).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub calibration_k: Option<[f64; 4]>,
    /// Principal point (X0, Y0) [px], 0-based with the first pixel's centre at (0, 0); inside
    /// the image.
    pub center_px: [f64; 2],
    /// Radius of the lens image circle [px], 10–4096: outside it the detector sees nothing.
    pub image_circle_px: f64,
    /// Circular-orbit altitude [km], 100–100000 (the paper's simulator: 950 km).
    pub altitude_km: f64,
    /// Earth and cold-space radiance as recorded [DN], 0–65535, Earth brighter than space.
    pub earth_dn: f64,
    pub space_dn: f64,
    /// Limb blur: Gaussian PSF σ [px], 0.2–10.
    pub psf_sigma_px: f64,
    /// Read noise σ [DN], 0–5000.
    pub noise_dn: f64,
    /// Detector full scale [DN], 1–65535.
    pub saturation_dn: u32,
    /// Time between frames [s], 1e-4–100 (the frame at index k ends its exposure at
    /// (k + 1) × this).
    pub frame_period_s: f64,
    /// Frames per turntable angle (the paper's K), 1–1000.
    pub images_per_angle: u32,
    /// The turntable's axis, as the azimuth of the tilt about Z_S [deg], −180–180: 0 turns
    /// the nadir in the X_S Z_S plane (tilt about Y_S).
    pub turntable_azimuth_deg: f64,
    /// A given trajectory of nadir tilts [deg], each −80–80, instead of the paper's sweep
    /// (−10° to 10° in 0.1° steps, ±10° to ±50° in 1° steps); `images_per_angle` frames each.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub trajectory_deg: Vec<f64>,
    /// The lookup version's σ(μ) table (`glint tool earth-calibrate` writes it); relative to the
    /// scenario file. Absent: the lookup uses each frame's own fitted σ.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma_table: Option<std::path::PathBuf>,
    /// Strong-edge threshold on the Sobel magnitude [DN]; absent: Otsu per frame.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub edge_threshold_dn: Option<f64>,
    /// Harder frames, all off by default. The Earth's flattening, 0–0.01 (0: a sphere; WGS 84:
    /// 0.0033528), its polar axis along Y_S.
    pub flattening: f64,
    /// The limb radiance's relative change from pole to pole (a seasonal limb), 0–0.9.
    pub limb_radiance_amplitude: f64,
    /// The limb's height above the mean Earth radius [km] (the CO₂ layer the sensor sees),
    /// −50–200: its mean, the seasonal difference between the summer and winter poles' limb
    /// (`limb_height_seasonal_km`, −50–50: H varies as ½ this × sin(latitude)), and the
    /// equator's over the poles' (`limb_height_latitude_km`, −50–50: as ½ this × cos(2·lat)
    /// about the mean). The earth service assumes 0 everywhere: the mean only rescales the
    /// ring, the variations tilt and stretch it.
    pub limb_height_km: f64,
    pub limb_height_seasonal_km: f64,
    pub limb_height_latitude_km: f64,
    /// The Sun in the field: its recorded radiance [DN], 0 (no Sun) to 1e6 (it saturates).
    pub sun_dn: f64,
    /// Its direction: angle from the optical axis, 0–180, and azimuth from X_S, −180–180 [deg].
    pub sun_direction_deg: [f64; 2],
}

impl Default for EarthScenario {
    fn default() -> Self {
        EarthScenario {
            width_px: 512,
            height_px: 512,
            f_px: 130.0,
            lens_k: [0.0; 4],
            calibration_k: None,
            center_px: [255.5, 255.5],
            image_circle_px: 255.0,
            altitude_km: 950.0,
            earth_dn: 3020.0,
            space_dn: 20.0,
            psf_sigma_px: 1.2,
            noise_dn: 10.0,
            saturation_dn: 4095,
            frame_period_s: 0.1,
            images_per_angle: 1,
            turntable_azimuth_deg: 0.0,
            trajectory_deg: vec![],
            sigma_table: None,
            edge_threshold_dn: None,
            flattening: 0.0,
            limb_radiance_amplitude: 0.0,
            limb_height_km: 0.0,
            limb_height_seasonal_km: 0.0,
            limb_height_latitude_km: 0.0,
            sun_dn: 0.0,
            sun_direction_deg: [100.0, 90.0],
        }
    }
}

/// The paper's turntable angles [deg], ascending: −50° to −11° in 1° steps, −10° to 10° in
/// 0.1° steps, 11° to 50° in 1° steps (281 angles).
pub fn paper_sweep_deg() -> Vec<f64> {
    let coarse = |sign: f64| (11..=50).map(move |d| sign * d as f64);
    let mut v: Vec<f64> = coarse(-1.0).collect();
    v.reverse();
    v.extend((-100..=100).map(|t| t as f64 / 10.0));
    v.extend(coarse(1.0));
    v
}

impl EarthScenario {
    /// Pixels of one Earth frame.
    pub fn pixels(&self) -> usize {
        self.width_px as usize * self.height_px as usize
    }

    /// The turntable angles [deg] in order: the trajectory, or the paper's sweep.
    pub fn angles_deg(&self) -> Vec<f64> {
        if self.trajectory_deg.is_empty() {
            paper_sweep_deg()
        } else {
            self.trajectory_deg.clone()
        }
    }

    /// Frames over the whole run.
    pub fn frames(&self) -> u64 {
        self.angles_deg().len() as u64 * self.images_per_angle as u64
    }

    /// The nadir tilt [deg] of frame `k`.
    pub fn tilt_deg(&self, angles: &[f64], k: u64) -> f64 {
        let i = (k / self.images_per_angle.max(1) as u64) as usize;
        angles.get(i).copied().unwrap_or(0.0)
    }

    /// The end of frame `k`'s exposure [ns since scenario start].
    pub fn exposure_end_ns(&self, k: u64) -> u64 {
        ((k + 1) as f64 * self.frame_period_s * 1e9).round() as u64
    }
}

pub(super) fn check_earth(c: &mut Checker, e: &EarthScenario) {
    c.range_u("earth.width_px", e.width_px as u64, 64, 2048);
    c.range_u("earth.height_px", e.height_px as u64, 64, 2048);
    c.range("earth.f_px", e.f_px, 10.0, 10_000.0);
    c.range(
        "earth.center_px[0]",
        e.center_px[0],
        0.0,
        e.width_px as f64 - 1.0,
    );
    c.range(
        "earth.center_px[1]",
        e.center_px[1],
        0.0,
        e.height_px as f64 - 1.0,
    );
    c.range("earth.image_circle_px", e.image_circle_px, 10.0, 4096.0);
    for (name, k) in std::iter::once(("earth.lens_k", &e.lens_k))
        .chain((e.calibration_k.as_ref()).map(|k| ("earth.calibration_k", k)))
    {
        for (i, v) in k.iter().enumerate() {
            c.range(&format!("{name}[{i}]"), *v, -1.0, 1.0);
        }
        if let Some(theta_deg) = kb_fold_deg(k, e.f_px, e.image_circle_px) {
            c.fail(
                name,
                format!(
                    "θ_d stops growing at θ = {theta_deg:.1}°, inside the image circle \
                     ({} px): the lens would image two angles to one radius",
                    e.image_circle_px
                ),
            );
        }
    }
    c.range("earth.altitude_km", e.altitude_km, 100.0, 100_000.0);
    c.range("earth.earth_dn", e.earth_dn, 0.0, 65535.0);
    c.range("earth.space_dn", e.space_dn, 0.0, 65535.0);
    if e.earth_dn <= e.space_dn {
        c.fail(
            "earth.earth_dn",
            format!(
                "{} must be above earth.space_dn = {} (the Earth is the warm side)",
                e.earth_dn, e.space_dn
            ),
        );
    }
    c.range("earth.psf_sigma_px", e.psf_sigma_px, 0.2, 10.0);
    c.range("earth.noise_dn", e.noise_dn, 0.0, 5000.0);
    c.range_u("earth.saturation_dn", e.saturation_dn as u64, 1, 65535);
    c.range("earth.frame_period_s", e.frame_period_s, 1e-4, 100.0);
    c.range_u("earth.images_per_angle", e.images_per_angle as u64, 1, 1000);
    c.range(
        "earth.turntable_azimuth_deg",
        e.turntable_azimuth_deg,
        -180.0,
        180.0,
    );
    c.range_u(
        "earth.trajectory_deg (count)",
        e.trajectory_deg.len() as u64,
        0,
        1_000_000,
    );
    for (i, t) in e.trajectory_deg.iter().enumerate() {
        c.range(&format!("earth.trajectory_deg[{i}]"), *t, -80.0, 80.0);
    }
    c.range_u(
        "earth frames (angles × images_per_angle)",
        e.frames(),
        1,
        10_000_000,
    );
    if let Some(t) = e.edge_threshold_dn {
        c.range("earth.edge_threshold_dn", t, 0.0, 1e7);
    }
    c.range("earth.flattening", e.flattening, 0.0, 0.01);
    c.range(
        "earth.limb_radiance_amplitude",
        e.limb_radiance_amplitude,
        0.0,
        0.9,
    );
    c.range("earth.limb_height_km", e.limb_height_km, -50.0, 200.0);
    c.range(
        "earth.limb_height_seasonal_km",
        e.limb_height_seasonal_km,
        -50.0,
        50.0,
    );
    c.range(
        "earth.limb_height_latitude_km",
        e.limb_height_latitude_km,
        -50.0,
        50.0,
    );
    c.range("earth.sun_dn", e.sun_dn, 0.0, 1e6);
    c.range(
        "earth.sun_direction_deg[0]",
        e.sun_direction_deg[0],
        0.0,
        180.0,
    );
    c.range(
        "earth.sun_direction_deg[1]",
        e.sun_direction_deg[1],
        -180.0,
        180.0,
    );
}

/// The first angle [deg] at which a Kannala–Brandt lens's θ_d stops growing while its image
/// radius f θ_d is still inside the image circle, if any (0.1° steps up to 180°).
fn kb_fold_deg(k: &[f64; 4], f_px: f64, image_circle_px: f64) -> Option<f64> {
    let theta_d = |t: f64| {
        let t2 = t * t;
        t * (1.0 + t2 * (k[0] + t2 * (k[1] + t2 * (k[2] + t2 * k[3]))))
    };
    let mut last = 0.0;
    for step in 1..=1800 {
        let deg = step as f64 / 10.0;
        let d = theta_d(deg.to_radians());
        if d <= last {
            return Some(deg);
        }
        if f_px * d > image_circle_px {
            return None;
        }
        last = d;
    }
    None
}
