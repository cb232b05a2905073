//! The [003] static panoramic infrared Earth sensor (docs/math.md §4): the attitude angle β
//! between the optical axis and nadir from the Earth-limb ring of a fisheye image.
//!
//! - [`edges`]: Sobel, the strong-edge threshold, masks and erosion (§4.2).
//! - [`estimate`]: one angle from the samples: the t fit with the interval mean, and the
//!   lookup (engineering) version (§4.6).
//! - [`hough`]: the baseline, a Hough circle and the Kåsa fit (§4.7).
//! - [`pipeline`]: one frame through every method, timed.
//! - [`ring`]: the fisheye camera, undistortion to the unit sphere and the interval cross
//!   product (§4.3–4.4).
//! - [`tfit`]: the t location-scale maximum-likelihood fit of the β_k samples (§4.5).
//! - [`validity`]: whether a method's answer holds for the frame, and why not.
//! - [`special`]: digamma and trigamma, which the fit needs.
//! - [`synthetic`]: reference frames in closed form, for tests and benchmarks.
//! - [`samples`]: the sample files `glint tool tfit` reads.
//! - [`service_core`]: one frame's wire answer from the scenario's settings; [`node`]: the
//!   service on glint's runtime (feature `node`).

pub mod edges;
pub mod estimate;
pub mod hough;
#[cfg(feature = "node")]
pub mod node;
pub mod pipeline;
pub mod ring;
pub mod samples;
pub mod service_core;
pub mod special;
pub mod synthetic;
pub mod tfit;
pub mod validity;
