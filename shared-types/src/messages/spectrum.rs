//! The attitude solve ([000]): spectrum samples and the solve calls of the three stages.

use iceoryx2::prelude::ZeroCopySend;

use super::*;

/// Which observation window a spectrum sample belongs to ([000] §1.4, §1.6).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum Window {
    /// Three-axis-stable attitude: stage 1 reconstructs the BRDF coefficients here.
    Stable = 0,
    /// Attitude motion: stage 3 fits the rates here.
    Motion = 1,
}

impl Window {
    pub fn from_u32(v: u32) -> Option<Self> {
        match v {
            0 => Some(Window::Stable),
            1 => Some(Window::Motion),
            _ => None,
        }
    }
}

/// One time sample of the target's spectrum plus the geometry the inversion needs.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend, bytemuck::Pod, bytemuck::Zeroable)]
#[type_name("glint.v1.Spectrum")]
#[repr(C)]
pub struct Spectrum {
    pub meta: Meta,
    /// Frame index within its window (t = 0 is the frame before the motion starts).
    pub frame_index: u64,
    /// [`Window`] as u32.
    pub window: u32,
    /// Number of valid bands (≤ [`MAX_BANDS`]).
    pub n_bands: u32,
    /// Unit vector target→Sun in the target body frame at rest (LVLH-nadir).
    pub sun_body: [f64; 3],
    /// Unit vector target→observer in the target body frame at rest.
    pub observer_body: [f64; 3],
    /// Target–observer range [m].
    pub range_m: f64,
    /// Phase angle Sun–target–observer [rad].
    pub phase_rad: f64,
    /// Band centre wavelengths [nm].
    pub wavelength_nm: [f64; MAX_BANDS],
    /// Band-integrated flux at the pupil [W].
    pub flux_w: [f64; MAX_BANDS],
    /// 1σ noise of `flux_w` [W] (0 when noise-free).
    pub sigma_w: [f64; MAX_BANDS],
    /// xxh3-64 of every field above except `meta.send_mono_ns`, set by the producer.
    pub content_xxh3: u64,
}

impl Default for Spectrum {
    fn default() -> Self {
        Spectrum {
            meta: Meta::default(),
            frame_index: 0,
            window: 0,
            n_bands: 0,
            sun_body: [0.0; 3],
            observer_body: [0.0; 3],
            range_m: 0.0,
            phase_rad: 0.0,
            wavelength_nm: [0.0; MAX_BANDS],
            flux_w: [0.0; MAX_BANDS],
            sigma_w: [0.0; MAX_BANDS],
            content_xxh3: 0,
        }
    }
}

impl Spectrum {
    /// Hash of the content (everything but the send time and the hash itself).
    pub fn compute_hash(&self) -> u64 {
        let mut h = xxhash_rust::xxh3::Xxh3::new();
        h.update(&self.meta.seq.to_le_bytes());
        h.update(&self.meta.t_ns.to_le_bytes());
        h.update(&self.frame_index.to_le_bytes());
        h.update(&self.window.to_le_bytes());
        h.update(&self.n_bands.to_le_bytes());
        for v in self
            .sun_body
            .iter()
            .chain(self.observer_body.iter())
            .chain([self.range_m, self.phase_rad].iter())
            .chain(self.wavelength_nm.iter())
            .chain(self.flux_w.iter())
            .chain(self.sigma_w.iter())
        {
            h.update(&v.to_le_bytes());
        }
        h.digest()
    }

    pub fn validate(&self) -> Result<(), Reject> {
        self.meta.validate()?;
        if Window::from_u32(self.window).is_none() {
            return Err(Reject::new(
                "spectrum.window",
                "not 0 (stable) or 1 (motion)",
            ));
        }
        if self.n_bands == 0 || self.n_bands as usize > MAX_BANDS {
            return Err(Reject::new("spectrum.n_bands", "out of range 1..=64"));
        }
        unit(&self.sun_body, "spectrum.sun_body")?;
        unit(&self.observer_body, "spectrum.observer_body")?;
        if !(self.range_m.is_finite() && self.range_m > 0.0) {
            return Err(Reject::new("spectrum.range_m", "not finite and > 0"));
        }
        let n = self.n_bands as usize;
        for i in 0..n {
            finite(self.wavelength_nm[i], "spectrum.wavelength_nm")?;
            finite(self.flux_w[i], "spectrum.flux_w")?;
            if !(self.sigma_w[i].is_finite() && self.sigma_w[i] >= 0.0) {
                return Err(Reject::new("spectrum.sigma_w", "not finite and >= 0"));
            }
        }
        if self.compute_hash() != self.content_xxh3 {
            return Err(Reject::new(
                "spectrum.content_xxh3",
                "does not match content",
            ));
        }
        Ok(())
    }
}

