//! Stage-1 basis selection (beyond the paper): which of the broad lobes the stable window can
//! support.
//!
//! Over the stable geometry the broad Beckmann lobes look almost Lambertian: the angle between
//! a lobe's column of G and the diffuse column shrinks with the width μ (on the cube scenarios
//! sin θ ≈ 0.41 / 0.20 / 0.003 for μ = 0.2 / 0.3 / 0.5). When noise is present, NNLS then moves
//! diffuse light into those lobes at random, the positivity bound keeps them there, and stage 3
//! turns a light that does not exist into a rate bias (noisy Z joint fit: w_z 0.22 against the
//! noise-free 0.248 in every seed). Such a lobe is a candidate for leaving the basis when its
//! column is collinear with the diffuse one by the usual rule of thumb, a variance inflation
//! factor VIF = 1/(1 − cos²θ) ≥ 10 (`basis_min_vif`; 5.9 / 25 / 1e5 for μ = 0.2 / 0.3 / 0.5
//! here). Lobes the stable window can resolve stay whatever their support: at low SNR the data
//! support few lobes, but dropping a resolvable one that is really there (the cell's μ = 0.2)
//! misplaces its light and cost the Z joint fit its sense of rotation at SNR 3 and 5. Among the
//! candidates, the data decide by a nested test:
//!
//! ```text
//! S_0 = all 2 × 11 columns;  S_d = S_0 without the d widest lobes of both facets (d = 1, 2, …,
//!       while those lobes are candidates)
//! s_b² = RSS_b(S_0) / (T − |P_b|)                       band b's residual variance in S_0
//! Δχ²_d = Σ_b (RSS_b(S_d) − RSS_b(S_0)) / s_b²          evidence for the dropped lobes
//! k_d   = Σ_b #{dropped columns with x_b > 0 in S_0}    the parameters that were in use
//! accept S_d while Δχ²_d ≤ k_d + z·sqrt(2 k_d)          (z = `basis_test_sigmas`, 3)
//! ```
//!
//! The widest lobes go first and the first rejection stops the search, so a lobe the data need
//! and every narrower one stay. Lobes that were not in use cost nothing to drop (k = 0,
//! Δχ² = 0: the optimum is unchanged). On noise-free data s_b² is the model mismatch, so a lobe
//! that explains more than the mismatch's own scatter stays; exact data keep every lobe they
//! use. The narrowest lobe is never dropped. Dropping columns is exact on the compressed system
//! ([`NnlsSystem::solve_subset`]), so the search costs a few NNLS solves of 22 unknowns per
//! band.

use crate::error::NnlsError;
use crate::nnls::{NnlsSolution, NnlsSystem};
use faer::MatRef;
use glint_physics::brdf::LOBE_WIDTHS_TABLE4;
use glint_physics::two_facet::TERMS_PER_FACET;
use serde::{Deserialize, Serialize};

/// The basis stage 1 settled on and the test that chose it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BasisChoice {
    /// Lobes kept per facet (the narrowest ones), of 10.
    pub lobes_kept: usize,
    /// Width μ of the widest lobe kept.
    pub widest_lobe_mu: f64,
    /// Δχ² and k of the last accepted reduction (0 when none was tested or accepted).
    pub delta_chi2: f64,
    pub dof: usize,
    /// Δχ² and k of the first rejected reduction, if one was rejected.
    pub rejected_delta_chi2: Option<f64>,
    pub rejected_dof: Option<usize>,
}

impl Default for BasisChoice {
    fn default() -> Self {
        Self::full()
    }
}

impl BasisChoice {
    /// The whole basis (no selection run).
    pub fn full() -> Self {
        BasisChoice {
            lobes_kept: LOBES,
            widest_lobe_mu: LOBE_WIDTHS_TABLE4[LOBES - 1],
            delta_chi2: 0.0,
            dof: 0,
            rejected_delta_chi2: None,
            rejected_dof: None,
        }
    }
}

const LOBES: usize = TERMS_PER_FACET - 1;

/// Columns used when the `dropped` widest lobes of both facets are left out.
pub fn column_mask(dropped: usize, facets: usize) -> Vec<bool> {
    (0..facets * TERMS_PER_FACET)
        .map(|c| c % TERMS_PER_FACET < TERMS_PER_FACET - dropped)
        .collect()
}

