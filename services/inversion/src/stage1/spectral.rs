//! Spectral pooling of the stable window for the single-band fit (beyond the paper).
//!
//! One band's stage-1 coefficients carry that band's noise alone, and NNLS bends it: positivity
//! holds coefficients at zero from one side only, so a noisy band's coefficients are biased,
//! and λ* lands wherever they point (about Z at SNR 10: median error 6.9, NEES in the hundreds). Surface reflectances change slowly with wavelength, so the light curves of
//! neighbouring bands, each divided by its own mean, nearly coincide. The pooled light curve of
//! band b is the local-linear fit across the bands within `window_nm` of it, evaluated at λ_b
//! (a line, so a spectral slope passes unchanged and the window may be one-sided at the ends):
//!
//! ```text
//! f_b'(t) = Φ_b'(t) / Φ̄_b'              Φ̄ = mean over the stable window
//! Φ̃_b(t)  = Φ̄_b Σ_b' w_bb' f_b'(t)      w_b· = the local-linear weights at λ_b
//! σ̃_b     = σ_b sqrt(Σ_b' w_bb'²)        (σ_b' / Φ̄_b' = σ_b / Φ̄_b: σ = mean/SNR)
//! ```
//!
//! Pooling trades noise for the spectral change it smears. The trade is tested on the data:
//! the residual e = f − W f of every sample has the noise variance v = Σ_b' (δ_bb' − w_bb')²
//! s_b'² (s = σ/Φ̄), and what it has beyond that is the pooled curve's bias. Its mean square,
//! in units of the raw noise, is
//!
//! ```text
//! ρ² = mean over (t, b) of (e² − v) / s_b²
//! ```
//!
//! The pooled window is used only when ρ ≤ `max_bias_to_noise` (1/3: the smeared change at most
//! a third of the noise it removes). Without σ nothing is pooled, so noise-free answers are
//! those of the bands alone. The joint fit keeps every band's own coefficients: it pools the
//! bands itself, and it counts their stage-1 errors as independent.

use crate::observation::Observation;

/// Local-linear weights of the bands within `window_nm` of each band: for band b, `(b', w)`
/// pairs with Σ w = 1 and Σ w (λ_b' − λ_b) = 0. A band with no neighbour in reach gets itself.
pub fn local_linear_weights(wavelengths_nm: &[f64], window_nm: f64) -> Vec<Vec<(usize, f64)>> {
    wavelengths_nm
        .iter()
        .map(|&centre| {
            let near: Vec<usize> = (0..wavelengths_nm.len())
                .filter(|&k| (wavelengths_nm[k] - centre).abs() <= window_nm + 1e-9)
                .collect();
            let n = near.len() as f64;
            let mean = near.iter().map(|&k| wavelengths_nm[k]).sum::<f64>() / n;
            let sxx: f64 = near
                .iter()
                .map(|&k| (wavelengths_nm[k] - mean).powi(2))
                .sum();
            near.iter()
                .map(|&k| {
                    let slope = if sxx > 0.0 {
                        (wavelengths_nm[k] - mean) * (centre - mean) / sxx
                    } else {
                        0.0
                    };
                    (k, 1.0 / n + slope)
                })
                .collect()
        })
        .collect()
}

/// Whether the window pools anything (some band has a neighbour in reach).
pub fn pools(weights: &[Vec<(usize, f64)>]) -> bool {
    weights.iter().any(|w| w.len() > 1)
}

/// Per-band mean flux of a window (0 for an empty window).
fn band_means(window: &[Observation], bands: usize) -> Vec<f64> {
    let n = window.len().max(1) as f64;
    (0..bands)
        .map(|b| window.iter().map(|o| o.flux_w[b]).sum::<f64>() / n)
        .collect()
}

/// ρ, the pooled curves' RMS bias in units of the raw noise (module docs); `None` unless every
/// sample carries σ and every band has flux.
pub fn bias_to_noise(window: &[Observation], weights: &[Vec<(usize, f64)>]) -> Option<f64> {
    residual_statistic(window, weights, true)
}

/// ρ of noise-free flux carrying the σ its noisy counterparts would have: there the residual
/// is the bias itself, so nothing is subtracted. What [`bias_to_noise`] estimates, on average,
/// from the noisy data (used to take the noisy runs' expected decision on a noise-free
/// reference).
pub fn bias_to_noise_noise_free(
    window: &[Observation],
    weights: &[Vec<(usize, f64)>],
) -> Option<f64> {
    residual_statistic(window, weights, false)
}

