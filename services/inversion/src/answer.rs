//! glint's answer to the attitude solve: one rate, its uncertainty along the directions the data
//! determine, the directions they do not (and the prior that held them), and the sense of
//! rotation when its mirror fits as well.
//!
//! The answer is the joint fit over every band when it ran (one p for all bands, docs/math.md
//! §1.6), else the fit at λ*, the paper's stage 3. The joint fit uses every band's light, so its
//! error at noise is the smaller (docs/attitude-solve.md); λ*'s fit stays in the result beside it
//! for the comparison with the paper.

use serde::{Deserialize, Serialize};

use crate::observability::UnobservableReason;
use crate::stage3::RateSolution;

/// Which fit the answer is.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "fit", rename_all = "snake_case")]
pub enum AnswerFit {
    /// One p for every band.
    Joint {
        /// Bands fitted.
        bands: usize,
    },
    /// The fit at one band (λ*).
    Band {
        /// Its centre \[nm\].
        wavelength_nm: f64,
    },
}

/// One eigen-direction of the rates' information, least informed first.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Direction {
    /// Unit vector in (w_x, w_y, w_z).
    pub axis: [f64; 3],
    /// 1σ along it \[deg/frame\].
    pub sigma_deg_per_frame: f64,
    /// Whether the data determine it (1σ within the observability threshold).
    pub determined: bool,
}

/// glint's answer (see the module docs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Answer {
    /// The fit the answer is.
    pub from: AnswerFit,
    /// p̂ = [w_x, w_y, w_z] \[deg/frame\]; `None` when the data do not determine a rate.
    pub rate_deg_per_frame: Option<[f64; 3]>,
    /// Cov(p̂) \[(deg/frame)²\]; `None` with the rate.
    pub covariance_deg2_per_frame2: Option<[[f64; 3]; 3]>,
    /// The information's eigen-directions with their 1σ.
    pub directions: [Direction; 3],
    /// The directions e the stated prior held at e·p = 0 (body axes), where the data could not
    /// determine them.
    pub held_axes: Vec<[f64; 3]>,
    /// The mirror (−w_x, w_y, −w_z) when it fits the data within what the noise allows: then
    /// the sense of rotation about X and Z is not determined and either may be the truth.
    pub mirror_deg_per_frame: Option<[f64; 3]>,
    /// Why there is no rate.
    pub unobservable: Option<UnobservableReason>,
    /// Motion frames fitted (the fit horizon).
    pub fitted_frames: usize,
}

impl Answer {
    /// The answer of `solution`, a fit of `from`.
    pub fn of(from: AnswerFit, solution: &RateSolution, fitted_frames: usize) -> Self {
        let (observability, rate, covariance, held_axes, mirror, unobservable) = match solution {
            RateSolution::Determined(fit) => (
                &fit.observability,
                Some(fit.rate_deg_per_frame),
                Some(fit.covariance_deg2_per_frame2),
                fit.held_directions.clone(),
                fit.mirror_deg_per_frame,
                None,
            ),
            RateSolution::Unobservable {
                reason,
                observability,
                ..
            } => (observability, None, None, vec![], None, Some(*reason)),
        };
        let directions = std::array::from_fn(|i| Direction {
            axis: observability.eigenvectors[i],
            sigma_deg_per_frame: observability.bounds_1sigma_deg_per_frame[i],
            determined: !observability.unobservable[i],
        });
        Answer {
            from,
            rate_deg_per_frame: rate,
            covariance_deg2_per_frame2: covariance,
            directions,
            held_axes,
            mirror_deg_per_frame: mirror,
            unobservable,
            fitted_frames,
        }
    }

    /// Whether the data fix the sense of rotation (no mirror fits as well).
    pub fn sense_determined(&self) -> bool {
        self.mirror_deg_per_frame.is_none()
    }
}
