//! Synthetic camera frames for seed 002 (docs/math.md §3.2, scenario §3.9): u16 gray levels
//! written in place into a caller-owned slice (an iceoryx2 loan in the sensor node).
//!
//! Model, per frame (`width_px × height_px`, row-major, pixel (x = column, y = row) centred at
//! the integer point (x, y), 0-based):
//! 1. **Background.** Every pixel gets `clamp(round(b + σ_b z), 0, sat)` with z ~ N(0, 1) and
//!    `σ_b² = b/g + σ_read²`: the background's Poisson shot noise (b DN = b·g electrons) folded
//!    with the read noise into one Gaussian. All 2^16 possible outputs are precomputed from the
//!    midpoint normal quantiles (`noise.rs`), so the pass is one table lookup per pixel, four
//!    pixels per 64-bit draw, and every pixel is written exactly once.
//! 2. **Streaks** (`streak.rs`). A [`Streak`] is the image-plane path of one object over the
//!    exposure with its integrated signal; a point (x0 = x1, y0 = y1) is a star or false target.
//!    Sub-steps along the path deposit signal through a Gaussian PSF (`psf.rs`), shot noise is
//!    added, and the sum is saturating-added into the frame, touching only pixels near the streak.
//!
//! Randomness: the stream `(seed, frame_index)` of xoshiro256++, split into two interleaved
//! lanes for the background (lane k = the stream jumped k·2^128 draws); lane 0 then goes on to the
//! streaks. Same inputs ⇒ byte-identical frame, whatever `out` held before.
//! [`FrameRenderer::render_reference`] is a slow per-pixel Box–Muller rendering of the same model,
//! for tests and as the benchmark baseline.

pub mod noise;
pub mod psf;
mod reference;
pub mod streak;

use noise::{boxed_table, Bits16, NormalTable, Xoshiro256pp, TABLE_LEN};
use std::fmt;

/// Path of one object's image over the exposure, in 0-based continuous pixel coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Streak {
    /// Column at the start of the exposure, px.
    pub x0_px: f64,
    /// Row at the start of the exposure, px.
    pub y0_px: f64,
    /// Column at the end of the exposure, px.
    pub x1_px: f64,
    /// Row at the end of the exposure, px.
    pub y1_px: f64,
    /// Signal integrated over the exposure, DN (≥ 0).
    pub total_signal_dn: f64,
}

impl Streak {
    /// A stationary source (star, false target) at (x_px, y_px).
    pub fn point(x_px: f64, y_px: f64, total_signal_dn: f64) -> Self {
        Self {
            x0_px: x_px,
            y0_px: y_px,
            x1_px: x_px,
            y1_px: y_px,
            total_signal_dn,
        }
    }

    /// Length of the path, px.
    pub fn length_px(&self) -> f64 {
        (self.x1_px - self.x0_px).hypot(self.y1_px - self.y0_px)
    }
}

/// Camera and rendering parameters. Fixed for a run; validated by [`FrameRenderer::new`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderConfig {
    /// Columns, 1..=16384 (§3.9: 1024).
    pub width_px: usize,
    /// Rows, 1..=16384 (§3.9: 1024).
    pub height_px: usize,
    /// Mean background level, DN, 0..=saturation_dn.
    pub background_dn: f64,
    /// Read noise standard deviation, DN, 0..=65535.
    pub read_noise_dn: f64,
    /// Conversion gain, electrons per DN, 1e-3..=1e6; shot-noise variance in DN² is signal/gain.
    pub gain_e_per_dn: f64,
    /// Full-scale gray level; every output is clipped to 0..=saturation_dn (≥ 1).
    pub saturation_dn: u16,
    /// Standard deviation of the Gaussian PSF, px, 0..=8 (0: bilinear splat only).
    pub psf_sigma_px: f64,
    /// Sub-steps per px of streak length, 1..=1000 (§3.2: K ≥ 10·length).
    pub substeps_per_px: f64,
}

