//! Non-negative least squares by Lawson–Hanson (docs/math.md §1.4; Lawson & Hanson 1974, ch. 23).
//!
//! ```text
//! min_x ‖q − G x‖₂²   subject to   x ≥ 0
//! ```
//!
//! Preparation (§1.4):
//! - each column is scaled to unit 2-norm, `A_j = G_j/‖G_j‖`, and unscaled afterwards
//!   (`x_j = x̂_j/‖G_j‖`; a positive scaling preserves x ≥ 0); an all-zero column gets x_j = 0;
//! - `tol = 10·ε_mach·‖A‖₁·max(T, n)`;
//! - the problem is compressed exactly by one QR of the augmented matrix
//!   `[A | q] = Q [[R₁₁, r₁₂], [0, ρ]]`: `‖q − A x‖² = ‖r₁₂ − R₁₁ x‖² + ρ²` and
//!   `Aᵀ(q − Ax) = R₁₁ᵀ(r₁₂ − R₁₁x)`, so the active-set loop runs on an n×n system. Several
//!   right-hand sides with one G (one per band in stage 1) share that QR.
//!
//! Active-set loop (P passive set, w the dual / negative gradient):
//! ```text
//! P = ∅, x = 0, w = Aᵀ(q − Ax)
//! while some j ∉ P has w_j > tol:
//!     P ← P ∪ {argmax w_j};  z = argmin ‖q − A_P z‖ (z = 0 off P)
//!     while min_P z ≤ 0:
//!         α = min_{i∈P, z_i≤0} x_i/(x_i − z_i);  x ← x + α(z − x)
//!         P ← P \ {i : x_i ≤ tol};  re-solve z
//!     x = z;  w = Aᵀ(q − Ax)
//! ```
//! Degeneracy guard (LH step 6): a newly added column whose own z is ≤ 0 is dropped again and
//! blocked until x next changes. At the solution the KKT conditions hold: x ≥ 0, w_j ≤ tol on
//! the zero set and w_j ≈ 0 on the positive set. The sub-problems are solved on the compressed
//! system by Givens rotations (see `passive_ls`).

use crate::error::NnlsError;
use faer::{Mat, MatRef};

/// Result of one NNLS solve.
#[derive(Debug, Clone, PartialEq)]
pub struct NnlsSolution {
    /// Minimiser x ≥ 0, in the units of the original (unscaled) columns.
    pub x: Vec<f64>,
    /// ‖q − G x‖₂.
    pub residual_norm: f64,
    /// Final dual `w_j = A_jᵀ(q − Gx)` for the unit-norm columns `A_j = G_j/‖G_j‖` (0 for
    /// all-zero columns).
    pub dual_scaled: Vec<f64>,
    /// The tolerance `10·ε·‖A‖₁·max(T, n)` used on w and on the scaled x.
    pub tolerance: f64,
    /// Outer iterations (columns moved into the passive set).
    pub iterations: usize,
}

/// One design matrix G with one or more right-hand sides, column-scaled and compressed.
#[derive(Debug, Clone)]
pub struct NnlsSystem {
    col_norms: Vec<f64>,
    reduced: Mat<f64>,
    reduced_rhs: Mat<f64>,
    outside_sq: Vec<f64>,
    tol: f64,
}

