//! The report's mission sections: each takes its facts from the run's taps once the run ended,
//! writes its typed part of `report.json`, its part of `summary.md` (the answers lead the
//! summary, in the order of [`SECTIONS`]) and its pictures. A new service's section is one
//! file here implementing [`Section`], one field in [`Results`] and one row of [`SECTIONS`].

use std::path::Path;

use anyhow::Result;
use shared_types::{Scenario, SolveResponse, TopicId, Truth};

use super::{Results, Timing};
use crate::run::taps::Taps;

mod debris;
mod earth;
mod inversion;

use debris::DebrisSection;
use earth::EarthSection;
use inversion::InversionSection;

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
pub(super) fn truths(taps: &Taps, kind: u32) -> Vec<Truth> {
    (taps.messages::<Truth>(TopicId::Truth).iter())
        .filter(|t| t.kind == kind)
        .copied()
        .collect()
}