impl Default for RenderConfig {
    /// The seed-002 camera (§3.9: 1024² px, 8-bit output per §3.2) with \[ASSUMP\] noise levels:
    /// background 20 DN, read noise 2 DN, gain 1 e⁻/DN, PSF σ 0.7 px, 10 sub-steps per px.
    fn default() -> Self {
        Self {
            width_px: 1024,
            height_px: 1024,
            background_dn: 20.0,
            read_noise_dn: 2.0,
            gain_e_per_dn: 1.0,
            saturation_dn: 255,
            psf_sigma_px: 0.7,
            substeps_per_px: 10.0,
        }
    }
}

/// Why a [`RenderConfig`] was rejected.
#[derive(Clone, Debug, PartialEq)]
pub enum RenderConfigError {
    /// A real-valued field is NaN or infinite.
    NotFinite { field: &'static str, value: f64 },
    /// A field lies outside its allowed closed range.
    OutOfRange {
        field: &'static str,
        value: f64,
        min: f64,
        max: f64,
    },
}

impl fmt::Display for RenderConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NotFinite { field, value } => {
                write!(f, "render config: {field} = {value} is not finite")
            }
            Self::OutOfRange {
                field,
                value,
                min,
                max,
            } => {
                write!(
                    f,
                    "render config: {field} = {value} is outside [{min}, {max}]"
                )
            }
        }
    }
}

impl std::error::Error for RenderConfigError {}

/// Why a frame could not be rendered (nothing was written).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum RenderError {
    /// `out` does not hold exactly width_px·height_px pixels.
    OutputLength {
        expected_px: usize,
        actual_px: usize,
    },
}

impl fmt::Display for RenderError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::OutputLength {
                expected_px,
                actual_px,
            } => {
                write!(
                    f,
                    "render: output holds {actual_px} px, the frame has {expected_px} px"
                )
            }
        }
    }
}

impl std::error::Error for RenderError {}

/// What happened to the streaks of one frame (counters for the node's heartbeat).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RenderReport {
    /// Streaks that reached the frame and were drawn (possibly clipped).
    pub streaks_rendered: u32,
    /// Streaks entirely outside the frame (beyond the PSF reach), or with zero signal.
    pub streaks_outside: u32,
    /// Streaks skipped for non-finite numbers or negative signal.
    pub streaks_invalid: u32,
    /// Streak pixel additions clipped at saturation_dn.
    pub saturated_px: u64,
}

/// Background lanes interleaved in the fast pass.
const LANES: usize = 2;

/// Precomputed tables for one [`RenderConfig`]; renders any number of frames.
pub struct FrameRenderer {
    config: RenderConfig,
    normal: NormalTable,
    background: Box<[u16; TABLE_LEN]>,
    kernel: Vec<f32>,
}

impl FrameRenderer {
    /// Validate `config` and precompute the normal, background and PSF tables (a few ms).
    pub fn new(config: RenderConfig) -> Result<Self, RenderConfigError> {
        validate(&config)?;
        let normal = NormalTable::new();
        let sigma_dn = background_sigma_dn(&config);
        let sat = f64::from(config.saturation_dn);
        let background = boxed_table(|i| {
            let v = (config.background_dn + sigma_dn * f64::from(normal.get(i as u16))).round();
            v.clamp(0.0, sat) as u16
        });
        let kernel = psf::gaussian_kernel_1d(config.psf_sigma_px);
        Ok(Self {
            config,
            normal,
            background,
            kernel,
        })
    }

    /// The validated configuration.
    pub fn config(&self) -> &RenderConfig {
        &self.config
    }

