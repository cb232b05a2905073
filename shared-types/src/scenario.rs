//! The scenario file: one TOML document that describes a whole deployment.
//!
//! Parsing is strict (`deny_unknown_fields`), and [`Scenario::validate`] checks every number
//! against its documented range, so a typo or an out-of-range value is reported with the file,
//! the field path and the allowed range instead of surfacing later as a wrong result.
//! The field docs here are the reference for the README's scenario section.

use serde::{Deserialize, Serialize};

/// A scenario problem: where it is and what is allowed.
#[derive(Debug, Clone, PartialEq)]
pub struct FieldError {
    /// Dotted path of the field, e.g. `camera.fov_deg` or `camera.debris[2].x_m`.
    pub field: String,
    /// What is wrong and what is allowed.
    pub message: String,
}

impl std::fmt::Display for FieldError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "field `{}`: {}", self.field, self.message)
    }
}

#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    #[error("{file}: cannot read: {source}")]
    Io {
        file: String,
        source: std::io::Error,
    },
    #[error("{file}:{line}: field `{field}`: {message}")]
    Parse {
        file: String,
        line: usize,
        field: String,
        message: String,
    },
    #[error("{file}: {}", .errors.iter().map(|e| e.to_string()).collect::<Vec<_>>().join("; "))]
    Invalid {
        file: String,
        errors: Vec<FieldError>,
    },
}

/// Which clock drives the run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Clock {
    /// Simulated time in lockstep with backpressure: nothing is dropped, runs are deterministic.
    #[default]
    Sim,
    /// The sensor paces frames at the scenario rate; slow consumers drop (counted) frames.
    Realtime,
}

/// Top level of a scenario file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// Short name, used in the run directory name. 1–64 characters of `[A-Za-z0-9_-]`.
    pub name: String,
    /// Free text shown in the summary.
    #[serde(default)]
    pub description: String,
    /// Seed of every random draw in the run (noise, false targets). `--seed` overrides it.
    #[serde(default = "default_seed")]
    pub seed: u64,
    /// `sim` (default) or `realtime`.
    #[serde(default)]
    pub clock: Clock,
    /// Limits of the run itself.
    #[serde(default)]
    pub run: RunLimits,
    /// The debris camera ([002]); absent = no frames.
    pub camera: Option<CameraScenario>,
    /// The spectrometer looking at the satellite ([000]); absent = no spectra.
    pub spectra: Option<SpectraScenario>,
    /// Sweep one parameter: one full deployment per value, results tabulated.
    pub campaign: Option<Campaign>,
}

/// A one-parameter sweep ([000] studies: phase, SNR, body shape, rotation axis, seed).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Campaign {
    /// One of `spectra.start_phase_deg`, `spectra.snr`, `spectra.body_shape`,
    /// `spectra.materials`, `spectra.rotation` (values "y" or "z": 0.25 deg/frame about that
    /// body axis), `seed`.
    pub parameter: String,
    /// 1–100 values of that parameter.
    pub values: Vec<toml::Value>,
    /// The paper's figure for each value (its error metric), shown beside ours; optional.
    #[serde(default)]
    pub paper: Vec<f64>,
}

/// Parameters a campaign may sweep.
pub const CAMPAIGN_PARAMETERS: [&str; 6] = [
    "spectra.start_phase_deg",
    "spectra.snr",
    "spectra.body_shape",
    "spectra.materials",
    "spectra.rotation",
    "seed",
];

