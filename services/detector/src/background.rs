//! Robust background level and noise of a u16 frame (docs/math.md §3.2 gray levels, §3.3).
//!
//! The background is the median of the pixel values and the noise is `σ = 1.4826 · MAD`, with
//! `MAD = median |v − median|` (1.4826 = 1/Φ⁻¹(¾) makes σ unbiased for Gaussian noise). Streaks
//! and point targets cover a tiny fraction of a frame, so both statistics ignore them.
//!
//! Speed: one pass over a subsample grid (every `step`-th pixel of every `step`-th row; step 4 ⇒
//! 1/16 of a 1024² frame) fills a histogram of the u16 values; only the occupied value range
//! `[min, max]` is scanned and cleared afterwards, so the cost does not depend on 65 536 bins.
//!
//! Integer DN values are quantised: a noise of σ ≈ 5 DN would give a MAD that is an integer or a
//! half-integer. Each value v is therefore treated as spread uniformly over `[v − ½, v + ½)`, which
//! makes the empirical CDF `F` continuous and piecewise linear; the median solves
//! `F(m) = N/2` and the MAD solves `F(m + d) − F(m − d) = N/2` (bisection; the left side is
//! monotone in d). The spreading adds a uniform ±½ DN jitter to the rounded values, so for
//! Gaussian noise of σ DN the estimate is ≈ `sqrt(σ² + 1/12 + 1/12)` (rounding + jitter): within
//! 0.2 % of the quantised noise `sqrt(σ² + 1/12)` at σ = 5 DN, and a few per cent high at
//! σ = 1.5 DN, where the rounded distribution is no longer Gaussian.

use crate::FrameError;

/// Number of distinct u16 values.
const N_VALUES: usize = 1 << 16;

/// Background statistics of one frame.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct BackgroundStats {
    /// Median pixel value \[DN\].
    pub background_dn: f64,
    /// Robust noise `1.4826 · MAD` \[DN\].
    pub sigma_dn: f64,
    /// Number of pixels sampled.
    pub samples: u64,
}

/// Histogram scratch reused across frames (768 KiB, allocated once).
pub struct BackgroundEstimator {
    hist: Box<[u32; N_VALUES]>,
    cum: Vec<u64>,
}

impl Default for BackgroundEstimator {
    fn default() -> Self {
        Self::new()
    }
}

impl std::fmt::Debug for BackgroundEstimator {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BackgroundEstimator")
            .finish_non_exhaustive()
    }
}

impl BackgroundEstimator {
    /// Allocates the histogram scratch.
    pub fn new() -> Self {
        let hist: Box<[u32; N_VALUES]> = match vec![0u32; N_VALUES].into_boxed_slice().try_into() {
            Ok(h) => h,
            Err(_) => unreachable!("the vector has exactly N_VALUES elements"),
        };
        Self {
            hist,
            cum: Vec::with_capacity(N_VALUES + 1),
        }
    }

    /// Median and `1.4826 · MAD` of the pixels on the grid `(x, y) = (i·step, j·step)`.
    /// `step_px = 1` uses every pixel.
    pub fn estimate(
        &mut self,
        frame: &[u16],
        width: usize,
        height: usize,
        step_px: usize,
    ) -> Result<BackgroundStats, FrameError> {
        crate::check_frame(frame, width, height)?;
        let step = step_px.max(1);
        let mut lo = u16::MAX;
        let mut hi = 0u16;
        let mut samples = 0u64;
        for row in frame.chunks_exact(width).step_by(step) {
            for &v in row.iter().step_by(step) {
                self.hist[usize::from(v)] += 1;
                lo = lo.min(v);
                hi = hi.max(v);
            }
            samples += row.len().div_ceil(step) as u64;
        }
        let lo_i = usize::from(lo);
        let hi_i = usize::from(hi);
        let counts = &mut self.hist[lo_i..=hi_i];
        // cum[o] = number of samples with value < lo + o; cum[len] = N.
        self.cum.clear();
        let mut acc = 0u64;
        self.cum.push(0);
        for &c in counts.iter() {
            acc += u64::from(c);
            self.cum.push(acc);
        }
        let cdf = Cdf {
            cum: &self.cum,
            total: samples as f64,
        };
        let median_rel = cdf.quantile(0.5 * cdf.total);
        let mad = cdf.half_mass_radius(median_rel);
        counts.fill(0);
        Ok(BackgroundStats {
            background_dn: f64::from(lo) + median_rel,
            sigma_dn: 1.4826 * mad,
            samples,
        })
    }
}

/// The continuous CDF of a histogram whose bin o covers `[o − ½, o + ½)` (offsets from the
/// smallest value).
struct Cdf<'a> {
    cum: &'a [u64],
    total: f64,
}

