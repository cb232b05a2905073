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

mod camera;
mod earth;
mod housekeeping;
pub mod layout;
mod photometry;
mod range;
mod spectrum;
mod stereo;
mod truth;

pub use camera::*;
pub use earth::*;
pub use housekeeping::*;
pub use photometry::*;
pub use range::*;
pub use spectrum::*;
pub use stereo::*;
pub use truth::*;

/// Maximum number of spectral bands in one [`Spectrum`].
pub const MAX_BANDS: usize = 64;
/// Coefficients of the two-facet model, `[panel; body]`, 11 terms each (math.md §3).
pub const TWO_FACET_TERMS: usize = 22;
/// Maximum number of debris objects carried in one [`Truth`] message.
pub const MAX_DEBRIS: usize = 16;
/// Number of per-reason drop counters in a [`Heartbeat`].
pub const DROP_REASONS: usize = 8;
/// Number of per-topic counters in a [`Heartbeat`].
pub const MAX_TOPICS: usize = 8;

/// Header common to every message.
#[derive(
    Debug, Default, Clone, Copy, PartialEq, Eq, ZeroCopySend, bytemuck::Pod, bytemuck::Zeroable,
)]
#[type_name("glint.v8.Meta")]
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

/// Access to the common header, and the validation every consumer runs before trusting a peer.
/// `NoUninit` (derived as `bytemuck::Pod`, which checks at compile time that a type has no
/// padding) lets a consumer read a message as bytes safely, e.g. to hash it.
pub trait Message:
    std::fmt::Debug + Copy + ZeroCopySend + bytemuck::NoUninit + bytemuck::AnyBitPattern + 'static
{
    fn meta(&self) -> &Meta;
    fn meta_mut(&mut self) -> &mut Meta;
    /// Called by the producer after the header is filled (e.g. to compute a content hash).
    fn seal(&mut self) {}
    /// Checks a received message; a failure is a counted `Malformed` drop.
    fn check(&self) -> Result<(), Reject>;
    /// Fault injection: makes this message invalid as `how` says, so that [`Message::check`]
    /// rejects it. A type without a field of that kind gets a wrong contract version.
    fn corrupt(&mut self, how: crate::scenario::Corruption) {
        let _ = how;
        self.meta_mut().contract_version = !CONTRACT_VERSION;
    }
    /// Folds the message's content into a run's digest: everything that is a function of the
    /// scenario and the seed, so two runs compare in one value. By default every byte but the
    /// send time (the only field that differs between two runs of the same scenario and seed)
    /// and the contract version (a new contract with the same content digests the same).
    fn fold_digest(&self, digest: &mut xxhash_rust::xxh3::Xxh3) {
        let mut copy = *self;
        copy.meta_mut().send_mono_ns = 0;
        copy.meta_mut().contract_version = 0;
        digest.update(bytemuck::bytes_of(&copy));
    }
}

macro_rules! message {
    ($t:ty, $check:expr, $corrupt:expr) => {
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
            fn corrupt(&mut self, how: crate::scenario::Corruption) {
                #[allow(clippy::redundant_closure_call)]
                ($corrupt)(self, how)
            }
        }
    };
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
    /// Its content hash (the header is left out).
    fn fold_digest(&self, digest: &mut xxhash_rust::xxh3::Xxh3) {
        digest.update(&self.content_xxh3.to_le_bytes());
    }
    fn corrupt(&mut self, how: crate::scenario::Corruption) {
        use crate::scenario::Corruption;
        match how {
            Corruption::Nan => self.flux_w[0] = f64::NAN,
            Corruption::Count => self.n_bands = MAX_BANDS as u32 + 1,
            Corruption::Version => self.meta.contract_version = !CONTRACT_VERSION,
        }
        // Sealed again: the validator, not the checksum, must be what rejects it.
        self.seal();
    }
}

