//! The `[camera]` section: the [002] debris camera, scene, laser, detector and tracker.

use serde::{Deserialize, Serialize};

use super::*;

/// One debris object: initial state relative to the observer in its LVLH-nadir frame
/// (x along-track, y = −orbit normal, z nadir; [002] Table 4, math.md §3.1).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Debris {
    pub x_m: f64,
    pub y_m: f64,
    pub z_m: f64,
    pub vx_mps: f64,
    pub vy_mps: f64,
    pub vz_mps: f64,
    /// Debris size [m], 0.001–100; brightness scales with (size/range)².
    pub size_m: f64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FalseTargets {
    /// Number of random point-like false targets per listed frame, 0–16.
    pub count: u32,
    /// Frame indices that get false targets.
    #[serde(default = "default_false_frames")]
    pub frames: Vec<u64>,
    /// Integrated signal of one false target [DN], 0–1e7.
    #[serde(default = "default_false_signal")]
    pub signal_dn: f64,
}

fn default_false_frames() -> Vec<u64> {
    vec![0]
}
fn default_false_signal() -> f64 {
    20000.0
}

impl Default for FalseTargets {
    fn default() -> Self {
        FalseTargets {
            count: 0,
            frames: default_false_frames(),
            signal_dn: default_false_signal(),
        }
    }
}

/// The laser rangefinder ([002] Table 2).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LaserScenario {
    /// Full beam width [deg], 0.001–10.
    pub beam_deg: f64,
    /// Ranging noise, 1σ [m], 0–100 (the paper: 0.1 m at 3σ).
    pub range_sigma_m: f64,
    /// Delay between firing and the echo [s], 0–1.
    pub delay_s: f64,
}

impl Default for LaserScenario {
    fn default() -> Self {
        LaserScenario {
            beam_deg: 0.5,
            range_sigma_m: 0.1 / 3.0,
            delay_s: 0.03,
        }
    }
}

/// The debris camera and scene ([002] Tables 1, 4; math.md §3.2, §3.9).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraScenario {
    /// Image width and height [px], 16–4096.
    pub width_px: u32,
    pub height_px: u32,
    /// Full field of view along each axis [deg], 0.1–90.
    pub fov_deg: f64,
    /// Exposure time [s], 1e-5–10.
    pub exposure_s: f64,
    /// Gap between exposures [s], 0–10.
    pub interval_s: f64,
    /// Number of frames to produce, 1–10_000_000.
    pub frames: u64,
    /// Mean sky + dark background [DN], 0–60000.
    #[serde(default = "default_background")]
    pub background_dn: f64,
    /// Read noise, 1σ [DN], 0–5000.
    #[serde(default = "default_read_noise")]
    pub read_noise_dn: f64,
    /// Saturation level [DN], 1–65535.
    #[serde(default = "default_saturation")]
    pub saturation_dn: u32,
    /// Gaussian PSF σ [px], 0.2–5.
    #[serde(default = "default_psf")]
    pub psf_sigma_px: f64,
    /// Integrated signal of a 0.1 m debris at 10 km [DN], 1–1e8.
    #[serde(default = "default_reference_signal")]
    pub reference_signal_dn: f64,
    /// Semi-major axis of the observer's circular orbit [km], 6500–500000 (GEO: 42164.1696).
    #[serde(default = "default_sma")]
    pub orbit_semi_major_axis_km: f64,
    /// 1–16 debris objects.
    pub debris: Vec<Debris>,
    #[serde(default)]
    pub false_targets: FalseTargets,
    #[serde(default)]
    pub laser: LaserScenario,
    #[serde(default)]
    pub detector: DetectorScenario,
    #[serde(default)]
    pub tracker: TrackerScenario,
}

