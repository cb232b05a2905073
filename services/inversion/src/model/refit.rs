//! The stage-3 polish's re-fitted terms (ADR 0010): which coefficients the problem re-estimates
//! at every p, their nuisance columns and their projection ([`crate::nuisance`]), and the
//! bisector the polish holds.

use super::{BandData, Basis, FacetSlopes, RateProblem};
use crate::facet::TERMS;
use crate::nuisance::{project_band, Row, NUISANCE};

impl RateProblem {
    /// Whether the diffuse terms are re-estimated at every p ([`super::MotionModelConfig::refit_diffuse`]).
    pub fn refits_diffuse(&self) -> bool {
        self.refit_diffuse
    }

    /// Whether each facet's widest lobe is re-estimated too ([`super::MotionModelConfig::refit_widest_lobe`]).
    pub fn refits_widest_lobe(&self) -> bool {
        self.refit_lobes.iter().any(|&k| k > 0)
    }

    /// The sun–observer bisector in the body frame at the epoch (unit; the earliest frame's
    /// `normalize(s + o)`): the axis a rotation about which only the diffuse terms see.
    pub fn bisector_at_epoch(&self) -> [f64; 3] {
        let first = self
            .frames
            .iter()
            .min_by(|a, b| a.t_frames.total_cmp(&b.t_frames))
            .expect("a problem has frames");
        let h = (first.s + first.o).normalize();
        [h.x, h.y, h.z]
    }

    /// The nuisance coefficients per band at p in the problem's units (zeros without the re-fit).
    pub(super) fn nuisance_fit(&self, p: [f64; 3]) -> Vec<[f64; NUISANCE]> {
        let mut scratch = vec![0.0; self.residual_count()];
        self.residuals_with_nuisance(p, &mut scratch).1
    }

    /// Empty per-band rows for the nuisance projection (none without the re-fit).
    pub(super) fn nuisance_rows(&self) -> Vec<Vec<Row>> {
        if self.refit_diffuse {
            vec![vec![Row::default(); self.frames.len()]; self.bands.len()]
        } else {
            Vec::new()
        }
    }

    /// Applies the variable projection of every band; returns the coefficients c per band.
    pub(super) fn project(
        &self,
        rows: &[Vec<Row>],
        r: &mut [f64],
        mut jac: Option<&mut [[f64; 3]]>,
    ) -> Vec<[f64; NUISANCE]> {
        let nb = self.bands.len();
        if rows.is_empty() {
            return vec![[0.0; NUISANCE]; nb];
        }
        rows.iter()
            .enumerate()
            .map(|(b, band_rows)| project_band(band_rows, |t| t * nb + b, r, jac.as_deref_mut()))
            .collect()
    }

    /// The re-fitted nuisance coefficients per band at p (stage-1 units W·m², like x̃; the
    /// constant remainder in W·m² per sr⁻¹ of G), or zeros without the re-fit.
    pub fn nuisance_coefficients(&self, p: [f64; 3]) -> Vec<[f64; NUISANCE]> {
        self.nuisance_fit(p)
            .iter()
            .zip(&self.bands)
            .map(|(c, band)| c.map(|v| v * band.mean_flux_w))
            .collect()
    }
}

/// The widest lobe any band uses, per facet: zeroed in every band's stage-1 coefficients (the
/// problem re-fits it) and returned as that facet's re-fitted lobe (0: none).
pub(super) fn take_widest_lobes(data: &mut [BandData], active: &[[bool; TERMS]; 2]) -> [usize; 2] {
    let mut lobes = [0usize; 2];
    for f in 0..2 {
        if let Some(k) = (1..TERMS).rev().find(|&k| active[f][k]) {
            lobes[f] = k;
            for band in data.iter_mut() {
                band.x[f][k] = 0.0;
            }
        }
    }
    lobes
}

/// The nuisance column row `scale·[G_0(panel), G_0(body), 1, G_k(panel), G_k(body)]`, k the
/// re-fitted lobe of each facet (a zero column when none).
pub(super) fn nuisance_columns(scale: f64, g: &Basis, lobes: [usize; 2]) -> [f64; NUISANCE] {
    let lobe = |f: usize| {
        if lobes[f] > 0 {
            scale * g[f][lobes[f]]
        } else {
            0.0
        }
    };
    [scale * g[0][0], scale * g[1][0], scale, lobe(0), lobe(1)]
}

/// ∂(scale·G_k)/∂p of facet slopes `sl` for lobe k (zeros when k = 0).
pub(super) fn lobe_slope_of(sl: &FacetSlopes, k: usize, scale: f64) -> [f64; 3] {
    if k == 0 {
        return [0.0; 3];
    }
    sl.dc.map(|dc| scale * sl.lobe[k - 1] * dc)
}
