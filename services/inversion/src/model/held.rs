//! Stage 1's coefficients held by their stable-window prior and re-estimated with the motion
//! window (opt-in, docs/adr/0030; beyond the paper).
//!
//! The polish keeps stage 1's coefficients x̃ fixed by default. Here every coefficient NNLS
//! left free and stage 3 does not re-fit outright (each band's glint lobes, usually) moves by
//! δ, held by the stable window's Gaussian likelihood δ ~ N(0, Cov(x̃)): the joint likelihood
//! of both windows with stage 1's passive set, in the form whose bound the campaigns report
//! (`coefficient_information_loss`). Per band, with A the free nuisance columns
//! ([`crate::nuisance`]) and B̃ = B L (B = w k G over the held terms, L Lᵀ = Cov):
//!
//! ```text
//! min_c ‖r⁰ − C c‖² + c_Bᵀ c_B,   C = [A, B̃],  c = [c_A, c_B],  δ = L c_B
//! ```
//!
//! solved as least squares on the augmented rows `[C; 0 I] c ≈ [r⁰; 0]`. The band's residual
//! vector gains k rows, `−c_B` (the prior's share of the cost), and the Jacobian is Kaufman's
//! variable projection of the augmented system, `J = P⊥ D` with `D = J⁰ + Σ_j c_j ∂C_j` on the
//! motion rows and 0 on the prior rows. So `Jᵀρ` is the exact gradient of the profiled cost
//! and `JᵀJ` its Gauss–Newton matrix, which counts what the stable window knows about the
//! coefficients and what the motion window adds. The propagated coefficient term is then not
//! added again ([`RateProblem::coefficient_term`] is `None`).

use super::{dot22, model_slope, FacetSlopes, RateProblem};
use crate::facet::TERMS;
use crate::nuisance::{project_band, Row, NUISANCE};
use crate::rotation::TrigStepper;
use nalgebra::{DMatrix, DVector};

/// One band's held terms: their flat indices (facet·TERMS + m) and L, L Lᵀ = Cov (the
/// problem's normalised units).
#[derive(Debug, Clone)]
pub(super) struct Held {
    idx: Vec<usize>,
    l: DMatrix<f64>,
}

impl Held {
    /// The held terms of a band: positive stage-1 variance, not re-fitted outright. `None`
    /// when there are none or Cov is not positive definite on them.
    pub(super) fn new(cov: &[f64], refitted: impl Fn(usize) -> bool) -> Option<Self> {
        let n = TERMS * 2;
        let idx: Vec<usize> = (0..n)
            .filter(|&m| cov[m * n + m] > 0.0 && !refitted(m))
            .collect();
        if idx.is_empty() {
            return None;
        }
        let k = idx.len();
        let c = DMatrix::from_fn(k, k, |i, j| cov[idx[i] * n + idx[j]]);
        let l = c.cholesky()?.l();
        Some(Self { idx, l })
    }

    /// Extra residual rows.
    pub(super) fn rows(&self) -> usize {
        self.idx.len()
    }
}

/// One band's motion rows: free columns and slopes, raw held columns (w k G_m) and slopes.
#[derive(Debug, Clone, Default)]
struct BandRows {
    a: Vec<[f64; NUISANCE]>,
    da: Vec<[[f64; 3]; NUISANCE]>,
    g: Vec<Vec<f64>>,
    dg: Vec<Vec<[f64; 3]>>,
}

impl BandRows {
    fn push(
        &mut self,
        held: &Held,
        row: Row,
        scale: f64,
        g: &[[f64; TERMS]; 2],
        sl: &[FacetSlopes; 2],
    ) {
        let mut col = Vec::with_capacity(held.idx.len());
        let mut dcol = Vec::with_capacity(held.idx.len());
        for &flat in &held.idx {
            let (f, m) = (flat / TERMS, flat % TERMS);
            col.push(scale * g[f][m]);
            dcol.push(if m == 0 {
                sl[f].d_diffuse.map(|v| scale * v)
            } else {
                sl[f].dc.map(|dc| scale * sl[f].lobe[m - 1] * dc)
            });
        }
        self.a.push(row.a);
        self.da.push(row.da);
        self.g.push(col);
        self.dg.push(dcol);
    }
}