/// Detector and inter-frame matcher settings ([002] §3.3–3.4). The paper gives no thresholds;
/// math.md's starting values (T_m 0.2, T_a 0.2, T_θ 5°, T_e 0.05) lose the short (1–10 px)
/// streaks of the [002] scene, whose eccentricity varies by ±0.3 and orientation by ±10° from
/// frame to frame under read noise, so the defaults here are wider; the centroid gate (eq 8)
/// does the discriminating.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DetectorScenario {
    /// Foreground threshold: background + k·σ (σ = 1.4826·MAD of the frame), 1–100.
    pub threshold_k_sigma: f64,
    /// Smallest connected component kept [px], 1–10000.
    pub min_area_px: u32,
    /// Matching gate T_m as a fraction of the previous area, 0.01–10.
    pub area_tol_frac: f64,
    /// Matching gate T_a as a fraction of the previous semi-major axis, 0.01–10.
    pub semi_axis_tol_frac: f64,
    /// Matching gate T_θ [deg], 0.1–90 (skipped for near-round blobs).
    pub theta_tol_deg: f64,
    /// Matching gate T_e, 0.001–1.
    pub ecc_tol: f64,
    /// Blobs with eccentricity below this are "round": no θ gate, and no e gate when both blobs
    /// are round (θ and e are noise for near-round blobs), 0–1.
    pub round_ecc: f64,
    /// δ_l of the centroid gate, eq (8) [px], 0–100.
    pub gate_margin_px: f64,
    /// Frames a matched object may go undetected before its track is dropped, 0–100.
    pub max_coast_frames: u32,
}

impl Default for DetectorScenario {
    fn default() -> Self {
        DetectorScenario {
            threshold_k_sigma: 5.0,
            min_area_px: 3,
            area_tol_frac: 0.3,
            semi_axis_tol_frac: 0.3,
            theta_tol_deg: 20.0,
            ecc_tol: 0.3,
            round_ecc: 0.7,
            gate_margin_px: 3.0,
            max_coast_frames: 2,
        }
    }
}

/// Tracker settings ([002] §3.6–3.8).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TrackerScenario {
    /// 1σ noise of a detection's line of sight assumed by the filters [px], 0.001–10. The
    /// default matches the centroid accuracy measured on the [002] scene (0.01–0.03 px).
    pub angle_sigma_px: f64,
    /// Angle-filter process noise √q_a [rad/s²], 0–1. math.md §3.6 suggests ≈ 1e-3; the line-of-
    /// sight accelerations of the [002] debris reach several 1e-3 rad/s², and at 1e-3 the
    /// filter lags behind its own measurements, so the default is 1e-2.
    pub angle_accel_rad_s2: f64,
    /// EKF process noise σ_a [m s^-1.5], 0–100 (math.md §3.8: 1e-3).
    pub ekf_accel_sigma: f64,
    /// Consecutive hits that confirm a track, 1–100.
    pub confirm_hits: u32,
    /// Consecutive misses that delete a track, 1–100.
    pub delete_misses: u32,
    /// Fire the laser at confirmed tracks.
    pub laser: bool,
    /// Wall-clock wait for a laser echo before the filter goes on with angles only [ms], 1–60000.
    pub range_timeout_ms: u64,
}

impl Default for TrackerScenario {
    fn default() -> Self {
        TrackerScenario {
            angle_sigma_px: 0.03,
            angle_accel_rad_s2: 1e-2,
            ekf_accel_sigma: 1e-3,
            confirm_hits: 2,
            delete_misses: 3,
            laser: true,
            range_timeout_ms: 1000,
        }
    }
}

fn default_background() -> f64 {
    100.0
}
fn default_read_noise() -> f64 {
    5.0
}
fn default_saturation() -> u32 {
    65535
}
fn default_psf() -> f64 {
    0.8
}
fn default_reference_signal() -> f64 {
    40000.0
}
fn default_sma() -> f64 {
    42164.1696
}

impl CameraScenario {
    pub fn pixels(&self) -> usize {
        self.width_px as usize * self.height_px as usize
    }
    pub fn frame_period_ns(&self) -> u64 {
        ((self.exposure_s + self.interval_s) * 1e9).round() as u64
    }
}

