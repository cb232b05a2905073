//! One frame through every method: the shared edge extraction, then the cross-product method,
//! its lookup (engineering) version and the Hough baseline, each timed.

use std::time::Instant;

use crate::edges::{EdgeConfig, EdgeError, EdgeExtractor};
use crate::estimate::{self, SigmaTable};
use crate::hough::Hough;
use crate::ring::{cross_product_samples, earth_angular_radius_rad, Fisheye};
use crate::tfit::TFit;
use crate::validity::{
    circle_model_bias, correlation_time, location_standard_error, nadir, on_limb_fraction,
    Undetermined, ValidityConfig, Visible,
};

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
    /// When a method's answer holds for the frame.
    pub validity: ValidityConfig,
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
            validity: ValidityConfig::default(),
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
    /// Each method's answer, or why the frame does not determine it.
    pub cross_product: Result<MethodResult, Undetermined>,
    pub lookup: Result<MethodResult, Undetermined>,
    pub hough: Result<MethodResult, Undetermined>,
    /// The t fit of the signed β_k (the cross-product method's).
    pub fit: Option<TFit>,
    /// The standard error of its location, the samples' correlation counted [deg].
    pub standard_error_deg: Option<f64>,
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
        let rho_rad = earth_angular_radius_rad(self.config.altitude_km);
        // The limb's radius in the ideal lens's image, where the baseline fits it.
        let r_px = cam.f_px * rho_rad;
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

        // Whether each answer holds for this frame (module `validity`).
        let v = &self.config.validity;
        let no_limb = Undetermined::NoLimb {
            edge_points: edges.points_px.len(),
            samples: samples.beta_deg.len(),
        };
        let azimuth_deg = estimate::tilt_azimuth_rad(&samples).to_degrees();
        let on_limb = |signed_beta_deg: f64| {
            let e = nadir(signed_beta_deg, azimuth_deg);
            let fraction = on_limb_fraction(&points, e, v.limb_tolerance_px / cam.f_px);
            (fraction >= v.min_on_limb_fraction)
                .then_some(())
                .ok_or(Undetermined::OffTheLimb {
                    on_limb_fraction: fraction,
                })
        };
        let signed_beta_deg = estimate::signed_beta(&samples);
        let se = cross.as_ref().map(|(_, fit)| {
            location_standard_error(fit, correlation_time(&signed_beta_deg, fit.mu))
        });
        let precise = se.map(|se| {
            (se <= v.max_standard_error_deg)
                .then_some(())
                .ok_or(Undetermined::Imprecise {
                    standard_error_deg: se,
                    samples: samples.beta_deg.len(),
                })
        });
        let holds = |mu_deg: f64| -> Result<(), Undetermined> {
            precise.unwrap_or(Err(no_limb))?;
            on_limb(mu_deg)
        };
        // The lookup's mode against the fit's location, both signed.
        let mode_holds = |mode_deg: f64| -> Result<(), Undetermined> {
            let (Some((_, fit)), Some(se)) = (&cross, se) else {
                return Ok(());
            };
            let allowed = (v.lookup_error_budget_deg - 2.0 * se).max(0.0);
            ((mode_deg - fit.mu).abs() <= allowed).then_some(()).ok_or(
                Undetermined::ModeOffLocation {
                    mode_deg,
                    location_deg: fit.mu,
                    allowed_deg: allowed,
                },
            )
        };
        let visible = Visible {
            width_px: width,
            height_px: height,
            r_min_px: cam.radius_px(self.config.edges.blind_zone_half_deg.to_radians()),
            r_max_px: self.config.edges.r_max_px(),
        };
        let circle_holds = |h: &crate::hough::HoughEstimate| -> Result<(), Undetermined> {
            let az = (h.circle.y_px - cam.y0_px)
                .atan2(h.circle.x_px - cam.x0_px)
                .to_degrees();
            let bias = circle_model_bias(&cam, h.beta_deg, az, rho_rad, &visible).ok_or(no_limb)?;
            (bias.abs() <= v.max_circle_bias_deg).then_some(()).ok_or(
                Undetermined::CircleModelBias {
                    beta_deg: h.beta_deg,
                    bias_deg: bias,
                },
            )
        };

        Ok(FrameResult {
            edge_points: edges.points_px.len(),
            samples: samples.beta_deg.len(),
            edges_us,
            cross_product: match &cross {
                Some((e, _)) => holds(e.mu_deg).map(|()| MethodResult {
                    beta_deg: e.beta_deg,
                    tilt_deg: e.tilt_deg,
                    time_us: edges_us + ring_us + cross_us,
                }),
                None => Err(no_limb),
            },
            lookup: match lookup {
                Some(e) => holds(e.mu_deg)
                    .and(mode_holds(e.mu_deg))
                    .map(|()| MethodResult {
                        beta_deg: e.beta_deg,
                        tilt_deg: e.tilt_deg,
                        time_us: edges_us + ring_us + lookup_us,
                    }),
                None => Err(no_limb),
            },
            hough: match hough {
                Some(e) => circle_holds(&e).map(|()| MethodResult {
                    beta_deg: e.beta_deg,
                    tilt_deg: e.tilt_deg,
                    time_us: edges_us + hough_us,
                }),
                None => Err(no_limb),
            },
            standard_error_deg: se,
            fit: cross.map(|(_, f)| f),
            signed_beta_deg,
        })
    }
}
