//! Linear nuisance terms of the stage-3 fit, removed by variable projection (beyond the paper).
//!
//! Stage 1 cannot tell apart the diffuse light of the panel, of the observed body face and of
//! everything else (white-painted appendages, other faces): in the three-axis-stable window
//! their cosine factors are nearly collinear. Out-of-plane motion (rotation about Z) separates
//! them, and the rates are then fitted on the diffuse *decay*, so a wrong split biases p. With
//! `refit_diffuse`, stage 3 keeps the stage-1 lobes but re-estimates per band, at every p, the
//! three linear coefficients c of
//!
//! ```text
//! a_t = w_t k_t [G_0(n_p, s'_t, o'_t), G_0(n_b, s'_t, o'_t), 1]      k_t = 1/(‖T0_t‖² Φ̄)
//! ```
//!
//! (panel diffuse, body diffuse, and a constant-intensity remainder). With r⁰ the residual of
//! the lobe-only model and A the T × 3 matrix of the a_t:
//!
//! ```text
//! c(p) = (AᵀA)⁻¹ Aᵀ r⁰,   r = r⁰ − A c = P⊥ r⁰                        (variable projection)
//! J_i = P⊥ (J⁰_i + ∂A_i c) + A (AᵀA)⁻¹ ∂A_iᵀ r                          (Golub–Pereyra)
//! ε = r⁰ᵀr⁰ − (Aᵀr⁰)ᵀ (AᵀA)⁻¹ (Aᵀr⁰)
//! ```
//!
//! with J = −∂r/∂p as everywhere in stage 3 and ∂A_i = ∂A/∂p_i. The Jacobian is the exact
//! derivative of the projected residual (tested against central differences).
//!
//! A column that is zero over the window (a facet never lit and visible) gets c = 0: AᵀA is
//! equilibrated and solved with a ridge of 1e-12.

/// Nuisance columns per band.
pub const NUISANCE: usize = 5;

/// Per-band sums `AᵀA`, `Aᵀr⁰`, `r⁰ᵀr⁰` for the cost-only path.
#[derive(Debug, Clone, Copy, Default)]
pub struct Normal {
    pub ata: [[f64; NUISANCE]; NUISANCE],
    pub atr: [f64; NUISANCE],
    pub rtr: f64,
}

impl Normal {
    /// Adds one residual r⁰ with its column row a.
    pub fn add(&mut self, a: &[f64; NUISANCE], r0: f64) {
        for i in 0..NUISANCE {
            self.atr[i] += a[i] * r0;
            for j in 0..NUISANCE {
                self.ata[i][j] += a[i] * a[j];
            }
        }
        self.rtr += r0 * r0;
    }

    /// The least-squares coefficients c.
    pub fn coefficients(&self) -> [f64; NUISANCE] {
        solve_ridge(&self.ata, &self.atr)
    }

    /// The projected cost `r⁰ᵀr⁰ − (Aᵀr⁰)ᵀc` (never below 0).
    pub fn projected_cost(&self) -> f64 {
        let c = self.coefficients();
        let explained: f64 = (0..NUISANCE).map(|i| self.atr[i] * c[i]).sum();
        (self.rtr - explained).max(0.0)
    }
}

