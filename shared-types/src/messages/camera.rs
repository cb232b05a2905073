//! The debris chain: camera frames ([002] §3.2), detections (§3.3–3.5), tracks (§3.6–3.8).

use iceoryx2::prelude::ZeroCopySend;

use super::*;

/// User header of a camera frame; the payload is `[u16]` of `width_px * height_px` pixels,
/// row-major, rendered in place in the loaned shared-memory sample.
#[derive(
    Debug, Default, Clone, Copy, PartialEq, Eq, ZeroCopySend, bytemuck::Pod, bytemuck::Zeroable,
)]
#[type_name("glint.v8.FrameHeader")]
#[repr(C)]
pub struct FrameHeader {
    pub meta: Meta,
    /// Frame index within the run (equals `meta.seq` for the sensor's frame stream).
    pub frame_index: u64,
    /// Start of the exposure [ns of simulated time].
    pub exposure_start_ns: u64,
    /// Exposure duration [ns].
    pub exposure_ns: u64,
    /// Interval between the end of one exposure and the start of the next [ns].
    pub interval_ns: u64,
    /// xxh3-64 of the pixel bytes (little-endian u16), computed by the producer after rendering.
    pub pixels_xxh3: u64,
    pub width_px: u32,
    pub height_px: u32,
}

impl FrameHeader {
    /// Checks the header against the received payload length.
    pub fn validate(&self, payload_len: usize) -> Result<(), Reject> {
        self.meta.validate()?;
        if self.width_px == 0
            || self.height_px == 0
            || self.width_px > 16384
            || self.height_px > 16384
        {
            return Err(Reject::new(
                "frame.width_px/height_px",
                "out of range 1..=16384",
            ));
        }
        if (self.width_px as usize) * (self.height_px as usize) != payload_len {
            return Err(Reject::new(
                "frame.payload",
                "length != width_px * height_px",
            ));
        }
        if self.exposure_ns == 0 {
            return Err(Reject::new("frame.exposure_ns", "zero"));
        }
        Ok(())
    }
}

impl FrameHeader {
    /// Fault injection: makes the frame invalid as `how` says, so that
    /// [`FrameHeader::validate`] rejects it (a frame has no float to make non-finite: `nan`
    /// zeroes its exposure; `count` makes its size disagree with its pixels).
    pub fn corrupt(&mut self, how: crate::scenario::Corruption) {
        use crate::scenario::Corruption;
        match how {
            Corruption::Nan => self.exposure_ns = 0,
            Corruption::Count => self.width_px += 1,
            Corruption::Version => self.meta.contract_version = !CONTRACT_VERSION,
        }
    }
}

/// Maximum detections in one [`Detections`] message.
pub const MAX_DETECTIONS: usize = 32;
/// Maximum tracks in one [`Tracks`] message.
pub const MAX_TRACKS: usize = 16;

/// One detected object in a frame ([002] §3.3–3.5).
#[derive(
    Debug, Default, Clone, Copy, PartialEq, ZeroCopySend, bytemuck::Pod, bytemuck::Zeroable,
)]
#[type_name("glint.v8.Detection")]
#[repr(C)]
pub struct Detection {
    /// Persistent id assigned by the inter-frame matcher.
    pub track_id: u32,
    /// [`Detection::FLAG_MATCHED`] | [`Detection::FLAG_BORDER`] | [`Detection::FLAG_SATURATED`].
    pub flags: u32,
    /// Intensity-weighted centroid, 0-based pixels (x = column, y = row).
    pub x_px: f64,
    pub y_px: f64,
    /// Position at the end of the exposure (eq 9), 0-based pixels.
    pub end_x_px: f64,
    pub end_y_px: f64,
    /// Equivalent-ellipse features (§3.3, fixed formulas).
    pub area_px: f64,
    pub a_px: f64,
    pub b_px: f64,
    pub theta_rad: f64,
    pub eccentricity: f64,
    /// Background-subtracted integrated signal [DN].
    pub flux_dn: f64,
    /// Line of sight of the end point (eq 10) [rad].
    pub azimuth_rad: f64,
    pub elevation_rad: f64,
    /// 1σ of that line of sight [rad], from the blob's centroid uncertainty (0 = unknown).
    pub sigma_rad: f64,
}

impl Detection {
    pub const FLAG_MATCHED: u32 = 1;
    pub const FLAG_BORDER: u32 = 2;
    pub const FLAG_SATURATED: u32 = 4;
}

/// The detector's output for one frame: matched objects only (false targets are rejected).
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend, bytemuck::Pod, bytemuck::Zeroable)]
#[type_name("glint.v8.Detections")]
#[repr(C)]
pub struct Detections {
    pub meta: Meta,
    pub frame_index: u64,
    /// End of the frame's exposure [ns of simulated time] (the time tag of every detection).
    pub exposure_end_ns: u64,
    /// Valid entries in `items`.
    pub n: u32,
    /// Connected components found in the frame (before matching).
    pub blobs_found: u32,
    /// Objects of the previous frame rejected as false targets (no match in this frame).
    pub rejected: u32,
    pub _pad: u32,
    pub items: [Detection; MAX_DETECTIONS],
}

