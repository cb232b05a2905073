//! What a fitted rate problem says about its own bands and terms: per-band mismatch scales
//! and reweighting (the joint fit's feasible weighted least squares, `fit_joint`), and the
//! lobes' share of the sensitivity to p (the "no glint" test of stage 3).

use super::RateProblem;
use crate::observability::correlation_time;

impl RateProblem {
    /// Divides each band's weights by its scale (> 0): the band's noise is taken `scale` times
    /// larger. Used to down-weight the bands the model fits worst (see
    /// [`Self::band_mismatch_scales`]).
    pub fn with_band_scales(mut self, scales: &[f64]) -> Self {
        for (band, s) in self.bands.iter_mut().zip(scales) {
            if *s > 0.0 && s.is_finite() {
                band.w.iter_mut().for_each(|w| *w /= s);
            }
        }
        self
    }

    /// Per band, the factor by which its residuals at `p` exceed their noise, counting serial
    /// correlation: sqrt(χ²_b/T · τ_b), τ_b the band's AR(1) correlation time, floored at 1
    /// with σ given (a band the model explains to the noise keeps its weight). Without σ the
    /// residual is all mismatch and the factors are relative (floored at 1e-12).
    pub fn band_mismatch_scales(&self, p: [f64; 3]) -> Vec<f64> {
        let nb = self.bands.len();
        let t = self.frames.len().max(1);
        let mut r = vec![0.0; self.residual_count()];
        self.residuals(p, &mut r);
        (0..nb)
            .map(|b| {
                let band: Vec<f64> = (0..t).map(|k| r[k * nb + b]).collect();
                let chi2: f64 = band.iter().map(|v| v * v).sum();
                let tau = correlation_time(&band, 1);
                let floor = if self.sigma_given { 1.0 } else { 1e-12 };
                (chi2 / t as f64 * tau).sqrt().max(floor)
            })
            .collect()
    }

    /// Share of the light curve's sensitivity to p that the specular lobes (m ≥ 1) carry at
    /// `p`: ‖J_lobes‖_F / ‖J‖_F, with J_lobes the Jacobian of the model with every diffuse
    /// coefficient set to 0 (no re-fit). About 1 when a glint or a broad lobe moves with p, 0
    /// when only the diffuse terms do. NaN when the light curve has no sensitivity at all.
    pub fn lobe_sensitivity_share(&self, p: [f64; 3]) -> f64 {
        let mut lobes = self.clone();
        lobes.refit_diffuse = false;
        lobes.refit_lobes = [0; 2];
        let refitted = self.nuisance_fit(p);
        for (band, c) in lobes.bands.iter_mut().zip(&refitted) {
            band.x[0][0] = 0.0;
            band.x[1][0] = 0.0;
            // A re-fitted lobe is a lobe: its fitted coefficient joins the others.
            for f in 0..2 {
                if self.refit_lobes[f] > 0 {
                    band.x[f][self.refit_lobes[f]] = c[3 + f];
                }
            }
        }
        let n = self.residual_count();
        let mut r = vec![0.0; n];
        let mut jac = vec![[0.0; 3]; n];
        let norm =
            |jac: &[[f64; 3]]| -> f64 { jac.iter().flatten().map(|v| v * v).sum::<f64>().sqrt() };
        self.residuals_and_jacobian(p, &mut r, &mut jac);
        let total = norm(&jac);
        let n = lobes.residual_count();
        let (mut r, mut jac) = (vec![0.0; n], vec![[0.0; 3]; n]);
        lobes.residuals_and_jacobian(p, &mut r, &mut jac);
        norm(&jac) / total
    }
}
