//! The [004] stereo rig's epochs and the `relnav` filter's estimates.

use iceoryx2::prelude::ZeroCopySend;

use super::*;
use crate::scenario::MAX_STEREO_FEATURES;

/// One feature seen at one epoch.
#[derive(
    Debug, Default, Clone, Copy, PartialEq, ZeroCopySend, bytemuck::Pod, bytemuck::Zeroable,
)]
#[type_name("glint.v8.StereoFeature")]
#[repr(C)]
pub struct StereoFeature {
    /// Index of the feature in the target's feature list.
    pub feature: u32,
    pub _pad: u32,
    /// Normalised image coordinates `[x_l, y_l, x_r, y_r]` (math.md §5.5).
    pub z: [f64; 4],
}

/// Every feature the rig saw at one epoch.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend, bytemuck::Pod, bytemuck::Zeroable)]
#[type_name("glint.v8.Stereo")]
#[repr(C)]
pub struct Stereo {
    pub meta: Meta,
    /// Index of the epoch over the run.
    pub epoch_index: u64,
    /// Valid entries of `features`.
    pub n_features: u32,
    pub _pad: u32,
    pub features: [StereoFeature; MAX_STEREO_FEATURES],
}

impl Default for Stereo {
    fn default() -> Self {
        bytemuck::Zeroable::zeroed()
    }
}

impl Stereo {
    /// The valid features.
    pub fn seen(&self) -> &[StereoFeature] {
        &self.features[..(self.n_features as usize).min(MAX_STEREO_FEATURES)]
    }

    pub fn validate(&self) -> Result<(), Reject> {
        self.meta.validate()?;
        if self.n_features as usize > MAX_STEREO_FEATURES {
            return Err(Reject::new("stereo.n_features", "out of range 0..=16"));
        }
        for f in self.seen() {
            if f.feature as usize >= MAX_STEREO_FEATURES {
                return Err(Reject::new(
                    "stereo.features.feature",
                    "out of range 0..=15",
                ));
            }
            for v in f.z {
                finite(v, "stereo.features.z")?;
            }
        }
        Ok(())
    }
}

/// Entries of the upper triangle of the 14 × 14 error covariance.
pub const RELNAV_COV_ENTRIES: usize = 14 * 15 / 2;

/// The filter's answer at one epoch.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend, bytemuck::Pod, bytemuck::Zeroable)]
#[type_name("glint.v8.RelNav")]
#[repr(C)]
pub struct RelNavEstimate {
    pub meta: Meta,
    /// Index of the stereo epoch answered.
    pub epoch_index: u64,
    /// [`RelNavEstimate::STARTING`], [`RelNavEstimate::RUNNING`] or [`RelNavEstimate::STARTED`].
    pub status: u32,
    /// Features the update used and refused.
    pub used: u32,
    pub rejected: u32,
    /// Degrees of freedom of `nis` (4 per feature used).
    pub dof: u32,
    /// Normalised innovation squared of the update.
    pub nis: f64,
    /// q_ct (Hamilton, scalar first, `R(q) = C_CT`, w ≥ 0).
    pub q_ct: [f64; 4],
    /// ω_t in T [rad/s].
    pub w_t_rad_s: [f64; 3],
    /// Inertia parameters k (math.md eq 16).
    pub k: [f64; 2],
    /// ρ [m] and v [m/s] in O (RSW).
    pub rho_o_m: [f64; 3],
    pub v_o_m_s: [f64; 3],
    /// The error covariance `[δθ, δω, δk, δρ, δv]`, upper triangle row by row.
    pub covariance: [f64; RELNAV_COV_ENTRIES],
    /// The filter's events so far: starts from the measurements, restarts after a
    /// divergence, after a numerical failure.
    pub starts: u32,
    pub diverged: u32,
    pub numerical_failures: u32,
    pub _pad: u32,
}

impl Default for RelNavEstimate {
    fn default() -> Self {
        bytemuck::Zeroable::zeroed()
    }
}

impl RelNavEstimate {
    /// No estimate yet: the filter is starting from the measurements.
    pub const STARTING: u32 = 0;
    /// An estimate.
    pub const RUNNING: u32 = 1;
    /// An estimate from a (re)start at this epoch.
    pub const STARTED: u32 = 2;

    /// Entry (i, j) of the covariance, either triangle.
    pub fn cov(&self, i: usize, j: usize) -> f64 {
        let (r, c) = if i <= j { (i, j) } else { (j, i) };
        self.covariance[r * 14 - r * (r + 1) / 2 + c]
    }

    pub fn validate(&self) -> Result<(), Reject> {
        self.meta.validate()?;
        if self.status > Self::STARTED {
            return Err(Reject::new("relnav.status", "not 0, 1 or 2"));
        }
        if self.status == Self::STARTING {
            return Ok(());
        }
        let values = self.q_ct.iter().chain(&self.w_t_rad_s).chain(&self.k);
        for v in values.chain(&self.rho_o_m).chain(&self.v_o_m_s) {
            finite(*v, "relnav.state")?;
        }
        let n2: f64 = self.q_ct.iter().map(|v| v * v).sum();
        if (n2 - 1.0).abs() > 1e-6 {
            return Err(Reject::new("relnav.q_ct", "not a unit quaternion"));
        }
        for v in self.covariance {
            finite(v, "relnav.covariance")?;
        }
        if (0..14).any(|i| self.cov(i, i) <= 0.0) {
            return Err(Reject::new("relnav.covariance", "a variance not positive"));
        }
        Ok(())
    }
}
