//! The sensor's streams: each a topic of the table whose message `k` the sensor makes from the
//! scenario and the seed alone — frame `k` rendered into a caller's buffer (the loaned sample in
//! the node), or message `k` made whole — with its truth and its simulated time. A stream knows
//! nothing of IPC or clocks: the node decides when to emit (credit, or the wall clock in
//! realtime mode), in simulated-time order over every stream, and a test calls a stream
//! directly. Because message `k` is a function of `k`, a restarted consumer is sent the same
//! messages again (the table's `Replay::Remade`).
//!
//! A new sensor mode is one implementation of [`FrameStream`] or [`MessageStream`] and one
//! line in the node's list of streams.

use std::sync::Arc;

use anyhow::{Context, Result};
use shared_types::scenario::{
    CameraScenario, EarthScenario, PhotometryScenario, SpectraScenario, StereoScenario,
};
use shared_types::{
    FrameHeader, Message, PhotometrySample, Scenario, Spectrum, Stereo, StereoFeature, TopicId,
    Truth,
};

use crate::debris_scene::DebrisScene;
use crate::earth_scene::EarthScene;
use crate::photometry_scene::PhotometryScene;
use crate::spectra_scene::SpectraScene;
use crate::stereo_scene::StereoScene;

/// What every stream says about itself.
pub trait Stream {
    /// The topic it publishes (a row of the table produced by the sensor).
    fn topic(&self) -> TopicId;
    /// Messages over the run.
    fn messages(&self) -> u64;
    /// The simulated time of message `k` [ns]: the end of a frame's exposure, a sample's time.
    fn t_ns(&self, k: u64) -> u64;
}

/// A stream of frames, rendered in place.
pub trait FrameStream: Stream {
    /// Writes every pixel of frame `k` into `pixels` and fills the header's frame fields.
    fn render(&self, k: u64, header: &mut FrameHeader, pixels: &mut [u16]);
    /// What frame `k` shows, for scoring.
    fn truth(&self, k: u64) -> Truth;
}

/// A stream of fixed-size messages.
pub trait MessageStream: Stream {
    type Msg: Message;
    /// Message `k` and its truth.
    fn make(&self, k: u64) -> Result<(Self::Msg, Truth)>;
}

/// The [002] debris camera's frames (`[camera]`).
pub struct DebrisStream {
    pub scene: Arc<DebrisScene>,
    frames: u64,
    exposure_ns: u64,
    interval_ns: u64,
}

impl DebrisStream {
    pub fn new(cam: &CameraScenario, scene: Arc<DebrisScene>) -> Self {
        DebrisStream {
            scene,
            frames: cam.frames,
            exposure_ns: (cam.exposure_s * 1e9).round() as u64,
            interval_ns: (cam.interval_s * 1e9).round() as u64,
        }
    }
}

impl Stream for DebrisStream {
    fn topic(&self) -> TopicId {
        TopicId::Frame
    }
    fn messages(&self) -> u64 {
        self.frames
    }
    fn t_ns(&self, k: u64) -> u64 {
        (self.scene.exposure_end_s(k) * 1e9).round() as u64
    }
}

impl FrameStream for DebrisStream {
    fn render(&self, k: u64, header: &mut FrameHeader, pixels: &mut [u16]) {
        header.frame_index = k;
        header.exposure_start_ns = (self.scene.exposure_start_s(k) * 1e9).round() as u64;
        header.exposure_ns = self.exposure_ns.max(1);
        header.interval_ns = self.interval_ns;
        header.width_px = self.scene.camera.width_px;
        header.height_px = self.scene.camera.height_px;
        self.scene.render(k, pixels);
    }
    fn truth(&self, k: u64) -> Truth {
        self.scene.truth(k)
    }
}

/// The [000] satellite's spectra (`[spectra]`), paced by credit alone.
pub struct SpectraStream {
    scene: SpectraScene,
}

impl SpectraStream {
    pub fn new(sp: &SpectraScenario, seed: u64) -> Result<Self> {
        Ok(SpectraStream {
            scene: SpectraScene::new(sp, seed).context("spectra scene")?,
        })
    }
}

impl Stream for SpectraStream {
    fn topic(&self) -> TopicId {
        TopicId::Spectrum
    }
    fn messages(&self) -> u64 {
        self.scene.len()
    }
    fn t_ns(&self, k: u64) -> u64 {
        self.scene.t_ns(k)
    }
}

impl MessageStream for SpectraStream {
    type Msg = Spectrum;
    fn make(&self, k: u64) -> Result<(Spectrum, Truth)> {
        let (sp, truth, _) = self.scene.sample(k).context("spectrum sample")?;
        Ok((sp, truth))
    }
}

/// The [003] infrared Earth sensor's fisheye frames (`[earth]`).
pub struct EarthStream {
    scene: EarthScene,
}