/// Solves `M x = b` for symmetric positive semi-definite M (3 × 3): M is equilibrated to unit
/// diagonal and a ridge of 1e-12 added, so a zero column gets x = 0 and nearly collinear
/// columns stay finite.
pub fn solve_ridge(m: &[[f64; NUISANCE]; NUISANCE], b: &[f64; NUISANCE]) -> [f64; NUISANCE] {
    let mut d = [0.0; NUISANCE];
    for i in 0..NUISANCE {
        d[i] = if m[i][i] > 0.0 && m[i][i].is_finite() {
            1.0 / m[i][i].sqrt()
        } else {
            0.0
        };
    }
    let mut a = [[0.0; NUISANCE]; NUISANCE];
    let mut x = [0.0; NUISANCE];
    for i in 0..NUISANCE {
        for j in 0..NUISANCE {
            a[i][j] = d[i] * m[i][j] * d[j];
        }
        a[i][i] += RIDGE;
        x[i] = d[i] * b[i];
    }
    // Gaussian elimination with partial pivoting (3 × 3).
    for col in 0..NUISANCE {
        let pivot = (col..NUISANCE)
            .max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))
            .unwrap_or(col);
        a.swap(col, pivot);
        x.swap(col, pivot);
        let p = a[col][col];
        if p.abs() <= f64::MIN_POSITIVE {
            return [0.0; NUISANCE];
        }
        let pivot_row = a[col];
        for row in col + 1..NUISANCE {
            let f = a[row][col] / p;
            for (v, pv) in a[row][col..].iter_mut().zip(&pivot_row[col..]) {
                *v -= f * pv;
            }
            x[row] -= f * x[col];
        }
    }
    for col in (0..NUISANCE).rev() {
        let s: f64 = (col + 1..NUISANCE).map(|k| a[col][k] * x[k]).sum();
        x[col] = (x[col] - s) / a[col][col];
    }
    std::array::from_fn(|i| d[i] * x[i])
}

/// Ridge on the equilibrated normal matrix (unit diagonal).
const RIDGE: f64 = 1e-12;

/// One residual's data for the full projection.
#[derive(Debug, Clone, Copy, Default)]
pub struct Row {
    /// Column row a_t.
    pub a: [f64; NUISANCE],
    /// ∂a_k/∂p_i.
    pub da: [[f64; 3]; NUISANCE],
}

