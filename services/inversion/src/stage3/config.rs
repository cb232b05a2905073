//! Stage-3 settings: the start strategy, the fit's options and their checks.

use super::weak::WeakPrior;
use crate::error::InversionError;
use crate::lm::LmConfig;
use crate::observability::ObservabilityConfig;
use serde::{Deserialize, Serialize};

/// Multi-start settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct StartConfig {
    /// Box half-width h \[deg/frame\] ((0, 10]; 0.5).
    pub half_width_deg_per_frame: f64,
    /// Grid points per axis (1..=41; 9). 1 means the single start p = 0.
    pub points_per_axis: usize,
    /// Frames used per grid evaluation, at most (1..=100000; 40).
    pub max_grid_frames: usize,
    /// Best grid points screened by short LM runs (1..=1000; 16).
    pub screen_starts: usize,
    /// LM iterations per screened start (1..=100; 6).
    pub screen_iterations: usize,
    /// Frames used while screening, at most (1..=100000; 90).
    pub max_screen_frames: usize,
    /// Screened starts polished to convergence (1..=100; 3).
    pub polish_starts: usize,
}

impl Default for StartConfig {
    fn default() -> Self {
        Self {
            half_width_deg_per_frame: 0.5,
            points_per_axis: 9,
            max_grid_frames: 40,
            screen_starts: 16,
            screen_iterations: 6,
            max_screen_frames: 90,
            polish_starts: 3,
        }
    }
}

/// Stage-3 settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Stage3Config {
    /// LM stopping rules.
    pub lm: LmConfig,
    /// Start strategy.
    pub start: StartConfig,
    /// Covariance and observability thresholds.
    pub observability: ObservabilityConfig,
    /// Hold unobservable eigen-directions at the stated prior ([`Self::weak_prior`]) and re-fit
    /// the rest (default);
    /// `false` reports the unconstrained optimum.
    pub hold_unobservable_at_prior: bool,
    /// Which prior holds an unobservable direction u (see [`WeakPrior`]).
    pub weak_prior: WeakPrior,
    /// Fit horizon: stage 3 fits the motion frames during which the body has turned at most
    /// this far from its stable attitude at the fitted rate \[deg\] (25; `None` or ∞ = every
    /// frame).
    /// The two-facet model holds only while the observed face and the panel front are the lit
    /// and visible surfaces; turned further, the other faces and the panel back appear.
    pub max_rotation_deg: Option<f64>,
    /// Polish the searched rate with each band's diffuse terms (panel, body) and a constant
    /// remainder re-estimated from the motion window, the sun–observer bisector held at the
    /// stated prior ([`crate::model::MotionModelConfig::refit_diffuse`]; default `true`, ADR
    /// 0010). The stable window cannot tell the panel's diffuse light from the body's and the
    /// rest's (their columns are nearly collinear there); the motion window can. The search
    /// itself, and so the sense of rotation, stays on the stage-1 coefficients. `false`: the
    /// paper's model throughout.
    pub refit_diffuse: bool,
    /// Which fits also re-estimate each facet's widest lobe in that polish: its stage-1
    /// estimate shares the stable window's diffuse column and carries most of stage 1's noise
    /// (default: the joint fit's when the data ask for it, see [`LobeRefit::WhenNeeded`]; its
    /// bands use their own unpooled stage-1 coefficients).
    pub refit_widest_lobe: LobeRefit,
    /// With [`LobeRefit::WhenNeeded`]: the confidence of the region, in the covariance of the
    /// fit that keeps stage 1's lobes, that the fit re-fitting them must leave for the joint fit
    /// to report it (in (0, 1); 0.99).
    pub lobe_test_confidence: f64,
}

impl Default for Stage3Config {
    fn default() -> Self {
        Stage3Config {
            lm: LmConfig::default(),
            start: StartConfig::default(),
            observability: ObservabilityConfig::default(),
            hold_unobservable_at_prior: true,
            weak_prior: WeakPrior::default(),
            max_rotation_deg: Some(DEFAULT_MAX_ROTATION_DEG),
            refit_diffuse: true,
            refit_widest_lobe: LobeRefit::WhenNeeded,
            lobe_test_confidence: DEFAULT_LOBE_TEST_CONFIDENCE,
        }
    }
}

/// Which stage-3 fits re-estimate the widest lobe ([`Stage3Config::refit_widest_lobe`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LobeRefit {
    /// None: every lobe comes from stage 1.
    None,
    /// The joint fit polishes twice, keeping stage 1's lobes and re-fitting them, and reports
    /// the re-fit only when it lies outside the other's confidence region
    /// ([`Stage3Config::lobe_test_confidence`]; default). Where stage 1's lobes explain the
    /// motion window (about Y) the re-fit only adds variance; where they do not (about Z, the
    /// noisy stable window's lobe is off by several of the fit's σ) the re-fit removes the bias.
    #[default]
    WhenNeeded,
    /// The fits of more than one band: the joint fit, always.
    Joint,
    /// Every fit.
    All,
}

