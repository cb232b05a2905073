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
#[type_name("glint.v8.Spectrum")]
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
#[type_name("glint.v8.SolveRequest")]
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

/// The answer to one solve call: the stage's figures and, for stage 3, glint's answer (the
/// joint fit over every band when it was asked for, else the fit at λ*) with its covariance,
/// the Fisher directions, what the data leave open, and λ*'s fit beside it (the paper's
/// stage 3). Per-band figures are `f32`: relative errors and degrees of separation, printed to
/// four digits.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend, bytemuck::Pod, bytemuck::Zeroable)]
#[type_name("glint.v8.SolveResponse")]
#[repr(C)]
pub struct SolveResponse {
    pub meta: Meta,
    /// The request answered.
    pub request_id: u64,
    /// 1, 2 or 3.
    pub stage: u32,
    /// [`SolveStatus`].
    pub status: u32,
    /// Bands of the spectra.
    pub n_bands: u32,
    /// Stage 2: λ*'s band index.
    pub chosen_band: u32,
    /// Samples the stable window had.
    pub stable_samples: u32,
    /// Frames the motion window had (stage 3; 0 for stages 1 and 2, which do not use it).
    pub motion_samples: u32,
    /// Stage 1: reconstruction error ε_rec per band.
    pub recon_err: [f32; MAX_BANDS],
    /// Stage 2: separation degree σ(λ) per band.
    pub separation: [f32; MAX_BANDS],
    /// Stage 3: [`Self::JOINT`], [`Self::SENSE_UNDETERMINED`], [`Self::LOBE_REFIT`].
    pub flags: u32,
    /// Why the answer has no rate ([`Self::REASON_NAMES`]; 0 with a rate).
    pub unobservable_reason: u32,
    /// Body axes the prior held: bit 0 X, 1 Y, 2 Z, 3 another direction.
    pub held_axes: u32,
    /// Bit i: Fisher direction i is determined.
    pub observable_mask: u32,
    /// Motion frames the answer fitted (its horizon).
    pub fitted_frames: u32,
    /// LM iterations of the answer's fit.
    pub iterations: u32,
    /// p̂ \[deg/frame\] (NaN without a rate).
    pub rate_deg_per_frame: [f64; 3],
    /// Cov(p̂), row-major \[(deg/frame)²\].
    pub covariance: [f64; 9],
    /// The Fisher eigen-directions as columns, least informed first.
    pub fisher_eigenvectors: [f64; 9],
    /// 1σ along each of them \[deg/frame\].
    pub bound_1sigma_deg_per_frame: [f64; 3],
    /// The mirror that fits as well, with [`Self::SENSE_UNDETERMINED`] (NaN otherwise).
    pub mirror_deg_per_frame: [f64; 3],
    /// λ*'s fit: [`SolveStatus`] (`Ok` or `Unobservable`).
    pub band_status: u32,
    /// λ*'s fit: its unobservable reason.
    pub band_unobservable_reason: u32,
    /// λ*'s fit: p̂ \[deg/frame\] (NaN without a rate).
    pub band_rate_deg_per_frame: [f64; 3],
    /// Stage 1's two-facet coefficients at λ*, `[panel; body]` (stages 2 and 3; NaN before
    /// λ* is chosen): the reconstruction of the stable window, and the joint fit's model.
    pub recon_coefficients: [f64; TWO_FACET_TERMS],
    /// The coefficients λ*'s own rate fit used, `[panel; body]`: the spectrally pooled ones
    /// when stage 1 pooled, else [`Self::recon_coefficients`] (stages 2 and 3).
    pub rate_coefficients: [f64; TWO_FACET_TERMS],
    /// With [`Self::LOBE_REFIT`]: the lobe the answer re-fitted per facet (panel, body), as a
    /// term index of [`Self::recon_coefficients`] (1–10; 0 for none).
    pub refit_lobes: [u32; 2],
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
            stable_samples: 0,
            motion_samples: 0,
            recon_err: [f32::NAN; MAX_BANDS],
            separation: [f32::NAN; MAX_BANDS],
            flags: 0,
            unobservable_reason: 0,
            held_axes: 0,
            observable_mask: 0,
            fitted_frames: 0,
            iterations: 0,
            rate_deg_per_frame: [f64::NAN; 3],
            covariance: [f64::NAN; 9],
            fisher_eigenvectors: [f64::NAN; 9],
            bound_1sigma_deg_per_frame: [f64::NAN; 3],
            mirror_deg_per_frame: [f64::NAN; 3],
            band_status: 0,
            band_unobservable_reason: 0,
            band_rate_deg_per_frame: [f64::NAN; 3],
            recon_coefficients: [f64::NAN; TWO_FACET_TERMS],
            rate_coefficients: [f64::NAN; TWO_FACET_TERMS],
            refit_lobes: [0; 2],
        }
    }
}

