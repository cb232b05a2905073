//! The synthetic sensor: renders camera frames of debris ([002]) into loaned shared memory,
//! produces time series of the satellite's spectrum ([000]), answers laser-range requests, and
//! publishes truth for scoring.
//!
//! Pure cores (`render`, `laser`, `debris_scene`, `spectra_scene`) beside one node loop (`node`).

pub mod debris_scene;
pub mod laser;
#[cfg(feature = "node")]
pub mod node;
pub mod render;
pub mod service_core;
pub mod spectra_scene;