    /// Render frame `frame_index` of run `seed` into `out` (row-major, width·height px): every
    /// pixel is written once by the background pass (prior contents are never read), then the
    /// streaks are added near their paths. Invalid or off-frame streaks are skipped and counted.
    pub fn render(
        &self,
        streaks: &[Streak],
        seed: u64,
        frame_index: u64,
        out: &mut [u16],
    ) -> Result<RenderReport, RenderError> {
        check_len(&self.config, out)?;
        let mut lanes = frame_lanes(seed, frame_index);
        fill_background(&self.background, &mut lanes, out);
        let [mut rng, ..] = lanes;
        let mut report = RenderReport::default();
        if !streaks.is_empty() {
            let pass = streak::StreakPass {
                width_px: self.config.width_px,
                height_px: self.config.height_px,
                saturation_dn: self.config.saturation_dn,
                inv_gain_dn_per_e: (1.0 / self.config.gain_e_per_dn) as f32,
                substeps_per_px: self.config.substeps_per_px,
                kernel: &self.kernel,
                normal: &self.normal,
            };
            let mut scratch = streak::TileScratch::default();
            pass.add_all(
                streaks,
                &mut Bits16::new(&mut rng),
                &mut scratch,
                out,
                &mut report,
            );
        }
        Ok(report)
    }
}

/// Standard deviation of a background pixel before quantisation, DN.
pub fn background_sigma_dn(config: &RenderConfig) -> f64 {
    (config.background_dn / config.gain_e_per_dn + config.read_noise_dn.powi(2)).sqrt()
}

fn check_len(config: &RenderConfig, out: &[u16]) -> Result<(), RenderError> {
    let expected_px = config.width_px * config.height_px;
    if out.len() != expected_px {
        return Err(RenderError::OutputLength {
            expected_px,
            actual_px: out.len(),
        });
    }
    Ok(())
}

fn validate(c: &RenderConfig) -> Result<(), RenderConfigError> {
    const MAX_SIDE_PX: f64 = 16_384.0;
    let sat = f64::from(c.saturation_dn);
    let fields = [
        ("width_px", c.width_px as f64, 1.0, MAX_SIDE_PX),
        ("height_px", c.height_px as f64, 1.0, MAX_SIDE_PX),
        ("saturation_dn", sat, 1.0, 65_535.0),
        ("background_dn", c.background_dn, 0.0, sat),
        ("read_noise_dn", c.read_noise_dn, 0.0, 65_535.0),
        ("gain_e_per_dn", c.gain_e_per_dn, 1e-3, 1e6),
        ("psf_sigma_px", c.psf_sigma_px, 0.0, 8.0),
        ("substeps_per_px", c.substeps_per_px, 1.0, 1000.0),
    ];
    for (field, value, min, max) in fields {
        if !value.is_finite() {
            return Err(RenderConfigError::NotFinite { field, value });
        }
        if !(min..=max).contains(&value) {
            return Err(RenderConfigError::OutOfRange {
                field,
                value,
                min,
                max,
            });
        }
    }
    Ok(())
}

/// The background lanes of one frame: the frame's stream and its 2^128-draw jumps.
fn frame_lanes(seed: u64, frame_index: u64) -> [Xoshiro256pp; LANES] {
    let mut next = Xoshiro256pp::new(seed, frame_index);
    std::array::from_fn(|_| {
        let lane = next.clone();
        next.jump();
        lane
    })
}

/// Write every pixel of `out` once from the background table: blocks of 8 pixels, lane k
/// filling pixels 4k..4k+3 of each block from one draw (low 16 bits first); the tail of fewer
/// than 8 pixels comes from lane 0.
fn fill_background(table: &[u16; TABLE_LEN], lanes: &mut [Xoshiro256pp; LANES], out: &mut [u16]) {
    #[inline(always)]
    fn quad(table: &[u16; TABLE_LEN], r: u64, dst: &mut [u16]) {
        for (k, px) in dst.iter_mut().enumerate() {
            *px = table[usize::from((r >> (16 * k)) as u16)];
        }
    }
    let mut blocks = out.chunks_exact_mut(4 * LANES);
    for block in &mut blocks {
        let r: [u64; LANES] = std::array::from_fn(|k| lanes[k].next_u64());
        for (dst, r) in block.chunks_exact_mut(4).zip(r) {
            quad(table, r, dst);
        }
    }
    for dst in blocks.into_remainder().chunks_mut(4) {
        let r = lanes[0].next_u64();
        quad(table, r, dst);
    }
}

#[cfg(test)]
mod tests;