impl EarthStream {
    pub fn new(e: &EarthScenario, seed: u64) -> Self {
        EarthStream {
            scene: EarthScene::new(e, seed),
        }
    }
}

impl Stream for EarthStream {
    fn topic(&self) -> TopicId {
        TopicId::EarthFrame
    }
    fn messages(&self) -> u64 {
        self.scene.frames()
    }
    fn t_ns(&self, k: u64) -> u64 {
        self.scene.t_ns(k)
    }
}

impl FrameStream for EarthStream {
    fn render(&self, k: u64, header: &mut FrameHeader, pixels: &mut [u16]) {
        self.scene.render(k, header, pixels);
    }
    fn truth(&self, k: u64) -> Truth {
        self.scene.truth(k)
    }
}

/// The [004] stereo rig's epochs (`[stereo]`).
pub struct StereoStream {
    pub scene: StereoScene,
}

impl StereoStream {
    pub fn new(s: &StereoScenario, seed: u64) -> Self {
        StereoStream {
            scene: StereoScene::new(s, seed),
        }
    }
}

impl Stream for StereoStream {
    fn topic(&self) -> TopicId {
        TopicId::Stereo
    }
    fn messages(&self) -> u64 {
        self.scene.len()
    }
    fn t_ns(&self, k: u64) -> u64 {
        self.scene.t_ns(k)
    }
}

impl MessageStream for StereoStream {
    type Msg = Stereo;
    fn make(&self, k: u64) -> Result<(Stereo, Truth)> {
        let mut msg = Stereo {
            epoch_index: k,
            ..Stereo::default()
        };
        for (slot, f) in msg.features.iter_mut().zip(self.scene.observe(k)) {
            *slot = StereoFeature {
                feature: f.feature,
                _pad: 0,
                z: f.z,
            };
            msg.n_features += 1;
        }
        let t = self.scene.truth(k);
        let q = t.q_ct.into_inner();
        let q = if q.w < 0.0 { -q } else { q };
        let mut state = [0.0; 15];
        let values = [q.w, q.i, q.j, q.k]
            .into_iter()
            .chain(t.w_t.iter().copied())
            .chain(self.scene.k.iter().copied())
            .chain(t.rho_o.iter().copied())
            .chain(t.v_o.iter().copied());
        for (slot, v) in state.iter_mut().zip(values) {
            *slot = v;
        }
        let truth = Truth {
            kind: Truth::KIND_STEREO,
            frame_index: k,
            target_state: state,
            ..Truth::default()
        };
        Ok((msg, truth))
    }
}

/// The [001] telescope's light curve (`[photometry]`).
pub struct PhotometryStream {
    pub scene: PhotometryScene,
}

impl PhotometryStream {
    pub fn new(p: &PhotometryScenario, seed: u64) -> Result<Self> {
        Ok(PhotometryStream {
            scene: PhotometryScene::new(p, seed)?,
        })
    }
}

impl Stream for PhotometryStream {
    fn topic(&self) -> TopicId {
        TopicId::Photometry
    }
    fn messages(&self) -> u64 {
        self.scene.len()
    }
    fn t_ns(&self, k: u64) -> u64 {
        self.scene.t_ns(k)
    }
}

impl MessageStream for PhotometryStream {
    type Msg = PhotometrySample;
    fn make(&self, k: u64) -> Result<(PhotometrySample, Truth)> {
        Ok((self.scene.sample(k), self.scene.truth(k)))
    }
}

/// The debris scene of a scenario's camera, shared by its frame stream and the laser.
pub fn debris_scene(scenario: &Scenario) -> Result<Option<Arc<DebrisScene>>> {
    match &scenario.camera {
        Some(cam) => Ok(Some(Arc::new(
            DebrisScene::new(cam, scenario.seed).map_err(|e| anyhow::anyhow!("{e}"))?,
        ))),
        None => Ok(None),
    }
}

/// Among streams standing at their next message (`(t_ns, index)` of each that has one left),
/// the one to emit next: the earliest in simulated time, the first listed on a tie (the
/// streams are listed in table order), so the interleaving — and every sequence number — is
/// deterministic.
pub fn next_in_time(next: impl IntoIterator<Item = Option<u64>>) -> Option<usize> {
    next.into_iter()
        .enumerate()
        .filter_map(|(i, t)| t.map(|t| (t, i)))
        .min()
        .map(|(_, i)| i)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_earliest_stream_goes_first_and_the_first_listed_on_a_tie() {
        assert_eq!(next_in_time([Some(5), Some(3), None]), Some(1));
        assert_eq!(next_in_time([Some(3), Some(3), Some(3)]), Some(0));
        assert_eq!(next_in_time([None, Some(7), Some(7)]), Some(1));
        assert_eq!(next_in_time([None, None]), None);
    }
}