impl Cdf<'_> {
    fn bins(&self) -> usize {
        self.cum.len() - 1
    }

    fn count(&self, o: usize) -> f64 {
        (self.cum[o + 1] - self.cum[o]) as f64
    }

    /// F(x): number of samples below x.
    fn at(&self, x: f64) -> f64 {
        if x < -0.5 {
            return 0.0;
        }
        let o_f = (x + 0.5).floor();
        if o_f >= self.bins() as f64 {
            return self.total;
        }
        let o = o_f as usize;
        self.cum[o] as f64 + self.count(o) * (x - o_f + 0.5)
    }

    /// The x with F(x) = mass (the first such x inside an occupied bin).
    fn quantile(&self, mass: f64) -> f64 {
        for o in 0..self.bins() {
            let above = self.cum[o + 1] as f64;
            if above >= mass && self.count(o) > 0.0 {
                return o as f64 - 0.5 + (mass - self.cum[o] as f64) / self.count(o);
            }
        }
        self.bins() as f64 - 0.5
    }

    /// The d ≥ 0 with F(m + d) − F(m − d) = N/2 (the MAD about m).
    fn half_mass_radius(&self, m: f64) -> f64 {
        let half = 0.5 * self.total;
        let (mut lo, mut hi) = (0.0f64, self.bins() as f64 + 1.0);
        for _ in 0..64 {
            let mid = 0.5 * (lo + hi);
            if self.at(m + mid) - self.at(m - mid) >= half {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        0.5 * (lo + hi)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Tiny LCG + Box–Muller for reproducible noise.
    fn gaussian_frame(n: usize, mean: f64, sigma: f64, seed: u64) -> Vec<u16> {
        let mut s = seed;
        let mut uniform = move || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((s >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        (0..n)
            .map(|_| {
                let z = (-2.0 * uniform().ln()).sqrt() * (std::f64::consts::TAU * uniform()).cos();
                (mean + sigma * z).round().clamp(0.0, 65535.0) as u16
            })
            .collect()
    }

    #[test]
    fn gaussian_noise_recovers_mean_and_quantised_sigma() {
        let mut est = BackgroundEstimator::new();
        for (mean, sigma, tol) in [(20.0, 4.9, 0.02), (1000.0, 30.0, 0.02), (300.0, 1.5, 0.05)] {
            let frame = gaussian_frame(512 * 512, mean, sigma, 7);
            let stats = est.estimate(&frame, 512, 512, 1).expect("valid frame");
            let want = (sigma * sigma + 1.0 / 6.0_f64).sqrt();
            assert!(
                (stats.background_dn - mean).abs() < 0.02 * sigma,
                "{stats:?}"
            );
            assert!(
                (stats.sigma_dn / want - 1.0).abs() < tol,
                "{stats:?} want {want}"
            );
            // The subsample grid agrees within its (4× larger) sampling error.
            let sub = est.estimate(&frame, 512, 512, 4).expect("valid frame");
            assert_eq!(sub.samples, 128 * 128);
            assert!((sub.sigma_dn / want - 1.0).abs() < 0.05, "{sub:?}");
        }
    }

    #[test]
    fn bright_targets_do_not_move_the_estimate() {
        let mut frame = gaussian_frame(256 * 256, 100.0, 5.0, 3);
        let clean = BackgroundEstimator::new()
            .estimate(&frame, 256, 256, 1)
            .expect("valid frame");
        for v in frame.iter_mut().step_by(97) {
            *v = 60_000; // 1 % saturated pixels
        }
        let dirty = BackgroundEstimator::new()
            .estimate(&frame, 256, 256, 1)
            .expect("valid frame");
        assert!((dirty.background_dn - clean.background_dn).abs() < 0.2);
        assert!((dirty.sigma_dn - clean.sigma_dn).abs() < 0.2);
    }

    #[test]
    fn constant_frame_and_reuse() {
        let mut est = BackgroundEstimator::new();
        let flat = vec![42u16; 64 * 32];
        let s = est.estimate(&flat, 64, 32, 1).expect("valid frame");
        // One occupied bin spread over [41.5, 42.5): median 42, MAD 0.25.
        assert!((s.background_dn - 42.0).abs() < 1e-12);
        assert!((s.sigma_dn - 1.4826 * 0.25).abs() < 1e-9);
        // The histogram is cleared: a second frame is unaffected by the first.
        let other = vec![7u16; 64 * 32];
        let s = est.estimate(&other, 64, 32, 2).expect("valid frame");
        assert!((s.background_dn - 7.0).abs() < 1e-12);
        assert_eq!(s.samples, 32 * 16);
    }

    #[test]
    fn two_values_interpolate() {
        // Half the pixels 10, half 12: F is flat between 10.5 and 11.5, so the median is 10.5
        // (the first x reaching N/2); the mass within 10.5 ± d is 50·d for d ≤ 1, so MAD = 1.
        let frame: Vec<u16> = (0..100).map(|i| if i % 2 == 0 { 10 } else { 12 }).collect();
        let s = BackgroundEstimator::new()
            .estimate(&frame, 10, 10, 1)
            .expect("valid frame");
        assert!((s.background_dn - 10.5).abs() < 1e-12, "{s:?}");
        assert!((s.sigma_dn - 1.4826).abs() < 1e-9, "{s:?}");
    }

    #[test]
    fn rejects_bad_sizes() {
        let mut est = BackgroundEstimator::new();
        assert!(est.estimate(&[1, 2, 3], 2, 2, 1).is_err());
        assert!(est.estimate(&[], 0, 0, 1).is_err());
    }
}