impl Scenario {
    /// The scenario of one campaign value (no campaign section, name suffixed).
    pub fn campaign_variant(&self, index: usize) -> Result<Scenario, FieldError> {
        let c = self.campaign.as_ref().ok_or(FieldError {
            field: "campaign".into(),
            message: "no campaign section".into(),
        })?;
        let v = &c.values[index];
        let field = format!("campaign.values[{index}]");
        let bad = |m: &str| FieldError {
            field: field.clone(),
            message: format!("{v} {m}"),
        };
        let mut s = self.clone();
        s.campaign = None;
        s.name = format!("{}-{index:02}", self.name);
        let num = || v.as_float().or_else(|| v.as_integer().map(|i| i as f64));
        let text = || v.as_str().map(str::to_string);
        let sp = || {
            s.spectra
                .clone()
                .ok_or_else(|| bad("needs a [spectra] section"))
        };
        match c.parameter.as_str() {
            "seed" => {
                s.seed = v
                    .as_integer()
                    .filter(|i| *i >= 0)
                    .ok_or_else(|| bad("is not a seed (a whole number >= 0)"))?
                    as u64
            }
            "spectra.start_phase_deg" => {
                let mut x = sp()?;
                x.start_phase_deg = num().ok_or_else(|| bad("is not a number"))?;
                s.spectra = Some(x);
            }
            "spectra.snr" => {
                let mut x = sp()?;
                x.snr = Some(num().ok_or_else(|| bad("is not a number"))?);
                s.spectra = Some(x);
            }
            "spectra.body_shape" | "spectra.materials" | "spectra.rotation" => {
                let mut x = sp()?;
                let t = text().ok_or_else(|| bad("is not a string"))?;
                let parsed = toml::Value::String(t.clone());
                match c.parameter.as_str() {
                    "spectra.body_shape" => {
                        x.body_shape = parsed
                            .try_into()
                            .map_err(|_| bad("is not cube, cylinder, sphere or hexagonal-prism"))?
                    }
                    "spectra.materials" => {
                        x.materials = parsed
                            .try_into()
                            .map_err(|_| bad("is not physical or paper-like"))?
                    }
                    _ => {
                        x.rate_deg_per_frame = match t.as_str() {
                            "y" => [0.0, 0.25, 0.0],
                            "z" => [0.0, 0.0, 0.25],
                            _ => return Err(bad("is not y or z")),
                        }
                    }
                }
                s.spectra = Some(x);
            }
            other => {
                return Err(FieldError {
                    field: "campaign.parameter".into(),
                    message: format!(
                        "`{other}` cannot be swept; allowed: {}",
                        CAMPAIGN_PARAMETERS.join(", ")
                    ),
                })
            }
        }
        Ok(s)
    }
}

fn default_seed() -> u64 {
    1
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RunLimits {
    /// Wall-clock limit of the whole run [s], 1–86400. The run fails if it is exceeded.
    pub timeout_s: f64,
    /// Heartbeat period of every service [ms], 10–10000.
    pub heartbeat_period_ms: u64,
    /// A service that sends no heartbeat for this long is declared hung [ms], 100–600000.
    pub heartbeat_deadline_ms: u64,
    /// Grace period between `Shutdown` and SIGTERM, and between SIGTERM and SIGKILL [ms], 10–60000.
    pub shutdown_grace_ms: u64,
    /// Time allowed for every service to come up [ms], 100–600000.
    pub startup_timeout_ms: u64,
}

impl Default for RunLimits {
    fn default() -> Self {
        RunLimits {
            timeout_s: 300.0,
            heartbeat_period_ms: 100,
            heartbeat_deadline_ms: 5000,
            shutdown_grace_ms: 2000,
            startup_timeout_ms: 20000,
        }
    }
}

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

/// Material preset of the simulated satellite (docs: materials.md §3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum MaterialPresetName {
    /// Sourced reflectances with diffuse and broad lobes.
    #[default]
    Physical,
    /// No diffuse or broad lobes, as the paper's simulation implies.
    PaperLike,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum BodyShapeName {
    #[default]
    Cube,
    Cylinder,
    Sphere,
    HexagonalPrism,
    /// Only what the inversion's two-facet model contains: the +X body face (1.2 m × 1.2 m,
    /// MLI) and the sun-pointing panel — a diagnostic that separates model mismatch from the
    /// solver.
    TwoFacet,
}

/// Attitude matrix convention of [000] eq (17) (math.md §1.6).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum AttitudeConvention {
    /// The paper's matrices verbatim: R_Z(ψ) R_Y(φ) R_X(θ) with its active R_Y.
    #[default]
    Verbatim,
    /// The consistent passive 3-2-1 form R1(θ) R2(φ) R3(ψ).
    Consistent,
}