/// A solve call to the inversion ([000] three-stage solve).
#[derive(
    Debug, Default, Clone, Copy, PartialEq, Eq, ZeroCopySend, bytemuck::Pod, bytemuck::Zeroable,
)]
#[type_name("glint.v1.SolveRequest")]
#[repr(C)]
pub struct SolveRequest {
    pub meta: Meta,
    pub request_id: u64,
    /// 1 = reconstruct (stable window), 2 = band selection, 3 = attitude rates (motion window).
    pub stage: u32,
    /// [`SolveRequest::FLAG_JOINT`]: also fit stage 3 on all bands jointly.
    pub flags: u32,
}

impl SolveRequest {
    pub const FLAG_JOINT: u32 = 1;

    pub fn validate(&self) -> Result<(), Reject> {
        self.meta.validate()?;
        if !(1..=3).contains(&self.stage) {
            return Err(Reject::new("solve_request.stage", "not 1, 2 or 3"));
        }
        Ok(())
    }
}

/// Outcome of a solve call.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum SolveStatus {
    Ok = 0,
    /// The window this stage needs is not complete yet (or an earlier stage has not run).
    NotReady = 1,
    /// The geometry does not determine the rates (no glint); no number is given.
    Unobservable = 2,
    /// The solver failed (diverged, singular).
    Failed = 3,
    /// The request was malformed.
    Rejected = 4,
}

impl SolveStatus {
    pub fn from_u32(v: u32) -> Option<Self> {
        [
            Self::Ok,
            Self::NotReady,
            Self::Unobservable,
            Self::Failed,
            Self::Rejected,
        ]
        .into_iter()
        .find(|s| *s as u32 == v)
    }
    pub fn name(self) -> &'static str {
        match self {
            Self::Ok => "ok",
            Self::NotReady => "not_ready",
            Self::Unobservable => "unobservable",
            Self::Failed => "failed",
            Self::Rejected => "rejected",
        }
    }
}

