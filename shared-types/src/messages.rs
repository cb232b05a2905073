//! Wire messages: every type that crosses a process boundary.
//!
//! All types are `#[repr(C)]`, hold no pointers, and derive [`ZeroCopySend`] with an explicit,
//! versioned `#[type_name]`: a process built from another contract version fails to open the
//! service with `IncompatibleTypes` instead of misreading memory. Padding is explicit (`_pad`
//! fields) so the layout is the same in every language; `tests/layout.rs` pins size, alignment
//! and field offsets.
//!
//! Every message starts with a [`Meta`]: a per-producer sequence number, the simulated time the
//! message describes, and the producer's monotonic send time (for cross-process latency).
//!
//! Messages come from peers, which may be buggy or corrupted by fault injection, so each type has
//! a `validate` method that a consumer calls before trusting the contents; a failure is counted
//! as a drop with reason [`DropReason::Malformed`], never a panic.

use iceoryx2::prelude::ZeroCopySend;

use crate::CONTRACT_VERSION;

/// Maximum number of spectral bands in one [`Spectrum`].
pub const MAX_BANDS: usize = 64;
/// Maximum number of debris objects carried in one [`Truth`] message.
pub const MAX_DEBRIS: usize = 16;
/// Number of per-reason drop counters in a [`Heartbeat`].
pub const DROP_REASONS: usize = 8;
/// Number of per-topic counters in a [`Heartbeat`].
pub const MAX_TOPICS: usize = 8;

/// Header common to every message.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq, ZeroCopySend)]
#[type_name("glint.v1.Meta")]
#[repr(C)]
pub struct Meta {
    /// Per-producer, per-topic sequence number, starting at 0, without gaps.
    pub seq: u64,
    /// Simulated time the content refers to [ns since scenario start].
    pub t_ns: u64,
    /// Producer's `CLOCK_MONOTONIC` at send [ns]; only for latency, never for results.
    pub send_mono_ns: u64,
    /// Contract version of the producer ([`CONTRACT_VERSION`]).
    pub contract_version: u32,
    /// Producer service id ([`crate::ServiceId`] as u32).
    pub producer: u32,
}

impl Meta {
    /// A header for a new message of this contract version.
    pub fn new(seq: u64, t_ns: u64, send_mono_ns: u64, producer: crate::ServiceId) -> Self {
        Meta {
            seq,
            t_ns,
            send_mono_ns,
            contract_version: CONTRACT_VERSION,
            producer: producer as u32,
        }
    }

    pub fn validate(&self) -> Result<(), Reject> {
        if self.contract_version != CONTRACT_VERSION {
            return Err(Reject::new("meta.contract_version", "mismatch"));
        }
        Ok(())
    }
}

/// Why a message was rejected by [`validate`](FrameHeader::validate).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Reject {
    /// The offending field.
    pub field: &'static str,
    /// What is wrong with it.
    pub what: &'static str,
}

impl Reject {
    fn new(field: &'static str, what: &'static str) -> Self {
        Reject { field, what }
    }
}

impl std::fmt::Display for Reject {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.field, self.what)
    }
}

fn finite(v: f64, field: &'static str) -> Result<(), Reject> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(Reject::new(field, "not finite"))
    }
}

fn unit(v: &[f64; 3], field: &'static str) -> Result<(), Reject> {
    let n2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
    if !n2.is_finite() || (n2 - 1.0).abs() > 1e-6 {
        return Err(Reject::new(field, "not a unit vector"));
    }
    Ok(())
}

/// User header of a camera frame; the payload is `[u16]` of `width_px * height_px` pixels,
/// row-major, rendered in place in the loaned shared-memory sample.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq, ZeroCopySend)]
#[type_name("glint.v1.FrameHeader")]
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
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
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

/// Ground truth for scoring; read only by the orchestrator.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("glint.v1.Truth")]
#[repr(C)]
pub struct Truth {
    pub meta: Meta,
    /// Which stream this truth belongs to: 0 = camera frame, 1 = spectrum sample.
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
        }
    }
}

