//! Scoring against the truth (docs/math.md §5.7): RTMSE per state group over a window at the
//! end of the run (eqs 40–41) and the mean NEES, accumulated as estimates arrive, merged over
//! Monte-Carlo runs.

use serde::{Deserialize, Serialize};

use crate::filter::group_errors;
use crate::model::{ErrMat, Nominal, N_ERR};

/// The state groups' names, in [`group_errors`] order.
pub const GROUP_NAMES: [&str; 5] = ["attitude", "rate", "inertia_k", "position", "velocity"];

/// Sums of squared errors and NEES over the epochs in the window.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Score {
    /// Σ e² per group (attitude e_θ = 2 arccos|δq_w| [rad]; rate [rad/s]; k; position [m];
    /// velocity [m/s]).
    pub sum_sq: [f64; 5],
    pub epochs: u64,
    pub nees_sum: f64,
    pub nees_epochs: u64,
    /// Epochs whose error lay within 3σ, per group (the largest component against its σ).
    pub within_3sigma: [u64; 5],
}

impl Score {
    /// Adds one epoch's estimate against its truth.
    pub fn add(&mut self, est: &Nominal, p: &ErrMat, truth: &Nominal) {
        let e = group_errors(est, truth);
        for (s, v) in self.sum_sq.iter_mut().zip(e) {
            *s += v * v;
        }
        self.epochs += 1;
        let dx = est.error_to(truth);
        if let Some(chol) = p.cholesky() {
            self.nees_sum += dx.dot(&chol.solve(&dx));
            self.nees_epochs += 1;
        }
        for (g, (_, first, size)) in crate::filter::GROUPS.iter().enumerate() {
            let inside =
                (*first..first + size).all(|i| dx[i].abs() <= 3.0 * p[(i, i)].max(0.0).sqrt());
            self.within_3sigma[g] += inside as u64;
        }
    }

    /// Another run's sums.
    pub fn merge(&mut self, other: &Score) {
        for g in 0..5 {
            self.sum_sq[g] += other.sum_sq[g];
            self.within_3sigma[g] += other.within_3sigma[g];
        }
        self.epochs += other.epochs;
        self.nees_sum += other.nees_sum;
        self.nees_epochs += other.nees_epochs;
    }

    /// RTMSE per group (eq 40), NaN without epochs.
    pub fn rtmse(&self) -> [f64; 5] {
        self.sum_sq.map(|s| (s / self.epochs as f64).sqrt())
    }

    /// Mean NEES (expected: the error state's dimension, 14).
    pub fn nees_mean(&self) -> f64 {
        self.nees_sum / self.nees_epochs as f64
    }

    /// The two-sided 95 % interval of the mean NEES over `runs` independent runs, each
    /// `epochs` epochs: `χ²(runs·14)/runs` taken per run (the epochs of one run are
    /// correlated, so only runs count as independent), by the Wilson–Hilferty approximation.
    pub fn nees_interval(runs: u64) -> (f64, f64) {
        let k = (runs.max(1) * N_ERR as u64) as f64;
        let q = |z: f64| {
            let a = 2.0 / (9.0 * k);
            k * (1.0 - a + z * a.sqrt()).powi(3)
        };
        (
            q(-1.959964) / runs.max(1) as f64,
            q(1.959964) / runs.max(1) as f64,
        )
    }
}
