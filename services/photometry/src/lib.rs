//! glint-photometry: the [001] chain's pure core (docs/math.md §2.5–2.7, docs/photometry.md).
//! From a light curve (apparent magnitudes with the Sun and observer directions and the range)
//! it identifies which known geometry the satellite has, its spin axis and rate, and its size:
//!
//! - [`spin`]: the spin attitude `q(v, φ)`, the Fibonacci axes and the rotation angles (§2.5);
//! - [`database`]: the geometry–attitude–photometry database for one Sun and observer geometry;
//! - [`rate`]: the spin rate by FFT with parabolic refinement, Lomb–Scargle across gaps (§2.6);
//! - [`matching`]: the matching degree and size over the database (§2.7);
//! - [`grp`], [`ukf`]: the attitude UKF on generalised Rodrigues parameters (USQUE, §2.8–2.9);
//! - [`shapes`]: shape libraries (SHAPES.toml and its OBJ files);
//! - [`service_core`]: samples in, identification then attitude out, as a checkpointable state;
//! - `node`: the service on glint's runtime (feature `node`).

pub mod database;
pub mod grp;
pub mod matching;
#[cfg(feature = "node")]
pub mod node;
pub mod rate;
pub mod service_core;
pub mod shapes;
pub mod spin;
pub mod ukf;

pub use database::Database;
pub use matching::{identify, Identification, Match};
pub use rate::dominant_angular_frequency;
pub use ukf::{Sample, StepOutcome, Ukf, UkfFailure, UkfSettings};
