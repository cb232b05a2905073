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
    /// Box half-width h \[deg/frame\] (> 0; 0.5).
    pub half_width_deg_per_frame: f64,
    /// Grid points per axis (≥ 1; 9). 1 means the single start p = 0.
    pub points_per_axis: usize,
    /// Frames used per grid evaluation, at most (≥ 1; 40).
    pub max_grid_frames: usize,
    /// Best grid points screened by short LM runs (≥ 1; 16).
    pub screen_starts: usize,
    /// LM iterations per screened start (≥ 1; 6).
    pub screen_iterations: usize,
    /// Frames used while screening, at most (≥ 1; 90).
    pub max_screen_frames: usize,
    /// Screened starts polished to convergence (≥ 1; 3).
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
    /// With the joint fit: a λ* solution farther than this many standard deviations (the two
    /// covariances summed, over their determined directions) from the joint solution is
    /// another minimum; stage 3 sets the band aside and fits the next in stage 2's ranking
    /// (`None` or ∞: never).
    pub joint_gate_sigma: Option<f64>,
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
    /// With the joint fit: widen the covariance of the rate kept at λ* (or the band that
    /// replaced it) by the Birge ratio of its distance from the joint solution, so that it
    /// covers that distance ([`widen_to_joint`](super::widen_to_joint)). `false`: the band's own covariance.
    pub widen_to_joint: bool,
    /// Report each answer's determined directions at their profile-likelihood intervals, once
    /// every decision is taken (docs/adr/0017). Off by default: over the SNR campaigns it moved
    /// the mean NEES by 1–20 %, into its interval in one row and out of it in another, for
    /// about 4 % more solve time.
    pub profile_intervals: bool,
    /// The polish of a model that re-fits the diffuse terms also starts from the searched rate's
    /// neighbours 1 … this many frames' shift away and takes a neighbouring minimum that fits
    /// clearly better ([`super::fit_from_neighbourhood`]). Off (0) by default: it finds those
    /// minima, but about Z the stable window's noise makes the deeper one the farther from the
    /// noise-free answer (docs/adr/0018).
    pub polish_reach_frames: usize,
    /// Once every decision is taken, the covariances of the joint answer and of λ*'s carry the
    /// minima one and two frames' shift from each, weighted by their likelihood, and the
    /// answers name them ([`RateFit::report_neighbours`](super::RateFit::report_neighbours);
    /// default `true`, docs/adr/0019 and 0020). `false`: the local covariance alone.
    pub cover_neighbours: bool,
    /// Once every decision is taken, the joint covariance also carries the lobe model the
    /// lobe test did not report ([`LobeRefit::WhenNeeded`]), weighted by how near the test was
    /// to going the other way: half at its threshold, little far from it
    /// ([`RateFit::report_lobe_alternative`](super::RateFit::report_lobe_alternative); default
    /// `true`, docs/adr/0023). `false`: the reported model's covariance alone.
    pub cover_lobe_alternative: bool,
    /// Once every decision is taken, each fit (λ*, or the band that replaced it, and the joint
    /// fit) widens its variance along each determined direction by the mean of its local
    /// variances at p̂ and at p̂ ± 2σ over the one at p̂, when that ratio exceeds 1
    /// ([`RateFit::average_over_interval`](super::RateFit::average_over_interval); default
    /// `true`, docs/adr/0027, 0028). `false`: the local covariance at p̂.
    pub average_over_interval: bool,
    /// Which fits' polish holds stage 1's coefficients by their stable-window prior and
    /// re-estimates them with the motion window: the joint likelihood of both windows on stage
    /// 1's passive set (`crate::model::held`, docs/adr/0030; beyond the paper). Needs σ.
    /// Default: none.
    pub held_coefficients: HeldCoefficients,
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
            joint_gate_sigma: Some(DEFAULT_JOINT_GATE_SIGMA),
            refit_diffuse: true,
            refit_widest_lobe: LobeRefit::WhenNeeded,
            lobe_test_confidence: DEFAULT_LOBE_TEST_CONFIDENCE,
            widen_to_joint: true,
            profile_intervals: false,
            polish_reach_frames: DEFAULT_POLISH_REACH_FRAMES,
            cover_neighbours: true,
            cover_lobe_alternative: true,
            average_over_interval: true,
            held_coefficients: HeldCoefficients::None,
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

/// Which polishes hold stage 1's coefficients by their prior ([`Stage3Config::held_coefficients`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum HeldCoefficients {
    /// None: the polish keeps stage 1's coefficients fixed (default).
    #[default]
    None,
    /// The fits of one band (λ* and the bands that replace it).
    SingleBand,
    /// Every fit.
    All,
}

impl HeldCoefficients {
    /// Whether a fit of `bands` bands holds its coefficients by their prior.
    pub fn applies(self, bands: usize) -> bool {
        match self {
            HeldCoefficients::None => false,
            HeldCoefficients::SingleBand => bands == 1,
            HeldCoefficients::All => true,
        }
    }
}

/// Default [`Stage3Config::lobe_test_confidence`].
pub const DEFAULT_LOBE_TEST_CONFIDENCE: f64 = 0.99;
/// Default [`Stage3Config::polish_reach_frames`].
pub const DEFAULT_POLISH_REACH_FRAMES: usize = 0;
/// Largest [`Stage3Config::polish_reach_frames`]: each frame of reach adds four LM starts.
const MAX_POLISH_REACH_FRAMES: usize = 10;

/// Default [`Stage3Config::joint_gate_sigma`]: far beyond any scatter of the two fits (they share
/// data), near nothing a second minimum can hide in.
pub const DEFAULT_JOINT_GATE_SIGMA: f64 = 6.0;

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

pub(super) fn validate(config: &Stage3Config) -> Result<(), InversionError> {
    let s = &config.start;
    let bad = |field, reason| Err(InversionError::InvalidConfig { field, reason });
    if !(s.half_width_deg_per_frame > 0.0 && s.half_width_deg_per_frame.is_finite()) {
        return bad("start.half_width_deg_per_frame", "must be > 0 and finite");
    }
    let counts = [
        s.points_per_axis,
        s.max_grid_frames,
        s.screen_starts,
        s.screen_iterations,
        s.max_screen_frames,
        s.polish_starts,
    ];
    if counts.contains(&0) {
        return bad("start", "every count must be ≥ 1");
    }
    if let Some(deg) = config.max_rotation_deg {
        if !(deg > 0.0 && (deg <= 360.0 || deg == f64::INFINITY)) {
            return bad(
                "max_rotation_deg",
                "must be in (0, 360], or inf for every frame",
            );
        }
    }
    if config
        .joint_gate_sigma
        .is_some_and(|g| g.is_nan() || g <= 0.0)
    {
        return bad("joint_gate_sigma", "must be > 0 (inf: never set λ* aside)");
    }
    let confidence = config.lobe_test_confidence;
    if !(confidence > 0.0 && confidence < 1.0) {
        return bad("lobe_test_confidence", "must be in (0, 1)");
    }
    if config.polish_reach_frames > MAX_POLISH_REACH_FRAMES {
        return bad("polish_reach_frames", "must be in 0 ..= 10");
    }
    if !(0.0..=1.0).contains(&config.observability.min_lobe_share) {
        return bad("observability.min_lobe_share", "must be in [0, 1]");
    }
    let lambda_ok = config.lm.lambda_init > 0.0 && config.lm.lambda_init.is_finite();
    if config.lm.max_iterations == 0 || !lambda_ok {
        return bad("lm", "max_iterations ≥ 1 and lambda_init > 0 required");
    }
    Ok(())
}