fn residual_statistic(
    window: &[Observation],
    weights: &[Vec<(usize, f64)>],
    subtract_noise: bool,
) -> Option<f64> {
    let bands = weights.len();
    if window.is_empty() || window.iter().any(|o| o.sigma_w.len() != bands) {
        return None;
    }
    let mean = band_means(window, bands);
    if !mean.iter().all(|m| m.is_finite() && *m > 0.0) {
        return None;
    }
    let mut excess = 0.0;
    let mut count = 0usize;
    for o in window {
        let f: Vec<f64> = (0..bands).map(|b| o.flux_w[b] / mean[b]).collect();
        let s: Vec<f64> = (0..bands).map(|b| o.sigma_w[b] / mean[b]).collect();
        for (b, w) in weights.iter().enumerate() {
            // Residual e = f_b − Σ w f and its noise variance Σ (δ − w)² s².
            let mut e = f[b];
            let mut v = s[b] * s[b];
            for &(k, wk) in w {
                e -= wk * f[k];
                v += if k == b { wk * wk - 2.0 * wk } else { wk * wk } * s[k] * s[k];
            }
            let noise = if subtract_noise { v } else { 0.0 };
            excess += (e * e - noise) / (s[b] * s[b]);
            count += 1;
        }
    }
    Some((excess / count as f64).max(0.0).sqrt())
}

