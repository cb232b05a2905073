//! The `[photometry]` section: a ground telescope's light curve of a spinning satellite ([001],
//! docs/math.md §2, docs/photometry.md) and what the `photometry` service assumes.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use super::*;

/// The satellite, its spin, the station and the arc; the service's settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PhotometryScenario {
    /// The shape library (SHAPES.toml: `[[shape]]` of name, OBJ file, material), relative to
    /// the scenario file. The sensor renders `geometry` from it; the service identifies
    /// among all of it.
    pub shapes: PathBuf,
    /// The satellite's shape: a name in the library.
    pub geometry: String,
    /// Linear scale of that shape, 0.05–20 (its facet areas scale by the square).
    pub scale: f64,
    /// The spin axis, fixed in ECI (any length but 0); absent: drawn from the seed, uniform
    /// on the sphere.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub spin_axis: Option<[f64; 3]>,
    /// One turn about it [s], 10–36000.
    pub spin_period_s: f64,
    /// The rotation angle at the start [deg], −360–360.
    pub phase0_deg: f64,
    /// The satellite's longitude on the geostationary orbit [deg], −180–360.
    pub satellite_longitude_deg: f64,
    /// The telescope.
    pub station: PhotometryStation,
    /// Start of the arc, UTC (RFC 3339, e.g. `2026-03-10T20:00:00Z`).
    pub start_utc: String,
    /// Length of the arc [s], 60–86400, and time between samples [s], 0.1–600.
    pub duration_s: f64,
    pub cadence_s: f64,
    /// 1σ of the magnitude noise [mag], 0–1 (0: noise-free; the samples still say 0.001).
    pub sigma_mag: f64,
    /// What the service assumes.
    pub service: PhotometryService,
}

/// The ground station.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PhotometryStation {
    /// Geodetic latitude [deg], −90–90; longitude [deg], −180–360; height [m], −500–9000.
    pub latitude_deg: f64,
    pub longitude_deg: f64,
    pub altitude_m: f64,
    /// Samples below this elevation are gaps [deg], 0–80.
    pub min_elevation_deg: f64,
}

/// The `photometry` service's settings (math.md §2.5–2.9).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PhotometryService {
    /// Data gathered before the identification [s], 60–86400: then the database is built for
    /// the arc's Sun and observer, the curve identified, and the UKF run from its start.
    pub identify_after_s: f64,
    /// Database: spin axes on the Fibonacci sphere, 8–2000, and rotation angles, 4–64.
    pub axes: u32,
    pub angles: u32,
    /// The UKF's spread γ, 0.1–1 (math.md §2.9; the patent's 0.5, glint's 1).
    pub gamma: f64,
}

impl Default for PhotometryStation {
    fn default() -> Self {
        PhotometryStation {
            latitude_deg: 40.0,
            longitude_deg: 116.0,
            altitude_m: 50.0,
            min_elevation_deg: 15.0,
        }
    }
}

impl Default for PhotometryService {
    fn default() -> Self {
        PhotometryService {
            identify_after_s: 600.0,
            axes: 200,
            angles: 8,
            gamma: 1.0,
        }
    }
}

impl Default for PhotometryScenario {
    fn default() -> Self {
        PhotometryScenario {
            shapes: PathBuf::from("shapes.toml"),
            geometry: String::new(),
            scale: 1.0,
            spin_axis: None,
            spin_period_s: 120.0,
            phase0_deg: 0.0,
            satellite_longitude_deg: 140.0,
            station: PhotometryStation::default(),
            start_utc: "2026-03-10T12:00:00Z".into(),
            duration_s: 1200.0,
            cadence_s: 2.0,
            sigma_mag: 0.05,
            service: PhotometryService::default(),
        }
    }
}

/// Julian date of the Unix epoch.
const JD_UNIX_EPOCH: f64 = 2_440_587.5;

impl PhotometryScenario {
    /// Samples over the arc: at 0, Δt, 2Δt, … up to the duration.
    pub fn samples(&self) -> u64 {
        if !(self.cadence_s > 0.0 && self.duration_s >= 0.0) {
            return 0;
        }
        (self.duration_s / self.cadence_s + 1e-9).floor() as u64 + 1
    }

    /// Sample `k`'s time [ns] after the start.
    pub fn t_ns(&self, k: u64) -> u64 {
        (k as f64 * self.cadence_s * 1e9).round() as u64
    }

    /// The start as a Julian date (UTC), if `start_utc` reads as RFC 3339.
    pub fn start_jd(&self) -> Option<f64> {
        let t: jiff::Timestamp = self.start_utc.parse().ok()?;
        Some(JD_UNIX_EPOCH + t.as_millisecond() as f64 / 86_400_000.0)
    }
}

pub(super) fn check_photometry(c: &mut Checker, p: &PhotometryScenario) {
    if p.geometry.is_empty() {
        c.fail(
            "photometry.geometry",
            "missing: the satellite's shape, a name in photometry.shapes".into(),
        );
    }
    c.range("photometry.scale", p.scale, 0.05, 20.0);
    if let Some(a) = p.spin_axis {
        let n = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
        c.range("photometry.spin_axis (length)", n, 1e-9, 1e9);
    }
    c.range("photometry.spin_period_s", p.spin_period_s, 10.0, 36_000.0);
    c.range("photometry.phase0_deg", p.phase0_deg, -360.0, 360.0);
    c.range(
        "photometry.satellite_longitude_deg",
        p.satellite_longitude_deg,
        -180.0,
        360.0,
    );
    let s = &p.station;
    c.range(
        "photometry.station.latitude_deg",
        s.latitude_deg,
        -90.0,
        90.0,
    );
    c.range(
        "photometry.station.longitude_deg",
        s.longitude_deg,
        -180.0,
        360.0,
    );
    c.range(
        "photometry.station.altitude_m",
        s.altitude_m,
        -500.0,
        9000.0,
    );
    c.range(
        "photometry.station.min_elevation_deg",
        s.min_elevation_deg,
        0.0,
        80.0,
    );
    if p.start_jd().is_none() {
        c.fail(
            "photometry.start_utc",
            format!(
                "`{}` is not an RFC 3339 UTC time (e.g. 2026-03-10T20:00:00Z)",
                p.start_utc
            ),
        );
    }
    c.range("photometry.duration_s", p.duration_s, 60.0, 86_400.0);
    c.range("photometry.cadence_s", p.cadence_s, 0.1, 600.0);
    if p.cadence_s > 0.0 {
        c.range(
            "photometry.duration_s / photometry.cadence_s (samples)",
            p.duration_s / p.cadence_s,
            16.0,
            100_000.0,
        );
    }
    c.range("photometry.sigma_mag", p.sigma_mag, 0.0, 1.0);
    let v = &p.service;
    c.range(
        "photometry.service.identify_after_s",
        v.identify_after_s,
        60.0,
        86_400.0,
    );
    c.range_u("photometry.service.axes", v.axes as u64, 8, 2000);
    c.range_u("photometry.service.angles", v.angles as u64, 4, 64);
    c.range("photometry.service.gamma", v.gamma, 0.1, 1.0);
}
