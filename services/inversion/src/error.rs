//! Errors of the three-stage solve. Every variant carries the figures needed to diagnose it.

use thiserror::Error;

/// Failure of the NNLS solver (docs/math.md §1.4).
#[derive(Debug, Clone, PartialEq, Error)]
pub enum NnlsError {
    /// The right-hand side does not have one entry per row of G.
    #[error("NNLS dimension mismatch: G has {rows} rows, rhs has {rhs_len} entries")]
    DimensionMismatch {
        /// Rows of G.
        rows: usize,
        /// Entries of the right-hand side.
        rhs_len: usize,
    },
    /// A column subset does not have one flag per column of G.
    #[error("NNLS column subset has {got} flags, G has {columns} columns")]
    SubsetLength {
        /// Columns of G.
        columns: usize,
        /// Flags given.
        got: usize,
    },
    /// G or the right-hand side contains NaN or ±∞.
    #[error("NNLS input is not finite")]
    NonFinite,
    /// The active-set loop did not terminate within its iteration budget.
    #[error("NNLS did not converge within {iterations} iterations")]
    IterationLimit {
        /// Outer iterations performed.
        iterations: usize,
    },
}

/// Failure of [`crate::solve_three_stage`] or one of its stages.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum InversionError {
    /// No band wavelengths were given.
    #[error("the observation set has no bands")]
    NoBands,
    /// An observation's per-band vector has the wrong length.
    #[error("{window} observation {index}: {field} has {len} entries, expected {bands}")]
    BandCountMismatch {
        /// "stable" or "motion".
        window: &'static str,
        /// Index of the observation inside its window.
        index: usize,
        /// Offending field name.
        field: &'static str,
        /// Its length.
        len: usize,
        /// Number of bands.
        bands: usize,
    },
    /// A geometry, range, flux or σ value is not finite or out of range.
    #[error("{window} observation {index}: invalid {field}")]
    InvalidObservation {
        /// "stable" or "motion".
        window: &'static str,
        /// Index of the observation inside its window.
        index: usize,
        /// Offending field name.
        field: &'static str,
    },
    /// Too few samples for the stage (stage 1 needs 2(M+1) = 22, stage 3 needs 3).
    #[error("{stage}: {got} samples, at least {need} required")]
    TooFewSamples {
        /// Stage name.
        stage: &'static str,
        /// Samples available.
        got: usize,
        /// Samples required.
        need: usize,
    },
    /// A configuration value is out of its documented range.
    #[error("invalid configuration: {field} ({reason})")]
    InvalidConfig {
        /// Field name.
        field: &'static str,
        /// What is wrong.
        reason: &'static str,
    },
    /// A setting's value is outside its documented range.
    #[error("{field}: {value} is out of range; allowed {allowed}")]
    SettingOutOfRange {
        /// Field name.
        field: &'static str,
        /// The value given.
        value: f64,
        /// The allowed range.
        allowed: &'static str,
    },
    /// A band has no flux at all (‖Φ‖ = 0 or mean Φ ≤ 0): nothing to fit.
    #[error("band {wavelength_nm} nm: no flux in the {window} window")]
    NoFlux {
        /// Band centre.
        wavelength_nm: f64,
        /// "stable" or "motion".
        window: &'static str,
    },
    /// A frame index precedes the motion epoch.
    #[error("motion observation {index}: frame {frame_index} precedes the epoch {epoch_frame}")]
    FrameBeforeEpoch {
        /// Index of the observation inside the motion window.
        index: usize,
        /// Its frame index.
        frame_index: u64,
        /// The epoch (t = 0) frame.
        epoch_frame: u64,
    },
    /// Stage 1 NNLS failed.
    #[error("stage 1, band {wavelength_nm} nm: {source}")]
    Nnls {
        /// Band centre.
        wavelength_nm: f64,
        /// Solver error.
        #[source]
        source: NnlsError,
    },
    /// Stage 2 found no band with a finite separation degree.
    #[error("stage 2: no band has a finite separation degree")]
    NoSeparableBand,
    /// The Levenberg–Marquardt iteration produced a non-finite cost or parameter.
    #[error("LM diverged after {iterations} iterations (cost {cost})")]
    Diverged {
        /// Iterations performed.
        iterations: usize,
        /// Last cost.
        cost: f64,
    },
    /// A σ-dependent quantity was requested but the observations carry no σ.
    #[error("σ is required for {what}")]
    MissingSigma {
        /// What needed σ.
        what: &'static str,
    },
    /// A dense factorisation failed (non-finite input).
    #[error("dense linear algebra failed in {what}")]
    LinearAlgebra {
        /// Which solve.
        what: &'static str,
    },
}
