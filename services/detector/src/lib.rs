//! glint-detector: the pure core of the seed-002 debris detector (docs/math.md §3.2–3.5).
//!
//! No IPC, no clock, no I/O except the PGM reader. Pixel convention everywhere: 0-based
//! continuous coordinates, x = column, y = row (down), the first pixel's centre at (0, 0);
//! angles θ from +x toward +y.
//!
//! Per frame: [`background`] (median, 1.4826·MAD) → threshold `b + kσ` → [`segment`]
//! (8-connected components with exact moments, one pass) → [`moments`] (eq 7 ellipses) →
//! `Vec<Blob>`. Inter-frame [`matching`] (§3.4, eqs 8–9) and [`angles`] (eq 10) are separate
//! steps, so a node can publish blobs before matching. [`pgm`] reads and writes 16-bit PGM files
//! for the offline tool.

pub mod angles;
pub mod background;
pub mod matching;
pub mod moments;
#[cfg(feature = "node")]
pub mod node;
pub mod pgm;
pub mod segment;
pub mod service_core;

pub use background::{BackgroundEstimator, BackgroundStats};
pub use matching::{MatchResult, MatchedDetection, Matcher, MatcherConfig};
pub use moments::{Blob, Ellipse, FeatureSet};
pub use segment::{Component, SegmentParams, Segmenter};

/// A frame's size does not fit its pixel buffer.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum FrameError {
    #[error("frame of {width}×{height} px needs {expected} pixels, got {len}")]
    SizeMismatch {
        width: usize,
        height: usize,
        expected: usize,
        len: usize,
    },
    #[error("frame of {width}×{height} px is empty")]
    Empty { width: usize, height: usize },
    #[error("frame of {width}×{height} px exceeds the {max} px side limit")]
    TooLarge {
        width: usize,
        height: usize,
        max: usize,
    },
}

/// Checks `frame.len() == width·height`, both sides in `1..=MAX_SIDE_PX`.
pub fn check_frame(frame: &[u16], width: usize, height: usize) -> Result<(), FrameError> {
    if width == 0 || height == 0 {
        return Err(FrameError::Empty { width, height });
    }
    if width > segment::MAX_SIDE_PX || height > segment::MAX_SIDE_PX {
        return Err(FrameError::TooLarge {
            width,
            height,
            max: segment::MAX_SIDE_PX,
        });
    }
    let expected = width * height;
    if frame.len() != expected {
        return Err(FrameError::SizeMismatch {
            width,
            height,
            expected,
            len: frame.len(),
        });
    }
    Ok(())
}

/// A configuration value outside its allowed range (one type for every service core).
pub use shared_types::ConfigError;

/// Foreground rule.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "mode", rename_all = "snake_case", deny_unknown_fields)]
pub enum Threshold {
    /// Foreground when `v > background + k·σ` (σ = 1.4826·MAD); k in \[0, 1000\].
    Sigma { k: f64 },
    /// Foreground when `v > threshold_dn`.
    AbsoluteDn { threshold_dn: u16 },
}

impl Default for Threshold {
    fn default() -> Self {
        Self::Sigma { k: 5.0 }
    }
}

/// Detector settings.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DetectorConfig {
    /// Foreground rule. Default: `Sigma { k: 5 }` (≈ 3e-7 false pixels per pixel for Gaussian
    /// noise).
    pub threshold: Threshold,
    /// Smallest component kept \[px\], ≥ 1. Default 3.
    pub min_area_px: u32,
    /// Background subsample step \[px\] in both directions, 1..=64 (1 = every pixel). Default 4.
    pub background_step_px: usize,
    /// Pixels at or above this value count as saturated \[DN\], ≥ 1. Default 65535.
    pub saturation_dn: u16,
}

impl Default for DetectorConfig {
    fn default() -> Self {
        Self {
            threshold: Threshold::default(),
            min_area_px: 3,
            background_step_px: 4,
            saturation_dn: u16::MAX,
        }
    }
}

impl DetectorConfig {
    /// Checks every field against its documented range.
    pub fn validate(&self) -> Result<(), ConfigError> {
        if let Threshold::Sigma { k } = self.threshold {
            if !(0.0..=1000.0).contains(&k) {
                return Err(ConfigError::new("threshold.k", k, "0 ≤ k ≤ 1000"));
            }
        }
        if self.min_area_px == 0 {
            return Err(ConfigError::new("min_area_px", 0, "≥ 1"));
        }
        if !(1..=64).contains(&self.background_step_px) {
            let step = self.background_step_px;
            return Err(ConfigError::new("background_step_px", step, "1..=64"));
        }
        if self.saturation_dn == 0 {
            return Err(ConfigError::new("saturation_dn", 0, "≥ 1"));
        }
        Ok(())
    }

    /// The integer threshold t (foreground: v > t) for the given background statistics.
    pub fn threshold_dn(&self, stats: &BackgroundStats) -> u16 {
        match self.threshold {
            Threshold::Sigma { k } => {
                let t = (stats.background_dn + k * stats.sigma_dn).floor();
                t.clamp(0.0, f64::from(u16::MAX)) as u16
            }
            Threshold::AbsoluteDn { threshold_dn } => threshold_dn,
        }
    }
}

/// Detection failure.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DetectError {
    #[error(transparent)]
    Frame(#[from] FrameError),
    #[error("invalid detector configuration: {0}")]
    Config(#[from] ConfigError),
}

/// The result of one frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameDetections<'a> {
    pub background: BackgroundStats,
    /// Foreground was `v > threshold_dn`.
    pub threshold_dn: u16,
    pub blobs: &'a [Blob],
}

/// Background → threshold → components → ellipses, with all scratch reused across frames.
#[derive(Debug)]
pub struct Detector {
    config: DetectorConfig,
    background: BackgroundEstimator,
    segmenter: Segmenter,
    blobs: Vec<Blob>,
}

impl Detector {
    /// A detector for validated settings.
    pub fn new(config: DetectorConfig) -> Result<Self, ConfigError> {
        config.validate()?;
        Ok(Self {
            config,
            background: BackgroundEstimator::new(),
            segmenter: Segmenter::new(),
            blobs: Vec::new(),
        })
    }

    pub fn config(&self) -> &DetectorConfig {
        &self.config
    }

    /// Detects the blobs of one row-major `width × height` frame.
    pub fn detect(
        &mut self,
        frame: &[u16],
        width: usize,
        height: usize,
    ) -> Result<FrameDetections<'_>, FrameError> {
        let background =
            self.background
                .estimate(frame, width, height, self.config.background_step_px)?;
        let threshold_dn = self.config.threshold_dn(&background);
        let params = SegmentParams {
            threshold_dn,
            background_dn: background.background_dn,
            min_area_px: self.config.min_area_px,
            saturation_dn: self.config.saturation_dn,
        };
        let components = self.segmenter.segment(frame, width, height, &params)?;
        self.blobs.clear();
        self.blobs
            .extend(components.iter().filter_map(Blob::from_component));
        Ok(FrameDetections {
            background,
            threshold_dn,
            blobs: &self.blobs,
        })
    }
}

/// One-shot convenience: validates `config`, detects, returns the blobs (allocates scratch; use
/// [`Detector`] for a stream of frames).
pub fn detect(
    frame: &[u16],
    width: usize,
    height: usize,
    config: &DetectorConfig,
) -> Result<Vec<Blob>, DetectError> {
    let mut detector = Detector::new(*config)?;
    Ok(detector.detect(frame, width, height)?.blobs.to_vec())
}

#[cfg(test)]
pub(crate) mod synth;

#[cfg(test)]
mod tests;
