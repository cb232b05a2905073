//! [002] the debris chain's section.

use std::path::Path;

use anyhow::Result;
use shared_types::{Detections, Scenario, TopicId, Tracks, Truth};

use super::{truths, Material, Section};
use crate::report::score_debris::{self, DebrisScore};
use crate::report::{debris, Results, Timing, TrackingReport};
use crate::run::taps::Snapshot;

/// [002] the debris chain: detections and tracks against truth, their pictures.
pub(super) struct DebrisSection {
    score: DebrisScore,
    camera: glint_physics::camera::PinholeCamera,
    snapshot: Option<Snapshot>,
    detections: Vec<Detections>,
    truths: Vec<Truth>,
}

impl DebrisSection {
    /// Frame 1 (the first with matched detections).
    pub(super) fn snapshots(scenario: &Scenario) -> Vec<(TopicId, u64)> {
        match scenario.camera {
            Some(_) => vec![(TopicId::Frame, 1)],
            None => vec![],
        }
    }

    pub(super) fn collect(m: &Material<'_>) -> Option<Self> {
        let cam = m.scenario.camera.as_ref()?;
        let camera = glint_detector::service_core::camera(cam);
        let a_m = cam.orbit_semi_major_axis_km * 1e3;
        let n_rad_s = (glint_physics::orbit::MU_EARTH_M3_S2 / (a_m * a_m * a_m)).sqrt();
        let truths = truths(m.taps, Truth::KIND_FRAME);
        let detections: Vec<Detections> = m.taps.messages(TopicId::Detections).to_vec();
        let tracks: &[Tracks] = m.taps.messages(TopicId::Tracks);
        Some(DebrisSection {
            score: score_debris::score(&camera, n_rad_s, &truths, &detections, tracks),
            camera,
            snapshot: m.taps.snapshot(TopicId::Frame).cloned(),
            detections,
            truths,
        })
    }
}

impl Section for DebrisSection {
    fn report(&self, results: &mut Results, _timing: &mut Timing) {
        results.detection = Some(self.score.detection.clone());
        results.tracking = Some(TrackingReport {
            targets: self.score.targets.clone(),
        });
    }

    fn markdown(&self) -> String {
        debris::markdown(&self.score)
    }

    fn plots(&self, dir: &Path) -> Result<()> {
        debris::plots(
            dir,
            &self.score,
            &self.camera,
            self.snapshot.as_ref(),
            &self.detections,
            &self.truths,
        )
    }
}
