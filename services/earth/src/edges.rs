//! Limb edge extraction (docs/math.md §4.2, eqs 2–5): Sobel magnitude, a strong-edge
//! threshold (Otsu's, unless given), the blind-zone and image-circle masks, one 3×3 erosion
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
}

impl Default for EdgeConfig {
    fn default() -> Self {
        Self {
            threshold_dn: None,
            blind_zone_half_deg: 30.0,
            image_circle_px: None,
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

/// Reusable buffers of the extraction (one per service: no allocation per frame).
#[derive(Default)]
pub struct EdgeExtractor {
    magnitude: Vec<f32>,
    valid: Vec<bool>,
    strong: Vec<bool>,
    eroded: Vec<bool>,
}

/// The Sobel magnitude (eq 3) of pixel (x, y), 0 < x < w − 1, 0 < y < h − 1.
#[inline]
fn sobel(px: &[u16], w: usize, x: usize, y: usize) -> f32 {
    let z = |dx: usize, dy: usize| f32::from(px[(y + dy - 1) * w + x + dx - 1]);
    let gy = (z(0, 2) + 2.0 * z(1, 2) + z(2, 2)) - (z(0, 0) + 2.0 * z(1, 0) + z(2, 0));
    let gx = (z(2, 0) + 2.0 * z(2, 1) + z(2, 2)) - (z(0, 0) + 2.0 * z(0, 1) + z(0, 2));
    (gx * gx + gy * gy).sqrt()
}

/// Otsu's threshold over `values` (256 bins from 0 to the maximum): the bin edge that
/// maximises the between-class variance.
pub fn otsu(values: impl Iterator<Item = f32> + Clone) -> f32 {
    let max = values.clone().fold(0.0f32, f32::max);
    if max <= 0.0 {
        return 0.0;
    }
    const BINS: usize = 256;
    let scale = (BINS as f32 - 1e-3) / max;
    let mut hist = [0u64; BINS];
    for v in values {
        hist[((v * scale) as usize).min(BINS - 1)] += 1;
    }
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
        let (w, h) = (width, height);
        for buf in [&mut self.valid, &mut self.strong, &mut self.eroded] {
            buf.clear();
            buf.resize(n, false);
        }
        self.magnitude.clear();
        self.magnitude.resize(n, 0.0);
        let r_blind = cam.f_px * cfg.blind_zone_half_deg.to_radians();
        let r_circle = cfg.image_circle_px.unwrap_or(f64::INFINITY);
        for y in 1..h - 1 {
            let dy = y as f64 - cam.y0_px;
            for x in 1..w - 1 {
                let r = (x as f64 - cam.x0_px).hypot(dy);
                if r < r_blind || r > r_circle {
                    continue;
                }
                let i = y * w + x;
                self.valid[i] = true;
                self.magnitude[i] = sobel(px, w, x, y);
            }
        }
        let threshold_dn = cfg.threshold_dn.unwrap_or_else(|| {
            let (m, v) = (&self.magnitude, &self.valid);
            otsu(m.iter().zip(v).filter(|(_, ok)| **ok).map(|(g, _)| *g))
        });
        let mut any_strong = false;
        for i in 0..n {
            let s = self.valid[i] && self.magnitude[i] >= threshold_dn && self.magnitude[i] > 0.0;
            self.strong[i] = s;
            any_strong |= s;
        }
        // Eq 5 with B the 3×3 square: kept where the whole neighbourhood is strong.
        let mut any_eroded = false;
        if any_strong {
            for y in 1..h - 1 {
                for x in 1..w - 1 {
                    let all = (0..3).all(|dy| {
                        let row = (y + dy - 1) * w + x - 1;
                        self.strong[row..row + 3].iter().all(|s| *s)
                    });
                    self.eroded[y * w + x] = all;
                    any_eroded |= all;
                }
            }
        }
        let map = if any_eroded {
            &self.eroded
        } else {
            &self.strong
        };
        let points_px = (0..n)
            .filter(|&i| map[i])
            .map(|i| ((i % w) as f64, (i / w) as f64))
            .collect();
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