/// `soak`: the camera runs until a soak ends (its frame count is the soak's, unbounded).
pub(super) fn check_camera(c: &mut Checker, cam: &CameraScenario, soak: bool) {
    c.range_u("camera.width_px", cam.width_px as u64, 16, 4096);
    c.range_u("camera.height_px", cam.height_px as u64, 16, 4096);
    c.range("camera.fov_deg", cam.fov_deg, 0.1, 90.0);
    c.range("camera.exposure_s", cam.exposure_s, 1e-5, 10.0);
    c.range("camera.interval_s", cam.interval_s, 0.0, 10.0);
    let frames_max = if soak { super::SOAK_FRAMES } else { 10_000_000 };
    c.range_u("camera.frames", cam.frames, 1, frames_max);
    c.range("camera.background_dn", cam.background_dn, 0.0, 60000.0);
    c.range("camera.read_noise_dn", cam.read_noise_dn, 0.0, 5000.0);
    c.range_u("camera.saturation_dn", cam.saturation_dn as u64, 1, 65535);
    c.range("camera.psf_sigma_px", cam.psf_sigma_px, 0.2, 5.0);
    c.range(
        "camera.reference_signal_dn",
        cam.reference_signal_dn,
        1.0,
        1e8,
    );
    c.range(
        "camera.orbit_semi_major_axis_km",
        cam.orbit_semi_major_axis_km,
        6500.0,
        500_000.0,
    );
    c.range_u("camera.debris (count)", cam.debris.len() as u64, 1, 16);
    for (i, d) in cam.debris.iter().enumerate() {
        let p = |f: &str| format!("camera.debris[{i}].{f}");
        for (f, v) in [("x_m", d.x_m), ("y_m", d.y_m), ("z_m", d.z_m)] {
            c.range(&p(f), v, -1e8, 1e8);
        }
        for (f, v) in [
            ("vx_mps", d.vx_mps),
            ("vy_mps", d.vy_mps),
            ("vz_mps", d.vz_mps),
        ] {
            c.range(&p(f), v, -1e5, 1e5);
        }
        c.range(&p("size_m"), d.size_m, 0.001, 100.0);
        if d.x_m <= 0.0 && d.x_m.is_finite() {
            c.fail(&p("x_m"), "must be > 0: the camera looks along +x".into());
        }
    }
    let ft = &cam.false_targets;
    c.range_u("camera.false_targets.count", ft.count as u64, 0, 16);
    c.range("camera.false_targets.signal_dn", ft.signal_dn, 0.0, 1e7);
    // Only against a valid frame count (frames = 0 is its own error).
    for (i, f) in ft.frames.iter().enumerate() {
        if cam.frames >= 1 && *f >= cam.frames {
            c.fail(
                &format!("camera.false_targets.frames[{i}]"),
                format!(
                    "{f} is out of range; allowed 0..={}",
                    cam.frames.saturating_sub(1)
                ),
            );
        }
    }
    c.range("camera.laser.beam_deg", cam.laser.beam_deg, 0.001, 10.0);
    c.range(
        "camera.laser.range_sigma_m",
        cam.laser.range_sigma_m,
        0.0,
        100.0,
    );
    c.range("camera.laser.delay_s", cam.laser.delay_s, 0.0, 1.0);
    let d = &cam.detector;
    c.range(
        "camera.detector.threshold_k_sigma",
        d.threshold_k_sigma,
        1.0,
        100.0,
    );
    c.range_u(
        "camera.detector.min_area_px",
        d.min_area_px as u64,
        1,
        10_000,
    );
    c.range("camera.detector.area_tol_frac", d.area_tol_frac, 0.01, 10.0);
    c.range(
        "camera.detector.semi_axis_tol_frac",
        d.semi_axis_tol_frac,
        0.01,
        10.0,
    );
    c.range("camera.detector.theta_tol_deg", d.theta_tol_deg, 0.1, 90.0);
    c.range("camera.detector.ecc_tol", d.ecc_tol, 0.001, 1.0);
    c.range("camera.detector.round_ecc", d.round_ecc, 0.0, 1.0);
    c.range(
        "camera.detector.gate_margin_px",
        d.gate_margin_px,
        0.0,
        100.0,
    );
    c.range_u(
        "camera.detector.max_coast_frames",
        d.max_coast_frames as u64,
        0,
        100,
    );
    let t = &cam.tracker;
    c.range(
        "camera.tracker.angle_sigma_px",
        t.angle_sigma_px,
        0.001,
        10.0,
    );
    c.range(
        "camera.tracker.angle_accel_rad_s2",
        t.angle_accel_rad_s2,
        0.0,
        1.0,
    );
    c.range(
        "camera.tracker.ekf_accel_sigma",
        t.ekf_accel_sigma,
        0.0,
        100.0,
    );
    c.range_u("camera.tracker.confirm_hits", t.confirm_hits as u64, 1, 100);
    c.range_u(
        "camera.tracker.delete_misses",
        t.delete_misses as u64,
        1,
        100,
    );
    c.range_u(
        "camera.tracker.range_timeout_ms",
        t.range_timeout_ms,
        1,
        60_000,
    );
}
