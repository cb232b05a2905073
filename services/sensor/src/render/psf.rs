//! Point-spread function: a pixel-integrated, separable Gaussian.
//!
//! A point source at pixel-centre offset 0 puts into the pixel at offset k ∈ [−R, R] the fraction
//! `w_k = Φ((k + ½)/σ) − Φ((k − ½)/σ)` per axis (the Gaussian PSF integrated over the pixel
//! aperture), with R = ⌈4σ⌉ and the weights renormalised to sum to exactly 1, so the PSF moves
//! no signal in or out (the cut tails hold < 7e-5 of it). The 2-D PSF is `w_i w_j`, applied as
//! two 1-D passes over a small tile. σ = 0 gives the identity kernel `[1]`.
//! Sub-pixel placement is done before the blur, by bilinear splatting (see `streak.rs`), so the
//! effective PSF is this kernel convolved with the bilinear tent; both preserve the centroid.

use super::noise::normal_cdf;

/// Radius R (in px) of the kernel for a PSF of standard deviation `sigma_px`.
pub fn kernel_radius_px(sigma_px: f64) -> usize {
    if sigma_px > 0.0 {
        (4.0 * sigma_px).ceil() as usize
    } else {
        0
    }
}

/// The normalised 1-D kernel, length 2R + 1, centre at index R.
pub fn gaussian_kernel_1d(sigma_px: f64) -> Vec<f32> {
    let r = kernel_radius_px(sigma_px) as isize;
    if r == 0 {
        return vec![1.0];
    }
    let w: Vec<f64> = (-r..=r)
        .map(|k| {
            let k = k as f64;
            normal_cdf((k + 0.5) / sigma_px) - normal_cdf((k - 0.5) / sigma_px)
        })
        .collect();
    let sum: f64 = w.iter().sum();
    w.iter().map(|v| (v / sum) as f32).collect()
}

/// Blur a row-major `width × height` tile in place with the separable kernel `kernel`
/// (odd length, centred), using `tmp` (same length as `tile`) as scratch. Values that would
/// fall outside the tile are dropped, so callers keep a margin of R px around the signal.
pub fn blur_separable(
    tile: &mut [f32],
    tmp: &mut [f32],
    width: usize,
    height: usize,
    kernel: &[f32],
) {
    let r = kernel.len() / 2;
    if r == 0 {
        return;
    }
    let n = width * height;
    let (tile, tmp) = (&mut tile[..n], &mut tmp[..n]);
    // Horizontal pass, scatter form: each non-zero input spreads along its row.
    tmp.fill(0.0);
    for y in 0..height {
        let row_in = &tile[y * width..(y + 1) * width];
        let row_out = &mut tmp[y * width..(y + 1) * width];
        for (x, &v) in row_in.iter().enumerate() {
            if v == 0.0 {
                continue;
            }
            let lo = x.saturating_sub(r);
            let hi = (x + r + 1).min(width);
            let k0 = lo + r - x;
            for (o, &k) in row_out[lo..hi].iter_mut().zip(&kernel[k0..]) {
                *o += v * k;
            }
        }
    }
    // Vertical pass, gather form, row by row so the inner loop runs along contiguous memory.
    tile.fill(0.0);
    for y in 0..height {
        let lo = y.saturating_sub(r);
        let hi = (y + r + 1).min(height);
        let dst = &mut tile[y * width..(y + 1) * width];
        for ys in lo..hi {
            let k = kernel[ys + r - y];
            for (d, &v) in dst.iter_mut().zip(&tmp[ys * width..(ys + 1) * width]) {
                *d += k * v;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kernel_is_normalised_symmetric_with_right_variance() {
        for sigma in [1.0, 1.3, 2.0] {
            let k = gaussian_kernel_1d(sigma);
            let r = kernel_radius_px(sigma);
            assert_eq!(k.len(), 2 * r + 1);
            let sum: f64 = k.iter().map(|&v| v as f64).sum();
            assert!((sum - 1.0).abs() < 1e-6);
            for i in 0..r {
                assert_eq!(k[i], k[2 * r - i]);
            }
            // Pixel integration adds the box variance 1/12 (Sheppard; exact only for σ ≳ 1).
            let var: f64 = k
                .iter()
                .enumerate()
                .map(|(i, &v)| v as f64 * (i as f64 - r as f64).powi(2))
                .sum();
            assert!(
                (var - (sigma * sigma + 1.0 / 12.0)).abs() < 2e-3,
                "σ={sigma}: {var}"
            );
        }
        assert_eq!(gaussian_kernel_1d(0.0), vec![1.0]);
        let small: f32 = gaussian_kernel_1d(0.3).iter().sum();
        assert!((small - 1.0).abs() < 1e-6);
    }

    #[test]
    fn blur_preserves_sum_and_centroid() {
        let (w, h) = (21usize, 17usize);
        let mut tile = vec![0.0f32; w * h];
        tile[8 * w + 10] = 3.0;
        tile[8 * w + 11] = 1.0;
        let mut tmp = vec![0.0f32; w * h];
        blur_separable(&mut tile, &mut tmp, w, h, &gaussian_kernel_1d(1.2));
        let sum: f64 = tile.iter().map(|&v| v as f64).sum();
        let cx: f64 = tile
            .iter()
            .enumerate()
            .map(|(i, &v)| v as f64 * (i % w) as f64)
            .sum::<f64>()
            / sum;
        let cy: f64 = tile
            .iter()
            .enumerate()
            .map(|(i, &v)| v as f64 * (i / w) as f64)
            .sum::<f64>()
            / sum;
        assert!((sum - 4.0).abs() < 1e-5);
        assert!(
            (cx - 10.25).abs() < 1e-5 && (cy - 8.0).abs() < 1e-5,
            "({cx}, {cy})"
        );
    }
}