/// Projects one band in place (module docs): `index(t)` maps motion row t into `r` and `jac`,
/// the k prior rows go to `prior_at..prior_at + k`; `scale` multiplies L (the band's weight
/// scale, so the prior keeps its weight against the data). Returns the free coefficients c_A.
#[allow(clippy::too_many_arguments, clippy::needless_range_loop)] // i: a Jacobian column
fn project(
    rows: &BandRows,
    held: &Held,
    scale: f64,
    index: impl Fn(usize) -> usize,
    prior_at: usize,
    r: &mut [f64],
    jac: Option<&mut [[f64; 3]]>,
) -> [f64; NUISANCE] {
    let t_len = rows.a.len();
    let k = held.idx.len();
    let m = NUISANCE + k;
    let lt = held.l.transpose() * scale;
    let mut c = DMatrix::zeros(t_len, m);
    for t in 0..t_len {
        for j in 0..NUISANCE {
            c[(t, j)] = rows.a[t][j];
        }
        let bt = &lt * DVector::from_column_slice(&rows.g[t]);
        for j in 0..k {
            c[(t, NUISANCE + j)] = bt[j];
        }
    }
    let rv = DVector::from_fn(t_len, |t, _| r[index(t)]);
    let gram = c.transpose() * &c;
    let z = c.transpose() * &rv;
    // (CᵀC + R) equilibrated to unit diagonal: R = I on the held columns, and the free
    // columns' ridge of `crate::nuisance` (1e-12), so a zero column gets c = 0.
    let mut d = DVector::zeros(m);
    for j in 0..m {
        let v = gram[(j, j)] + if j >= NUISANCE { 1.0 } else { 0.0 };
        d[j] = if v > 0.0 { 1.0 / v.sqrt() } else { 0.0 };
    }
    let mut mat = DMatrix::from_fn(m, m, |i, j| d[i] * gram[(i, j)] * d[j]);
    for j in 0..m {
        mat[(j, j)] += if j >= NUISANCE { d[j] * d[j] } else { 1e-12 };
    }
    let Some(chol) = mat.cholesky() else {
        return [0.0; NUISANCE];
    };
    let solve = |x: &DVector<f64>| -> DVector<f64> {
        let scaled = x.component_mul(&d);
        chol.solve(&scaled).component_mul(&d)
    };
    let coef = solve(&z);
    let e = &rv - &c * &coef;
    for t in 0..t_len {
        r[index(t)] = e[t];
    }
    for j in 0..k {
        r[prior_at + j] = -coef[NUISANCE + j];
    }
    let free = std::array::from_fn(|j| coef[j]);
    let Some(jac) = jac else {
        return free;
    };
    let delta = &held.l * coef.rows(NUISANCE, k) * scale; // Σ_j c_j ∂B̃_j = ∂B δ
    for i in 0..3 {
        let dcol = DVector::from_fn(t_len, |t, _| {
            let mut v = jac[index(t)][i];
            for j in 0..NUISANCE {
                v += coef[j] * rows.da[t][j][i];
            }
            for j in 0..k {
                v += delta[j] * rows.dg[t][j][i];
            }
            v
        });
        let x = solve(&(c.transpose() * &dcol));
        let jd = &dcol - &c * &x;
        for t in 0..t_len {
            jac[index(t)][i] = jd[t];
        }
        for j in 0..k {
            jac[prior_at + j][i] = -x[NUISANCE + j];
        }
    }
    free
}

/// Residuals (rows t·B + b of every `stride`-th frame, then each held band's prior rows), the
/// Jacobian with `with_jac`, the cost, and the free coefficients per band.
pub(super) struct Evaluation {
    pub r: Vec<f64>,
    pub jac: Vec<[f64; 3]>,
    pub cost: f64,
    pub free: Vec<[f64; NUISANCE]>,
}

