//! The [001] telescope's light-curve samples and the `photometry` service's answers.

use iceoryx2::prelude::ZeroCopySend;

use super::*;

/// One sample of the light curve.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend, bytemuck::Pod, bytemuck::Zeroable)]
#[type_name("glint.v8.PhotometrySample")]
#[repr(C)]
pub struct PhotometrySample {
    pub meta: Meta,
    /// Index of the sample over the arc.
    pub sample_index: u64,
    /// [`PhotometrySample::SEEN`], or why there is no magnitude: [`PhotometrySample::SHADOW`],
    /// [`PhotometrySample::BELOW_HORIZON`], [`PhotometrySample::NO_FLUX`].
    pub status: u32,
    pub _pad: u32,
    /// Apparent magnitude and its 1σ [mag] (status `SEEN`).
    pub mag: f64,
    pub sigma_mag: f64,
    /// Unit vectors from the satellite to the Sun and to the observer, ECI.
    pub sun: [f64; 3],
    pub obs: [f64; 3],
    /// Satellite–observer range [m].
    pub range_m: f64,
}

impl Default for PhotometrySample {
    fn default() -> Self {
        bytemuck::Zeroable::zeroed()
    }
}

impl PhotometrySample {
    pub const SEEN: u32 = 0;
    pub const SHADOW: u32 = 1;
    pub const BELOW_HORIZON: u32 = 2;
    /// Lit and above the horizon, but no lit facet faces the observer.
    pub const NO_FLUX: u32 = 3;

    pub fn validate(&self) -> Result<(), Reject> {
        self.meta.validate()?;
        if self.status > Self::NO_FLUX {
            return Err(Reject::new("photometry.status", "not 0, 1, 2 or 3"));
        }
        if self.status != Self::SEEN {
            return Ok(());
        }
        if !(self.mag.is_finite() && (-30.0..=40.0).contains(&self.mag)) {
            return Err(Reject::new("photometry.mag", "not a magnitude in −30..=40"));
        }
        if !(self.sigma_mag.is_finite() && self.sigma_mag > 0.0 && self.sigma_mag <= 10.0) {
            return Err(Reject::new("photometry.sigma_mag", "not in (0, 10]"));
        }
        unit(&self.sun, "photometry.sun")?;
        unit(&self.obs, "photometry.obs")?;
        if !(self.range_m.is_finite() && self.range_m >= 1.0) {
            return Err(Reject::new("photometry.range_m", "not a range ≥ 1 m"));
        }
        Ok(())
    }
}

/// Runners-up carried with an identification.
pub const MAX_MATCHES: usize = 8;
/// Entries of the upper triangle of the UKF's 6 × 6 error covariance.
pub const PHOTOMETRY_COV_ENTRIES: usize = 6 * 7 / 2;

/// One geometry's best fit to the light curve.
#[derive(
    Debug, Default, Clone, Copy, PartialEq, ZeroCopySend, bytemuck::Pod, bytemuck::Zeroable,
)]
#[type_name("glint.v8.PhotometryMatch")]
#[repr(C)]
pub struct PhotometryMatch {
    /// Index of the geometry in the scenario's shape library.
    pub geometry: u32,
    pub _pad: u32,
    /// Matching degree F / P̄ (0: a perfect match; math.md §2.7).
    pub score: f64,
    /// P̄: the observed facet areas over the model's; the scaled model's total area [m²].
    pub area_scale: f64,
    pub area_m2: f64,
    /// Spin axis (unit, ECI) and rate [rad/s].
    pub axis: [f64; 3],
    pub spin_rad_s: f64,
    /// Time [s] at which its rotation angle is the database's 0.
    pub t0_s: f64,
}

