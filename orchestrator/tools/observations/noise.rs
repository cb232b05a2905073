//! σ from the data, for observation files without `sigma_*` columns (another tool's light
//! curves rarely carry them). Each band's noise is read off the light curve's high-frequency
//! scatter: the second differences of each window's fluxes in frame order,
//! σ̂ = 1.4826 · median |Δ²y| / √6. For independent Gaussian noise Δ²y has variance 6σ², and
//! the median makes it robust to outliers and to the curve's own (slow) curvature.

use glint_inversion::Observation;

/// Each band's σ̂ [W] over one window's rows (0 for fewer than three rows). Windows are
/// estimated apart: their exposures, and so their noise, differ.
pub fn estimate_sigma_w(rows: &[Observation], bands: usize) -> Vec<f64> {
    let mut rows: Vec<&Observation> = rows.iter().collect();
    rows.sort_by_key(|o| o.frame_index);
    (0..bands)
        .map(|b| {
            let y: Vec<f64> = rows
                .iter()
                .filter_map(|o| o.flux_w.get(b).copied())
                .collect();
            let mut d2: Vec<f64> = (y.windows(3))
                .map(|w| (w[2] - 2.0 * w[1] + w[0]).abs())
                .collect();
            if d2.is_empty() {
                return 0.0;
            }
            d2.sort_by(f64::total_cmp);
            1.4826 * d2[d2.len() / 2] / 6f64.sqrt()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    /// A smooth light curve with Gaussian noise of σ (Box–Muller on a fixed LCG).
    fn noisy(sigma: f64, n: usize) -> Vec<Observation> {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut uniform = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        let mut draw = || {
            let (u, v) = (uniform(), uniform());
            sigma * (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
        };
        // in reverse frame order: the estimate sorts them
        (0..n)
            .rev()
            .map(|k| Observation {
                frame_index: k as u64,
                t_s: k as f64,
                sun_body: Vector3::x(),
                observer_body: Vector3::z(),
                range_m: 2e6,
                flux_w: vec![1e-14 * (1.0 + 0.5 * (k as f64 * 0.05).sin()) + draw()],
                sigma_w: vec![],
            })
            .collect()
    }

    #[test]
    fn the_scatter_of_a_smooth_curve_gives_its_noise() {
        for sigma in [1e-15, 3e-16] {
            let s = estimate_sigma_w(&noisy(sigma, 4000), 1)[0];
            assert!((s / sigma - 1.0).abs() < 0.1, "σ̂ {s} against σ {sigma}");
        }
        // without noise, what is left is the curve's curvature, far below any noise above
        let s = estimate_sigma_w(&noisy(0.0, 400), 1)[0];
        assert!(s < 1e-17, "{s}");
        assert_eq!(estimate_sigma_w(&noisy(1e-15, 2), 1), [0.0]);
    }
}