impl RateProblem {
    /// Whether some band's coefficients are held by their prior ([`Self::with_held_coefficients`]).
    pub fn holds_coefficients(&self) -> bool {
        self.held.iter().any(Option::is_some)
    }

    /// Prior rows over the bands (0 without held coefficients).
    pub(super) fn prior_rows(&self) -> usize {
        self.held.iter().flatten().map(Held::rows).sum()
    }

    /// The problem with each band's stage-1 coefficients held by their prior (module docs):
    /// with the diffuse re-fit, σ given and a coefficient covariance attached
    /// ([`Self::with_coefficient_covariance`]); unchanged otherwise.
    pub fn with_held_coefficients(mut self) -> Self {
        if !(self.refit_diffuse && self.sigma_given) {
            return self;
        }
        self.held = self
            .coeff_cov
            .iter()
            .map(|c| c.as_ref().and_then(|c| Held::new(c, |m| self.refitted(m))))
            .collect();
        self
    }

    /// The held model at p (see [`Evaluation`]).
    pub(super) fn evaluate_held(&self, p: [f64; 3], stride: usize, with_jac: bool) -> Evaluation {
        let nb = self.bands.len();
        let frames: Vec<usize> = (0..self.frames.len()).step_by(stride.max(1)).collect();
        let nt = frames.len();
        let extra = self.prior_rows();
        let mut r = vec![0.0; nt * nb + extra];
        let mut jac = vec![[0.0; 3]; if with_jac { nt * nb + extra } else { 0 }];
        let mut rows = vec![BandRows::default(); nb];
        let mut free_rows = vec![vec![Row::default(); nt]; nb];
        let mut g = [[0.0; TERMS]; 2];
        let mut slopes = [FacetSlopes::default(); 2];
        let mut trig = TrigStepper::new(p);
        for (ti, &t) in frames.iter().enumerate() {
            let frame = &self.frames[t];
            self.basis_and_slopes_at(frame, &mut trig, &mut g, &mut slopes);
            for (b, band) in self.bands.iter().enumerate() {
                let m = dot22(&band.x, &g);
                let dm = model_slope(&band.x, &slopes);
                let (w, k) = (band.w[t], frame.inv_range2);
                let wk = w * k;
                r[ti * nb + b] = w * (band.y[t] - k * m);
                if with_jac {
                    jac[ti * nb + b] = [wk * dm[0], wk * dm[1], wk * dm[2]];
                }
                let row = self.nuisance_row(wk, &g, &slopes);
                match &self.held[b] {
                    Some(held) => rows[b].push(held, row, wk, &g, &slopes),
                    None => free_rows[b][ti] = row,
                }
            }
        }
        let mut prior_at = nt * nb;
        let mut free = Vec::with_capacity(nb);
        for b in 0..nb {
            let jac_b = with_jac.then_some(&mut jac[..]);
            free.push(match &self.held[b] {
                Some(held) => {
                    let c = project(
                        &rows[b],
                        held,
                        self.held_scale[b],
                        |t| t * nb + b,
                        prior_at,
                        &mut r,
                        jac_b,
                    );
                    prior_at += held.rows();
                    c
                }
                None => project_band(&free_rows[b], |t| t * nb + b, &mut r, jac_b),
            });
        }
        let cost = r.iter().map(|v| v * v).sum();
        Evaluation { r, jac, cost, free }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deterministic pseudo-random numbers in [−1, 1).
    fn numbers(seed: u64, n: usize) -> Vec<f64> {
        let mut state = seed;
        (0..n)
            .map(|_| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                (state >> 11) as f64 / (1u64 << 52) as f64 - 1.0
            })
            .collect()
    }

