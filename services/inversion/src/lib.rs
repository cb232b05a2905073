//! glint-inversion: the seed-000 three-stage photometric attitude solve (docs/math.md §1).
//!
//! Pure numerical code over plain data: no IPC, no clock, no I/O.
//!
//! 1. [`stage1`]: per band, NNLS fit of the 22 area×BRDF products x ≥ 0 to the
//!    three-axis-stable window, `Φ‖T0‖² = G x` (eqs 7–12), and the reconstruction error.
//! 2. [`stage2`]: separation degree σ(λ) of the body and panel lobes (eqs 13–14) and the band
//!    λ* = argmax σ.
//! 3. [`stage3`]: LM fit of the rates p = [w_x, w_y, w_z] \[deg/frame\] to the motion window at
//!    λ* (eq 20, analytic Jacobian, multi-start), covariance and observability; optionally the
//!    joint fit of all bands with one p. [`rates`] runs it as the solve does: each fit over
//!    its horizon, the joint fit reweighted by each band's mismatch and testing stage 1's
//!    widest lobes.
//! 4. [`answer`]: glint's answer — the joint fit when it ran, else λ*'s — with its 1σ along
//!    each Fisher direction, the directions the prior held and the mirror when it fits as well.
//!
//! Entry point: [`solve_three_stage`]`(&ObservationSet, &InversionConfig)`. The stages are also
//! usable alone: [`nnls::nnls`], [`stage1::run_stage1`], [`stage2::run_stage2`],
//! [`RateProblem`] + [`stage3::fit_multistart`] / [`stage3::fit_single_start`], and the Fisher
//! analysis [`observability::analyse`]. Benchmark: `benches/solve.rs` (8 bands, 720 + 360
//! frames). The estimator's bounds (Cramér–Rao, Hammersley–Chapman–Robbins) are in the
//! `glint-lab` crate, beside the solve.
//!
//! Units: the per-band pupil factor E_sun Δλ A_ap is absorbed in the stage-1 coefficients
//! (see [`stage1`]); stage 3 normalises each band by its mean observed flux. The error metric
//! of the paper is [`rate_error_metric`] = 100·‖p̂ − p*‖ (deg/frame, printed as "%").

pub mod answer;
pub mod error;
pub mod facet;
pub mod lm;
pub mod model;
pub mod nnls;
#[cfg(feature = "node")]
pub mod node;
pub mod nuisance;
pub mod observability;
pub mod observation;
pub mod rates;
pub mod rotation;
mod serde_coeffs;
pub mod service_core;
pub mod session;
pub mod stage1;
pub mod stage2;
pub mod stage3;

pub use answer::{Answer, AnswerFit, Direction};
pub use error::{InversionError, NnlsError};
pub use model::{MotionModelConfig, PanelNormalMode, RateBand, RateProblem};
pub use observation::{Observation, ObservationSet};
pub use rates::{fit_band, fit_joint, fit_rates, fit_within_horizon, BandFit, RateFits};
pub use rotation::AttitudeModel;
pub use stage1::{BasisChoice, SpectralPooling, Stage1Band, Stage1Config, Stage1Output};
pub use stage2::{BandSelection, Stage2Config, Stage2Result};
pub use stage3::{LobeRefit, RateFit, RateSolution, Refit, Stage3Config, WeakPrior};

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// Settings of [`solve_three_stage`].
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct InversionConfig {
    /// Facet normals, panel-normal option, eq-(17) convention, motion epoch.
    pub model: MotionModelConfig,
    /// Per-band `E_sun Δλ A_ap` \[W\], to report stage-1 coefficients in m² as well.
    pub band_scale_w: Option<Vec<f64>>,
    /// Stage-1 basis selection.
    pub stage1: Stage1Config,
    /// Band selection.
    pub stage2: Stage2Config,
    /// LM, start strategy and observability thresholds.
    pub stage3: Stage3Config,
    /// Also fit one p to the stacked residuals of all bands.
    pub joint_fit: bool,
}