impl LobeRefit {
    /// Whether a fit of `bands` bands may re-estimate the widest lobe.
    pub fn applies(self, bands: usize) -> bool {
        match self {
            LobeRefit::None => false,
            LobeRefit::WhenNeeded | LobeRefit::Joint => bands > 1,
            LobeRefit::All => true,
        }
    }
}

/// Default [`Stage3Config::lobe_test_confidence`].
pub const DEFAULT_LOBE_TEST_CONFIDENCE: f64 = 0.99;
/// Default fit horizon \[deg of rotation\]. The noise-free Z error at λ* grows steadily with
/// it (0.10 / 0.13 / 0.18 / 0.24 / 0.39 / 0.58 at 22 / 24 / 25 / 26 / 28 / 30°): the longer
/// the window, the more light from surfaces outside the two-facet model. 25° keeps 100 frames
/// at 0.25 deg/frame for the noise.
pub const DEFAULT_MAX_ROTATION_DEG: f64 = 25.0;

impl Stage3Config {
    /// Checks every setting (the error names the field).
    pub fn validate(&self) -> Result<(), InversionError> {
        validate(self)
    }
}

/// The largest grid, per axis: 41³ = 68,921 points (95 × the default's 729), a few seconds per
/// search. Larger counts only cost time (and memory: a grid of 1000 per axis is 10⁹ points).
pub const MAX_POINTS_PER_AXIS: usize = 41;
/// Upper limits of the other start counts and of LM's iterations (see [`StartConfig`]).
const MAX_FRAMES: usize = 100_000;
const MAX_SCREEN_STARTS: usize = 1_000;
const MAX_SCREEN_ITERATIONS: usize = 100;
const MAX_POLISH_STARTS: usize = 100;
const MAX_LM_ITERATIONS: usize = 10_000;

pub(super) fn validate(config: &Stage3Config) -> Result<(), InversionError> {
    let s = &config.start;
    let bad = |field, reason| Err(InversionError::InvalidConfig { field, reason });
    let out_of_range = |field, value, allowed| {
        Err(InversionError::SettingOutOfRange {
            field,
            value,
            allowed,
        })
    };
    let h = s.half_width_deg_per_frame;
    if !(h > 0.0 && h <= 10.0) {
        return out_of_range("stage3.start.half_width_deg_per_frame", h, "(0, 10]");
    }
    // (field, value, largest allowed, the allowed range as printed)
    let counts = [
        (
            "stage3.start.points_per_axis",
            s.points_per_axis,
            MAX_POINTS_PER_AXIS,
            "1..=41",
        ),
        (
            "stage3.start.max_grid_frames",
            s.max_grid_frames,
            MAX_FRAMES,
            "1..=100000",
        ),
        (
            "stage3.start.screen_starts",
            s.screen_starts,
            MAX_SCREEN_STARTS,
            "1..=1000",
        ),
        (
            "stage3.start.screen_iterations",
            s.screen_iterations,
            MAX_SCREEN_ITERATIONS,
            "1..=100",
        ),
        (
            "stage3.start.max_screen_frames",
            s.max_screen_frames,
            MAX_FRAMES,
            "1..=100000",
        ),
        (
            "stage3.start.polish_starts",
            s.polish_starts,
            MAX_POLISH_STARTS,
            "1..=100",
        ),
        (
            "stage3.lm.max_iterations",
            config.lm.max_iterations,
            MAX_LM_ITERATIONS,
            "1..=10000",
        ),
    ];
    for (field, value, max, allowed) in counts {
        if !(1..=max).contains(&value) {
            return out_of_range(field, value as f64, allowed);
        }
    }
    if let Some(deg) = config.max_rotation_deg {
        if !(deg > 0.0 && (deg <= 360.0 || deg == f64::INFINITY)) {
            return bad(
                "max_rotation_deg",
                "must be in (0, 360], or inf for every frame",
            );
        }
    }
    let confidence = config.lobe_test_confidence;
    if !(confidence > 0.0 && confidence < 1.0) {
        return bad("lobe_test_confidence", "must be in (0, 1)");
    }
    if !(0.0..=1.0).contains(&config.observability.min_lobe_share) {
        return bad("observability.min_lobe_share", "must be in [0, 1]");
    }
    let lm = &config.lm;
    if !(lm.lambda_init > 0.0 && lm.lambda_init < lm.lambda_max && lm.lambda_max.is_finite()) {
        return bad(
            "lm.lambda_init",
            "allowed 0 < lambda_init < lambda_max (finite)",
        );
    }
    Ok(())
}
