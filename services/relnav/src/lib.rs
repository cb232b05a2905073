//! glint-relnav: seed 004 (docs/math.md §5), stereo relative navigation of a non-cooperative,
//! tumbling target. One error-state EKF estimates the target's attitude relative to the
//! camera, its inertial angular velocity, its inertia ratios (the tanh parametrisation, so
//! every estimate is a physical body), and its centre of mass's position and velocity in the
//! chaser's orbit frame (CW dynamics), from the normalised image coordinates of known feature
//! points in a rectified stereo pair.
//!
//! - [`model`]: rig, nominal state, propagation (RK4, CW STM), Φ and Q, the measurement and H
//! - [`filter`]: gating, the Joseph update, the multiplicative reset
//! - [`start`]: the start from the measurements alone (triangulation, absolute orientation)
//! - [`service_core`]: epochs in, estimates out; divergence and numerical failure as events
//! - [`score`]: RTMSE per group over the last minutes, NEES
//! - [`scenario`]: the rig, settings and start of a `[stereo]` section
//! - `node`: the service on glint's runtime (feature `node`)

pub mod filter;
pub mod model;
#[cfg(feature = "node")]
pub mod node;
pub mod scenario;
pub mod score;
pub mod service_core;
pub mod start;

pub use filter::{FeatureObs, Filter, UpdateOutcome};
pub use model::{Nominal, Rig};
pub use service_core::{Counters, Estimate, RelNav, Settings, Start};