impl Truth {
    pub const KIND_FRAME: u32 = 0;
    pub const KIND_SPECTRUM: u32 = 1;

    pub fn validate(&self) -> Result<(), Reject> {
        self.meta.validate()?;
        if self.kind > 1 {
            return Err(Reject::new("truth.kind", "not 0 or 1"));
        }
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

/// Maximum detections in one [`Detections`] message.
pub const MAX_DETECTIONS: usize = 32;
/// Maximum tracks in one [`Tracks`] message.
pub const MAX_TRACKS: usize = 16;

/// One detected object in a frame ([002] §3.3–3.5).
#[derive(Debug, Default, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("glint.v1.Detection")]
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
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("glint.v1.Detections")]
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
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("glint.v1.TrackEstimate")]
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
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("glint.v1.Tracks")]
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

/// A laser-range request: fire along (azimuth, elevation) at simulated time `meta.t_ns`.
#[derive(Debug, Default, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("glint.v1.RangeRequest")]
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
#[derive(Debug, Default, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("glint.v1.RangeResponse")]
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

/// A solve call to the inversion ([000] three-stage solve).
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq, ZeroCopySend)]
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
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
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
    pub _pad: u32,
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
            _pad: 0,
        }
    }
}

impl SolveResponse {
    pub fn validate(&self) -> Result<(), Reject> {
        self.meta.validate()?;
        if SolveStatus::from_u32(self.status).is_none() {
            return Err(Reject::new("solve_response.status", "unknown status"));
        }
        if self.n_bands as usize > MAX_BANDS
            || (self.n_bands > 0 && self.chosen_band >= self.n_bands)
        {
            return Err(Reject::new(
                "solve_response.n_bands/chosen_band",
                "out of range",
            ));
        }
        Ok(())
    }
}

/// Reasons a consumer drops a message; index into [`Heartbeat::dropped`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(usize)]
pub enum DropReason {
    /// A sequence gap: the transport overwrote samples the consumer had not read (realtime mode).
    Overflow = 0,
    /// The message failed validation.
    Malformed = 1,
    /// Dropped on purpose by an injected fault.
    Injected = 2,
    /// Arrived after its deadline.
    Late = 3,
    /// Duplicate or out-of-order sequence number.
    Stale = 4,
}

impl DropReason {
    pub const ALL: [DropReason; 5] = [
        DropReason::Overflow,
        DropReason::Malformed,
        DropReason::Injected,
        DropReason::Late,
        DropReason::Stale,
    ];

    pub fn name(self) -> &'static str {
        match self {
            DropReason::Overflow => "overflow",
            DropReason::Malformed => "malformed",
            DropReason::Injected => "injected",
            DropReason::Late => "late",
            DropReason::Stale => "stale",
        }
    }
}

/// Per-topic counters of one consumer, carried in a [`Heartbeat`].
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq, ZeroCopySend)]
#[type_name("glint.v1.TopicCounters")]
#[repr(C)]
pub struct TopicCounters {
    /// [`crate::TopicId`] as u32, or `u32::MAX` for an unused slot.
    pub topic: u32,
    pub _pad: u32,
    /// Messages published (producer side) on this topic.
    pub published: u64,
    /// Messages received and accepted.
    pub received: u64,
    /// Messages dropped, by [`DropReason`].
    pub dropped: [u64; DROP_REASONS],
    /// Highest sequence number seen + 1 (0 = none yet).
    pub next_seq: u64,
}

/// Periodic liveness and counters of a service.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq, ZeroCopySend)]
#[type_name("glint.v1.Heartbeat")]
#[repr(C)]
pub struct Heartbeat {
    pub meta: Meta,
    pub pid: u32,
    /// 0 = starting, 1 = ready, 2 = running, 3 = finished (producer done), 4 = stopping.
    pub state: u32,
    /// Last end-to-end latency observed by this service [ns] (send → processed).
    pub last_latency_ns: u64,
    pub topics: [TopicCounters; MAX_TOPICS],
}

impl Heartbeat {
    pub const STARTING: u32 = 0;
    pub const READY: u32 = 1;
    pub const RUNNING: u32 = 2;
    pub const FINISHED: u32 = 3;
    pub const STOPPING: u32 = 4;