impl NnlsSystem {
    /// Prepares `min ‖rhs_k − G x‖, x ≥ 0` for every column k of `rhs` (T × K).
    pub fn new(g: MatRef<'_, f64>, rhs: MatRef<'_, f64>) -> Result<Self, NnlsError> {
        let (rows, n) = (g.nrows(), g.ncols());
        if rhs.nrows() != rows {
            return Err(NnlsError::DimensionMismatch {
                rows,
                rhs_len: rhs.nrows(),
            });
        }
        let k = rhs.ncols();
        let finite = (0..n).all(|j| (0..rows).all(|i| g[(i, j)].is_finite()))
            && (0..k).all(|j| (0..rows).all(|i| rhs[(i, j)].is_finite()));
        if !finite {
            return Err(NnlsError::NonFinite);
        }
        let col_norms: Vec<f64> = (0..n)
            .map(|j| (0..rows).map(|i| g[(i, j)].powi(2)).sum::<f64>().sqrt())
            .collect();
        let inv = |j: usize| {
            if col_norms[j] > 0.0 {
                1.0 / col_norms[j]
            } else {
                0.0
            }
        };
        let a = Mat::from_fn(rows, n, |i, j| g[(i, j)] * inv(j));
        let norm1 = (0..n)
            .map(|j| (0..rows).map(|i| a[(i, j)].abs()).sum::<f64>())
            .fold(0.0, f64::max);
        let tol = 10.0 * f64::EPSILON * norm1 * rows.max(n) as f64;

        let aug = Mat::from_fn(
            rows,
            n + k,
            |i, j| {
                if j < n {
                    a[(i, j)]
                } else {
                    rhs[(i, j - n)]
                }
            },
        );
        // [A | q] = Q R: R is upper trapezoidal, min(rows, n + k) × (n + k).
        let qr = aug.qr();
        let r = qr.thin_R();
        let m = r.nrows();
        let reduced = Mat::from_fn(m.min(n), n, |i, j| if i <= j { r[(i, j)] } else { 0.0 });
        let reduced_rhs = Mat::from_fn(m.min(n), k, |i, j| r[(i, n + j)]);
        let outside_sq = (0..k)
            .map(|j| (n..m).map(|i| r[(i, n + j)].powi(2)).sum::<f64>())
            .collect();
        Ok(Self {
            col_norms,
            reduced,
            reduced_rhs,
            outside_sq,
            tol,
        })
    }

    /// Number of unknowns n.
    pub fn ncols(&self) -> usize {
        self.col_norms.len()
    }

    /// Number of right-hand sides.
    pub fn nrhs(&self) -> usize {
        self.reduced_rhs.ncols()
    }

    /// Solves the NNLS problem for right-hand side `k` (panics if `k ≥ nrhs()`).
    pub fn solve(&self, k: usize) -> Result<NnlsSolution, NnlsError> {
        self.solve_subset(k, &vec![true; self.ncols()])
    }

    /// Solves right-hand side `k` on the columns where `use_column` is true (the others are held
    /// at 0). Exact on the compressed system: dropping columns of `[A | q]` drops the same
    /// columns of its R factor, so no new QR is needed.
    pub fn solve_subset(&self, k: usize, use_column: &[bool]) -> Result<NnlsSolution, NnlsError> {
        let m = &self.reduced;
        let n = self.ncols();
        if use_column.len() != n {
            return Err(NnlsError::SubsetLength {
                columns: n,
                got: use_column.len(),
            });
        }
        let r: Vec<f64> = (0..m.nrows()).map(|i| self.reduced_rhs[(i, k)]).collect();
        let allowed: Vec<bool> = self
            .col_norms
            .iter()
            .zip(use_column)
            .map(|(&c, &u)| u && c > 0.0)
            .collect();
        let tol = self.tol;
        let max_outer = (3 * n).max(30);

        let mut x = vec![0.0; n];
        let mut passive = vec![false; n];
        let mut blocked = vec![false; n];
        let mut w = dual(m, &r, &x);
        let mut iterations = 0;
        loop {
            let pick = (0..n)
                .filter(|&j| allowed[j] && !passive[j] && !blocked[j] && w[j] > tol)
                .max_by(|&a, &b| w[a].total_cmp(&w[b]));
            let Some(j) = pick else { break };
            iterations += 1;
            if iterations > max_outer {
                return Err(NnlsError::IterationLimit { iterations });
            }
            passive[j] = true;
            let mut z = passive_ls(m, &r, &passive);
            if z[j] <= 0.0 {
                passive[j] = false;
                blocked[j] = true;
                continue;
            }
            let mut inner = 0;
            while (0..n).any(|i| passive[i] && z[i] <= 0.0) {
                inner += 1;
                if inner > n {
                    return Err(NnlsError::IterationLimit { iterations });
                }
                let alpha = (0..n)
                    .filter(|&i| passive[i] && z[i] <= 0.0)
                    .map(|i| x[i] / (x[i] - z[i]))
                    .fold(f64::INFINITY, f64::min);
                for i in 0..n {
                    if passive[i] {
                        x[i] += alpha * (z[i] - x[i]);
                        if x[i] <= tol {
                            passive[i] = false;
                            x[i] = 0.0;
                        }
                    }
                }
                z = passive_ls(m, &r, &passive);
            }
            x = z;
            blocked.fill(false);
            w = dual(m, &r, &x);
        }

        let resid_sq: f64 = residual(m, &r, &x).iter().map(|v| v * v).sum();
        let x_orig = x
            .iter()
            .zip(&self.col_norms)
            .map(|(&xi, &c)| if c > 0.0 { xi / c } else { 0.0 })
            .collect();
        Ok(NnlsSolution {
            x: x_orig,
            residual_norm: (resid_sq + self.outside_sq[k]).sqrt(),
            dual_scaled: w,
            tolerance: tol,
            iterations,
        })
    }
}