    /// A band of `t_len` rows: three free columns (two zero, as without a re-fitted lobe),
    /// k held columns, a residual r⁰ and a covariance `cov_scale²·(M Mᵀ + I)`.
    fn band(t_len: usize, k: usize, cov_scale: f64) -> (BandRows, Held, Vec<f64>) {
        let x = numbers(0x2545_f491_4f6c_dd1d, t_len * (NUISANCE + k + 1) + k * k);
        let mut rows = BandRows::default();
        for t in 0..t_len {
            let at = &x[t * (NUISANCE + k + 1)..];
            let mut a = [0.0; NUISANCE];
            a[..3].copy_from_slice(&at[..3]);
            rows.a.push(a);
            rows.da.push([[0.0; 3]; NUISANCE]);
            rows.g.push(at[NUISANCE..NUISANCE + k].to_vec());
            rows.dg.push(vec![[0.0; 3]; k]);
        }
        let r0: Vec<f64> = (0..t_len)
            .map(|t| 3.0 * x[t * (NUISANCE + k + 1) + NUISANCE + k])
            .collect();
        let m = DMatrix::from_row_slice(k, k, &x[t_len * (NUISANCE + k + 1)..]);
        let cov = (&m * m.transpose() + DMatrix::identity(k, k)) * cov_scale.powi(2);
        let l = cov.cholesky().expect("positive definite").l();
        let held = Held {
            idx: (0..k).collect(),
            l,
        };
        (rows, held, r0)
    }

    /// The profiled cost against the marginal likelihood of the data with the held
    /// coefficients integrated out: with P⊥ the projection off the free columns,
    /// `ε = (P⊥r⁰)ᵀ (I + P⊥B Cov BᵀP⊥)⁻¹ (P⊥r⁰)` (a dense T × T solve).
    #[test]
    fn cost_is_the_marginal_likelihood_with_the_coefficients_integrated_out() {
        let (t_len, k) = (40, 4);
        let (rows, held, r0) = band(t_len, k, 0.7);
        let mut r_full = vec![0.0; t_len + k];
        r_full[..t_len].copy_from_slice(&r0);
        project(&rows, &held, 1.0, |t| t, t_len, &mut r_full, None);
        let cost: f64 = r_full.iter().map(|v| v * v).sum();

        let a = DMatrix::from_fn(t_len, 3, |t, j| rows.a[t][j]);
        let perp = DMatrix::identity(t_len, t_len)
            - &a * (a.transpose() * &a).try_inverse().expect("full rank") * a.transpose();
        let b = DMatrix::from_fn(t_len, k, |t, j| rows.g[t][j]);
        let cov = &held.l * held.l.transpose();
        let r1 = &perp * DVector::from_vec(r0);
        let b1 = &perp * b;
        let s = DMatrix::identity(t_len, t_len) + &b1 * cov * b1.transpose();
        let expected = r1.dot(&s.lu().solve(&r1).expect("invertible"));
        assert!(
            (cost - expected).abs() < 1e-10 * expected,
            "{cost} vs {expected}"
        );
    }

    /// With a vanishing covariance the held coefficients cannot move: the cost and the free
    /// coefficients are the plain projection's ([`project_band`]).
    #[test]
    fn a_vanishing_prior_is_the_plain_projection() {
        let (t_len, k) = (30, 3);
        let (rows, held, r0) = band(t_len, k, 1e-9);
        let mut r = r0.clone();
        r.resize(t_len + k, 0.0);
        let free = project(&rows, &held, 1.0, |t| t, t_len, &mut r, None);
        let plain_rows: Vec<Row> = rows
            .a
            .iter()
            .map(|a| Row {
                a: *a,
                da: [[0.0; 3]; NUISANCE],
            })
            .collect();
        let mut plain = r0;
        let plain_free = project_band(&plain_rows, |t| t, &mut plain, None);
        let cost: f64 = r.iter().map(|v| v * v).sum();
        let plain_cost: f64 = plain.iter().map(|v| v * v).sum();
        assert!(
            (cost - plain_cost).abs() < 1e-9 * plain_cost,
            "{cost} vs {plain_cost}"
        );
        for j in 0..3 {
            assert!(
                (free[j] - plain_free[j]).abs() < 1e-6,
                "{free:?} vs {plain_free:?}"
            );
        }
    }
}