/// The inversion's answer; every stage fills what it computed (NaN elsewhere).
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend, bytemuck::Pod, bytemuck::Zeroable)]
#[type_name("glint.v1.SolveResponse")]
#[repr(C)]
pub struct SolveResponse {
    pub meta: Meta,
    pub request_id: u64,
    pub stage: u32,
    /// [`SolveStatus`] as u32.
    pub status: u32,
    pub n_bands: u32,
    /// Index of the chosen band λ* (stage 2 and 3).
    pub chosen_band: u32,
    pub wavelength_nm: [f64; MAX_BANDS],
    /// Stage 1: relative reconstruction error per band.
    pub recon_err: [f64; MAX_BANDS],
    /// Stage 2: separation degree σ(λ) per band.
    pub separation: [f64; MAX_BANDS],
    /// Stage 3 at λ*: rates [deg/frame] and their covariance (row-major).
    pub p_deg_per_frame: [f64; 3],
    pub p_covariance: [f64; 9],
    /// Stage 3 on all bands jointly (NaN when not requested).
    pub p_joint_deg_per_frame: [f64; 3],
    pub p_joint_covariance: [f64; 9],
    /// Fisher information at the solution: eigenvalues (ascending) and eigenvectors (columns).
    pub fisher_eigenvalues: [f64; 3],
    pub fisher_eigenvectors: [f64; 9],
    /// 1σ bound along each eigen-direction [deg/frame].
    pub bound_1sigma_deg_per_frame: [f64; 3],
    /// Final normalised cost, LM iterations, starts tried.
    pub cost: f64,
    pub iterations: u32,
    pub starts: u32,
    /// Bit i set when eigen-direction i is observable (its bound below the threshold).
    pub observable_mask: u32,
    pub stable_samples: u32,
    pub motion_samples: u32,
    /// Stage 3: motion frames fitted at λ* (those within the fit horizon).
    pub fitted_frames: u32,
    /// Stage 3: the mirror solution (−w_x, w_y, −w_z) when it fits the data as well as p — the
    /// sense of rotation about X and Z is then not observable; NaN when the data tell them apart.
    pub p_mirror_deg_per_frame: [f64; 3],
    /// Stage 3: why no rate is reported at λ* (status `Unobservable`), see
    /// [`SolveResponse::REASON_NAMES`]; 0 otherwise.
    pub unobservable_reason: u32,
    /// The same for the joint fit.
    pub joint_unobservable_reason: u32,
    /// Stage 2: index of argmax σ(λ), the paper's choice (λ* may differ, see the inversion's
    /// band-selection rule).
    pub separation_band: u32,
    /// Stage 3 flags: [`SolveResponse::SENSE_FROM_JOINT`], [`SolveResponse::LAMBDA_REJECTED`],
    /// [`SolveResponse::JOINT_LOBE_REFIT`], [`SolveResponse::JOINT_LOBE_RATE_TRADED`],
    /// [`SolveResponse::JOINT_GLINT_LOBES_ONLY`], [`SolveResponse::JOINT_LOBE_KEPT_OFF_MINIMUM`],
    /// [`SolveResponse::HELD_COEFFICIENTS`], [`SolveResponse::JOINT_HELD_COEFFICIENTS`].
    pub stage3_flags: u32,
    /// Stage 2: the lobes' share of the stage-1 coefficients per band.
    pub specular_share: [f64; MAX_BANDS],
    /// Stage 1: width μ of the widest lobe kept by the basis test (NaN before stage 1).
    pub stage1_widest_lobe_mu: f64,
    /// Stage 1: Δχ² of the accepted basis reduction and its parameter count k.
    pub stage1_basis_delta_chi2: f64,
    pub stage1_basis_dof: u32,
    /// Stage 1: lobes kept per facet, of 10.
    pub stage1_lobes_kept: u32,
    /// Stage 3: index of the band the rate was fitted at: λ* (`chosen_band`), unless the joint
    /// fit rejected λ*'s solution as another minimum ([`SolveResponse::LAMBDA_REJECTED`]).
    pub stage3_band: u32,
    /// Stage 3: bands whose solution the joint fit rejected before `stage3_band` was accepted
    /// (with every candidate rejected, 1 and `stage3_band == chosen_band`).
    pub stage3_set_aside: u32,
    /// Stage 1: half-width \[nm\] of the spectral window stage 2 and the single-band fit used
    /// (0: every band on its own).
    pub stage1_spectral_window_nm: f64,
    /// Stage 1: the pooled curves' RMS bias in units of the noise, the pooling test's statistic
    /// (NaN when not tested: no σ, or no band within the window of another).
    pub stage1_spectral_bias_to_noise: f64,
    /// Stage 3: the rate's distance from the joint solution in standard deviations (the two
    /// covariances summed, over the directions both determine); NaN without both.
    pub stage3_joint_disagreement_sigma: f64,
    /// Stage 3: the factor `p_covariance` was widened by to cover the rate's distance from the
    /// joint solution (1: they agree within their errors); NaN without both.
    pub stage3_covariance_scale: f64,
    /// Stage 3: the joint fit's test of stage 1's widest lobes, χ² of the fit re-fitting them
    /// in the covariance of the fit keeping them (re-fitted when above its 99 % point, see
    /// [`SolveResponse::JOINT_LOBE_REFIT`]); NaN when not tested.
    pub stage3_joint_lobe_test_chi2: f64,
    /// Stage 3: the joint fit's mirror solution (−w_x, w_y, −w_z) when it fits all bands as
    /// well as `p_joint_deg_per_frame` (the joint fit cannot tell the sense of rotation); NaN
    /// when the data tell them apart or without a joint rate.
    pub p_joint_mirror_deg_per_frame: [f64; 3],
    /// Stage 3 at λ*: the directions the stated prior held at zero, bit k for body axis k
    /// (x, y, z) and [`SolveResponse::HELD_OTHER`] for one that is not a body axis. A direction
    /// `observable_mask` leaves out but not held here sits where the fit ended.
    pub stage3_held_axes: u32,
    /// Stage 3 at λ*: where the covariance's noise level came from, see
    /// [`SolveResponse::COVARIANCE_SOURCE_NAMES`] (0 without a rate).
    pub stage3_covariance_source: u32,
    /// Stage 3: the likeliest of the joint fit's minima one or two frames' shift from
    /// `p_joint_deg_per_frame`, which `p_joint_covariance` carries weighted by its likelihood;
    /// NaN when none was found.
    pub p_joint_neighbour_deg_per_frame: [f64; 3],
    /// Stage 3: that minimum's cost minus the joint fit's, in noise variances (negative: it
    /// fits better); NaN without one.
    pub stage3_joint_neighbour_delta_chi2: f64,
    /// Stage 3 at λ*: the likeliest of the fit's minima one or two frames' shift from
    /// `p_deg_per_frame`, which `p_covariance` carries weighted by its likelihood; NaN when
    /// none was found.
    pub p_neighbour_deg_per_frame: [f64; 3],
    /// Stage 3 at λ*: that minimum's cost minus the fit's, in noise variances (negative: it
    /// fits better); NaN without one.
    pub stage3_neighbour_delta_chi2: f64,
    /// Stage 3: the joint fit's rate under the lobe model its lobe test did not report (the
    /// re-fit's when stage 1's lobes were kept, the kept fit's when re-fitted); NaN when the
    /// lobes were not tested.
    pub p_joint_lobe_other_deg_per_frame: [f64; 3],
    /// Stage 3: the weight `p_joint_covariance` gives that rate (½ at the test's threshold, 0
    /// when it carries none); NaN when the lobes were not tested.
    pub stage3_joint_lobe_other_weight: f64,
}