/// Solves `min ‖q − G x‖₂, x ≥ 0` (one right-hand side).
pub fn nnls(g: MatRef<'_, f64>, q: &[f64]) -> Result<NnlsSolution, NnlsError> {
    if q.len() != g.nrows() {
        return Err(NnlsError::DimensionMismatch {
            rows: g.nrows(),
            rhs_len: q.len(),
        });
    }
    let rhs = Mat::from_fn(q.len(), 1, |i, _| q[i]);
    NnlsSystem::new(g, rhs.as_ref())?.solve(0)
}

fn residual(m: &Mat<f64>, r: &[f64], x: &[f64]) -> Vec<f64> {
    (0..m.nrows())
        .map(|i| r[i] - (0..m.ncols()).map(|j| m[(i, j)] * x[j]).sum::<f64>())
        .collect()
}

fn dual(m: &Mat<f64>, r: &[f64], x: &[f64]) -> Vec<f64> {
    let res = residual(m, r, x);
    (0..m.ncols())
        .map(|j| (0..m.nrows()).map(|i| m[(i, j)] * res[i]).sum())
        .collect()
}

/// Unconstrained least squares on the passive columns; zero elsewhere.
///
/// The compressed system is upper trapezoidal (column j has no entry below row j), so its
/// passive columns, taken in order, form a staircase that Givens rotations of adjacent rows
/// bring to triangular form without fill-in: a column that follows d dropped ones takes d
/// rotations. Then back substitution; a zero pivot (a column exactly dependent on the ones
/// before it) leaves its unknown at 0.
fn passive_ls(m: &Mat<f64>, r: &[f64], passive: &[bool]) -> Vec<f64> {
    let rows = m.nrows();
    let cols: Vec<usize> = (0..passive.len()).filter(|&j| passive[j]).collect();
    let k = cols.len();
    let mut a: Vec<f64> = cols
        .iter()
        .flat_map(|&j| (0..rows).map(move |i| m[(i, j)]))
        .collect();
    let mut b = r.to_vec();
    let rank = k.min(rows);
    for i in 0..rank {
        for l in (i + 1..=cols[i].min(rows - 1)).rev() {
            let (x, y) = (a[i * rows + l - 1], a[i * rows + l]);
            if y == 0.0 {
                continue;
            }
            let h = (x * x + y * y).sqrt();
            let (c, s) = (x / h, y / h);
            let rotate = |u: &mut f64, v: &mut f64| {
                (*u, *v) = (c * *u + s * *v, c * *v - s * *u);
            };
            for col in a[i * rows..].chunks_exact_mut(rows) {
                let (upper, lower) = col.split_at_mut(l);
                rotate(&mut upper[l - 1], &mut lower[0]);
            }
            let (upper, lower) = b.split_at_mut(l);
            rotate(&mut upper[l - 1], &mut lower[0]);
        }
    }
    let mut y = vec![0.0; k];
    for j in (0..rank).rev() {
        let d = a[j * rows + j];
        if d != 0.0 {
            let s: f64 = (j + 1..rank).map(|c| a[c * rows + j] * y[c]).sum();
            y[j] = (b[j] - s) / d;
        }
    }
    let mut z = vec![0.0; passive.len()];
    for (&j, &yj) in cols.iter().zip(&y) {
        z[j] = yj;
    }
    z
}

