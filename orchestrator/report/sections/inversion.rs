//! [000] the attitude solve's section.

use std::path::Path;

use anyhow::Result;
use shared_types::scenario::SpectraScenario;
use shared_types::{SolveResponse, Spectrum, TopicId};

use super::{Material, Section};
use crate::report::{fit, inversion, Results, Timing};

/// [000] the attitude solve: its answer, the observation file, the light curve, the fits.
pub(super) struct InversionSection {
    spectra_section: SpectraScenario,
    solve: Vec<SolveResponse>,
    spectra: Vec<Spectrum>,
}

impl InversionSection {
    pub(super) fn collect(m: &Material<'_>) -> Option<Self> {
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
        crate::report::light_curve_plot(dir, &self.spectra)
    }
}
