//! [003] the infrared Earth sensor's section.

use std::path::Path;

use anyhow::Result;
use shared_types::scenario::EarthScenario;
use shared_types::{Scenario, TopicId, Truth};

use super::{Material, Section};
use crate::report::{earth, earth_frame, Results, Timing};
use crate::run::taps::{Fold, Snapshot};

/// The Earth sensor's truths and answers, every one: the scenario's sweep bounds them.
#[derive(Default)]
pub(super) struct EarthFold {
    truths: Vec<Truth>,
    answers: Vec<shared_types::EarthAttitude>,
}

impl Fold for EarthFold {
    fn take(&mut self, _topic: TopicId, msg: &dyn std::any::Any) {
        if let Some(t) = msg.downcast_ref::<Truth>() {
            if t.kind == Truth::KIND_EARTH {
                self.truths.push(*t);
            }
        } else if let Some(a) = msg.downcast_ref::<shared_types::EarthAttitude>() {
            self.answers.push(*a);
        }
    }
    fn as_any(&self) -> &dyn std::any::Any {
        self
    }
}

/// [003] the infrared Earth sensor: each method's error per interval, its pictures.
pub(super) struct EarthSection {
    section: EarthScenario,
    score: earth::EarthScore,
    snapshot: Option<Snapshot>,
    answers: Vec<shared_types::EarthAttitude>,
    truths: Vec<Truth>,
}

impl EarthSection {
    /// The first Earth frame at the angle nearest 20° (a ring clear of the blind zone and of
    /// the image circle's edge).
    pub(super) fn snapshots(scenario: &Scenario) -> Vec<(TopicId, u64)> {
        let Some(e) = &scenario.earth else {
            return vec![];
        };
        let angles = e.angles_deg();
        let near_20 = |a: f64| (a.abs() - 20.0).abs();
        let best = (0..angles.len())
            .min_by(|&a, &b| near_20(angles[a]).total_cmp(&near_20(angles[b])))
            .unwrap_or(0);
        vec![(TopicId::EarthFrame, best as u64 * e.images_per_angle as u64)]
    }

    pub(super) fn fold(scenario: &Scenario) -> Option<EarthFold> {
        scenario.earth.as_ref().map(|_| EarthFold::default())
    }

    pub(super) fn collect(m: &Material<'_>) -> Option<Self> {
        let section = m.scenario.earth.clone()?;
        let fold = m.taps.fold::<EarthFold>()?;
        let (truths, answers) = (fold.truths.clone(), fold.answers.clone());
        Some(EarthSection {
            section,
            score: earth::score(&truths, &answers),
            snapshot: m.taps.snapshot(TopicId::EarthFrame).cloned(),
            answers,
            truths,
        })
    }
}

impl Section for EarthSection {
    fn report(&self, results: &mut Results, timing: &mut Timing) {
        results.earth = Some(self.score.report());
        timing.earth_us_per_frame = self.score.times();
    }

    fn markdown(&self) -> String {
        self.score.markdown()
    }

    /// Error against angle, the β_k samples at the paper's three angles, one annotated frame.
    fn plots(&self, dir: &Path) -> Result<()> {
        earth::error_plot(dir, &self.score)?;
        let figures = earth::sample_figures(&self.answers, &self.truths, &[5.0, 30.0, 60.0]);
        earth::samples_plot(dir, &figures)?;
        if let Some(snap) = &self.snapshot {
            earth_frame::annotated(dir, &self.section, snap, &self.answers, &self.truths)?;
        }
        Ok(())
    }
}
