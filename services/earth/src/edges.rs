//! Limb edge extraction (docs/math.md §4.2, eqs 2–5): Sobel magnitude, a strong-edge
//! threshold (Otsu's, unless given), the blind-zone and image-circle masks (the circle's own
//! edge excluded), one 3×3 erosion
//! (skipped if it would leave nothing), and the surviving pixels as edge points.

use crate::ring::Fisheye;

/// Settings of the edge extraction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EdgeConfig {
    /// Strong-edge threshold on the Sobel magnitude [DN]; None: Otsu's threshold over the
    /// unmasked pixels.
    pub threshold_dn: Option<f32>,
    /// Pixels closer than this to the optical axis are the central blind zone [deg] (math.md:
    /// the 60° zone, θ < 30°).
    pub blind_zone_half_deg: f64,
    /// Pixels farther than this from the principal point are outside the lens image circle
    /// [px]; None: no circle (the whole frame is imaged).
    pub image_circle_px: Option<f64>,
    /// Pixels within this of the image circle are never limb points [px]: the bright-to-black
    /// step where the Earth reaches the lens's field boundary is an edge too (a few PSF widths
    /// and the Sobel kernel's reach).
    pub field_margin_px: f64,
}

impl EdgeConfig {
    /// The largest radius from the principal point an edge point may have [px].
    pub fn r_max_px(&self) -> f64 {
        self.image_circle_px
            .map_or(f64::INFINITY, |r| r - self.field_margin_px)
    }
}

impl Default for EdgeConfig {
    fn default() -> Self {
        Self {
            threshold_dn: None,
            blind_zone_half_deg: 30.0,
            image_circle_px: None,
            field_margin_px: 3.0,
        }
    }
}

/// The edge points of one frame.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Edges {
    /// Pixel centres (x = column, y = row) of the edge pixels, row-major order.
    pub points_px: Vec<(f64, f64)>,
    /// The threshold used [DN of Sobel magnitude].
    pub threshold_dn: f32,
    /// Whether the erosion was kept (false: it left nothing, the un-eroded map is used).
    pub eroded: bool,
}

/// Why a frame cannot be processed.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum EdgeError {
    #[error("the frame has {actual} pixels, {width}×{height} needs {expected}")]
    Size {
        width: usize,
        height: usize,
        expected: usize,
        actual: usize,
    },
    #[error("the frame is {width}×{height}: at least 3×3 pixels are needed")]
    TooSmall { width: usize, height: usize },
}

/// Reusable buffers of the extraction (one per service: no allocation per frame). The masks
/// depend on the frame size, the camera and the settings only: the pixels they leave are
/// listed once and reused while those stay the same.
#[derive(Default)]
pub struct EdgeExtractor {
    /// (width, height, camera, config) the `spans` were built for.
    key: Option<(usize, usize, [u64; 10])>,
    /// The unmasked interior pixels as runs of one row: (first index, length), row-major.
    spans: Vec<(u32, u32)>,
    magnitude: Vec<f32>,
    /// Per pixel: 1 where strong (reset after every frame, only where set).
    strong_map: Vec<u8>,
    strong: Vec<u32>,
}

/// The Sobel magnitude (eq 3) of pixel (x, y), 0 < x < w − 1, 0 < y < h − 1: the same run
/// kernel, on one pixel.
#[cfg(test)]
fn sobel(px: &[u16], w: usize, x: usize, y: usize) -> f32 {
    let mut out = vec![];
    sobel_run(px, w, y * w + x, 1, &mut out);
    out[0]
}

