//! The stage-3 polish's re-fitted terms (ADR 0010): which coefficients the problem re-estimates
//! at every p, their nuisance columns and their projection ([`crate::nuisance`]), and the
//! bisector the polish holds.

use super::{BandData, Basis, FacetSlopes, RateBand, RateProblem};
use crate::facet::TERMS;
use crate::nuisance::{project_band, Row, NUISANCE};
use glint_physics::brdf::LOBE_WIDTHS_TABLE4;

impl RateProblem {
    /// Whether the diffuse terms are re-estimated at every p ([`super::MotionModelConfig::refit_diffuse`]).
    pub fn refits_diffuse(&self) -> bool {
        self.refit_diffuse
    }

    /// Whether each facet's widest lobe is re-estimated too ([`super::MotionModelConfig::refit_widest_lobe`]).
    pub fn refits_widest_lobe(&self) -> bool {
        self.refit_lobes.iter().any(|&k| k > 0)
    }

    /// The lobe re-fitted per facet (panel, body) as a term index, 0 for none.
    pub fn refit_lobes(&self) -> [usize; 2] {
        self.refit_lobes
    }

    /// Whether the widest-lobe re-fit was asked for but every facet's widest lobe in use is a
    /// glint lobe (narrower than [`BROAD_LOBE_MIN_MU`]), so only the diffuse terms are re-fitted.
    pub fn keeps_glint_lobes(&self) -> bool {
        self.glint_lobes_only
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

    /// The nuisance columns of one residual with their slopes, `scale = w k`.
    pub(super) fn nuisance_row(&self, scale: f64, g: &Basis, slopes: &[FacetSlopes; 2]) -> Row {
        Row {
            a: nuisance_columns(scale, g, self.refit_lobes),
            da: [
                slopes[0].d_diffuse.map(|d| scale * d),
                slopes[1].d_diffuse.map(|d| scale * d),
                [0.0; 3],
                lobe_slope_of(&slopes[0], self.refit_lobes[0], scale),
                lobe_slope_of(&slopes[1], self.refit_lobes[1], scale),
            ],
        }
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
}

/// Lobes at least this wide \[rms facet slope μ\] are broad: light spread over tens of degrees
/// (wrinkled film, a cell's grid), which the two-facet model places as poorly as the diffuse
/// light and which the stable window may weigh differently from the motion window
/// (the material data draw the line at μ = 0.2). A narrower lobe is the glint
/// itself: its amplitude sets the glint's height and apparent width, so re-fitting it trades
/// against the rate.
pub const BROAD_LOBE_MIN_MU: f64 = 0.2;

/// The widest lobe any band uses, per facet, when it is broad ([`BROAD_LOBE_MIN_MU`]): zeroed
/// in every band's stage-1 coefficients (the problem re-fits it) and returned as that facet's
/// re-fitted lobe (0: none, also when the facet's widest lobe is a glint lobe).
pub(super) fn take_widest_lobes(data: &mut [BandData], active: &[[bool; TERMS]; 2]) -> [usize; 2] {
    let mut lobes = [0usize; 2];
    for f in 0..2 {
        if let Some(k) = broad_widest_lobe(&active[f]) {
            lobes[f] = k;
            for band in data.iter_mut() {
                band.x[f][k] = 0.0;
            }
        }
    }
    lobes
}

/// Re-fits the given lobe of each facet (a term index, 0 for none) instead of choosing it: the
/// lobes a fit over more bands chose.
pub(super) fn take_lobes(
    data: &mut [BandData],
    active: &mut [[bool; TERMS]; 2],
    lobes: [usize; 2],
) -> [usize; 2] {
    for (f, &k) in lobes.iter().enumerate() {
        if (1..TERMS).contains(&k) {
            active[f][k] = true;
            for band in data.iter_mut() {
                band.x[f][k] = 0.0;
            }
        }
    }
    lobes.map(|k| if k < TERMS { k } else { 0 })
}

/// A facet's widest lobe in use (`active`: its terms any band uses), when it is broad.
fn broad_widest_lobe(active: &[bool; TERMS]) -> Option<usize> {
    (1..TERMS)
        .rev()
        .find(|&k| active[k])
        .filter(|&k| LOBE_WIDTHS_TABLE4[k - 1] >= BROAD_LOBE_MIN_MU)
}

/// Whether a widest-lobe re-fit of `bands` would re-fit anything: some facet's widest lobe in
/// use, over the bands' stage-1 coefficients, is broad.
pub fn broad_lobe_in_use(bands: &[RateBand]) -> bool {
    let mut active = [[false; TERMS]; 2];
    for band in bands {
        for (act, c) in active
            .iter_mut()
            .zip([&band.coeffs.panel, &band.coeffs.body])
        {
            for (a, v) in act.iter_mut().zip(c) {
                *a |= *v != 0.0;
            }
        }
    }
    active.iter().any(|a| broad_widest_lobe(a).is_some())
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
fn lobe_slope_of(sl: &FacetSlopes, k: usize, scale: f64) -> [f64; 3] {
    if k == 0 {
        return [0.0; 3];
    }
    sl.dc.map(|dc| scale * sl.lobe[k - 1] * dc)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn band(x: Basis) -> BandData {
        BandData {
            x,
            y: vec![],
            w: vec![],
            mean_flux_w: 1.0,
        }
    }

    /// Index of the lobe of width `mu` in the basis (the diffuse term is index 0).
    fn lobe(mu: f64) -> usize {
        1 + LOBE_WIDTHS_TABLE4.iter().position(|&m| m == mu).unwrap()
    }

    #[test]
    fn only_a_broad_widest_lobe_is_taken_for_the_re_fit() {
        // Physical-like panel (glint lobe μ = 0.07 and broad μ = 0.2) and paper-like body
        // (glint lobes μ = 0.01 and 0.05 only).
        let mut x: Basis = [[0.0; TERMS]; 2];
        x[0][0] = 0.3;
        x[0][lobe(0.07)] = 0.6;
        x[0][lobe(0.2)] = 0.08;
        x[1][lobe(0.01)] = 0.04;
        x[1][lobe(0.05)] = 0.2;
        let active = x.map(|f| f.map(|v| v != 0.0));
        let mut data = vec![band(x), band(x)];
        let lobes = take_widest_lobes(&mut data, &active);
        assert_eq!(lobes, [lobe(0.2), 0]);
        for d in &data {
            // The broad lobe is the problem's to estimate; the glint lobes stay stage 1's.
            assert_eq!(d.x[0][lobe(0.2)], 0.0);
            assert_eq!(d.x[0][lobe(0.07)], 0.6);
            assert_eq!(d.x[1], x[1]);
        }
    }
}
