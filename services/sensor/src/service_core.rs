//! The sensor service's laser, and the scenes its streams share with it: a laser echo per
//! request, deterministic per request id. The streams themselves are in [`crate::streams`].
//! No IPC and no clock: the node answers requests with it, a test calls it directly.

use std::sync::Arc;

use anyhow::Result;
use shared_types::scenario::{CameraScenario, Scenario};
use shared_types::{RangeRequest, RangeResponse, RangeStatus};

use crate::debris_scene::DebrisScene;
use crate::laser::{respond, LaserConfig, RangeOutcome};
use crate::render::noise::{inverse_normal_cdf, Xoshiro256pp};
use crate::streams::{debris_scene, DebrisStream};

const LASER_STREAM: u64 = 1 << 56;

/// The debris scene of a scenario's camera and the laser that ranges it.
pub struct SensorCore {
    pub debris: Option<Arc<DebrisScene>>,
    camera: Option<CameraScenario>,
    laser: Option<LaserConfig>,
    seed: u64,
}

impl SensorCore {
    pub fn new(scenario: &Scenario) -> Result<Self> {
        let cam = scenario.camera.as_ref();
        Ok(SensorCore {
            debris: debris_scene(scenario)?,
            camera: cam.cloned(),
            laser: cam.map(|c| LaserConfig {
                beam_full_width_rad: c.laser.beam_deg.to_radians(),
                range_sigma_m: c.laser.range_sigma_m,
                delay_s: c.laser.delay_s,
            }),
            seed: scenario.seed,
        })
    }

    /// The camera's frame stream over the same scene as the laser (none without a camera).
    pub fn debris_stream(&self) -> Option<DebrisStream> {
        let (cam, scene) = (self.camera.as_ref()?, self.debris.as_ref()?);
        Some(DebrisStream::new(cam, scene.clone()))
    }

    /// The laser: fire at the request's time, echo after the delay, deterministic noise per
    /// request id. Returns the answer and the echo's time [ns].
    pub fn answer_range(&self, req: &RangeRequest) -> (RangeResponse, u64) {
        let mut resp = RangeResponse {
            request_id: req.request_id,
            track_id: req.track_id,
            status: RangeStatus::Miss as u32,
            ..Default::default()
        };
        let (Some(scene), Some(cfg)) = (&self.debris, &self.laser) else {
            return (resp, req.meta.t_ns);
        };
        let t_fire_s = req.meta.t_ns as f64 * 1e-9;
        let echo_ns = req.meta.t_ns + (cfg.delay_s * 1e9).round() as u64;
        let targets = scene.laser_targets(t_fire_s + cfg.delay_s);
        let mut rng = Xoshiro256pp::new(self.seed, LASER_STREAM + req.request_id);
        let noise = inverse_normal_cdf(rng.next_open01());
        if let RangeOutcome::Hit { range_m, .. } =
            respond(cfg, req.azimuth_rad, req.elevation_rad, &targets, noise)
        {
            resp.status = RangeStatus::Hit as u32;
            resp.range_m = range_m;
        }
        (resp, echo_ns)
    }
}