/// The Sobel magnitudes of the `len` interior pixels from index `start` of one row, appended
/// to `out`, and their maximum: the three rows are cut into eight slices of exactly `len` (the
/// kernel's taps), so the loop has no bounds checks and vectorises.
fn sobel_run(px: &[u16], w: usize, start: usize, len: usize, out: &mut Vec<f32>) -> f32 {
    let tap = |row: usize, dx: usize| &px[row + dx - 1..row + dx - 1 + len];
    let (up, mid, down) = (start - w, start, start + w);
    let (u0, u1, u2) = (tap(up, 0), tap(up, 1), tap(up, 2));
    let (m0, m2) = (tap(mid, 0), tap(mid, 2));
    let (d0, d1, d2) = (tap(down, 0), tap(down, 1), tap(down, 2));
    let base = out.len();
    out.resize(base + len, 0.0);
    let dst = &mut out[base..base + len];
    for j in 0..len {
        let z = |row: &[u16]| i32::from(row[j]);
        let gy = (z(d0) + 2 * z(d1) + z(d2)) - (z(u0) + 2 * z(u1) + z(u2));
        let gx = (z(u2) + 2 * z(m2) + z(d2)) - (z(u0) + 2 * z(m0) + z(d0));
        // In f32: a 16-bit edge's gradient squared overflows i32.
        let (gx, gy) = (gx as f32, gy as f32);
        dst[j] = (gx * gx + gy * gy).sqrt();
    }
    lane_max(dst)
}

/// The maximum of non-negative values (0 for none), eight lanes at a time.
fn lane_max(values: &[f32]) -> f32 {
    let mut lanes = [0.0f32; 8];
    let mut chunks = values.chunks_exact(8);
    for c in &mut chunks {
        for (l, &v) in lanes.iter_mut().zip(c) {
            *l = if v > *l { v } else { *l };
        }
    }
    let tail = chunks.remainder().iter().fold(0.0f32, |a, &v| a.max(v));
    lanes.iter().fold(tail, |a, &v| a.max(v))
}

/// Whether any of `values` reaches `threshold`, as one vectorised reduction.
fn any_at_least(values: &[f32], threshold: f32) -> bool {
    values.iter().fold(false, |a, &v| a | (v >= threshold))
}

/// Above this many magnitudes, Otsu's histogram takes every [`OTSU_STRIDE`]-th one: a
/// systematic sample of tens of thousands of pixels fixes the threshold as well as all of
/// them, at a quarter of the cost.
const OTSU_SAMPLE_ABOVE: usize = 16_384;
const OTSU_STRIDE: usize = 4;

/// Otsu's threshold over non-negative `values` (256 bins from 0 to the maximum): the bin edge
/// that maximises the between-class variance. Large inputs are sampled (every
/// [`OTSU_STRIDE`]-th value).
pub fn otsu(values: &[f32]) -> f32 {
    otsu_below(values, lane_max(values))
}

/// [`otsu`] with the values' maximum already known.
fn otsu_below(values: &[f32], max: f32) -> f32 {
    let stride = if values.len() > OTSU_SAMPLE_ABOVE {
        OTSU_STRIDE
    } else {
        1
    };
    let sample = || values.iter().step_by(stride).copied();
    if max <= 0.0 {
        return 0.0;
    }
    const BINS: usize = 256;
    let scale = (BINS as f32 - 1e-3) / max;
    // Four interleaved histograms: runs of equal bins (the flat sky and Earth) would otherwise
    // chain every increment through one memory cell.
    let mut parts = [[0u32; BINS]; 4];
    for (k, v) in sample().enumerate() {
        parts[k & 3][((v * scale) as usize).min(BINS - 1)] += 1;
    }
    let hist: [u64; BINS] = std::array::from_fn(|b| parts.iter().map(|p| u64::from(p[b])).sum());
    let total: u64 = hist.iter().sum();
    let sum_all: f64 = hist
        .iter()
        .enumerate()
        .map(|(i, &c)| i as f64 * c as f64)
        .sum();
    let (mut w0, mut sum0, mut best, mut best_k) = (0u64, 0.0f64, -1.0f64, 0usize);
    for (k, &c) in hist.iter().enumerate().take(BINS - 1) {
        w0 += c;
        sum0 += k as f64 * c as f64;
        let w1 = total - w0;
        if w0 == 0 || w1 == 0 {
            continue;
        }
        let (m0, m1) = (sum0 / w0 as f64, (sum_all - sum0) / w1 as f64);
        let between = w0 as f64 * w1 as f64 * (m0 - m1).powi(2);
        if between > best {
            best = between;
            best_k = k;
        }
    }
    // Class 0 is bins 0..=best_k: the threshold is the upper edge of bin best_k.
    (best_k + 1) as f32 / scale
}

