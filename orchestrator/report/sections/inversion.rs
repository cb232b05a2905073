//! [000] the attitude solve's section.

use std::path::Path;

use anyhow::Result;
use shared_types::scenario::SpectraScenario;
use shared_types::{Scenario, SolveResponse, Spectrum, TopicId};

use super::{Material, Section};
use crate::report::{fit, inversion, Results, Timing};
use crate::run::taps::Fold;

/// Every spectrum: the scenario's windows bound them (the observation file and the light
/// curve are made of all of them).
#[derive(Default)]
pub(super) struct SpectraFold {
    spectra: Vec<Spectrum>,
}

impl Fold for SpectraFold {
    fn take(&mut self, topic: TopicId, msg: &dyn std::any::Any) {
        if topic == TopicId::Spectrum {
            if let Some(s) = msg.downcast_ref::<Spectrum>() {
                self.spectra.push(*s);
            }
        }
    }
    fn as_any(&self) -> &dyn std::any::Any {
        self
    }
}

/// [000] the attitude solve: its answer, the observation file, the light curve, the fits.
pub(super) struct InversionSection {
    spectra_section: SpectraScenario,
    solve: Vec<SolveResponse>,
    spectra: Vec<Spectrum>,
}

impl InversionSection {
    pub(super) fn fold(scenario: &Scenario) -> Option<SpectraFold> {
        scenario.spectra.as_ref().map(|_| SpectraFold::default())
    }

    pub(super) fn collect(m: &Material<'_>) -> Option<Self> {
        Some(InversionSection {
            spectra_section: m.scenario.spectra.clone()?,
            solve: m.solve.to_vec(),
            spectra: m.taps.fold::<SpectraFold>()?.spectra.clone(),
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
        crate::report::light_curve_plot(dir, &self.spectra)
    }
}