    pub fn validate(&self) -> Result<(), Reject> {
        self.meta.validate()?;
        if self.state > Self::STOPPING {
            return Err(Reject::new("heartbeat.state", "out of range 0..=4"));
        }
        Ok(())
    }
}

/// Per-message acknowledgement from a consumer to a producer: credit for lockstep flow control
/// in sim-clock mode (the producer never has more than the subscriber buffer in flight).
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq, ZeroCopySend)]
#[type_name("glint.v1.Ack")]
#[repr(C)]
pub struct Ack {
    pub meta: Meta,
    /// Topic acknowledged ([`crate::TopicId`] as u32).
    pub topic: u32,
    /// Consumer ([`crate::ServiceId`] as u32).
    pub consumer: u32,
    /// Every message with `seq < next_seq` has been processed or counted as dropped.
    pub next_seq: u64,
}

/// Orchestrator → services commands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum Command {
    /// Stop gracefully: finish the current message, publish a last heartbeat, exit 0.
    Shutdown = 1,
    /// Stop producing until `Resume` (sensor).
    Pause = 2,
    Resume = 3,
    /// Start producing (sensor): sent once every consumer is ready.
    Start = 4,
}

impl Command {
    pub fn from_u32(v: u32) -> Option<Self> {
        match v {
            1 => Some(Command::Shutdown),
            2 => Some(Command::Pause),
            3 => Some(Command::Resume),
            4 => Some(Command::Start),
            _ => None,
        }
    }
}

/// A control message; `target` is a [`crate::ServiceId`] as u32 or [`Control::ALL`].
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq, ZeroCopySend)]
#[type_name("glint.v1.Control")]
#[repr(C)]
pub struct Control {
    pub meta: Meta,
    pub command: u32,
    pub target: u32,
    pub arg: [u64; 2],
}

impl Control {
    pub const ALL: u32 = u32::MAX;

    pub fn validate(&self) -> Result<(), Reject> {
        self.meta.validate()?;
        if Command::from_u32(self.command).is_none() {
            return Err(Reject::new("control.command", "unknown command"));
        }
        Ok(())
    }
}

/// Access to the common header, and the validation every consumer runs before trusting a peer.
pub trait Message: std::fmt::Debug + Copy + ZeroCopySend + 'static {
    fn meta(&self) -> &Meta;
    fn meta_mut(&mut self) -> &mut Meta;
    /// Called by the producer after the header is filled (e.g. to compute a content hash).
    fn seal(&mut self) {}
    /// Checks a received message; a failure is a counted `Malformed` drop.
    fn check(&self) -> Result<(), Reject>;
}

macro_rules! message {
    ($t:ty, $check:expr) => {
        impl Message for $t {
            fn meta(&self) -> &Meta {
                &self.meta
            }
            fn meta_mut(&mut self) -> &mut Meta {
                &mut self.meta
            }
            fn check(&self) -> Result<(), Reject> {
                #[allow(clippy::redundant_closure_call)]
                ($check)(self)
            }
        }
    };
}

impl Message for Spectrum {
    fn meta(&self) -> &Meta {
        &self.meta
    }
    fn meta_mut(&mut self) -> &mut Meta {
        &mut self.meta
    }
    fn seal(&mut self) {
        self.content_xxh3 = self.compute_hash();
    }
    fn check(&self) -> Result<(), Reject> {
        self.validate()
    }
}

message!(Truth, |m: &Truth| m.validate());
message!(Detections, |m: &Detections| m.validate());
message!(Tracks, |m: &Tracks| m.validate());
message!(SolveRequest, |m: &SolveRequest| m.validate());
message!(SolveResponse, |m: &SolveResponse| m.validate());
message!(RangeRequest, |m: &RangeRequest| m.validate());
message!(RangeResponse, |m: &RangeResponse| m.meta.validate());
message!(Heartbeat, |m: &Heartbeat| m.validate());
message!(Control, |m: &Control| m.validate());
message!(Ack, |m: &Ack| m.meta.validate());