/// The satellite, its orbit geometry and the spectrometer ([000] Tables 1–2; math.md §1.7).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpectraScenario {
    /// First and last band centre [nm], 380–780, and the step between centres [nm], 1–100.
    pub band_start_nm: f64,
    pub band_stop_nm: f64,
    pub band_step_nm: f64,
    /// Width of each band [nm], 1–100 (the flux is band-integrated).
    #[serde(default = "default_band_width")]
    pub band_width_nm: f64,
    #[serde(default)]
    pub materials: MaterialPresetName,
    #[serde(default)]
    pub body_shape: BodyShapeName,
    /// Entrance pupil diameter [m], 0.001–10 (paper: 0.1505).
    #[serde(default = "default_aperture")]
    pub aperture_diameter_m: f64,
    /// Attitude rates during the motion window [deg/frame], each |w| ≤ 10.
    pub rate_deg_per_frame: [f64; 3],
    /// Phase angle at which the motion starts [deg], 0.5–90 (on the rising branch after the pass).
    pub start_phase_deg: f64,
    /// The stable window starts at this phase angle on the falling branch [deg], 1–120, and runs
    /// through the minimum-phase pass up to the motion start.
    #[serde(default = "default_stable_start_phase")]
    pub stable_start_phase_deg: f64,
    /// Samples in the stable window, 22–1_000_000 (≥ 2(M+1) unknowns of stage 1).
    pub stable_samples: u64,
    /// Frames in the motion window, 2–1_000_000.
    pub motion_frames: u64,
    /// Time between motion-window frames [s], 0.001–3600.
    pub frame_interval_s: f64,
    /// Signal-to-noise ratio σ = mean Φ / SNR per band; absent = noise-free. 0.01–1e9.
    pub snr: Option<f64>,
    /// Sun declination [deg], −23.5–23.5 (0 = equinox, the paper's 2019-03-21).
    #[serde(default)]
    pub sun_declination_deg: f64,
    #[serde(default)]
    pub attitude_convention: AttitudeConvention,
}

fn default_band_width() -> f64 {
    10.0
}
fn default_aperture() -> f64 {
    0.1505
}
fn default_stable_start_phase() -> f64 {
    40.0
}

impl SpectraScenario {
    /// Band centres [nm].
    pub fn wavelengths_nm(&self) -> Vec<f64> {
        let n = ((self.band_stop_nm - self.band_start_nm) / self.band_step_nm + 1e-9).floor()
            as usize
            + 1;
        (0..n)
            .map(|i| self.band_start_nm + i as f64 * self.band_step_nm)
            .collect()
    }
}

impl CameraScenario {
    pub fn pixels(&self) -> usize {
        self.width_px as usize * self.height_px as usize
    }
    pub fn frame_period_ns(&self) -> u64 {
        ((self.exposure_s + self.interval_s) * 1e9).round() as u64
    }
}

struct Checker {
    errors: Vec<FieldError>,
}

impl Checker {
    fn range(&mut self, field: &str, v: f64, lo: f64, hi: f64) {
        if !v.is_finite() {
            self.fail(
                field,
                format!("{v} is not a finite number; allowed {lo}..={hi}"),
            );
        } else if v < lo || v > hi {
            self.fail(field, format!("{v} is out of range; allowed {lo}..={hi}"));
        }
    }
    fn range_u(&mut self, field: &str, v: u64, lo: u64, hi: u64) {
        if v < lo || v > hi {
            self.fail(field, format!("{v} is out of range; allowed {lo}..={hi}"));
        }
    }
    fn fail(&mut self, field: &str, message: String) {
        self.errors.push(FieldError {
            field: field.to_string(),
            message,
        });
    }
}