/// Every figure of the solve (serde-serialisable; non-finite numbers become `null` in JSON).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct InversionResult {
    /// Stage 1 per band: coefficients and ε_rec.
    pub stage1: Vec<Stage1Band>,
    /// The lobes stage 1 kept ([`stage1::basis`]).
    #[serde(default)]
    pub stage1_basis: BasisChoice,
    /// Stage 1 on the spectrally pooled stable window, when pooling applied: the coefficients
    /// stage 2 and the single-band fit used ([`stage1::spectral`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stage1_pooled: Option<Vec<Stage1Band>>,
    /// The pooling decision.
    #[serde(default)]
    pub spectral_pooling: SpectralPooling,
    /// Stage 2: σ(λ, θ_I), σ(λ) and λ*.
    pub stage2: Stage2Result,
    /// λ* \[nm\].
    pub chosen_wavelength_nm: f64,
    /// glint's answer: the joint fit when it ran, else the fit at λ* ([`answer`]).
    pub answer: Answer,
    /// Stage 3 at λ* (the paper's answer).
    pub rate: RateSolution,
    /// Joint fit over all bands, when enabled.
    pub joint_rate: Option<RateSolution>,
    /// Motion frames stage 3 fitted at λ* (the fit horizon, see
    /// [`Stage3Config::max_rotation_deg`]).
    pub fitted_frames: usize,
    /// Motion frames of the joint fit (its own horizon), when run.
    pub joint_fitted_frames: Option<usize>,
}

impl InversionResult {
    /// The stage-1 coefficients stage 2 and the single-band fit used: the pooled ones when
    /// stage 1 pooled, else every band's own.
    pub fn single_band_stage1(&self) -> &[Stage1Band] {
        self.stage1_pooled.as_deref().unwrap_or(&self.stage1)
    }
}

/// The paper's error metric ε_p = 100·‖p̂ − p*‖₂ (p in deg/frame; §1.6, not relative).
pub fn rate_error_metric(p_hat_deg_per_frame: [f64; 3], p_true_deg_per_frame: [f64; 3]) -> f64 {
    let d: f64 = (0..3)
        .map(|i| (p_hat_deg_per_frame[i] - p_true_deg_per_frame[i]).powi(2))
        .sum();
    100.0 * d.sqrt()
}

/// Runs stages 1–3 (and the joint fit if configured).
pub fn solve_three_stage(
    set: &ObservationSet,
    config: &InversionConfig,
) -> Result<InversionResult, InversionError> {
    set.validate()?;
    // Every setting before any work: an out-of-range count would otherwise surface (or
    // allocate) only in stage 3.
    config.stage1.validate()?;
    config.stage2.validate()?;
    config.stage3.validate()?;
    let body_normal = Vector3::from(config.model.body_normal);
    let stage1 = stage1::run_stage1_full(
        &set.stable,
        &set.wavelengths_nm,
        body_normal,
        config.band_scale_w.as_deref(),
        &config.stage1,
    )?;
    let stage2 = stage2::run_stage2_with(stage1.single_band(), &config.stage2)?;
    let fits = fit_rates(
        &set.motion,
        &stage1.bands,
        stage1.single_band(),
        &stage2.ranking,
        &config.model,
        &config.stage3,
        config.joint_fit,
    )?;
    let stage1::Stage1Output {
        bands: stage1_bands,
        basis: stage1_basis,
        pooled,
        pooling: spectral_pooling,
    } = stage1;
    let answer = fits.answer(stage2.chosen_wavelength_nm);
    Ok(InversionResult {
        chosen_wavelength_nm: stage2.chosen_wavelength_nm,
        stage1: stage1_bands,
        stage1_basis,
        stage1_pooled: pooled,
        spectral_pooling,
        stage2,
        answer,
        rate: fits.rate,
        joint_rate: fits.joint_rate,
        fitted_frames: fits.fitted_frames,
        joint_fitted_frames: fits.joint_fitted_frames,
    })
}
