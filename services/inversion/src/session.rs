//! The inversion service's state between solve calls: the two windows as they arrive, and the
//! results of each stage, so the orchestrator can sequence stage 1 (stable window complete),
//! stage 2, and stage 3 (motion window complete) as separate calls. Pure: no I/O.

use nalgebra::Vector3;

use crate::model::MotionModelConfig;
use crate::stage1::{run_stage1_full, Stage1Config, Stage1Output};
use crate::stage2::{run_stage2, Stage2Result};
use crate::stage3::Stage3Config;
use crate::{fit_rates, Answer, InversionError, Observation, ObservationSet, RateFits};

/// Why a stage cannot run yet.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum NotReady {
    /// The window has fewer samples than expected.
    Window { have: usize, need: usize },
    /// An earlier stage has not run.
    Stage(u32),
}

pub struct Session {
    pub set: ObservationSet,
    pub expected_stable: usize,
    pub expected_motion: usize,
    pub model: MotionModelConfig,
    pub stage3_config: Stage3Config,
    pub stage1_config: Stage1Config,
    /// Stage 1: every band on its own, and on the pooled window when pooling applied.
    pub stage1: Option<Stage1Output>,
    pub stage2: Option<Stage2Result>,
    /// Stage 3: λ*'s fit and the joint fit.
    pub fits: Option<RateFits>,
    /// glint's answer ([`crate::Answer`]).
    pub answer: Option<Answer>,
}

pub enum StageOutcome {
    Done,
    NotReady(NotReady),
}

impl Session {
    pub fn new(
        wavelengths_nm: Vec<f64>,
        expected_stable: usize,
        expected_motion: usize,
        model: MotionModelConfig,
        stage3_config: Stage3Config,
    ) -> Self {
        Session {
            set: ObservationSet {
                wavelengths_nm,
                stable: Vec::with_capacity(expected_stable),
                motion: Vec::with_capacity(expected_motion),
            },
            expected_stable,
            expected_motion,
            model,
            stage3_config,
            stage1_config: Stage1Config::default(),
            stage1: None,
            stage2: None,
            fits: None,
            answer: None,
        }
    }

    pub fn push(&mut self, motion: bool, obs: Observation) {
        if motion {
            self.set.motion.push(obs);
        } else {
            self.set.stable.push(obs);
        }
    }

    /// Stage 1: NNLS reconstruction per band over the complete stable window.
    pub fn stage1(&mut self) -> Result<StageOutcome, InversionError> {
        if self.set.stable.len() < self.expected_stable {
            return Ok(StageOutcome::NotReady(NotReady::Window {
                have: self.set.stable.len(),
                need: self.expected_stable,
            }));
        }
        let body = Vector3::from(self.model.body_normal);
        self.stage1 = Some(run_stage1_full(
            &self.set.stable,
            &self.set.wavelengths_nm,
            body,
            None,
            &self.stage1_config,
        )?);
        Ok(StageOutcome::Done)
    }

    /// Stage 2: separation degree per band and the chosen band.
    pub fn stage2(&mut self) -> Result<StageOutcome, InversionError> {
        let Some(s1) = &self.stage1 else {
            return Ok(StageOutcome::NotReady(NotReady::Stage(1)));
        };
        self.stage2 = Some(run_stage2(s1.single_band())?);
        Ok(StageOutcome::Done)
    }

    /// Stage 3: rates at the chosen band over the complete motion window (and, with `joint`,
    /// one p for all bands, started from the single-band solution).
    pub fn stage3(&mut self, joint: bool) -> Result<StageOutcome, InversionError> {
        let (Some(s1), Some(s2)) = (&self.stage1, &self.stage2) else {
            return Ok(StageOutcome::NotReady(NotReady::Stage(2)));
        };
        if self.set.motion.len() < self.expected_motion {
            return Ok(StageOutcome::NotReady(NotReady::Window {
                have: self.set.motion.len(),
                need: self.expected_motion,
            }));
        }
        let fits = fit_rates(
            &self.set.motion,
            &s1.bands,
            s1.single_band(),
            &s2.ranking,
            &self.model,
            &self.stage3_config,
            joint,
        )?;
        self.answer = Some(fits.answer(s2.chosen_wavelength_nm));
        self.fits = Some(fits);
        Ok(StageOutcome::Done)
    }
}
