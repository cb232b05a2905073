//! What stage 3 owes to the stage-1 coefficients' uncertainty.
//!
//! With B_b = w ∂m/∂x_b the whitened sensitivity of band b's residuals to its coefficients,
//! J the whitened Jacobian in p, F = JᵀJ, F_pb = Jᵀ B_b and S_b = Cov(x̃_b)⁻¹ (stage 1, on the
//! coefficients NNLS left free):
//!
//! ```text
//! two-stage estimator (x̃ plugged in):  Cov(p̂) ≈ F⁻¹ + F⁻¹ C F⁻¹,   C = Σ_b F_pb Cov(x̃_b) F_bp
//! Cramér–Rao bound with x unknown and both windows informing it (the scenario's bound):
//!     CRB_p = (F − L)⁻¹,   L = Σ_b F_pb (S_b + B_bᵀB_b)⁻¹ F_bp
//! ```
//!
//! With the diffuse re-fit (`refit_diffuse`) the coefficients stage 3 re-estimates drop out
//! (their stage-1 values are not used), and the others act through the residual after the
//! nuisance projection: B_b becomes P⊥B_b with P⊥ = I − A(AᵀA)⁻¹Aᵀ, A the band's nuisance
//! columns (`crate::nuisance`).

use super::{nuisance_columns, RateProblem};
use crate::facet::TERMS;
use crate::nuisance::{solve_ridge, NUISANCE};
use crate::rotation::TrigStepper;
use nalgebra::DMatrix;

/// Per band: `F_bp` as n rows of 3, and `B_bᵀB_b` (n × n, row-major) when asked.
type Sensitivity = Option<(Vec<[f64; 3]>, Option<Vec<f64>>)>;

impl RateProblem {
    /// Attaches the stage-1 coefficient covariance of each band (x̃ units, 22 × 22 row-major;
    /// `None` where unknown) so that [`Self::coefficient_term`] can propagate it.
    pub fn with_coefficient_covariance(mut self, per_band: Vec<Option<Vec<f64>>>) -> Self {
        let n = TERMS * 2;
        self.coeff_cov = per_band
            .into_iter()
            .zip(&self.bands)
            .map(|(c, band)| {
                let k = band.mean_flux_w.powi(-2);
                c.filter(|c| c.len() == n * n)
                    .map(|c| c.iter().map(|v| v * k).collect())
            })
            .collect();
        self.coeff_cov.resize(self.bands.len(), None);
        self
    }

    /// Whether some band carries a stage-1 coefficient covariance to propagate (not when the
    /// diffuse re-fit replaces the coefficients).
    fn propagates_coefficients(&self) -> bool {
        self.coeff_cov.iter().any(Option::is_some)
    }

    /// Whether coefficient m (of 22) is re-estimated by stage 3 (so its stage-1 value is not
    /// used).
    pub(super) fn refitted(&self, m: usize) -> bool {
        let (f, k) = (m / TERMS, m % TERMS);
        self.refit_diffuse && (k == 0 || k == self.refit_lobes[f])
    }

    /// `C = Σ_b F_pb Cov(x_b) F_bp` (3 × 3) at p, with `jac` the whitened Jacobian at p. The
    /// rates' covariance including the coefficients' uncertainty is F⁻¹ + F⁻¹ C F⁻¹. `None`
    /// when no band carries a coefficient covariance (or the diffuse re-fit replaces them).
    pub fn coefficient_term(&self, p: [f64; 3], jac: &[[f64; 3]]) -> Option<[[f64; 3]; 3]> {
        if !self.propagates_coefficients() {
            return None;
        }
        let n = TERMS * 2;
        let mut c = [[0.0; 3]; 3];
        for (sens, cov) in self
            .coefficient_sensitivity(p, jac, false)
            .iter()
            .zip(&self.coeff_cov)
        {
            let (Some((jb, _)), Some(cov)) = (sens, cov) else {
                continue;
            };
            for m in 0..n {
                for k in 0..n {
                    let v = cov[m * n + k];
                    if v == 0.0 || self.refitted(m) || self.refitted(k) {
                        continue;
                    }
                    for i in 0..3 {
                        for j in 0..3 {
                            c[i][j] += jb[m][i] * v * jb[k][j];
                        }
                    }
                }
            }
        }
        Some(c)
    }

    /// `L = Σ_b F_pb (S_b + B_bᵀB_b)⁻¹ F_bp` (3 × 3): the information about p lost to not
    /// knowing the coefficients, when the stable window (S_b) and the motion window (B_bᵀB_b)
    /// both inform them. The Cramér–Rao bound of p is then `(JᵀJ − L)⁻¹`. Only coefficients
    /// with a positive stable-window variance are free; `None` as for
    /// [`Self::coefficient_term`].
    pub fn coefficient_information_loss(
        &self,
        p: [f64; 3],
        jac: &[[f64; 3]],
    ) -> Option<[[f64; 3]; 3]> {
        if !self.propagates_coefficients() {
            return None;
        }
        let n = TERMS * 2;
        let mut loss = [[0.0; 3]; 3];
        for (sens, cov) in self
            .coefficient_sensitivity(p, jac, true)
            .iter()
            .zip(&self.coeff_cov)
        {
            let (Some((jb, Some(btb))), Some(cov)) = (sens, cov) else {
                continue;
            };
            let free: Vec<usize> = (0..n)
                .filter(|&m| cov[m * n + m] > 0.0 && !self.refitted(m))
                .collect();
            if free.is_empty() {
                continue;
            }
            let k = free.len();
            let cov_free = DMatrix::from_fn(k, k, |i, j| cov[free[i] * n + free[j]]);
            let stable_info = cov_free.cholesky()?.inverse();
            let total = stable_info + DMatrix::from_fn(k, k, |i, j| btb[free[i] * n + free[j]]);
            let f_bp = DMatrix::from_fn(k, 3, |i, j| jb[free[i]][j]);
            let solved = total.cholesky()?.solve(&f_bp);
            let term = f_bp.transpose() * solved;
            for i in 0..3 {
                for j in 0..3 {
                    loss[i][j] += term[(i, j)];
                }
            }
        }
        Some(loss)
    }

