//! Ground truth for scoring; read only by the orchestrator.

use iceoryx2::prelude::ZeroCopySend;

use super::*;

/// Ground truth for scoring; read only by the orchestrator.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend, bytemuck::Pod, bytemuck::Zeroable)]
#[type_name("glint.v8.Truth")]
#[repr(C)]
pub struct Truth {
    pub meta: Meta,
    /// Which stream this truth belongs to: 0 = camera frame, 1 = spectrum sample, 2 = Earth
    /// frame, 3 = stereo epoch, 4 = light-curve sample.
    pub kind: u32,
    /// Number of valid debris entries.
    pub n_debris: u32,
    /// Frame index (camera) or spectrum frame index.
    pub frame_index: u64,
    /// Debris relative states [x, y, z, ẋ, ẏ, ż] in the observer's LVLH-nadir frame [m, m/s],
    /// at the end of the exposure.
    pub debris_state_lvlh: [[f64; 6]; MAX_DEBRIS],
    /// Attitude of the target body relative to its rest frame, row-major 3×3 (R(t), [000] eq 17).
    pub attitude_body_rest: [f64; 9],
    /// True attitude rates [deg/frame] ([000] p*).
    pub rate_deg_per_frame: [f64; 3],
    /// [`Window`] as u32 for spectrum truth.
    pub window: u32,
    /// Number of valid false-target positions.
    pub n_false: u32,
    /// False targets rendered into this frame: 0-based pixel (x, y).
    pub false_targets_px: [[f64; 2]; MAX_DEBRIS],
    /// Earth frame: β, the angle from the optical axis to nadir [deg], and the nadir's signed
    /// tilt about the turntable axis [deg].
    pub earth_beta_deg: f64,
    pub earth_tilt_deg: f64,
    /// The target's state, by kind. Stereo epoch ([004]): `[q_ct (w, x, y, z; Hamilton, R =
    /// C_CT), ω_t in T (rad/s), k, ρ in O (m), v in O (m/s)]`. Light-curve sample ([001]):
    /// `[q_IB (w, x, y, z; body → ECI), ω in the body frame (rad/s), the shape's index in the
    /// library, its total facet area (m²), the spin rate (rad/s), 0 × 5]`.
    pub target_state: [f64; 15],
}

impl Default for Truth {
    fn default() -> Self {
        Truth {
            meta: Meta::default(),
            kind: 0,
            n_debris: 0,
            frame_index: 0,
            debris_state_lvlh: [[0.0; 6]; MAX_DEBRIS],
            attitude_body_rest: [0.0; 9],
            rate_deg_per_frame: [0.0; 3],
            window: 0,
            n_false: 0,
            false_targets_px: [[0.0; 2]; MAX_DEBRIS],
            earth_beta_deg: 0.0,
            earth_tilt_deg: 0.0,
            target_state: [0.0; 15],
        }
    }
}

impl Truth {
    pub const KIND_FRAME: u32 = 0;
    pub const KIND_SPECTRUM: u32 = 1;
    pub const KIND_EARTH: u32 = 2;
    pub const KIND_STEREO: u32 = 3;
    pub const KIND_PHOTOMETRY: u32 = 4;

    pub fn validate(&self) -> Result<(), Reject> {
        self.meta.validate()?;
        if self.kind > Self::KIND_PHOTOMETRY {
            return Err(Reject::new("truth.kind", "not 0, 1, 2, 3 or 4"));
        }
        for v in self.target_state {
            finite(v, "truth.target_state")?;
        }
        finite(self.earth_beta_deg, "truth.earth_beta_deg")?;
        finite(self.earth_tilt_deg, "truth.earth_tilt_deg")?;
        if self.n_debris as usize > MAX_DEBRIS || self.n_false as usize > MAX_DEBRIS {
            return Err(Reject::new("truth.n_debris/n_false", "out of range 0..=16"));
        }
        for s in &self.debris_state_lvlh[..self.n_debris as usize] {
            for v in s {
                finite(*v, "truth.debris_state_lvlh")?;
            }
        }
        Ok(())
    }
}
