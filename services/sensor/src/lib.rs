//! The synthetic sensor: renders camera frames of debris ([002]) into loaned shared memory,
//! produces time series of the satellite's spectrum ([000]), answers laser-range requests, and
//! publishes truth for scoring; renders fisheye infrared Earth frames ([003], `earth_render`),
//! the stereo rig's epochs ([004]) and a ground telescope's light curve ([001]).
//!
//! Pure cores (`render`, `laser`, `debris_scene`, `spectra_scene`, `earth_render`,
//! `earth_scene`; `streams`: each stream the sensor produces, behind one trait) beside one node
//! loop (`node`).

pub mod debris_scene;
pub mod earth_hazards;
pub mod earth_render;
pub mod earth_scene;
pub mod laser;
#[cfg(feature = "node")]
pub mod node;
pub mod photometry_scene;
pub mod recorded;
pub mod recording;
pub mod render;
pub mod service_core;
pub mod spectra_scene;
pub mod stereo_scene;
pub mod streams;
