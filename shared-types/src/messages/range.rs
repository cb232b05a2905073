//! The laser rangefinder ([002] §3.7, Table 2).

use iceoryx2::prelude::ZeroCopySend;

use super::*;

/// A laser-range request: fire along (azimuth, elevation) at simulated time `meta.t_ns`.
#[derive(
    Debug, Default, Clone, Copy, PartialEq, ZeroCopySend, bytemuck::Pod, bytemuck::Zeroable,
)]
#[type_name("glint.v8.RangeRequest")]
#[repr(C)]
pub struct RangeRequest {
    pub meta: Meta,
    pub request_id: u64,
    /// Pointing azimuth α [rad] ([002] eq 10).
    pub azimuth_rad: f64,
    /// Pointing elevation β [rad].
    pub elevation_rad: f64,
    /// Track id the requester intends to range (echoed back).
    pub track_id: u32,
    pub _pad: u32,
}

impl RangeRequest {
    pub fn validate(&self) -> Result<(), Reject> {
        self.meta.validate()?;
        finite(self.azimuth_rad, "range_request.azimuth_rad")?;
        finite(self.elevation_rad, "range_request.elevation_rad")?;
        if self.azimuth_rad.abs() > std::f64::consts::PI
            || self.elevation_rad.abs() > std::f64::consts::FRAC_PI_2
        {
            return Err(Reject::new(
                "range_request.azimuth/elevation",
                "out of range",
            ));
        }
        Ok(())
    }
}

/// Outcome of a laser-range request.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum RangeStatus {
    Hit = 0,
    Miss = 1,
    Rejected = 2,
}

/// The rangefinder's answer; `meta.t_ns` is the time of the echo (request time + delay).
#[derive(
    Debug, Default, Clone, Copy, PartialEq, ZeroCopySend, bytemuck::Pod, bytemuck::Zeroable,
)]
#[type_name("glint.v8.RangeResponse")]
#[repr(C)]
pub struct RangeResponse {
    pub meta: Meta,
    pub request_id: u64,
    /// Measured range [m] (valid when `status == Hit`).
    pub range_m: f64,
    /// [`RangeStatus`] as u32.
    pub status: u32,
    pub track_id: u32,
}