impl Default for SolveResponse {
    fn default() -> Self {
        SolveResponse {
            meta: Meta::default(),
            request_id: 0,
            stage: 0,
            status: SolveStatus::Failed as u32,
            n_bands: 0,
            chosen_band: 0,
            wavelength_nm: [0.0; MAX_BANDS],
            recon_err: [f64::NAN; MAX_BANDS],
            separation: [f64::NAN; MAX_BANDS],
            p_deg_per_frame: [f64::NAN; 3],
            p_covariance: [f64::NAN; 9],
            p_joint_deg_per_frame: [f64::NAN; 3],
            p_joint_covariance: [f64::NAN; 9],
            fisher_eigenvalues: [f64::NAN; 3],
            fisher_eigenvectors: [f64::NAN; 9],
            bound_1sigma_deg_per_frame: [f64::NAN; 3],
            cost: f64::NAN,
            iterations: 0,
            starts: 0,
            observable_mask: 0,
            stable_samples: 0,
            motion_samples: 0,
            fitted_frames: 0,
            p_mirror_deg_per_frame: [f64::NAN; 3],
            unobservable_reason: 0,
            joint_unobservable_reason: 0,
            separation_band: 0,
            stage3_flags: 0,
            specular_share: [f64::NAN; MAX_BANDS],
            stage1_widest_lobe_mu: f64::NAN,
            stage1_basis_delta_chi2: f64::NAN,
            stage1_basis_dof: 0,
            stage1_lobes_kept: 0,
            stage3_band: 0,
            stage3_set_aside: 0,
            stage1_spectral_window_nm: 0.0,
            stage1_spectral_bias_to_noise: f64::NAN,
            stage3_joint_disagreement_sigma: f64::NAN,
            stage3_covariance_scale: f64::NAN,
            stage3_joint_lobe_test_chi2: f64::NAN,
            p_joint_mirror_deg_per_frame: [f64::NAN; 3],
            stage3_held_axes: 0,
            stage3_covariance_source: 0,
            p_joint_neighbour_deg_per_frame: [f64::NAN; 3],
            stage3_joint_neighbour_delta_chi2: f64::NAN,
            p_neighbour_deg_per_frame: [f64::NAN; 3],
            stage3_neighbour_delta_chi2: f64::NAN,
            p_joint_lobe_other_deg_per_frame: [f64::NAN; 3],
            stage3_joint_lobe_other_weight: f64::NAN,
        }
    }
}

