//! The `[spectra]` section: the [000] satellite, hover geometry and spectrometer.

use serde::{Deserialize, Serialize};

use super::*;

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

/// Which windows carry the noise of `snr`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum NoiseWindows {
    /// Both windows (the paper's setting).
    #[default]
    Both,
    /// Only the motion window: stage 1 sees a noise-free stable window, which isolates the
    /// rate fit's own efficiency (a diagnostic).
    Motion,
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
    /// First and last band centre [nm], 400–750 (the material tables), and the step between
    /// centres [nm], 1–100.
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
    /// Windows the noise applies to: "both" (default) or "motion".
    #[serde(default)]
    pub noise_windows: NoiseWindows,
    /// Sun declination [deg], −23.5–23.5 (0 = equinox; the paper's motion starts at
    /// 2019-03-21 05:30 UTC, 7.5 h after the equinox: +0.124°). At exactly 0 every geometry
    /// vector lies in the body XZ plane and a rotation cannot be told from its mirror image.
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

/// Band centres the sensor can render \[nm\]: the range of its material tables (the physics
/// crate's `MATERIAL_BANDS_NM`; a sensor test keeps the two equal).
pub const BAND_CENTRE_RANGE_NM: (f64, f64) = (400.0, 750.0);

pub(super) fn check_spectra(c: &mut Checker, sp: &SpectraScenario) {
    let (lo, hi) = BAND_CENTRE_RANGE_NM;
    c.range("spectra.band_start_nm", sp.band_start_nm, lo, hi);
    c.range("spectra.band_stop_nm", sp.band_stop_nm, lo, hi);
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
            "band edges must stay inside 380..=780 nm (the solar spectrum table)".into(),
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