impl EdgeExtractor {
    fn build_masks(&mut self, w: usize, h: usize, cam: &Fisheye, cfg: &EdgeConfig) {
        let [k1, k2, k3, k4] = cam.k;
        let key = (
            w,
            h,
            [
                cam.f_px,
                cam.x0_px,
                cam.y0_px,
                k1,
                k2,
                k3,
                k4,
                cfg.blind_zone_half_deg,
                cfg.image_circle_px.unwrap_or(f64::INFINITY),
                cfg.field_margin_px,
            ]
            .map(f64::to_bits),
        );
        if self.key == Some(key) {
            return;
        }
        let r_blind = cam.radius_px(cfg.blind_zone_half_deg.to_radians());
        let r_circle = cfg.r_max_px();
        self.spans.clear();
        for y in 1..h - 1 {
            let dy = y as f64 - cam.y0_px;
            let mut run: Option<(usize, usize)> = None;
            for x in 1..w - 1 {
                let r = (x as f64 - cam.x0_px).hypot(dy);
                let i = y * w + x;
                if r >= r_blind && r <= r_circle {
                    run = Some(run.map_or((i, 1), |(s, n)| (s, n + 1)));
                } else if let Some((s, n)) = run.take() {
                    self.spans.push((s as u32, n as u32));
                }
            }
            if let Some((s, n)) = run {
                self.spans.push((s as u32, n as u32));
            }
        }
        self.strong_map.clear();
        self.strong_map.resize(w * h, 0);
        self.key = Some(key);
    }

    /// The edge points of a `width`×`height` u16 frame seen through `cam`.
    pub fn extract(
        &mut self,
        px: &[u16],
        width: usize,
        height: usize,
        cam: &Fisheye,
        cfg: &EdgeConfig,
    ) -> Result<Edges, EdgeError> {
        let n = width * height;
        if px.len() != n {
            return Err(EdgeError::Size {
                width,
                height,
                expected: n,
                actual: px.len(),
            });
        }
        if width < 3 || height < 3 {
            return Err(EdgeError::TooSmall { width, height });
        }
        let w = width;
        self.build_masks(width, height, cam, cfg);
        self.magnitude.clear();
        let mut max = 0.0f32;
        for &(start, len) in &self.spans {
            let (start, len) = (start as usize, len as usize);
            max = max.max(sobel_run(px, w, start, len, &mut self.magnitude));
        }
        let threshold_dn = cfg
            .threshold_dn
            .unwrap_or_else(|| otsu_below(&self.magnitude, max));
        // Strong pixels are few: blocks of 16 with none are skipped by one reduction each.
        let cut = threshold_dn.max(f32::MIN_POSITIVE);
        self.strong.clear();
        let mut k = 0;
        for &(start, len) in &self.spans {
            let run = &self.magnitude[k..k + len as usize];
            for (b, block) in run.chunks(16).enumerate() {
                if !any_at_least(block, cut) {
                    continue;
                }
                for (j, &g) in block.iter().enumerate() {
                    if g >= cut {
                        let i = start + (b * 16 + j) as u32;
                        self.strong.push(i);
                        self.strong_map[i as usize] = 1;
                    }
                }
            }
            k += len as usize;
        }
        // Eq 5 with B the 3×3 square: kept where the whole neighbourhood is strong (a strong
        // pixel is never on the frame's border, so its neighbours exist).
        let map = &self.strong_map;
        let kept = |i: usize| {
            [i - w, i, i + w]
                .iter()
                .all(|&c| map[c - 1] & map[c] & map[c + 1] == 1)
        };
        let eroded: Vec<(f64, f64)> = (self.strong.iter())
            .filter(|&&i| kept(i as usize))
            .map(|&i| ((i as usize % w) as f64, (i as usize / w) as f64))
            .collect();
        let any_eroded = !eroded.is_empty();
        let points_px = if any_eroded {
            eroded
        } else {
            (self.strong.iter())
                .map(|&i| ((i as usize % w) as f64, (i as usize / w) as f64))
                .collect()
        };
        for &i in &self.strong {
            self.strong_map[i as usize] = 0;
        }
        Ok(Edges {
            points_px,
            threshold_dn,
            eroded: any_eroded,
        })
    }
}

#[cfg(test)]
#[path = "edges_tests.rs"]
mod tests;