#[cfg(test)]
mod tests {
    use super::*;
    use faer::linalg::solvers::SolveLstsq;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn random_matrix(rng: &mut ChaCha8Rng, rows: usize, cols: usize) -> Mat<f64> {
        Mat::from_fn(rows, cols, |_, _| rng.random_range(-1.0..1.0))
    }

    fn matvec(g: &Mat<f64>, x: &[f64]) -> Vec<f64> {
        (0..g.nrows())
            .map(|i| (0..g.ncols()).map(|j| g[(i, j)] * x[j]).sum())
            .collect()
    }

    /// KKT in the scaled problem, recomputed from the original G.
    fn assert_kkt(g: &Mat<f64>, q: &[f64], sol: &NnlsSolution, slack: f64) {
        let res: Vec<f64> = matvec(g, &sol.x)
            .iter()
            .zip(q)
            .map(|(gx, qi)| qi - gx)
            .collect();
        let qn = q.iter().map(|v| v * v).sum::<f64>().sqrt().max(1.0);
        for j in 0..g.ncols() {
            assert!(sol.x[j] >= 0.0, "x[{j}] = {}", sol.x[j]);
            let cn = (0..g.nrows())
                .map(|i| g[(i, j)].powi(2))
                .sum::<f64>()
                .sqrt();
            if cn == 0.0 {
                assert_eq!(sol.x[j], 0.0);
                continue;
            }
            let w = (0..g.nrows()).map(|i| g[(i, j)] * res[i]).sum::<f64>() / cn;
            if sol.x[j] > 0.0 {
                assert!(w.abs() <= slack * qn, "positive set w[{j}] = {w:e}");
            } else {
                assert!(w <= slack * qn, "zero set w[{j}] = {w:e}");
            }
        }
    }