/// Projects one band's residuals and Jacobian rows in place (`r` holds r⁰ and `jac` J⁰ on
/// entry; `index(t)` maps the band's t-th row into them). Returns the band's coefficients c.
pub fn project_band(
    rows: &[Row],
    index: impl Fn(usize) -> usize,
    r: &mut [f64],
    jac: Option<&mut [[f64; 3]]>,
) -> [f64; NUISANCE] {
    let mut normal = Normal::default();
    for (t, row) in rows.iter().enumerate() {
        normal.add(&row.a, r[index(t)]);
    }
    let c = normal.coefficients();
    for (t, row) in rows.iter().enumerate() {
        let k = index(t);
        r[k] -= (0..NUISANCE).map(|i| row.a[i] * c[i]).sum::<f64>();
    }
    let Some(jac) = jac else {
        return c;
    };
    // J = J⁰ + Σ c_k ∂a_k/∂p, then J ← J − A (AᵀA)⁻¹ (AᵀJ − ∂Aᵀr).
    let mut atj = [[0.0; 3]; NUISANCE];
    for (t, row) in rows.iter().enumerate() {
        let k = index(t);
        for i in 0..3 {
            jac[k][i] += (0..NUISANCE).map(|m| c[m] * row.da[m][i]).sum::<f64>();
            for (m, atj_m) in atj.iter_mut().enumerate() {
                atj_m[i] += row.a[m] * jac[k][i] - row.da[m][i] * r[k];
            }
        }
    }
    let mut coef = [[0.0; 3]; NUISANCE]; // (AᵀA)⁻¹ (AᵀJ − ∂Aᵀr), column by column
    for i in 0..3 {
        let x = solve_ridge(&normal.ata, &std::array::from_fn(|m| atj[m][i]));
        for m in 0..NUISANCE {
            coef[m][i] = x[m];
        }
    }
    for (t, row) in rows.iter().enumerate() {
        let k = index(t);
        for i in 0..3 {
            jac[k][i] -= (0..NUISANCE).map(|m| row.a[m] * coef[m][i]).sum::<f64>();
        }
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ridge_solve_matches_a_known_system() {
        // Tridiagonal, diagonally dominant: b = M x for a known x.
        let m: [[f64; NUISANCE]; NUISANCE] = std::array::from_fn(|i| {
            std::array::from_fn(|j| match i.abs_diff(j) {
                0 => 4.0 + i as f64,
                1 => 1.0,
                _ => 0.0,
            })
        });
        let x_true: [f64; NUISANCE] = std::array::from_fn(|i| [1.0, -2.0, 0.5, 3.0, -0.25][i]);
        let b: [f64; NUISANCE] =
            std::array::from_fn(|i| (0..NUISANCE).map(|j| m[i][j] * x_true[j]).sum());
        let x = solve_ridge(&m, &b);
        for i in 0..NUISANCE {
            assert!((x[i] - x_true[i]).abs() < 1e-9, "{x:?}");
        }
    }

    /// A synthetic problem: a_t(p) = a0_t + Σ_i p_i a1_{t,i}, r⁰_t(p) = y_t − Σ_i p_i g_{t,i}
    /// − ½ Σ_i p_i² h_{t,i}; the projected residual's Jacobian against central differences.
    #[test]
    fn projected_jacobian_matches_central_differences() {
        const T: usize = 25;
        // Deterministic pseudo-random numbers in [−1, 1).
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut rnd = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 52) as f64 - 1.0
        };
        let mut gen = |n: usize| (0..n).map(|_| rnd()).collect::<Vec<f64>>();
        let (a0, a1, y, g, h) = (
            gen(T * NUISANCE),
            gen(T * NUISANCE * 3),
            gen(T),
            gen(T * 3),
            gen(T * 3),
        );
        let eval = |p: [f64; 3], with_jac: bool| {
            let mut rows = vec![Row::default(); T];
            let mut r = vec![0.0; T];
            let mut jac = vec![[0.0; 3]; T];
            for t in 0..T {
                for m in 0..NUISANCE {
                    let k = (t * NUISANCE + m) * 3;
                    rows[t].a[m] =
                        a0[t * NUISANCE + m] + (0..3).map(|i| p[i] * a1[k + i]).sum::<f64>();
                    rows[t].da[m].copy_from_slice(&a1[k..k + 3]);
                }
                r[t] = y[t]
                    - (0..3)
                        .map(|i| p[i] * g[t * 3 + i] + 0.5 * p[i] * p[i] * h[t * 3 + i])
                        .sum::<f64>();
                for i in 0..3 {
                    jac[t][i] = g[t * 3 + i] + p[i] * h[t * 3 + i];
                }
            }
            project_band(&rows, |t| t, &mut r, with_jac.then_some(&mut jac[..]));
            (r, jac)
        };
        let p = [0.3, -0.2, 0.5];
        let (_, jac) = eval(p, true);
        let step = 1e-6;
        for i in 0..3 {
            let (mut pp, mut pm) = (p, p);
            pp[i] += step;
            pm[i] -= step;
            let (rp, rm) = (eval(pp, false).0, eval(pm, false).0);
            for t in 0..T {
                let fd = -(rp[t] - rm[t]) / (2.0 * step);
                assert!(
                    (fd - jac[t][i]).abs() < 1e-7,
                    "t {t} i {i}: {fd} vs {}",
                    jac[t][i]
                );
            }
        }
    }

    #[test]
    fn zero_column_gets_zero_coefficient() {
        let mut n = Normal::default();
        for t in 0..10 {
            let a = [t as f64, 0.0, 1.0, 0.0, 0.0];
            n.add(&a, 2.0 * t as f64 + 3.0);
        }
        let c = n.coefficients();
        assert!((c[0] - 2.0).abs() < 1e-6, "{c:?}");
        assert!(c[1].abs() < 1e-12, "{c:?}");
        assert!((c[2] - 3.0).abs() < 1e-6, "{c:?}");
        // Cancellation in r⁰ᵀr⁰ − (Aᵀr⁰)ᵀc: relative to r⁰ᵀr⁰.
        assert!(n.projected_cost() < 1e-9 * n.rtr, "{}", n.projected_cost());
    }
}