impl Message for Truth {
    fn meta(&self) -> &Meta {
        &self.meta
    }
    fn meta_mut(&mut self) -> &mut Meta {
        &mut self.meta
    }
    fn check(&self) -> Result<(), Reject> {
        self.validate()
    }
    /// Its seq and time, the debris states, the satellite's attitude and rate, the Earth
    /// sensor's angles, the stereo target's or the spinning satellite's state.
    fn fold_digest(&self, digest: &mut xxhash_rust::xxh3::Xxh3) {
        digest.update(&self.meta.seq.to_le_bytes());
        digest.update(&self.meta.t_ns.to_le_bytes());
        let n = (self.n_debris as usize).min(self.debris_state_lvlh.len());
        for s in &self.debris_state_lvlh[..n] {
            for v in s {
                digest.update(&v.to_le_bytes());
            }
        }
        for v in (self.attitude_body_rest.iter())
            .chain(self.rate_deg_per_frame.iter())
            .chain([self.earth_beta_deg, self.earth_tilt_deg].iter())
        {
            digest.update(&v.to_le_bytes());
        }
        if matches!(self.kind, Truth::KIND_STEREO | Truth::KIND_PHOTOMETRY) {
            for v in &self.target_state {
                digest.update(&v.to_le_bytes());
            }
        }
    }
}
impl Message for EarthAttitude {
    fn meta(&self) -> &Meta {
        &self.meta
    }
    fn meta_mut(&mut self) -> &mut Meta {
        &mut self.meta
    }
    fn check(&self) -> Result<(), Reject> {
        self.validate()
    }
    fn corrupt(&mut self, how: crate::scenario::Corruption) {
        use crate::scenario::Corruption;
        match how {
            Corruption::Nan => self.methods[0].beta_deg = f64::NAN,
            Corruption::Count => self.methods[0].valid = 2,
            Corruption::Version => self.meta.contract_version = !CONTRACT_VERSION,
        }
    }
    /// The answers, not what they took: compute times differ between runs.
    fn fold_digest(&self, digest: &mut xxhash_rust::xxh3::Xxh3) {
        let mut copy = *self;
        copy.meta.send_mono_ns = 0;
        copy.meta.contract_version = 0;
        for method in &mut copy.methods {
            method.time_us = 0.0;
        }
        digest.update(bytemuck::bytes_of(&copy));
    }
}
message!(
    Detections,
    |m: &Detections| m.validate(),
    |m: &mut Detections, how| {
        use crate::scenario::Corruption;
        match how {
            Corruption::Nan => {
                m.n = m.n.max(1);
                m.items[0].x_px = f64::NAN;
            }
            Corruption::Count => m.n = MAX_DETECTIONS as u32 + 1,
            Corruption::Version => m.meta.contract_version = !CONTRACT_VERSION,
        }
    }
);
message!(Tracks, |m: &Tracks| m.validate(), |m: &mut Tracks, how| {
    use crate::scenario::Corruption;
    match how {
        Corruption::Nan => {
            m.n = m.n.max(1);
            m.items[0].azimuth_filt_rad = f64::NAN;
        }
        Corruption::Count => m.n = MAX_TRACKS as u32 + 1,
        Corruption::Version => m.meta.contract_version = !CONTRACT_VERSION,
    }
});
message!(Stereo, |m: &Stereo| m.validate(), |m: &mut Stereo, how| {
    use crate::scenario::Corruption;
    match how {
        Corruption::Nan => {
            m.n_features = m.n_features.max(1);
            m.features[0].z[0] = f64::NAN;
        }
        Corruption::Count => m.n_features = crate::scenario::MAX_STEREO_FEATURES as u32 + 1,
        Corruption::Version => m.meta.contract_version = !CONTRACT_VERSION,
    }
});
message!(
    RelNavEstimate,
    |m: &RelNavEstimate| m.validate(),
    |m: &mut RelNavEstimate, how| {
        use crate::scenario::Corruption;
        match how {
            Corruption::Nan => {
                m.status = RelNavEstimate::RUNNING;
                m.q_ct[0] = f64::NAN;
            }
            Corruption::Count => m.status = RelNavEstimate::STARTED + 1,
            Corruption::Version => m.meta.contract_version = !CONTRACT_VERSION,
        }
    }
);
message!(
    PhotometrySample,
    |m: &PhotometrySample| m.validate(),
    |m: &mut PhotometrySample, how| {
        use crate::scenario::Corruption;
        match how {
            Corruption::Nan => {
                m.status = PhotometrySample::SEEN;
                m.mag = f64::NAN;
            }
            Corruption::Count => m.status = PhotometrySample::NO_FLUX + 1,
            Corruption::Version => m.meta.contract_version = !CONTRACT_VERSION,
        }
    }
);
message!(
    PhotometryEstimate,
    |m: &PhotometryEstimate| m.validate(),
    |m: &mut PhotometryEstimate, how| {
        use crate::scenario::Corruption;
        match how {
            Corruption::Nan => {
                m.status = PhotometryEstimate::TRACKING;
                m.n_matching = m.n_matching.max(1);
                m.q_ib[0] = f64::NAN;
            }
            Corruption::Count => m.n_matching = MAX_MATCHES as u32 + 1,
            Corruption::Version => m.meta.contract_version = !CONTRACT_VERSION,
        }
    }
);
message!(SolveRequest, |m: &SolveRequest| m.validate());
message!(
    SolveResponse,
    |m: &SolveResponse| m.validate(),
    |m: &mut SolveResponse, how| {
        use crate::scenario::Corruption;
        match how {
            // An answer's numbers may be NaN by design (no rate); its status may not be unknown.
            Corruption::Nan => m.status = u32::MAX,
            Corruption::Count => m.stage = 0,
            Corruption::Version => m.meta.contract_version = !CONTRACT_VERSION,
        }
    }
);
message!(RangeRequest, |m: &RangeRequest| m.validate());
message!(RangeResponse, |m: &RangeResponse| m.meta.validate());
message!(Heartbeat, |m: &Heartbeat| m.validate());
message!(Control, |m: &Control| m.validate());
message!(Ack, |m: &Ack| m.meta.validate());