    /// Per band with a coefficient covariance: `F_bp` (n rows of 3) and, with `with_btb`,
    /// `B_bᵀB_b`; with the diffuse re-fit, of the projected P⊥B_b (see the module docs).
    fn coefficient_sensitivity(
        &self,
        p: [f64; 3],
        jac: &[[f64; 3]],
        with_btb: bool,
    ) -> Vec<Sensitivity> {
        let nb = self.bands.len();
        let n = TERMS * 2;
        let mut out: Vec<Sensitivity> = self
            .coeff_cov
            .iter()
            .map(|c| {
                c.as_ref()
                    .map(|_| (vec![[0.0; 3]; n], with_btb.then(|| vec![0.0; n * n])))
            })
            .collect();
        // Per band, for the projection: AᵀA, Aᵀ B (NUISANCE × n) and Jᵀ A (3 × NUISANCE).
        let mut projections = vec![Projection::new(n); if self.refit_diffuse { nb } else { 0 }];
        let mut g = [[0.0; TERMS]; 2];
        let mut trig = TrigStepper::new(p);
        for (t, frame) in self.frames.iter().enumerate() {
            let rot = self.attitude.matrix_from_trig(&trig.at(frame.t_frames));
            self.basis(frame, &rot, &mut g);
            for (b, band) in self.bands.iter().enumerate() {
                let Some((jb, btb)) = &mut out[b] else {
                    continue;
                };
                let scale = band.w[t] * frame.inv_range2;
                let row = jac[t * nb + b];
                let mut flat = [0.0; 2 * TERMS];
                for (dst, gm) in flat.iter_mut().zip(g.iter().flatten()) {
                    *dst = scale * gm;
                }
                if let Some(projection) = projections.get_mut(b) {
                    projection.add(&nuisance_columns(scale, &g, self.refit_lobes), &flat, &row);
                }
                for (m, bm) in flat.iter().enumerate() {
                    for i in 0..3 {
                        jb[m][i] += row[i] * bm;
                    }
                }
                if let Some(btb) = btb {
                    for (m, bm) in flat.iter().enumerate() {
                        if *bm == 0.0 {
                            continue;
                        }
                        for (k, bk) in flat.iter().enumerate() {
                            btb[m * n + k] += bm * bk;
                        }
                    }
                }
            }
        }
        for (sens, projection) in out.iter_mut().zip(&projections) {
            if let Some((jb, btb)) = sens {
                projection.apply(jb, btb.as_deref_mut());
            }
        }
        out
    }
}

/// One band's sums for replacing B by P⊥B: AᵀA, AᵀB and JᵀA.
#[derive(Clone)]
struct Projection {
    ata: [[f64; NUISANCE]; NUISANCE],
    atb: Vec<[f64; NUISANCE]>,
    jta: [[f64; NUISANCE]; 3],
}

impl Projection {
    fn new(n: usize) -> Self {
        Projection {
            ata: [[0.0; NUISANCE]; NUISANCE],
            atb: vec![[0.0; NUISANCE]; n],
            jta: [[0.0; NUISANCE]; 3],
        }
    }

    fn add(&mut self, a: &[f64; NUISANCE], b: &[f64], j: &[f64; 3]) {
        for i in 0..NUISANCE {
            for k in 0..NUISANCE {
                self.ata[i][k] += a[i] * a[k];
            }
            for (atb, bm) in self.atb.iter_mut().zip(b) {
                atb[i] += a[i] * bm;
            }
            for (jta, jv) in self.jta.iter_mut().zip(j) {
                jta[i] += jv * a[i];
            }
        }
    }

    /// `jb ← Jᵀ P⊥ B = JᵀB − (JᵀA)(AᵀA)⁻¹AᵀB`, `btb ← BᵀP⊥B = BᵀB − (AᵀB)ᵀ(AᵀA)⁻¹AᵀB`.
    fn apply(&self, jb: &mut [[f64; 3]], btb: Option<&mut [f64]>) {
        let n = self.atb.len();
        let solved: Vec<[f64; NUISANCE]> =
            self.atb.iter().map(|c| solve_ridge(&self.ata, c)).collect();
        let dot = |a: &[f64; NUISANCE], b: &[f64; NUISANCE]| {
            (0..NUISANCE).map(|i| a[i] * b[i]).sum::<f64>()
        };
        for (row, x) in jb.iter_mut().zip(&solved) {
            for (v, jta) in row.iter_mut().zip(&self.jta) {
                *v -= dot(jta, x);
            }
        }
        if let Some(btb) = btb {
            for m in 0..n {
                for k in 0..n {
                    btb[m * n + k] -= dot(&self.atb[m], &solved[k]);
                }
            }
        }
    }
}