/// The window with every band's flux replaced by its pooled curve and σ scaled to match
/// (module docs).
pub fn pooled(window: &[Observation], weights: &[Vec<(usize, f64)>]) -> Vec<Observation> {
    let bands = weights.len();
    let mean = band_means(window, bands);
    let noise_factor: Vec<f64> = weights
        .iter()
        .map(|w| w.iter().map(|(_, wk)| wk * wk).sum::<f64>().sqrt())
        .collect();
    window
        .iter()
        .map(|o| {
            let mut out = o.clone();
            for (b, w) in weights.iter().enumerate() {
                out.flux_w[b] = mean[b]
                    * w.iter()
                        .map(|&(k, wk)| wk * o.flux_w[k] / mean[k])
                        .sum::<f64>();
            }
            if out.sigma_w.len() == bands {
                for (s, k) in out.sigma_w.iter_mut().zip(&noise_factor) {
                    *s *= k;
                }
            }
            out
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    const BANDS_NM: [f64; 8] = [400.0, 410.0, 420.0, 430.0, 440.0, 450.0, 460.0, 470.0];

    /// A stable window whose band b has the light curve `shape(t) · level(λ_b)` plus `dev(t, b)`,
    /// with σ = `sigma_rel` × the band's mean.
    fn window(
        level: impl Fn(f64) -> f64,
        dev: impl Fn(usize, usize) -> f64,
        sigma_rel: f64,
    ) -> Vec<Observation> {
        let shape = |t: usize| 1.0 + 0.5 * (t as f64 * 0.07).sin();
        let mut out: Vec<Observation> = (0..200)
            .map(|t| Observation {
                frame_index: t as u64,
                t_s: t as f64,
                sun_body: Vector3::x(),
                observer_body: Vector3::x(),
                range_m: 1.0,
                flux_w: BANDS_NM
                    .iter()
                    .enumerate()
                    .map(|(b, &nm)| shape(t) * level(nm) + dev(t, b))
                    .collect(),
                sigma_w: vec![],
            })
            .collect();
        let n = out.len() as f64;
        let means: Vec<f64> = (0..BANDS_NM.len())
            .map(|b| out.iter().map(|o| o.flux_w[b]).sum::<f64>() / n)
            .collect();
        for o in &mut out {
            o.sigma_w = means.iter().map(|m| m * sigma_rel).collect();
        }
        out
    }

    #[test]
    fn the_weights_reproduce_a_line_and_sum_to_one() {
        for window_nm in [0.0, 10.0, 20.0, 35.0] {
            let w = local_linear_weights(&BANDS_NM, window_nm);
            for (b, wb) in w.iter().enumerate() {
                let sum: f64 = wb.iter().map(|(_, x)| x).sum();
                let at: f64 = wb.iter().map(|&(k, x)| x * (3.0 + 0.2 * BANDS_NM[k])).sum();
                assert!(
                    (sum - 1.0).abs() < 1e-12,
                    "{window_nm} nm, band {b}: Σw = {sum}"
                );
                assert!(
                    (at - (3.0 + 0.2 * BANDS_NM[b])).abs() < 1e-9,
                    "{window_nm} nm, band {b}: a line comes back as {at}"
                );
            }
        }
        // ±20 nm at 10 nm spacing: 5 bands inside, 3 at the ends; nothing to pool at 5 nm.
        let w = local_linear_weights(&BANDS_NM, 20.0);
        assert_eq!(w[3].len(), 5);
        assert_eq!(w[0].len(), 3);
        // Interior: the plain mean of five (Σw² = 1/5).
        let sq: f64 = w[3].iter().map(|(_, x)| x * x).sum();
        assert!((sq - 0.2).abs() < 1e-12, "{sq}");
        assert!(!pools(&local_linear_weights(&BANDS_NM, 5.0)));
    }

    #[test]
    fn spectrally_linear_curves_pool_unchanged_and_show_no_bias() {
        let obs = window(|nm| 2.0 + 0.01 * nm, |_, _| 0.0, 0.05);
        let w = local_linear_weights(&BANDS_NM, 20.0);
        let pooled = pooled(&obs, &w);
        for (a, b) in obs.iter().zip(&pooled) {
            for (x, y) in a.flux_w.iter().zip(&b.flux_w) {
                assert!((x - y).abs() < 1e-12 * x.abs(), "{x} → {y}");
            }
        }
        assert!(bias_to_noise_noise_free(&obs, &w).unwrap() < 1e-9);
        // σ falls as the root of the weights' sum of squares.
        let ratio = pooled[0].sigma_w[3] / obs[0].sigma_w[3];
        assert!((ratio - 0.2f64.sqrt()).abs() < 1e-12, "{ratio}");
    }

    #[test]
    fn the_test_measures_a_spectral_feature_against_the_noise() {
        // Band 3's light curve carries its own term a·g(t). Every band b's pooled residual then
        // holds (δ_b3 − w_b3)·a·g/m (m the band mean), so over the 8 bands
        // ρ² = a² mean(g²) Σ_b (δ_b3 − w_b3)² / 8 / (m s)².
        let s = 0.01;
        let a = 0.05;
        let g = |t: usize| (t as f64 * 0.31).cos();
        let obs = window(|_| 1.0, |t, b| if b == 3 { a * g(t) } else { 0.0 }, s);
        let w = local_linear_weights(&BANDS_NM, 20.0);
        // The window pools bands 1..=5 into band 3, but the ends use one-sided lines: compute
        // the exact prediction from the weights themselves.
        let mean_g2 = (0..200).map(|t| g(t).powi(2)).sum::<f64>() / 200.0;
        // Each band is divided by its mean, that of the shape (≈ 1.03 here).
        let shape_mean = obs.iter().map(|o| o.flux_w[0]).sum::<f64>() / 200.0;
        let expected2: f64 = w
            .iter()
            .enumerate()
            .map(|(b, wb)| {
                let delta = if b == 3 { 1.0 } else { 0.0 };
                let w3 = wb.iter().find(|(k, _)| *k == 3).map_or(0.0, |(_, x)| *x);
                (delta - w3).powi(2)
            })
            .sum::<f64>()
            * (a / shape_mean).powi(2)
            * mean_g2
            / 8.0
            / (s * s);
        let rho = bias_to_noise_noise_free(&obs, &w).unwrap();
        // Band 3's mean also holds the bump's (small) mean: allow a per-cent.
        assert!(
            (rho * rho / expected2 - 1.0).abs() < 0.02,
            "ρ² = {} against {expected2}",
            rho * rho
        );
        // Without σ there is nothing to test against.
        let mut bare = obs.clone();
        bare.iter_mut().for_each(|o| o.sigma_w.clear());
        assert!(bias_to_noise(&bare, &w).is_none());
    }

    #[test]
    fn on_noise_the_test_subtracts_the_noise_it_expects() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let s = 0.02;
        let mut noise = || {
            // Box–Muller: standard normal.
            let (u1, u2): (f64, f64) = (rng.random_range(1e-12..1.0), rng.random_range(0.0..1.0));
            (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
        };
        let mut obs = window(|nm| 1.0 + 0.001 * nm, |_, _| 0.0, s);
        for o in &mut obs {
            for (f, sig) in o.flux_w.iter_mut().zip(&o.sigma_w) {
                *f += sig * noise();
            }
        }
        let w = local_linear_weights(&BANDS_NM, 20.0);
        // A spectrally linear signal: the noisy residual is noise alone, so ρ ≈ 0 (its sampling
        // error over 200 × 8 residuals is ≈ 0.2), while the noise-free formula reads the noise
        // as bias (ρ ≈ sqrt(mean v / s²) ≈ 0.85).
        let rho = bias_to_noise(&obs, &w).unwrap();
        assert!(rho < 0.25, "ρ = {rho}");
        let as_if_noise_free = bias_to_noise_noise_free(&obs, &w).unwrap();
        assert!(as_if_noise_free > 0.6, "{as_if_noise_free}");
    }
}
