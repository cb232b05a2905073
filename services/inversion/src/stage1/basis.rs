//! Stage-1 basis selection (beyond the paper): which of the broad lobes the stable window can
//! support.
//!
//! Over the stable geometry the broad Beckmann lobes look almost Lambertian: the angle between
//! a lobe's column of G and the diffuse column shrinks with the width μ (on the cube scenarios
//! sin θ ≈ 0.41 / 0.20 / 0.003 for μ = 0.2 / 0.3 / 0.5). When noise is present, NNLS then moves
//! diffuse light into those lobes at random, the positivity bound keeps them there, and stage 3
//! turns a light that does not exist into a rate bias (noisy Z joint fit: w_z 0.22 against the
//! noise-free 0.248 in every seed). The basis is therefore chosen by a nested test on the data:
//!
//! ```text
//! S_0 = all 2 × 11 columns;  S_d = S_0 without the d widest lobes of both facets (d = 1, 2, …)
//! s_b² = RSS_b(S_0) / (T − |P_b|)                       band b's residual variance in S_0
//! Δχ²_d = Σ_b (RSS_b(S_d) − RSS_b(S_0)) / s_b²          evidence for the dropped lobes
//! k_d   = Σ_b #{dropped columns with x_b > 0 in S_0}    the parameters that were in use
//! accept S_d while Δχ²_d ≤ k_d + z·sqrt(2 k_d)          (z = `basis_test_sigmas`, 3)
//! ```
//!
//! The widest lobes go first and the first rejection stops the search, so a lobe the data need
//! (the μ = 0.2 lobe of the physical materials) and every narrower one stay. Lobes that were
//! not in use cost nothing to drop (k = 0, Δχ² = 0: the optimum is unchanged). On noise-free
//! data s_b² is the model mismatch, so a lobe that explains more than the mismatch's own scatter
//! stays; exact data keep every lobe they use. The narrowest lobe is never dropped. Dropping columns is exact on the
//! compressed system ([`NnlsSystem::solve_subset`]), so the search costs a few NNLS solves of
//! 22 unknowns per band.

use crate::error::NnlsError;
use crate::nnls::{NnlsSolution, NnlsSystem};
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

/// Runs the nested test from the full-basis solutions `full` (one per right-hand side of
/// `system`, `rows` samples each). Returns the choice and the solutions in the chosen basis.
pub fn select(
    system: &NnlsSystem,
    full: Vec<NnlsSolution>,
    rows: usize,
    test_sigmas: f64,
) -> Result<(BasisChoice, Vec<NnlsSolution>), NnlsError> {
    let facets = system.ncols() / TERMS_PER_FACET;
    let variance: Vec<f64> = full
        .iter()
        .map(|s| {
            let used = s.x.iter().filter(|v| **v > 0.0).count();
            s.residual_norm.powi(2) / rows.saturating_sub(used).max(1) as f64
        })
        .collect();
    let mut choice = BasisChoice::full();
    let mut chosen = full.clone();
    for dropped in 1..LOBES {
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
            let sol = system.solve_subset(b, &mask)?;
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
        chosen = solutions;
    }
    Ok((choice, chosen))
}
