//! The relnav service's pure core: epochs of stereo features in, estimates out. It starts the
//! filter from the measurements ([`crate::start`]) or from a given state, predicts and updates
//! at each epoch, and restarts from the measurements when the filter has diverged (every
//! feature of several epochs in a row refused) or failed numerically — each an event it counts,
//! never a crash. No I/O, no clock: the node and `glint tool relnav` drive it the same way.

use serde::{Deserialize, Serialize};

use crate::filter::{FeatureObs, Filter, UpdateOutcome};
use crate::model::{ErrMat, Nominal, Rig};
use crate::start::{pose_fix, start_state, PoseFix};

/// How the core starts, gates and gives up.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Settings {
    /// Epochs with a pose fix the start fits its lines through.
    pub start_epochs: usize,
    /// The start's epochs lie within this span [s]; older fixes are let go.
    pub start_span_s: f64,
    /// Gate on a feature's squared Mahalanobis distance (χ², 4 degrees of freedom; 23.5 is
    /// the 0.9999 quantile).
    pub gate_chi2: f64,
    /// Epochs in a row with three or more features, every one refused, after which the filter
    /// is taken as diverged and started again from the measurements.
    pub diverged_after_epochs: u32,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            start_epochs: 5,
            start_span_s: 60.0,
            gate_chi2: 23.5,
            diverged_after_epochs: 5,
        }
    }
}

/// How the filter begins.
#[derive(Debug, Clone, PartialEq)]
pub enum Start {
    /// From the measurements alone.
    Measurements,
    /// From a given state and covariance at `t_s` (the paper's Table 1 start).
    Given {
        x: Nominal,
        p: Box<ErrMat>,
        t_s: f64,
    },
}

/// What the core did, over the run.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Counters {
    pub epochs: u64,
    pub estimates: u64,
    /// Epochs that gave no estimate: the filter was starting, or the epoch was not later
    /// than the one before.
    pub epochs_without_estimate: u64,
    pub epochs_out_of_order: u64,
    pub features_used: u64,
    /// Features refused by the gate or the start's consistency check.
    pub features_rejected: u64,
    /// Starts from the measurements (the first included).
    pub starts: u64,
    /// Restarts after a divergence.
    pub diverged: u64,
    /// Restarts after a numerical failure.
    pub numerical_failures: u64,
}

/// One epoch's estimate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate {
    pub t_s: f64,
    pub x: Nominal,
    pub p: ErrMat,
    /// The update at this epoch (empty at a start from the measurements, whose epochs the
    /// start has already used).
    pub update: UpdateOutcome,
    /// This epoch (re)started the filter.
    pub started: bool,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
enum Phase {
    Starting(Vec<PoseFix>),
    Running(Box<Filter>),
}

/// The core's state between epochs: what a checkpoint keeps (the rig and settings come from
/// the scenario).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct CoreState {
    phase: Phase,
    last_t_s: Option<f64>,
    refused_in_a_row: u32,
    pub counters: Counters,
}

/// The core.
#[derive(Debug, Clone)]
pub struct RelNav {
    rig: Rig,
    settings: Settings,
    phase: Phase,
    last_t_s: Option<f64>,
    refused_in_a_row: u32,
    pub counters: Counters,
}

impl RelNav {
    pub fn new(rig: Rig, settings: Settings, start: Start) -> Self {
        let phase = match start {
            Start::Measurements => Phase::Starting(Vec::new()),
            Start::Given { x, p, t_s } => Phase::Running(Box::new(Filter::new(x, *p, t_s))),
        };
        RelNav {
            rig,
            settings,
            phase,
            last_t_s: None,
            refused_in_a_row: 0,
            counters: Counters::default(),
        }
    }

    /// What a checkpoint keeps.
    pub fn state(&self) -> CoreState {
        CoreState {
            phase: self.phase.clone(),
            last_t_s: self.last_t_s,
            refused_in_a_row: self.refused_in_a_row,
            counters: self.counters,
        }
    }

    /// The core as it was when `state` was taken.
    pub fn restore(rig: Rig, settings: Settings, state: CoreState) -> Self {
        RelNav {
            rig,
            settings,
            phase: state.phase,
            last_t_s: state.last_t_s,
            refused_in_a_row: state.refused_in_a_row,
            counters: state.counters,
        }
    }

    pub fn rig(&self) -> &Rig {
        &self.rig
    }

    /// Takes one epoch's features; returns the estimate at `t_s` once the filter runs.
    pub fn epoch(&mut self, t_s: f64, features: &[FeatureObs]) -> Option<Estimate> {
        self.counters.epochs += 1;
        if self.last_t_s.is_some_and(|t| t_s <= t) || !t_s.is_finite() {
            self.counters.epochs_out_of_order += 1;
            self.counters.epochs_without_estimate += 1;
            return None;
        }
        self.last_t_s = Some(t_s);
        let out = match &mut self.phase {
            Phase::Starting(_) => self.starting(t_s, features),
            Phase::Running(_) => self.running(t_s, features),
        };
        match &out {
            Some(_) => self.counters.estimates += 1,
            None => self.counters.epochs_without_estimate += 1,
        }
        out
    }

    fn starting(&mut self, t_s: f64, features: &[FeatureObs]) -> Option<Estimate> {
        let Phase::Starting(fixes) = &mut self.phase else {
            return None;
        };
        if let Some(fix) = pose_fix(&self.rig, t_s, features) {
            self.counters.features_used += fix.used as u64;
            self.counters.features_rejected += fix.rejected as u64;
            fixes.push(fix);
        } else {
            self.counters.features_rejected += features.len() as u64;
        }
        let span = self.settings.start_span_s;
        fixes.retain(|f| t_s - f.t_s <= span);
        if fixes.len() < self.settings.start_epochs.max(2) {
            return None;
        }
        let Some((x, p)) = start_state(&self.rig, fixes) else {
            fixes.remove(0); // inconsistent: slide the window on
            return None;
        };
        self.phase = Phase::Running(Box::new(Filter::new(x, p, t_s)));
        self.counters.starts += 1;
        self.refused_in_a_row = 0;
        Some(Estimate {
            t_s,
            x,
            p,
            update: UpdateOutcome::default(),
            started: true,
        })
    }

    fn running(&mut self, t_s: f64, features: &[FeatureObs]) -> Option<Estimate> {
        let Phase::Running(filter) = &mut self.phase else {
            return None;
        };
        filter.predict_to(&self.rig, t_s);
        match filter.update(&self.rig, features, self.settings.gate_chi2) {
            Ok(u) => {
                self.counters.features_used += u.used as u64;
                self.counters.features_rejected += u.rejected as u64;
                if u.used > 0 {
                    self.refused_in_a_row = 0;
                } else if features.len() >= 3 {
                    self.refused_in_a_row += 1;
                }
                if self.refused_in_a_row >= self.settings.diverged_after_epochs {
                    self.counters.diverged += 1;
                    self.phase = Phase::Starting(Vec::new());
                    return self.starting(t_s, features);
                }
                Some(Estimate {
                    t_s,
                    x: filter.x,
                    p: filter.p,
                    update: u,
                    started: false,
                })
            }
            Err(_) => {
                self.counters.numerical_failures += 1;
                self.phase = Phase::Starting(Vec::new());
                self.starting(t_s, features)
            }
        }
    }
}