impl SolveResponse {
    /// The answer is the joint fit over every band (else λ*'s fit).
    pub const JOINT: u32 = 1;
    /// The mirror fits as well: the sense of rotation is not determined.
    pub const SENSE_UNDETERMINED: u32 = 2;
    /// The answer re-fitted each facet's widest lobe from the motion window.
    pub const LOBE_REFIT: u32 = 4;
    /// Every defined flag.
    pub const FLAGS_KNOWN: u32 = Self::JOINT | Self::SENSE_UNDETERMINED | Self::LOBE_REFIT;

    /// `held_axes` bit of a direction other than a body axis.
    pub const HELD_OTHER: u32 = 8;

    pub const REASON_NAMES: [&'static str; 6] = [
        "none",
        "flat light curve",
        "rank deficient",
        "every direction above the threshold",
        "no glint: only the diffuse terms move the light curve",
        "no solution within twice the search box",
    ];

    pub fn reason_name(code: u32) -> &'static str {
        Self::REASON_NAMES
            .get(code as usize)
            .copied()
            .unwrap_or("unknown")
    }

    /// Checks a response from a peer before it is trusted: codes within their tables, band
    /// indices within the bands, and a stage-3 rate that is a number with a covariance.
    pub fn validate(&self) -> Result<(), Reject> {
        self.meta.validate()?;
        let Some(status) = SolveStatus::from_u32(self.status) else {
            return Err(Reject::new("solve_response.status", "unknown status"));
        };
        if !(1..=3).contains(&self.stage) {
            return Err(Reject::new("solve_response.stage", "not 1, 2 or 3"));
        }
        if self.flags & !Self::FLAGS_KNOWN != 0 {
            return Err(Reject::new("solve_response.flags", "unknown bits"));
        }
        if self.held_axes > 0xF {
            return Err(Reject::new("solve_response.held_axes", "unknown bits"));
        }
        if self.observable_mask > 0b111 {
            return Err(Reject::new(
                "solve_response.observable_mask",
                "unknown bits",
            ));
        }
        let codes = Self::REASON_NAMES.len() as u32;
        if self.unobservable_reason >= codes || self.band_unobservable_reason >= codes {
            return Err(Reject::new(
                "solve_response.unobservable_reason",
                "unknown reason code",
            ));
        }
        if SolveStatus::from_u32(self.band_status).is_none() {
            return Err(Reject::new("solve_response.band_status", "unknown status"));
        }
        if self.n_bands as usize > MAX_BANDS
            || (self.n_bands > 0 && self.chosen_band >= self.n_bands)
        {
            return Err(Reject::new(
                "solve_response.n_bands/chosen_band",
                "out of range",
            ));
        }
        for (field, c) in [
            (
                "solve_response.recon_coefficients",
                &self.recon_coefficients,
            ),
            ("solve_response.rate_coefficients", &self.rate_coefficients),
        ] {
            // Given (every term a number) or not (every term NaN), never a mix or an infinity.
            if !(c.iter().all(|v| v.is_finite()) || c.iter().all(|v| v.is_nan())) {
                return Err(Reject::new(field, "a mix of numbers and non-numbers"));
            }
        }
        if self
            .refit_lobes
            .iter()
            .any(|&k| k as usize >= TWO_FACET_TERMS / 2)
        {
            return Err(Reject::new(
                "solve_response.refit_lobes",
                "not a lobe's term index (0–10)",
            ));
        }
        if self.stage == 3 && status == SolveStatus::Ok {
            let numbers = self.rate_deg_per_frame.iter().chain(&self.covariance);
            if !numbers.into_iter().all(|v| v.is_finite()) {
                return Err(Reject::new(
                    "solve_response.rate_deg_per_frame",
                    "a rate reported ok must be finite, with a finite covariance",
                ));
            }
        }
        Ok(())
    }
}