/// Variance inflation of each column of G against its facet's diffuse column,
/// `1/(1 − cos²θ)` with θ the angle between the two columns (∞ for a column parallel to it, 1
/// for the diffuse column itself and for an all-zero column).
pub fn diffuse_vif(g: MatRef<'_, f64>) -> Vec<f64> {
    let dot = |a: usize, b: usize| (0..g.nrows()).map(|i| g[(i, a)] * g[(i, b)]).sum::<f64>();
    (0..g.ncols())
        .map(|c| {
            let d = c - c % TERMS_PER_FACET;
            let (cc, dd) = (dot(c, c), dot(d, d));
            if c == d || cc == 0.0 || dd == 0.0 {
                return 1.0;
            }
            let cos2 = (dot(c, d).powi(2) / (cc * dd)).min(1.0);
            1.0 / (1.0 - cos2)
        })
        .collect()
}

/// How many of the widest lobes are candidates: the run of lobes, from the widest down, whose
/// columns (in every facet) have a variance inflation ≥ `min_vif` against the diffuse column.
pub fn candidate_count(vif: &[f64], min_vif: f64) -> usize {
    let facets = vif.len() / TERMS_PER_FACET;
    (1..LOBES)
        .take_while(|&dropped| {
            let lobe = TERMS_PER_FACET - dropped;
            (0..facets).all(|f| vif[f * TERMS_PER_FACET + lobe] >= min_vif)
        })
        .count()
}

/// Runs the nested test from the full-basis solutions `full` (one per right-hand side of
/// `system`, `rows` samples each) over the `candidates` widest lobes. Returns the choice and
/// the solutions in the chosen basis; an NNLS failure comes with its right-hand side.
pub fn select(
    system: &NnlsSystem,
    full: Vec<NnlsSolution>,
    rows: usize,
    candidates: usize,
    test_sigmas: f64,
) -> Result<(BasisChoice, Vec<NnlsSolution>), (usize, NnlsError)> {
    let facets = system.ncols() / TERMS_PER_FACET;
    let variance: Vec<f64> = full
        .iter()
        .map(|s| {
            let used = s.x.iter().filter(|v| **v > 0.0).count();
            s.residual_norm.powi(2) / rows.saturating_sub(used).max(1) as f64
        })
        .collect();
    let mut choice = BasisChoice::full();
    let mut chosen = None;
    for dropped in 1..=candidates.min(LOBES - 1) {
        let mask = column_mask(dropped, facets);
        let mut delta_chi2 = 0.0;
        let mut dof = 0;
        let mut solutions = Vec::with_capacity(full.len());
        for (b, base) in full.iter().enumerate() {
            let in_use = (0..mask.len())
                .filter(|&c| !mask[c] && base.x[c] > 0.0)
                .count();
            dof += in_use;
            if in_use == 0 {
                // The full optimum is feasible without those columns, hence still optimal.
                solutions.push(base.clone());
                continue;
            }
            let sol = system.solve_subset(b, &mask).map_err(|e| (b, e))?;
            let increase = (sol.residual_norm.powi(2) - base.residual_norm.powi(2)).max(0.0);
            delta_chi2 += if variance[b] > 0.0 {
                increase / variance[b]
            } else if increase > 0.0 {
                f64::INFINITY
            } else {
                0.0
            };
            solutions.push(sol);
        }
        let threshold = dof as f64 + test_sigmas * (2.0 * dof as f64).sqrt();
        if delta_chi2 > threshold {
            choice.rejected_delta_chi2 = Some(delta_chi2);
            choice.rejected_dof = Some(dof);
            break;
        }
        choice.lobes_kept = LOBES - dropped;
        choice.widest_lobe_mu = LOBE_WIDTHS_TABLE4[LOBES - dropped - 1];
        choice.delta_chi2 = delta_chi2;
        choice.dof = dof;
        chosen = Some(solutions);
    }
    Ok((choice, chosen.unwrap_or(full)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use faer::Mat;

    #[test]
    fn vif_of_parallel_orthogonal_and_oblique_columns() {
        // Facet 0: diffuse e0; lobe 1 parallel (2·e0), lobe 2 orthogonal (e1), lobe 3 at 60°.
        let g = Mat::from_fn(3, 2 * TERMS_PER_FACET, |i, c| match (c, i) {
            (0, 0) => 1.0,
            (1, 0) => 2.0,
            (2, 1) => 1.0,
            (3, 0) => 0.5,
            (3, 1) => 0.75f64.sqrt(),
            _ => 0.0,
        });
        let vif = diffuse_vif(g.as_ref());
        assert_eq!(vif[0], 1.0);
        assert!(vif[1] > 1e12, "{}", vif[1]);
        assert!((vif[2] - 1.0).abs() < 1e-12);
        assert!((vif[3] - 4.0 / 3.0).abs() < 1e-12, "{}", vif[3]);
        // Facet 1 is all zero: VIF 1, never a candidate.
        assert!(vif[TERMS_PER_FACET..].iter().all(|v| *v == 1.0));
        assert_eq!(candidate_count(&vif, 10.0), 0);
    }
}