/// The service's answer to one sample.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend, bytemuck::Pod, bytemuck::Zeroable)]
#[type_name("glint.v8.PhotometryEstimate")]
#[repr(C)]
pub struct PhotometryEstimate {
    pub meta: Meta,
    /// Index of the sample answered.
    pub sample_index: u64,
    /// [`PhotometryEstimate::GATHERING`], [`PhotometryEstimate::TRACKING`] or
    /// [`PhotometryEstimate::UNIDENTIFIED`].
    pub status: u32,
    /// Valid entries of `matching` (best first; the first is the identification).
    pub n_matching: u32,
    pub matching: [PhotometryMatch; MAX_MATCHES],
    /// The UKF: q_IB (Hamilton, scalar first, body → ECI, w ≥ 0), ω in the body frame [rad/s].
    pub q_ib: [f64; 4],
    pub w_body_rad_s: [f64; 3],
    /// Its error covariance `[δp (GRP), ω]`, upper triangle row by row.
    pub covariance: [f64; PHOTOMETRY_COV_ENTRIES],
    /// Whether this sample updated the filter (1) or was a gap (0).
    pub updated: u32,
    /// Steps taken again with γ = 1, and filter restarts from the identification.
    pub fallbacks: u32,
    pub restarts: u32,
    pub _pad: u32,
}

impl Default for PhotometryEstimate {
    fn default() -> Self {
        bytemuck::Zeroable::zeroed()
    }
}

impl PhotometryEstimate {
    /// Gathering the light curve; no identification yet.
    pub const GATHERING: u32 = 0;
    /// Identified; the UKF tracks the attitude.
    pub const TRACKING: u32 = 1;
    /// The arc so far fits no geometry (no spin line): still gathering.
    pub const UNIDENTIFIED: u32 = 2;

    /// The identification, once there is one.
    pub fn best(&self) -> Option<&PhotometryMatch> {
        (self.status == Self::TRACKING && self.n_matching > 0).then(|| &self.matching[0])
    }

    /// The valid runners-up, best first.
    pub fn matches(&self) -> &[PhotometryMatch] {
        &self.matching[..(self.n_matching as usize).min(MAX_MATCHES)]
    }

    /// Entry (i, j) of the covariance, either triangle.
    pub fn cov(&self, i: usize, j: usize) -> f64 {
        let (r, c) = if i <= j { (i, j) } else { (j, i) };
        self.covariance[r * 6 - r * (r + 1) / 2 + c]
    }

    pub fn validate(&self) -> Result<(), Reject> {
        self.meta.validate()?;
        if self.status > Self::UNIDENTIFIED {
            return Err(Reject::new("photometry_estimate.status", "not 0, 1 or 2"));
        }
        if self.n_matching as usize > MAX_MATCHES {
            return Err(Reject::new(
                "photometry_estimate.n_matching",
                "out of range 0..=8",
            ));
        }
        for m in self.matches() {
            for v in [m.score, m.area_scale, m.area_m2, m.spin_rad_s, m.t0_s] {
                finite(v, "photometry_estimate.matching")?;
            }
            unit(&m.axis, "photometry_estimate.matching.axis")?;
        }
        if self.status != Self::TRACKING {
            return Ok(());
        }
        if self.n_matching == 0 {
            return Err(Reject::new(
                "photometry_estimate.n_matching",
                "0 while tracking",
            ));
        }
        for v in self.q_ib.iter().chain(&self.w_body_rad_s) {
            finite(*v, "photometry_estimate.state")?;
        }
        let n2: f64 = self.q_ib.iter().map(|v| v * v).sum();
        if (n2 - 1.0).abs() > 1e-6 {
            return Err(Reject::new(
                "photometry_estimate.q_ib",
                "not a unit quaternion",
            ));
        }
        for v in self.covariance {
            finite(v, "photometry_estimate.covariance")?;
        }
        if (0..6).any(|i| self.cov(i, i) <= 0.0) {
            return Err(Reject::new(
                "photometry_estimate.covariance",
                "a variance not positive",
            ));
        }
        Ok(())
    }
}