impl Default for Detections {
    fn default() -> Self {
        Detections {
            meta: Meta::default(),
            frame_index: 0,
            exposure_end_ns: 0,
            n: 0,
            blobs_found: 0,
            rejected: 0,
            _pad: 0,
            items: [Detection::default(); MAX_DETECTIONS],
        }
    }
}

impl Detections {
    pub fn validate(&self) -> Result<(), Reject> {
        self.meta.validate()?;
        if self.n as usize > MAX_DETECTIONS {
            return Err(Reject::new("detections.n", "out of range 0..=32"));
        }
        for d in &self.items[..self.n as usize] {
            for v in [
                d.x_px,
                d.y_px,
                d.end_x_px,
                d.end_y_px,
                d.area_px,
                d.a_px,
                d.b_px,
                d.theta_rad,
                d.eccentricity,
                d.flux_dn,
                d.azimuth_rad,
                d.elevation_rad,
                d.sigma_rad,
            ] {
                finite(v, "detections.items")?;
            }
        }
        Ok(())
    }
}

/// One track's estimate after a frame ([002] §3.6–3.8).
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend, bytemuck::Pod, bytemuck::Zeroable)]
#[type_name("glint.v8.TrackEstimate")]
#[repr(C)]
pub struct TrackEstimate {
    pub track_id: u32,
    /// 0 tentative, 1 confirmed, 2 coasting (missed this frame).
    pub status: u32,
    /// [`RangeStatus`] of this frame's laser shot, or `u32::MAX` if none was fired.
    pub range_status: u32,
    /// `1` when the angle filter is initialised and the `*_filt_rad` angles are valid.
    pub angles_valid: u32,
    /// Measured and filtered line of sight [rad].
    pub azimuth_meas_rad: f64,
    pub elevation_meas_rad: f64,
    pub azimuth_filt_rad: f64,
    pub elevation_filt_rad: f64,
    /// Laser range of this frame [m] (valid when `range_status` is Hit).
    pub range_meas_m: f64,
    /// Laser pointing sent for this frame (delay-predicted) [rad].
    pub pointing_azimuth_rad: f64,
    pub pointing_elevation_rad: f64,
    /// EKF state [x, y, z, ẋ, ẏ, ż] in the observer's LVLH-nadir frame [m, m/s].
    pub state_lvlh: [f64; 6],
    /// EKF covariance, row-major 6×6.
    pub covariance: [f64; 36],
    /// Direct fix from (α, β, r) of this frame ("before filtering"), [m]; NaN if no range.
    pub direct_position_m: [f64; 3],
    /// `1` when the EKF is initialised and `state_lvlh` is valid.
    pub ekf_valid: u32,
    pub _pad2: u32,
    /// Time of `state_lvlh` and `direct_position_m` [ns of simulated time]: the laser echo
    /// when a range was applied this frame, else the end of the exposure.
    pub state_t_ns: u64,
}

impl Default for TrackEstimate {
    fn default() -> Self {
        TrackEstimate {
            track_id: 0,
            status: 0,
            range_status: u32::MAX,
            angles_valid: 0,
            azimuth_meas_rad: 0.0,
            elevation_meas_rad: 0.0,
            azimuth_filt_rad: 0.0,
            elevation_filt_rad: 0.0,
            range_meas_m: 0.0,
            pointing_azimuth_rad: 0.0,
            pointing_elevation_rad: 0.0,
            state_lvlh: [0.0; 6],
            covariance: [0.0; 36],
            direct_position_m: [0.0; 3],
            ekf_valid: 0,
            _pad2: 0,
            state_t_ns: 0,
        }
    }
}

/// The tracker's output for one frame.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend, bytemuck::Pod, bytemuck::Zeroable)]
#[type_name("glint.v8.Tracks")]
#[repr(C)]
pub struct Tracks {
    pub meta: Meta,
    pub frame_index: u64,
    pub n: u32,
    /// Range requests that got no answer in time this frame.
    pub range_timeouts: u32,
    pub items: [TrackEstimate; MAX_TRACKS],
}

impl Default for Tracks {
    fn default() -> Self {
        Tracks {
            meta: Meta::default(),
            frame_index: 0,
            n: 0,
            range_timeouts: 0,
            items: [TrackEstimate::default(); MAX_TRACKS],
        }
    }
}

impl Tracks {
    pub fn validate(&self) -> Result<(), Reject> {
        self.meta.validate()?;
        if self.n as usize > MAX_TRACKS {
            return Err(Reject::new("tracks.n", "out of range 0..=16"));
        }
        for t in &self.items[..self.n as usize] {
            for v in [
                t.azimuth_filt_rad,
                t.elevation_filt_rad,
                t.azimuth_meas_rad,
                t.elevation_meas_rad,
            ] {
                finite(v, "tracks.items")?;
            }
            if t.ekf_valid == 1 {
                for v in t.state_lvlh.iter().chain(t.covariance.iter()) {
                    finite(*v, "tracks.items.state")?;
                }
            }
        }
        Ok(())
    }
}