impl Scenario {
    /// Parses and validates a scenario held in memory; `file` names it in errors.
    pub fn from_toml_str(text: &str, file: &str) -> Result<Scenario, ScenarioError> {
        let scenario: Scenario = toml::from_str(text).map_err(|e| parse_error(text, file, &e))?;
        scenario
            .validate()
            .map_err(|errors| ScenarioError::Invalid {
                file: file.to_string(),
                errors,
            })?;
        Ok(scenario)
    }

    /// Reads, parses and validates a scenario file.
    pub fn from_file(path: &std::path::Path) -> Result<Scenario, ScenarioError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| ScenarioError::Io {
            file: file.clone(),
            source,
        })?;
        Self::from_toml_str(&text, &file)
    }

    /// Serialises back to TOML (the resolved scenario written into the run directory).
    pub fn to_toml(&self) -> String {
        toml::to_string(self).unwrap_or_default()
    }

    /// Every range check; all problems are reported, not only the first.
    pub fn validate(&self) -> Result<(), Vec<FieldError>> {
        let mut c = Checker { errors: vec![] };
        if self.name.is_empty()
            || self.name.len() > 64
            || !self
                .name
                .chars()
                .all(|ch| ch.is_ascii_alphanumeric() || ch == '-' || ch == '_')
        {
            c.fail("name", "must be 1-64 characters of [A-Za-z0-9_-]".into());
        }
        let r = &self.run;
        c.range("run.timeout_s", r.timeout_s, 1.0, 86400.0);
        c.range_u("run.heartbeat_period_ms", r.heartbeat_period_ms, 10, 10_000);
        c.range_u(
            "run.heartbeat_deadline_ms",
            r.heartbeat_deadline_ms,
            100,
            600_000,
        );
        c.range_u("run.shutdown_grace_ms", r.shutdown_grace_ms, 10, 60_000);
        c.range_u("run.startup_timeout_ms", r.startup_timeout_ms, 100, 600_000);
        if r.heartbeat_deadline_ms < 2 * r.heartbeat_period_ms {
            c.fail(
                "run.heartbeat_deadline_ms",
                "must be at least twice run.heartbeat_period_ms".into(),
            );
        }
        if self.camera.is_none() && self.spectra.is_none() {
            c.fail(
                "camera",
                "a scenario needs a [camera] or a [spectra] section (or both)".into(),
            );
        }
        if let Some(cam) = &self.camera {
            check_camera(&mut c, cam);
        }
        if let Some(sp) = &self.spectra {
            check_spectra(&mut c, sp);
        }
        if let Some(camp) = &self.campaign {
            c.range_u("campaign.values (count)", camp.values.len() as u64, 1, 100);
            if !camp.paper.is_empty() && camp.paper.len() != camp.values.len() {
                c.fail(
                    "campaign.paper",
                    "give one paper figure per value, or none".into(),
                );
            }
            if c.errors.is_empty() {
                for i in 0..camp.values.len() {
                    match self.campaign_variant(i) {
                        Ok(v) => {
                            if let Err(errs) = v.validate() {
                                for e in errs {
                                    c.fail(
                                        &format!("campaign.values[{i}] → {}", e.field),
                                        e.message,
                                    );
                                }
                            }
                        }
                        Err(e) => c.errors.push(e),
                    }
                }
            }
        }
        if c.errors.is_empty() {
            Ok(())
        } else {
            Err(c.errors)
        }
    }
}