impl SolveResponse {
    /// The λ* data fit p and its mirror equally well; the joint fit decided the sense.
    pub const SENSE_FROM_JOINT: u32 = 1;
    /// The joint fit rejected the solution at λ* as another minimum of that band's cost.
    pub const LAMBDA_REJECTED: u32 = 2;
    /// The joint fit re-fitted each facet's widest lobe from the motion window.
    pub const JOINT_LOBE_REFIT: u32 = 4;
    /// The joint fit kept stage 1's lobes because the re-fit traded the rate for the lobe (it
    /// ended below half the kept rate).
    pub const JOINT_LOBE_RATE_TRADED: u32 = 8;
    /// The joint fit re-fitted no lobe: each facet's widest lobe in use is a glint lobe
    /// (μ < 0.2), whose amplitude trades against the rate, so it stays stage 1's.
    pub const JOINT_GLINT_LOBES_ONLY: u32 = 16;
    /// The joint fit re-fitted the widest lobes because the fit keeping stage 1's has a
    /// neighbouring minimum that fits clearly better (Δχ² < −4): it is not its own model's best
    /// fit, whatever the lobe test's χ².
    pub const JOINT_LOBE_KEPT_OFF_MINIMUM: u32 = 32;
    /// The λ* fit held stage 1's coefficients by their stable-window prior (the scenario's
    /// `spectra.held_coefficients`).
    pub const HELD_COEFFICIENTS: u32 = 64;
    /// The joint fit did.
    pub const JOINT_HELD_COEFFICIENTS: u32 = 128;
    /// Every `stage3_flags` bit defined above.
    pub const STAGE3_FLAGS_KNOWN: u32 = Self::SENSE_FROM_JOINT
        | Self::LAMBDA_REJECTED
        | Self::JOINT_LOBE_REFIT
        | Self::JOINT_LOBE_RATE_TRADED
        | Self::JOINT_GLINT_LOBES_ONLY
        | Self::JOINT_LOBE_KEPT_OFF_MINIMUM
        | Self::HELD_COEFFICIENTS
        | Self::JOINT_HELD_COEFFICIENTS;

    /// `stage3_held_axes`: a held direction that is not a body axis (bits 0–2 are x, y, z).
    pub const HELD_OTHER: u32 = 8;

    /// Names of the `stage3_covariance_source` codes (index = code).
    pub const COVARIANCE_SOURCE_NAMES: [&'static str; 4] = [
        "none",
        "the observations' σ",
        "the observations' σ, scaled by the Birge ratio (the residuals reject the model)",
        "the residual variance, inflated for the residuals' serial correlation",
    ];

    /// Names of the `unobservable_reason` codes (index = code).
    pub const REASON_NAMES: [&'static str; 7] = [
        "none",
        "flat light curve",
        "rank deficient",
        "every direction above the threshold",
        "no glint: only the diffuse terms move the light curve",
        "no solution within twice the search box",
        "not confirmed: the joint fit over all bands finds no rate near it",
    ];

    /// The name of a reason code ("unknown" outside the table).
    pub fn reason_name(code: u32) -> &'static str {
        Self::REASON_NAMES
            .get(code as usize)
            .copied()
            .unwrap_or("unknown")
    }

    pub fn validate(&self) -> Result<(), Reject> {
        self.meta.validate()?;
        if SolveStatus::from_u32(self.status).is_none() {
            return Err(Reject::new("solve_response.status", "unknown status"));
        }
        if self.stage3_flags & !Self::STAGE3_FLAGS_KNOWN != 0 {
            return Err(Reject::new("solve_response.stage3_flags", "unknown bits"));
        }
        if self.stage3_held_axes > 0xF {
            return Err(Reject::new(
                "solve_response.stage3_held_axes",
                "unknown bits",
            ));
        }
        if self.stage3_covariance_source as usize >= Self::COVARIANCE_SOURCE_NAMES.len() {
            return Err(Reject::new(
                "solve_response.stage3_covariance_source",
                "unknown code",
            ));
        }
        let codes = Self::REASON_NAMES.len() as u32;
        if self.unobservable_reason >= codes || self.joint_unobservable_reason >= codes {
            return Err(Reject::new(
                "solve_response.unobservable_reason",
                "unknown reason code",
            ));
        }
        if self.n_bands as usize > MAX_BANDS
            || (self.n_bands > 0
                && (self.chosen_band >= self.n_bands
                    || self.separation_band >= self.n_bands
                    || self.stage3_band >= self.n_bands))
        {
            return Err(Reject::new(
                "solve_response.n_bands/chosen_band",
                "out of range",
            ));
        }
        Ok(())
    }
}
