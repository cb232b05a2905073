//! The sensor service's core: what to emit next, in simulated-time order, and how to make it —
//! a frame rendered into a caller's buffer (the loaned sample in the node), a spectrum with its
//! truth, a laser echo. No IPC and no clock: the node decides when (credit, or the wall clock in
//! realtime mode), a test calls it directly.

use anyhow::{Context, Result};
use shared_types::scenario::Scenario;
use shared_types::{
    deployment, FrameHeader, RangeRequest, RangeResponse, RangeStatus, Spectrum, TopicId, Truth,
};

use crate::debris_scene::DebrisScene;
use crate::earth_scene::EarthScene;
use crate::laser::{respond, LaserConfig, RangeOutcome};
use crate::render::noise::{inverse_normal_cdf, Xoshiro256pp};
use crate::spectra_scene::SpectraScene;

const LASER_STREAM: u64 = 1 << 56;

/// The next message of the sensor's streams.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Emission {
    /// Frame `k`, its exposure ending at `t_ns`.
    Frame { k: u64, t_ns: u64 },
    /// Spectrum sample `k`.
    Spectrum { k: u64, t_ns: u64 },
    /// Earth-sensor frame `k`, its exposure ending at `t_ns`.
    Earth { k: u64, t_ns: u64 },
}

impl Emission {
    fn t_ns(self) -> u64 {
        match self {
            Emission::Frame { t_ns, .. }
            | Emission::Spectrum { t_ns, .. }
            | Emission::Earth { t_ns, .. } => t_ns,
        }
    }
}

/// The scenes of a scenario and how many messages each stream has.
pub struct SensorCore {
    pub debris: Option<DebrisScene>,
    pub spectra: Option<SpectraScene>,
    pub earth: Option<EarthScene>,
    laser: Option<LaserConfig>,
    seed: u64,
    pub n_frames: u64,
    pub n_spectra: u64,
    pub n_earth: u64,
    exposure_ns: u64,
    interval_ns: u64,
}

impl SensorCore {
    pub fn new(scenario: &Scenario) -> Result<Self> {
        let debris = match &scenario.camera {
            Some(cam) => {
                Some(DebrisScene::new(cam, scenario.seed).map_err(|e| anyhow::anyhow!("{e}"))?)
            }
            None => None,
        };
        let spectra = match &scenario.spectra {
            Some(sp) => Some(SpectraScene::new(sp, scenario.seed).context("spectra scene")?),
            None => None,
        };
        let earth = (scenario.earth.as_ref()).map(|e| EarthScene::new(e, scenario.seed));
        let cam = scenario.camera.as_ref();
        Ok(SensorCore {
            debris,
            spectra,
            earth,
            laser: cam.map(|c| LaserConfig {
                beam_full_width_rad: c.laser.beam_deg.to_radians(),
                range_sigma_m: c.laser.range_sigma_m,
                delay_s: c.laser.delay_s,
            }),
            seed: scenario.seed,
            n_frames: deployment::expected_messages(scenario, TopicId::Frame),
            n_spectra: deployment::expected_messages(scenario, TopicId::Spectrum),
            n_earth: deployment::expected_messages(scenario, TopicId::EarthFrame),
            exposure_ns: cam.map_or(0, |c| (c.exposure_s * 1e9).round() as u64),
            interval_ns: cam.map_or(0, |c| (c.interval_s * 1e9).round() as u64),
        })
    }

    /// Frame `k` (while `k < n_frames`) and its exposure end [ns].
    pub fn frame(&self, k: u64) -> Option<Emission> {
        let scene = self.debris.as_ref().filter(|_| k < self.n_frames)?;
        let t_ns = (scene.exposure_end_s(k) * 1e9).round() as u64;
        Some(Emission::Frame { k, t_ns })
    }

    /// Spectrum sample `k` (while `k < n_spectra`).
    pub fn spectrum_at(&self, k: u64) -> Option<Emission> {
        let scene = self.spectra.as_ref().filter(|_| k < self.n_spectra)?;
        Some(Emission::Spectrum {
            k,
            t_ns: scene.t_ns(k),
        })
    }

    /// Earth frame `k` (while `k < n_earth`).
    pub fn earth_at(&self, k: u64) -> Option<Emission> {
        let scene = self.earth.as_ref().filter(|_| k < self.n_earth)?;
        Some(Emission::Earth {
            k,
            t_ns: scene.t_ns(k),
        })
    }

    /// The next message when the streams stand at frame `next_frame`, spectrum
    /// `next_spectrum` and Earth frame `next_earth`: strictly in simulated-time order — camera
    /// frames, then spectra, then Earth frames on a tie — so the interleaving, and with it
    /// every sequence number, is deterministic.
    pub fn next(&self, next_frame: u64, next_spectrum: u64, next_earth: u64) -> Option<Emission> {
        [
            self.frame(next_frame),
            self.spectrum_at(next_spectrum),
            self.earth_at(next_earth),
        ]
        .into_iter()
        .flatten()
        .min_by_key(|e| e.t_ns())
    }

    /// Renders Earth frame `k` into `pixels` and fills the header's frame fields.
    pub fn render_earth(&self, k: u64, header: &mut FrameHeader, pixels: &mut [u16]) {
        if let Some(scene) = self.earth.as_ref() {
            scene.render(k, header, pixels);
        }
    }

    /// The truth of Earth frame `k`.
    pub fn earth_truth(&self, k: u64) -> Option<Truth> {
        self.earth.as_ref().map(|s| s.truth(k))
    }

    /// Renders frame `k`: every pixel of `pixels` and the header's frame fields.
    pub fn render_frame(&self, k: u64, header: &mut FrameHeader, pixels: &mut [u16]) {
        let Some(scene) = self.debris.as_ref() else {
            return;
        };
        header.frame_index = k;
        header.exposure_start_ns = (scene.exposure_start_s(k) * 1e9).round() as u64;
        header.exposure_ns = self.exposure_ns.max(1);
        header.interval_ns = self.interval_ns;
        header.width_px = scene.camera.width_px;
        header.height_px = scene.camera.height_px;
        scene.render(k, pixels);
    }

    /// The truth of frame `k`.
    pub fn frame_truth(&self, k: u64) -> Option<Truth> {
        self.debris.as_ref().map(|s| s.truth(k))
    }

    /// Spectrum sample `k`, its truth and its time [ns].
    pub fn spectrum(&self, k: u64) -> Result<(Spectrum, Truth, u64)> {
        let scene = self
            .spectra
            .as_ref()
            .context("no [spectra] in the scenario")?;
        scene.sample(k).context("spectrum sample")
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
