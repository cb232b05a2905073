//! One frame through every method: the shared edge extraction, then the cross-product method,
//! its lookup (engineering) version and the Hough baseline, each timed.

use std::time::Instant;

use crate::edges::{EdgeConfig, EdgeError, EdgeExtractor};
use crate::estimate::{self, SigmaTable};
use crate::hough::Hough;
use crate::ring::{cross_product_samples, earth_angular_radius_rad, Fisheye};
use crate::tfit::TFit;

/// Settings of the Earth sensor's processing.
#[derive(Clone, Debug, PartialEq)]
pub struct EarthConfig {
    pub camera: Fisheye,
    /// Orbit altitude [km]: the limb's angular radius ρ_E (the Hough radius range).
    pub altitude_km: f64,
    pub edges: EdgeConfig,
    /// Bins of the lookup version's histogram over (−90°, 90°) (math.md: 1° bins).
    pub lookup_bins: usize,
    /// σ(μ) of the lookup version; None: the frame's own fitted σ (an uncalibrated sensor).
    pub sigma_table: Option<SigmaTable>,
    /// The Hough radius range: f ρ_E ± this fraction of f (0.15: ±8.6° of limb radius, wider
    /// than the limb circle's change up to β = 50°).
    pub hough_radius_band: f64,
}

impl EarthConfig {
    pub fn new(camera: Fisheye, altitude_km: f64) -> Self {
        Self {
            camera,
            altitude_km,
            edges: EdgeConfig::default(),
            lookup_bins: 180,
            sigma_table: None,
            hough_radius_band: 0.15,
        }
    }
}

/// One method's answer on one frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MethodResult {
    /// β ≥ 0 [deg].
    pub beta_deg: f64,
    /// Signed tilt about Y_S [deg].
    pub tilt_deg: f64,
    /// Its compute time, the shared edge extraction included [µs].
    pub time_us: f64,
}

/// Every method's answer on one frame.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameResult {
    pub edge_points: usize,
    /// β_k samples of the cross products.
    pub samples: usize,
    /// The shared edge extraction [µs].
    pub edges_us: f64,
    pub cross_product: Option<MethodResult>,
    pub lookup: Option<MethodResult>,
    pub hough: Option<MethodResult>,
    /// The t fit of the signed β_k (the cross-product method's).
    pub fit: Option<TFit>,
    /// The signed β_k themselves [deg].
    pub signed_beta_deg: Vec<f64>,
}

/// The Earth sensor's processing, with its reusable buffers.
pub struct EarthCore {
    pub config: EarthConfig,
    extractor: EdgeExtractor,
    hough: Hough,
}

fn us(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e6
}

impl EarthCore {
    pub fn new(config: EarthConfig) -> Self {
        Self {
            config,
            extractor: EdgeExtractor::default(),
            hough: Hough::default(),
        }
    }

    /// Runs every method on a `width`×`height` frame.
    pub fn process(
        &mut self,
        px: &[u16],
        width: usize,
        height: usize,
    ) -> Result<FrameResult, EdgeError> {
        let cam = self.config.camera;
        let t0 = Instant::now();
        let edges = self
            .extractor
            .extract(px, width, height, &cam, &self.config.edges)?;
        let edges_us = us(t0);

        let t1 = Instant::now();
        let points: Vec<[f64; 3]> = (edges.points_px.iter())
            .map(|&(x, y)| cam.direction(x, y))
            .collect();
        let samples = cross_product_samples(&points);
        let ring_us = us(t1);

        let t2 = Instant::now();
        let cross = estimate::cross_product(&samples).ok();
        let cross_us = us(t2);

        let t3 = Instant::now();
        let fitted_table;
        let table = match (&self.config.sigma_table, &cross) {
            (Some(t), _) => Some(t),
            (None, Some((e, _))) => {
                fitted_table = SigmaTable {
                    points: vec![(0.0, e.sigma_deg)],
                };
                Some(&fitted_table)
            }
            (None, None) => None,
        };
        let lookup =
            table.and_then(|t| estimate::lookup(&samples, t, self.config.lookup_bins).ok());
        let lookup_us = us(t3);

        let t4 = Instant::now();
        let r_px = cam.f_px * earth_angular_radius_rad(self.config.altitude_km);
        let band = self.config.hough_radius_band * cam.f_px;
        let hough = self.hough.estimate(
            px,
            width,
            height,
            &edges.points_px,
            &cam,
            r_px - band,
            r_px + band,
        );
        let hough_us = us(t4);

        let signed_beta_deg = estimate::signed_beta(&samples);
        Ok(FrameResult {
            edge_points: edges.points_px.len(),
            samples: samples.beta_deg.len(),
            edges_us,
            cross_product: cross.as_ref().map(|(e, _)| MethodResult {
                beta_deg: e.beta_deg,
                tilt_deg: e.tilt_deg,
                time_us: edges_us + ring_us + cross_us,
            }),
            lookup: lookup.map(|e| MethodResult {
                beta_deg: e.beta_deg,
                tilt_deg: e.tilt_deg,
                time_us: edges_us + ring_us + lookup_us,
            }),
            hough: hough.map(|e| MethodResult {
                beta_deg: e.beta_deg,
                tilt_deg: e.tilt_deg,
                time_us: edges_us + hough_us,
            }),
            fit: cross.map(|(_, f)| f),
            signed_beta_deg,
        })
    }
}