    #[test]
    fn kkt_holds_on_random_problems() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        for (rows, cols) in [(40, 8), (200, 22), (15, 22), (22, 22), (60, 30)] {
            for _ in 0..5 {
                let g = random_matrix(&mut rng, rows, cols);
                let q: Vec<f64> = (0..rows).map(|_| rng.random_range(-1.0..1.0)).collect();
                let sol = nnls(g.as_ref(), &q).expect("nnls");
                assert_kkt(&g, &q, &sol, 1e-10);
            }
        }
    }

    /// A column subset on the shared compressed system equals a fresh NNLS on G without those
    /// columns (its own scaling and QR), solution and residual.
    #[test]
    fn column_subset_equals_nnls_on_the_reduced_matrix() {
        let mut rng = ChaCha8Rng::seed_from_u64(21);
        let (rows, cols, rhs) = (150, 22, 3);
        let g = random_matrix(&mut rng, rows, cols);
        let q = random_matrix(&mut rng, rows, rhs);
        let system = NnlsSystem::new(g.as_ref(), q.as_ref()).expect("system");
        let keep: Vec<bool> = (0..cols).map(|c| c % 11 < 8).collect();
        let kept: Vec<usize> = (0..cols).filter(|&c| keep[c]).collect();
        let reduced = Mat::from_fn(rows, kept.len(), |i, j| g[(i, kept[j])]);
        for k in 0..rhs {
            let sub = system.solve_subset(k, &keep).expect("subset");
            let qk: Vec<f64> = (0..rows).map(|i| q[(i, k)]).collect();
            let direct = nnls(reduced.as_ref(), &qk).expect("direct");
            for (j, &c) in kept.iter().enumerate() {
                assert!((sub.x[c] - direct.x[j]).abs() < 1e-10, "rhs {k} column {c}");
            }
            assert!((0..cols).filter(|&c| !keep[c]).all(|c| sub.x[c] == 0.0));
            assert!((sub.residual_norm - direct.residual_norm).abs() < 1e-10);
        }
        assert!(matches!(
            system.solve_subset(0, &keep[..5]),
            Err(NnlsError::SubsetLength {
                columns: 22,
                got: 5
            })
        ));
    }

    #[test]
    fn recovers_known_sparse_nonnegative_solution() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        for _ in 0..10 {
            let (rows, cols) = (120, 22);
            let g = random_matrix(&mut rng, rows, cols);
            let x_true: Vec<f64> = (0..cols)
                .map(|_| {
                    if rng.random_range(0.0..1.0) < 0.4 {
                        rng.random_range(0.1..2.0)
                    } else {
                        0.0
                    }
                })
                .collect();
            let q = matvec(&g, &x_true);
            let sol = nnls(g.as_ref(), &q).expect("nnls");
            for (a, b) in sol.x.iter().zip(&x_true) {
                assert!((a - b).abs() < 1e-10, "{a} vs {b}");
            }
            assert!(sol.residual_norm < 1e-10);
        }
    }

    #[test]
    fn equals_unconstrained_ls_when_that_is_positive() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let (rows, cols) = (80, 6);
        let g = random_matrix(&mut rng, rows, cols);
        let x0 = [1.0, 2.0, 0.5, 3.0, 1.5, 0.8];
        let q: Vec<f64> = matvec(&g, &x0)
            .iter()
            .map(|v| v + 0.05 * rng.random_range(-1.0..1.0))
            .collect();
        let rhs = Mat::from_fn(rows, 1, |i, _| q[i]);
        let ls = g.qr().solve_lstsq(rhs);
        assert!((0..cols).all(|j| ls[(j, 0)] > 0.0));
        let sol = nnls(g.as_ref(), &q).expect("nnls");
        for j in 0..cols {
            assert!((sol.x[j] - ls[(j, 0)]).abs() < 1e-12 * (1.0 + ls[(j, 0)].abs()));
        }
    }

    #[test]
    fn zero_columns_and_negative_targets() {
        let mut g = Mat::from_fn(10, 3, |i, j| ((i + 1) * (j + 2)) as f64 % 7.0 + 1.0);
        for i in 0..10 {
            g[(i, 1)] = 0.0;
        }
        let q: Vec<f64> = (0..10).map(|i| -(i as f64) - 1.0).collect();
        let sol = nnls(g.as_ref(), &q).expect("nnls");
        assert!(sol.x.iter().all(|&v| v == 0.0));
        assert_eq!(sol.iterations, 0);
        assert_kkt(&g, &q, &sol, 1e-12);
    }

    #[test]
    fn shared_system_matches_single_solves() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let g = random_matrix(&mut rng, 50, 7);
        let rhs = random_matrix(&mut rng, 50, 3);
        let sys = NnlsSystem::new(g.as_ref(), rhs.as_ref()).expect("system");
        for k in 0..3 {
            let q: Vec<f64> = (0..50).map(|i| rhs[(i, k)]).collect();
            let a = sys.solve(k).expect("shared");
            let b = nnls(g.as_ref(), &q).expect("single");
            for (u, v) in a.x.iter().zip(&b.x) {
                assert!((u - v).abs() < 1e-12);
            }
            assert!((a.residual_norm - b.residual_norm).abs() < 1e-12);
        }
    }

    #[test]
    fn rejects_bad_input() {
        let g = Mat::from_fn(4, 2, |i, j| (i + j) as f64);
        assert!(matches!(
            nnls(g.as_ref(), &[1.0, 2.0]),
            Err(NnlsError::DimensionMismatch {
                rows: 4,
                rhs_len: 2
            })
        ));
        assert_eq!(
            nnls(g.as_ref(), &[1.0, f64::NAN, 0.0, 0.0]),
            Err(NnlsError::NonFinite)
        );
    }
}