fn check_camera(c: &mut Checker, cam: &CameraScenario) {
    c.range_u("camera.width_px", cam.width_px as u64, 16, 4096);
    c.range_u("camera.height_px", cam.height_px as u64, 16, 4096);
    c.range("camera.fov_deg", cam.fov_deg, 0.1, 90.0);
    c.range("camera.exposure_s", cam.exposure_s, 1e-5, 10.0);
    c.range("camera.interval_s", cam.interval_s, 0.0, 10.0);
    c.range_u("camera.frames", cam.frames, 1, 10_000_000);
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
    for (i, f) in ft.frames.iter().enumerate() {
        if *f >= cam.frames {
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

fn check_spectra(c: &mut Checker, sp: &SpectraScenario) {
    c.range("spectra.band_start_nm", sp.band_start_nm, 380.0, 780.0);
    c.range("spectra.band_stop_nm", sp.band_stop_nm, 380.0, 780.0);
    c.range("spectra.band_step_nm", sp.band_step_nm, 1.0, 100.0);
    c.range("spectra.band_width_nm", sp.band_width_nm, 1.0, 100.0);
    if sp.band_stop_nm < sp.band_start_nm {
        c.fail(
            "spectra.band_stop_nm",
            "must be >= spectra.band_start_nm".into(),
        );
    } else if sp.band_step_nm >= 1.0 && sp.wavelengths_nm().len() > crate::MAX_BANDS {
        c.fail(
            "spectra.band_step_nm",
            format!("gives more than {} bands", crate::MAX_BANDS),
        );
    }
    if sp.band_start_nm - sp.band_width_nm / 2.0 < 380.0
        || sp.band_stop_nm + sp.band_width_nm / 2.0 > 780.0
    {
        c.fail(
            "spectra.band_width_nm",
            "bands must stay inside 380..=780 nm (the material data range)".into(),
        );
    }
    c.range(
        "spectra.aperture_diameter_m",
        sp.aperture_diameter_m,
        0.001,
        10.0,
    );
    for (i, w) in sp.rate_deg_per_frame.iter().enumerate() {
        c.range(&format!("spectra.rate_deg_per_frame[{i}]"), *w, -10.0, 10.0);
    }
    c.range("spectra.start_phase_deg", sp.start_phase_deg, 0.5, 90.0);
    c.range(
        "spectra.stable_start_phase_deg",
        sp.stable_start_phase_deg,
        1.0,
        120.0,
    );
    c.range_u("spectra.stable_samples", sp.stable_samples, 22, 1_000_000);
    c.range_u("spectra.motion_frames", sp.motion_frames, 2, 1_000_000);
    c.range(
        "spectra.frame_interval_s",
        sp.frame_interval_s,
        0.001,
        3600.0,
    );
    if let Some(snr) = sp.snr {
        c.range("spectra.snr", snr, 0.01, 1e9);
    }
    c.range(
        "spectra.sun_declination_deg",
        sp.sun_declination_deg,
        -23.5,
        23.5,
    );
}

/// Turns a TOML/serde error into file:line + field path.
fn parse_error(text: &str, file: &str, e: &toml::de::Error) -> ScenarioError {
    let (line, field) = match e.span() {
        Some(span) => locate(text, span.start),
        None => (0, String::from("(document)")),
    };
    ScenarioError::Parse {
        file: file.to_string(),
        line,
        field,
        message: e.message().trim().to_string(),
    }
}

/// Line number (1-based) and dotted field path at a byte offset of a TOML document.
fn locate(text: &str, offset: usize) -> (usize, String) {
    let before = &text[..offset.min(text.len())];
    let line_no = before.matches('\n').count() + 1;
    let line = text.lines().nth(line_no - 1).unwrap_or("");
    let key = line
        .split('=')
        .next()
        .map(|k| k.trim().trim_matches('"').to_string())
        .filter(|k| !k.is_empty() && !k.starts_with('['))
        .unwrap_or_default();
    let table = before
        .lines()
        .rev()
        .map(str::trim)
        .find(|l| l.starts_with('['))
        .map(|l| {
            l.trim_matches(|ch| ch == '[' || ch == ']')
                .trim()
                .to_string()
        });
    let field = match (table, key.is_empty()) {
        (Some(t), false) => format!("{t}.{key}"),
        (Some(t), true) => t,
        (None, false) => key,
        (None, true) => "(document)".to_string(),
    };
    (line_no, field)
}
