//! glint-tracker: the pure core of the seed-002 debris tracker (docs/math.md §3.6–3.8).
//!
//! No IPC, no clock: every time is passed in (`t_s`, seconds of scenario time).
//!
//! - [`angle_filter`]: the position–velocity Kalman filter on (α, β) (§3.6, eqs 11–15, fixed Φ
//!   and H), initialised from two frames;
//! - [`pointing`]: laser pointing with delay prediction and the beam success check (§3.7, eq 16);
//! - [`ekf`]: the CW extended Kalman filter on the LVLH_N relative state with (α, β, r) or
//!   angles-only updates (§3.8, eqs 17–28), NEES;
//! - [`track`]: per-track life cycle (tentative → confirmed → deleted) owning both filters.

pub mod angle_filter;
pub mod ekf;
#[cfg(feature = "node")]
pub mod node;
pub mod pointing;
pub mod service_core;
pub mod track;

/// Two times closer than this are the same instant \[s\]: the wire's resolution (1 ns). Times
/// reach the filters as f64 seconds computed along different paths (an exposure's end minus
/// half its length, a laser fire time), which can differ in the last bit; a filter asked for a
/// time within this of its own does not move and skips nothing.
pub const SAME_INSTANT_S: f64 = 1e-9;

pub use angle_filter::{AngleEstimate, AngleFilter, AngleFilterConfig, AngleMeasurement};
pub use ekf::{CwEkf, CwEkfConfig, EkfEstimate, RangeFix};
pub use pointing::{predict_pointing, PointingCommand};
pub use track::{TrackManager, TrackManagerConfig, TrackObservation, TrackReport, TrackStatus};

/// A configuration value outside its allowed range (one type for every service core).
pub use shared_types::ConfigError;
