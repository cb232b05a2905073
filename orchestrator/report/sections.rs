//! The report's mission sections: each takes its facts from the run's taps once the run ended,
//! writes its typed part of `report.json`, its part of `summary.md` (the answers lead the
//! summary, in the order of [`SECTIONS`]) and its pictures. A new service's section is one
//! implementation of [`Section`], one field in [`Results`] and one row of [`SECTIONS`].

use std::path::Path;

use anyhow::Result;
use shared_types::scenario::{EarthScenario, SpectraScenario};
use shared_types::{Detections, Scenario, SolveResponse, Spectrum, TopicId, Tracks, Truth};

use super::score_debris::{self, DebrisScore};
use super::{debris, earth, earth_frame, fit, inversion, Results, Timing, TrackingReport};
use crate::run::taps::{Snapshot, Taps};

/// What a section is made from: the run's taps and the solve's answers.
pub struct Material<'a> {
    pub scenario: &'a Scenario,
    pub taps: &'a Taps,
    pub solve: &'a [SolveResponse],
}

/// One mission section of the report.
pub trait Section {
    /// Its typed part of report.json (and of its timing).
    fn report(&self, results: &mut Results, timing: &mut Timing);
    /// Its part of summary.md.
    fn markdown(&self) -> String;
    /// Its pictures and files in the run directory.
    fn plots(&self, dir: &Path) -> Result<()>;
}

/// A row of [`SECTIONS`].
pub struct SectionRow {
    /// The frames whose pixels it draws, per frame topic (asked of the taps before the run).
    pub snapshots: fn(&Scenario) -> Vec<(TopicId, u64)>,
    /// The section of a finished run (`None`: the scenario has no such mission).
    pub collect: fn(&Material<'_>) -> Option<Box<dyn Section>>,
}

/// Every mission section, in the order summary.md shows them.
pub const SECTIONS: [SectionRow; 3] = [
    SectionRow {
        snapshots: |_| vec![],
        collect: |m| Some(Box::new(InversionSection::collect(m)?)),
    },
    SectionRow {
        snapshots: EarthSection::snapshots,
        collect: |m| Some(Box::new(EarthSection::collect(m)?)),
    },
    SectionRow {
        snapshots: DebrisSection::snapshots,
        collect: |m| Some(Box::new(DebrisSection::collect(m)?)),
    },
];

/// The frames every section draws.
pub fn snapshots(scenario: &Scenario) -> Vec<(TopicId, u64)> {
    SECTIONS
        .iter()
        .flat_map(|s| (s.snapshots)(scenario))
        .collect()
}

/// The sections of a finished run.
pub fn collect(material: &Material<'_>) -> Vec<Box<dyn Section>> {
    SECTIONS
        .iter()
        .filter_map(|s| (s.collect)(material))
        .collect()
}

/// The truths of one kind.
fn truths(taps: &Taps, kind: u32) -> Vec<Truth> {
    (taps.messages::<Truth>(TopicId::Truth).iter())
        .filter(|t| t.kind == kind)
        .copied()
        .collect()
}

/// [000] the attitude solve: its answer, the observation file, the light curve, the fits.
struct InversionSection {
    spectra_section: SpectraScenario,
    solve: Vec<SolveResponse>,
    spectra: Vec<Spectrum>,
}

impl InversionSection {
    fn collect(m: &Material<'_>) -> Option<Self> {
        Some(InversionSection {
            spectra_section: m.scenario.spectra.clone()?,
            solve: m.solve.to_vec(),
            spectra: m.taps.messages(TopicId::Spectrum).to_vec(),
        })
    }

    fn answer(&self) -> inversion::InversionReport {
        inversion::InversionReport::new(&self.spectra_section, &self.solve)
    }
}

impl Section for InversionSection {
    fn report(&self, results: &mut Results, _timing: &mut Timing) {
        results.inversion = Some(self.answer());
    }

    fn markdown(&self) -> String {
        let bands = self.spectra_section.wavelengths_nm().len();
        let mut s = self.answer().markdown(bands);
        if !self.spectra.is_empty() {
            s.push_str("\n## Light curve\n\n![light curve](light-curve.svg)\n");
        }
        s
    }

    fn plots(&self, dir: &Path) -> Result<()> {
        let sp = &self.spectra_section;
        self.answer().plots(dir)?;
        crate::tools::observations::write(
            &dir.join("observations.csv"),
            &self.spectra,
            Some(sp.rate_deg_per_frame),
        )?;
        // Fit plots need complete windows (a run cut short has none to solve).
        if self.solve.iter().any(|r| r.stage == 3) {
            if let Err(e) = fit::plots(dir, sp, &self.solve) {
                tracing::warn!(error = %e, "fit plots skipped");
            }
        }
        super::light_curve_plot(dir, &self.spectra)
    }
}

/// [003] the infrared Earth sensor: each method's error per interval, its pictures.
struct EarthSection {
    section: EarthScenario,
    score: earth::EarthScore,
    snapshot: Option<Snapshot>,
    answers: Vec<shared_types::EarthAttitude>,
    truths: Vec<Truth>,
}

impl EarthSection {
    /// The first Earth frame at the angle nearest 20° (a ring clear of the blind zone and of
    /// the image circle's edge).
    fn snapshots(scenario: &Scenario) -> Vec<(TopicId, u64)> {
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

    fn collect(m: &Material<'_>) -> Option<Self> {
        let section = m.scenario.earth.clone()?;
        let truths = truths(m.taps, Truth::KIND_EARTH);
        let answers = m.taps.messages(TopicId::EarthAttitude).to_vec();
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

/// [002] the debris chain: detections and tracks against truth, their pictures.
struct DebrisSection {
    score: DebrisScore,
    camera: glint_physics::camera::PinholeCamera,
    snapshot: Option<Snapshot>,
    detections: Vec<Detections>,
    truths: Vec<Truth>,
}

impl DebrisSection {
    /// Frame 1 (the first with matched detections).
    fn snapshots(scenario: &Scenario) -> Vec<(TopicId, u64)> {
        match scenario.camera {
            Some(_) => vec![(TopicId::Frame, 1)],
            None => vec![],
        }
    }

    fn collect(m: &Material<'_>) -> Option<Self> {
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
