//! glint-photometry: the [001] chain's pure core (docs/math.md §2.5–2.7, docs/photometry.md).
//! From a light curve (apparent magnitudes with the Sun and observer directions and the range)
//! it identifies which known geometry the satellite has, its spin axis and rate, and its size:
//!
//! - [`spin`]: the spin attitude `q(v, φ)`, the Fibonacci axes and the rotation angles (§2.5);
//! - [`database`]: the geometry–attitude–photometry database for one Sun and observer geometry;
//! - [`rate`]: the spin rate by FFT with parabolic refinement, Lomb–Scargle across gaps (§2.6);
//! - [`matching`]: the matching degree and size over the database (§2.7).

pub mod database;
pub mod matching;
pub mod rate;
pub mod spin;

pub use database::Database;
pub use matching::{identify, Identification, Match};
pub use rate::dominant_angular_frequency;
