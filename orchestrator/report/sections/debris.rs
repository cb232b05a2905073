//! [002] the debris chain's section.

use std::path::Path;

use anyhow::Result;
use shared_types::{deployment, Detections, Scenario, ServiceId, TopicId, Tracks, Truth};

use super::{Material, Section};
use crate::report::score_debris::{DebrisScore, DebrisScorer, Expect};
use crate::report::{debris, Results, Timing, TrackingReport};
use crate::run::taps::{Fold, Snapshot};

/// The frame the annotated picture shows: the first with matched detections.
const PICTURE_FRAME: u64 = 1;

impl Fold for DebrisScorer {
    fn take(&mut self, _topic: TopicId, msg: &dyn std::any::Any) {
        if let Some(t) = msg.downcast_ref::<Truth>() {
            self.take_truth(t);
        } else if let Some(d) = msg.downcast_ref::<Detections>() {
            self.take_detections(d);
        } else if let Some(t) = msg.downcast_ref::<Tracks>() {
            self.take_tracks(t);
        }
    }
    fn finish(&mut self) {
        DebrisScorer::finish(self);
    }
    fn as_any(&self) -> &dyn std::any::Any {
        self
    }
}

/// [002] the debris chain: detections and tracks against truth, their pictures.
pub(super) struct DebrisSection {
    score: DebrisScore,
    camera: glint_physics::camera::PinholeCamera,
    snapshot: Option<Snapshot>,
    detections: Option<Detections>,
    truth: Option<Truth>,
}

impl DebrisSection {
    pub(super) fn snapshots(scenario: &Scenario) -> Vec<(TopicId, u64)> {
        match scenario.camera {
            Some(_) => vec![(TopicId::Frame, PICTURE_FRAME)],
            None => vec![],
        }
    }

    /// Scores the chain as its messages arrive.
    pub(super) fn fold(scenario: &Scenario) -> Option<DebrisScorer> {
        let cam = scenario.camera.as_ref()?;
        let camera = glint_detector::service_core::camera(cam);
        let a_m = cam.orbit_semi_major_axis_km * 1e3;
        let n_rad_s = (glint_physics::orbit::MU_EARTH_M3_S2 / (a_m * a_m * a_m)).sqrt();
        let tapped = deployment::inputs(scenario, ServiceId::Orchestrator);
        let expect = Expect {
            truth: tapped.contains(&TopicId::Truth),
            detections: tapped.contains(&TopicId::Detections),
            tracks: tapped.contains(&TopicId::Tracks),
        };
        Some(DebrisScorer::new(
            camera,
            n_rad_s,
            expect,
            Some(PICTURE_FRAME),
        ))
    }

    pub(super) fn collect(m: &Material<'_>) -> Option<Self> {
        let cam = m.scenario.camera.as_ref()?;
        let scorer = m.taps.fold::<DebrisScorer>()?;
        Some(DebrisSection {
            score: scorer.score(),
            camera: glint_detector::service_core::camera(cam),
            snapshot: m.taps.snapshot(TopicId::Frame).cloned(),
            detections: scorer.picture_detections,
            truth: scorer.picture_truth,
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
            self.detections.as_slice(),
            self.truth.as_slice(),
        )
    }
}
