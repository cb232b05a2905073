//! The report's mission sections: each folds the messages it scores while the run goes (its
//! [`Fold`], handed every message the taps take), and once the run has ended writes its typed part of `report.json`, its part of `summary.md` (the answers lead the
//! summary, in the order of [`SECTIONS`]) and its pictures. A new service's section is one
//! file here implementing [`Section`] and its fold, one field in [`Results`] and one row of
//! [`SECTIONS`].

use std::path::Path;

use anyhow::Result;
use shared_types::{Scenario, SolveResponse, TopicId};

use super::{Results, Timing};
use crate::run::taps::{Fold, Taps};

mod debris;
mod earth;
mod inversion;
pub mod photometry;
pub mod relnav;

use debris::DebrisSection;
use earth::EarthSection;
use inversion::InversionSection;
pub use photometry::PhotometryReport;
use photometry::PhotometrySection;
pub use relnav::RelNavReport;
use relnav::RelNavSection;

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
    /// What it folds of the taps' messages during the run (`None`: the scenario has no such
    /// mission).
    pub fold: fn(&Scenario) -> Option<Box<dyn Fold>>,
    /// The frames whose pixels it draws, per frame topic (asked of the taps before the run).
    pub snapshots: fn(&Scenario) -> Vec<(TopicId, u64)>,
    /// The section of a finished run (`None`: the scenario has no such mission).
    pub collect: fn(&Material<'_>) -> Option<Box<dyn Section>>,
}

/// Every mission section, in the order summary.md shows them.
pub const SECTIONS: [SectionRow; 5] = [
    SectionRow {
        fold: |s| Some(Box::new(InversionSection::fold(s)?)),
        snapshots: |_| vec![],
        collect: |m| Some(Box::new(InversionSection::collect(m)?)),
    },
    SectionRow {
        fold: |s| Some(Box::new(EarthSection::fold(s)?)),
        snapshots: EarthSection::snapshots,
        collect: |m| Some(Box::new(EarthSection::collect(m)?)),
    },
    SectionRow {
        fold: |s| Some(Box::new(RelNavSection::fold(s)?)),
        snapshots: |_| vec![],
        collect: |m| Some(Box::new(RelNavSection::collect(m)?)),
    },
    SectionRow {
        fold: |s| Some(Box::new(PhotometrySection::fold(s)?)),
        snapshots: |_| vec![],
        collect: |m| Some(Box::new(PhotometrySection::collect(m)?)),
    },
    SectionRow {
        fold: |s| Some(Box::new(DebrisSection::fold(s)?)),
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

/// The folds of every section the scenario has.
pub fn folds(scenario: &Scenario) -> Vec<Box<dyn Fold>> {
    SECTIONS.iter().filter_map(|s| (s.fold)(scenario)).collect()
}
