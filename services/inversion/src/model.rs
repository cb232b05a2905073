//! Stage-3 measurement model, eq (20), with its analytic Jacobian (docs/math.md §1.6).
//!
//! ```text
//! s'_t = R(t; p) s_t,  o'_t = R(t; p) o_t                                      (18–19)
//! Φ_model(t, λ; p) = (1/‖T0_t‖²) Σ_{k∈{p,b}} Σ_m x̃^k_m(λ) G_m(n_k, s'_t, o'_t)        (20)
//! ```
//!
//! with G_m the masked basis of [`crate::facet`] and x̃ the stage-1 coefficients (which absorb
//! E_sun Δλ A_ap, see [`crate::stage1`]). n_b is fixed in B. The panel normal follows
//! [`PanelNormalMode`]: (a) eq (4) on the nominal s_t (default), (b) frozen at n_p(s_0), or
//! (c) tracking, `n_p = normalize(P s'_t)` with P = diag(1, 0, 1).
//!
//! Residuals, per frame t and fitted band λ (index t·B + b), normalised by `Φ̄_λ = mean_t Φ_obs`:
//!
//! ```text
//! r = w (y − m),  y = Φ_obs/Φ̄,  m = Φ_model/Φ̄,  w = Φ̄/σ (σ given) or 1
//! J_{·,i} = w ∂m/∂p_i = w (1/(‖T0‖² Φ̄)) Σ x̃_m dG_m/dp_i
//! dG/dp_i via s', o' (and n_p in mode c):  ds'_i = (∂R/∂w_i) s,  do'_i = (∂R/∂w_i) o,
//! dn_p,i = (I − n_p n_pᵀ) P ds'_i / ‖P s'‖
//! ```
//!
//! Cost `ε(p) = Σ r²` (no ½).

use crate::error::InversionError;
use crate::facet::{FacetGeometry, LOBES, TERMS};
use crate::nuisance::{Normal, NUISANCE};
use crate::observation::Observation;
use crate::rotation::{AttitudeModel, TrigStepper};
use glint_physics::two_facet::{panel_normal, TwoFacetCoefficients};
use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};
use std::f64::consts::FRAC_1_PI;

mod coefficients;
mod diagnostics;
pub mod refit;

use refit::{nuisance_columns, take_lobes, take_widest_lobes};

/// Panel normal during the motion window (§1.6 \[ASSUMP\]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PanelNormalMode {
    /// (a) eq (4) on the nominal (un-rotated) s_t, as eq (20) is printed.
    #[default]
    Literal,
    /// (b) n_p = n_p(s_0), s_0 the first motion frame.
    Frozen,
    /// (c) n_p = normalize(s'_t − (s'_t·Y)Y), the panel keeps tracking the Sun.
    Tracking,
}

/// Geometry settings of the motion model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MotionModelConfig {
    /// Observed body-facet normal n_b in B (unit; default +X_B).
    pub body_normal: [f64; 3],
    /// Panel-normal option (a)/(b)/(c).
    pub panel_normal: PanelNormalMode,
    /// Eq (17) convention.
    pub attitude: AttitudeModel,
    /// Re-estimate the diffuse coefficients of both facets and a constant remainder per band
    /// at every p (variable projection, [`crate::nuisance`]; beyond the paper), with the
    /// sun–observer bisector held at the stated prior. `false` (default) is the paper's model:
    /// every coefficient from stage 1. The solve searches with this model and polishes with
    /// the re-fit ([`crate::stage3::Stage3Config::refit_diffuse`]).
    pub refit_diffuse: bool,
    /// With `refit_diffuse`: also re-estimate each facet's widest lobe in use.
    pub refit_widest_lobe: bool,
    /// With `refit_widest_lobe`: the lobe to re-fit per facet (a term index, 0 for none)
    /// instead of the widest in use over these bands — a fit over more bands chose it.
    pub widest_lobes: Option<[usize; 2]>,
    /// Frame index with t = 0 (all angles 0); `None` = the smallest motion frame index.
    pub epoch_frame: Option<u64>,
}

impl Default for MotionModelConfig {
    fn default() -> Self {
        Self {
            body_normal: [1.0, 0.0, 0.0],
            panel_normal: PanelNormalMode::Literal,
            attitude: AttitudeModel::Verbatim,
            refit_diffuse: false,
            refit_widest_lobe: false,
            widest_lobes: None,
            epoch_frame: None,
        }
    }
}

/// One band to fit: its index in the observations' flux vectors and its stage-1 coefficients.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RateBand {
    /// Index into `Observation::flux_w` / `sigma_w`.
    pub band_index: usize,
    /// Band centre \[nm\].
    pub wavelength_nm: f64,
    /// x̃ of this band (stage-1 units).
    pub coeffs: TwoFacetCoefficients,
}

#[derive(Debug, Clone)]
struct Frame {
    t_frames: f64,
    s: Vector3<f64>,
    o: Vector3<f64>,
    n_p: Vector3<f64>,
    inv_range2: f64,
}

#[derive(Debug, Clone)]
struct BandData {
    x: Basis,
    y: Vec<f64>,
    w: Vec<f64>,
    mean_flux_w: f64,
}

/// The stage-3 least-squares problem over the motion window for one or more bands.
#[derive(Debug, Clone)]
pub struct RateProblem {
    frames: Vec<Frame>,
    bands: Vec<BandData>,
    wavelengths_nm: Vec<f64>,
    body_normal: Vector3<f64>,
    panel_mode: PanelNormalMode,
    attitude: AttitudeModel,
    active: [[bool; TERMS]; 2],
    sigma_given: bool,
    refit_diffuse: bool,
    /// Per facet: the lobe re-fitted with the diffuse terms (0: none).
    refit_lobes: [usize; 2],
    /// The widest-lobe re-fit was asked for, and every facet's widest lobe in use is a glint
    /// lobe, which stays stage 1's ([`refit::BROAD_LOBE_MIN_MU`]).
    glint_lobes_only: bool,
    /// Per band: Cov(x̃) of the stage-1 coefficients, normalised like `x` (22 × 22), if known.
    coeff_cov: Vec<Option<Vec<f64>>>,
}

/// Per-facet arrays: `[panel, body]`.
type Basis = [[f64; TERMS]; 2];

/// Derivative data of one facet at one frame (see `RateProblem::basis_and_slopes`).
#[derive(Debug, Clone, Copy, Default)]
struct FacetSlopes {
    /// d(ab/π)/dp_i.
    d_diffuse: [f64; 3],
    /// dc/dp_i, c = cos τ.
    dc: [f64; 3],
    /// d(D_m/4)/dc per lobe.
    lobe: [f64; LOBES],
}

impl RateProblem {
    /// Builds the problem from validated motion observations.
    pub fn new(
        motion: &[Observation],
        bands: &[RateBand],
        config: &MotionModelConfig,
    ) -> Result<Self, InversionError> {
        let body_normal = Vector3::from(config.body_normal);
        let unit = (body_normal.norm() - 1.0).abs() < 1e-6;
        if !unit {
            return Err(InversionError::InvalidConfig {
                field: "body_normal",
                reason: "must be a unit vector",
            });
        }
        if motion.len() < 3 {
            return Err(InversionError::TooFewSamples {
                stage: "stage 3",
                got: motion.len(),
                need: 3,
            });
        }
        if bands.is_empty() {
            return Err(InversionError::NoBands);
        }
        let epoch = config
            .epoch_frame
            .unwrap_or_else(|| motion.iter().map(|o| o.frame_index).min().unwrap_or(0));
        let s0 = motion[0].sun_body;
        let frozen = panel_normal(s0, body_normal);
        let mut prev = body_normal;
        let mut frames = Vec::with_capacity(motion.len());
        for (index, o) in motion.iter().enumerate() {
            let Some(dt) = o.frame_index.checked_sub(epoch) else {
                return Err(InversionError::FrameBeforeEpoch {
                    index,
                    frame_index: o.frame_index,
                    epoch_frame: epoch,
                });
            };
            prev = panel_normal(o.sun_body, prev);
            frames.push(Frame {
                t_frames: dt as f64,
                s: o.sun_body,
                o: o.observer_body,
                n_p: if config.panel_normal == PanelNormalMode::Frozen {
                    frozen
                } else {
                    prev
                },
                inv_range2: o.range_m.powi(-2),
            });
        }
        let sigma_given = motion.iter().all(|o| !o.sigma_w.is_empty());
        let mut data = Vec::with_capacity(bands.len());
        let mut active = [[false; TERMS]; 2];
        for band in bands {
            let flux = |o: &Observation| o.flux_w.get(band.band_index).copied();
            let mut y = Vec::with_capacity(motion.len());
            for (index, o) in motion.iter().enumerate() {
                y.push(flux(o).ok_or(InversionError::BandCountMismatch {
                    window: "motion",
                    index,
                    field: "flux_w",
                    len: o.flux_w.len(),
                    bands: band.band_index + 1,
                })?);
            }
            let mean = y.iter().sum::<f64>() / y.len() as f64;
            if !(mean > 0.0 && mean.is_finite()) {
                return Err(InversionError::NoFlux {
                    wavelength_nm: band.wavelength_nm,
                    window: "motion",
                });
            }
            let w = if sigma_given {
                motion
                    .iter()
                    .map(|o| mean / o.sigma_w.get(band.band_index).copied().unwrap_or(mean))
                    .collect()
            } else {
                vec![1.0; motion.len()]
            };
            let mut x = [band.coeffs.panel, band.coeffs.body].map(|c| c.map(|v| v / mean));
            if config.refit_diffuse {
                // Stage 3 estimates these itself (the nuisance columns).
                x[0][0] = 0.0;
                x[1][0] = 0.0;
            }
            for (act, xf) in active.iter_mut().zip(&x) {
                for (a, v) in act.iter_mut().zip(xf) {
                    *a |= *v != 0.0;
                }
            }
            y.iter_mut().for_each(|v| *v /= mean);
            data.push(BandData {
                x,
                y,
                w,
                mean_flux_w: mean,
            });
        }
        let mut refit_lobes = [0usize; 2];
        if config.refit_diffuse {
            // The nuisance columns need the diffuse basis of both facets.
            active[0][0] = true;
            active[1][0] = true;
            if config.refit_widest_lobe {
                refit_lobes = match config.widest_lobes {
                    Some(lobes) => take_lobes(&mut data, &mut active, lobes),
                    None => take_widest_lobes(&mut data, &active),
                };
            }
        }
        Ok(Self {
            glint_lobes_only: config.refit_diffuse
                && config.refit_widest_lobe
                && refit_lobes == [0; 2],
            refit_lobes,
            frames,
            bands: data,
            wavelengths_nm: bands.iter().map(|b| b.wavelength_nm).collect(),
            body_normal,
            panel_mode: config.panel_normal,
            attitude: config.attitude,
            active,
            sigma_given,
            refit_diffuse: config.refit_diffuse,
            coeff_cov: vec![None; bands.len()],
        })
    }

    /// The same problem on every `stride`-th frame (normalisation and weights unchanged), used
    /// for cheap screening of starts.
    pub fn subsampled(&self, stride: usize) -> Self {
        let stride = stride.max(1);
        let mut out = self.clone();
        out.frames = self.frames.iter().step_by(stride).cloned().collect();
        for (dst, src) in out.bands.iter_mut().zip(&self.bands) {
            dst.y = src.y.iter().step_by(stride).copied().collect();
            dst.w = src.w.iter().step_by(stride).copied().collect();
        }
        out
    }

    /// Frames in the motion window.
    pub fn frame_count(&self) -> usize {
        self.frames.len()
    }

    /// Residual count: T·B.
    pub fn residual_count(&self) -> usize {
        self.frames.len() * self.bands.len()
    }

    /// Fitted band centres \[nm\].
    pub fn wavelengths_nm(&self) -> &[f64] {
        &self.wavelengths_nm
    }

    /// sqrt(mean w²) over all residuals (1 when σ is not given).
    pub fn weight_rms(&self) -> f64 {
        let sum: f64 = self.bands.iter().flat_map(|b| &b.w).map(|w| w * w).sum();
        (sum / (self.frames.len() * self.bands.len()).max(1) as f64).sqrt()
    }

    /// Whether residuals are whitened by the observations' σ.
    pub fn sigma_given(&self) -> bool {
        self.sigma_given
    }

    fn facets(&self, frame: &Frame, s: Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
        let n_p = match self.panel_mode {
            PanelNormalMode::Tracking => panel_normal(s, frame.n_p),
            _ => frame.n_p,
        };
        (n_p, self.body_normal)
    }

    fn basis(&self, frame: &Frame, r: &Matrix3<f64>, g: &mut Basis) {
        let (s, o) = (r * frame.s, r * frame.o);
        let (n_p, n_b) = self.facets(frame, s);
        for ((n, out), act) in [n_p, n_b].into_iter().zip(g.iter_mut()).zip(&self.active) {
            match FacetGeometry::new(n, s, o) {
                Some(geom) => geom.basis(act, out),
                None => out.fill(0.0),
            }
        }
    }

    /// Basis values and, per facet, the derivative data of eq (20): `d(ab/π)/dp_i`, `dc/dp_i`
    /// and the lobe slopes `d(D_m/4)/dc`, so that for coefficients x
    /// `d(Σ_m x_m G_m)/dp_i = x_0 d(ab/π)/dp_i + (Σ_{m≥1} x_m d(D_m/4)/dc) dc/dp_i`.
    fn basis_and_slopes(
        &self,
        frame: &Frame,
        r: &Matrix3<f64>,
        dr: &[Matrix3<f64>; 3],
        g: &mut Basis,
        slopes: &mut [FacetSlopes; 2],
    ) {
        let (s, o) = (r * frame.s, r * frame.o);
        let ds = [dr[0] * frame.s, dr[1] * frame.s, dr[2] * frame.s];
        let d_o = [dr[0] * frame.o, dr[1] * frame.o, dr[2] * frame.o];
        let (n_p, n_b) = self.facets(frame, s);
        // dn_p for mode (c); zero otherwise (or when the tracking normal is undefined).
        let mut dn_p = [Vector3::zeros(); 3];
        if self.panel_mode == PanelNormalMode::Tracking {
            let ps = Vector3::new(s.x, 0.0, s.z);
            let len = ps.norm();
            if len > 1e-12 {
                let proj = Matrix3::identity() - n_p * n_p.transpose();
                for i in 0..3 {
                    dn_p[i] = proj * Vector3::new(ds[i].x, 0.0, ds[i].z) / len;
                }
            }
        }
        let facets = [(n_p, dn_p), (n_b, [Vector3::zeros(); 3])];
        for (k, (n, dn)) in facets.into_iter().enumerate() {
            let Some(geom) = FacetGeometry::new(n, s, o) else {
                g[k].fill(0.0);
                slopes[k] = FacetSlopes::default();
                continue;
            };
            let (a, b) = (geom.cos_ns, geom.cos_no);
            let dc_dso = geom.dcos_tau_dso();
            let slope = &mut slopes[k];
            for i in 0..3 {
                let da = n.dot(&ds[i]) + dn[i].dot(&s);
                let db = n.dot(&d_o[i]) + dn[i].dot(&o);
                slope.d_diffuse[i] = (da * b + a * db) * FRAC_1_PI;
                slope.dc[i] = dc_dso.dot(&(ds[i] + d_o[i])) + dn[i].dot(&geom.half);
            }
            let [_, active_lobes @ ..] = &self.active[k];
            let (lobes, lobe_slopes) = geom.quarter_lobes(active_lobes, true);
            g[k][0] = a * b * FRAC_1_PI;
            g[k][1..].copy_from_slice(&lobes);
            slope.lobe = lobe_slopes;
        }
    }

    /// [`Self::basis_and_slopes`] at `frame` for the rate `trig` steps through.
    fn basis_and_slopes_at(
        &self,
        frame: &Frame,
        trig: &mut TrigStepper,
        g: &mut Basis,
        slopes: &mut [FacetSlopes; 2],
    ) {
        let (rot, drot) = self
            .attitude
            .matrix_and_partials_from_trig(&trig.at(frame.t_frames), frame.t_frames);
        self.basis_and_slopes(frame, &rot, &drot, g, slopes);
    }

    /// Writes residuals `r` (length T·B) and returns the cost Σ r².
    pub fn residuals(&self, p: [f64; 3], r: &mut [f64]) -> f64 {
        self.residuals_with_nuisance(p, r).0
    }

    /// Residuals, cost and the nuisance coefficients per band (zeros without the re-fit).
    fn residuals_with_nuisance(&self, p: [f64; 3], r: &mut [f64]) -> (f64, Vec<[f64; NUISANCE]>) {
        let nb = self.bands.len();
        let mut g = [[0.0; TERMS]; 2];
        let mut rows = self.nuisance_rows();
        let mut trig = TrigStepper::new(p);
        for (t, frame) in self.frames.iter().enumerate() {
            let rot = self.attitude.matrix_from_trig(&trig.at(frame.t_frames));
            self.basis(frame, &rot, &mut g);
            for (b, band) in self.bands.iter().enumerate() {
                let m = frame.inv_range2 * dot22(&band.x, &g);
                r[t * nb + b] = band.w[t] * (band.y[t] - m);
                if let Some(rows) = rows.get_mut(b) {
                    rows[t].a =
                        nuisance_columns(band.w[t] * frame.inv_range2, &g, self.refit_lobes);
                }
            }
        }
        let c = self.project(&rows, r, None);
        (r.iter().map(|v| v * v).sum(), c)
    }

    /// Cost Σ r² over every `stride`-th frame (stride ≥ 1), without storing residuals.
    pub fn cost_strided(&self, p: [f64; 3], stride: usize) -> f64 {
        self.cost_strided_within(p, stride, f64::INFINITY)
    }

    /// [`RateProblem::cost_strided`], stopped as soon as the partial sum exceeds `bound`: the
    /// value returned is then a partial sum above `bound`, and the full cost lies above it too
    /// (every term is a square). A problem that re-fits the diffuse terms projects them out at
    /// the end, so its partial sums bound nothing and it always runs to the end. A cost at or
    /// below `bound` is bit-for-bit [`RateProblem::cost_strided`]'s.
    pub fn cost_strided_within(&self, p: [f64; 3], stride: usize, bound: f64) -> f64 {
        let frames: Vec<usize> = (0..self.frames.len()).step_by(stride.max(1)).collect();
        self.cost_over_within(p, &frames, bound)
    }

    /// Every `stride`-th frame, brightest first (the observed flux summed over the bands, in
    /// units of each band's mean): the frames of the glint, where rates differ most, lead.
    /// Summed in this order, the cost of a rate that misses the glint passes a bound soonest.
    pub fn brightest_first(&self, stride: usize) -> Vec<usize> {
        let mut frames: Vec<usize> = (0..self.frames.len()).step_by(stride.max(1)).collect();
        let flux = |t: usize| self.bands.iter().map(|b| b.y[t]).sum::<f64>();
        frames.sort_by(|&i, &j| flux(j).total_cmp(&flux(i)));
        frames
    }

    /// Σ r² over `frames` (indices, summed in that order), stopped as soon as the partial sum
    /// exceeds `bound` ([`Self::cost_strided_within`]).
    pub fn cost_over_within(&self, p: [f64; 3], frames: &[usize], bound: f64) -> f64 {
        let mut g = [[0.0; TERMS]; 2];
        let mut cost = 0.0;
        let mut normals = vec![Normal::default(); self.bands.len()];
        let mut trig = TrigStepper::new(p);
        for &t in frames {
            let frame = &self.frames[t];
            let rot = self.attitude.matrix_from_trig(&trig.at(frame.t_frames));
            self.basis(frame, &rot, &mut g);
            for (band, normal) in self.bands.iter().zip(normals.iter_mut()) {
                let res = band.w[t] * (band.y[t] - frame.inv_range2 * dot22(&band.x, &g));
                if self.refit_diffuse {
                    normal.add(
                        &nuisance_columns(band.w[t] * frame.inv_range2, &g, self.refit_lobes),
                        res,
                    );
                } else {
                    cost += res * res;
                }
            }
            if cost > bound {
                return cost;
            }
        }
        if self.refit_diffuse {
            cost = normals.iter().map(Normal::projected_cost).sum();
        }
        cost
    }

    /// Cost Σ r² over all frames.
    pub fn cost(&self, p: [f64; 3]) -> f64 {
        self.cost_strided(p, 1)
    }

    /// Residuals and the Jacobian `J = w ∂m/∂p` (rows T·B, 3 columns); returns Σ r².
    pub fn residuals_and_jacobian(&self, p: [f64; 3], r: &mut [f64], jac: &mut [[f64; 3]]) -> f64 {
        self.residuals_and_jacobian_within(p, r, jac, f64::INFINITY)
    }

    /// [`Self::residuals_and_jacobian`], stopped once the partial Σ r² exceeds `bound`: the
    /// value returned is then only known to exceed `bound`, and `r`, `jac` are incomplete.
    /// Otherwise the full cost, to the bit (the sum runs in the same order). Stops only when
    /// the diffuse terms are not re-fitted (their projection needs every frame).
    pub fn residuals_and_jacobian_within(
        &self,
        p: [f64; 3],
        r: &mut [f64],
        jac: &mut [[f64; 3]],
        bound: f64,
    ) -> f64 {
        let nb = self.bands.len();
        let mut cost = 0.0;
        let mut g = [[0.0; TERMS]; 2];
        let mut slopes = [FacetSlopes::default(); 2];
        let mut rows = self.nuisance_rows();
        let mut trig = TrigStepper::new(p);
        for (t, frame) in self.frames.iter().enumerate() {
            self.basis_and_slopes_at(frame, &mut trig, &mut g, &mut slopes);
            for (b, band) in self.bands.iter().enumerate() {
                let m = dot22(&band.x, &g);
                let dm = model_slope(&band.x, &slopes);
                let (w, k) = (band.w[t], frame.inv_range2);
                let wk = w * k;
                let res = w * (band.y[t] - k * m);
                cost += res * res;
                r[t * nb + b] = res;
                jac[t * nb + b] = [wk * dm[0], wk * dm[1], wk * dm[2]];
                if let Some(rows) = rows.get_mut(b) {
                    rows[t] = self.nuisance_row(wk, &g, &slopes);
                }
            }
            if cost > bound && !self.refit_diffuse {
                return cost;
            }
        }
        if !self.refit_diffuse {
            return cost;
        }
        self.project(&rows, r, Some(jac));
        r.iter().map(|v| v * v).sum()
    }

    /// Model flux Φ_model(t; p) \[W\] per fitted band (outer) and frame (inner).
    pub fn model_flux_w(&self, p: [f64; 3]) -> Vec<Vec<f64>> {
        let mut scratch = vec![0.0; self.residual_count()];
        let (_, c) = self.residuals_with_nuisance(p, &mut scratch);
        let mut g = [[0.0; TERMS]; 2];
        let mut out = vec![Vec::with_capacity(self.frames.len()); self.bands.len()];
        let mut trig = TrigStepper::new(p);
        for frame in &self.frames {
            let rot = self.attitude.matrix_from_trig(&trig.at(frame.t_frames));
            self.basis(frame, &rot, &mut g);
            for ((band, series), c) in self.bands.iter().zip(out.iter_mut()).zip(&c) {
                let a = nuisance_columns(frame.inv_range2, &g, self.refit_lobes);
                let nuisance: f64 = (0..NUISANCE).map(|i| a[i] * c[i]).sum();
                let m = frame.inv_range2 * dot22(&band.x, &g) + nuisance;
                series.push(m * band.mean_flux_w);
            }
        }
        out
    }
}

/// `d(Σ_m x_m G_m)/dp` of coefficients x from the facets' slopes (see `basis_and_slopes`).
fn model_slope(x: &Basis, slopes: &[FacetSlopes; 2]) -> [f64; 3] {
    let mut dm = [0.0; 3];
    for (x, sl) in x.iter().zip(slopes) {
        let lobe_slope: f64 = x[1..].iter().zip(&sl.lobe).map(|(a, b)| a * b).sum();
        for ((d, dd), dc) in dm.iter_mut().zip(&sl.d_diffuse).zip(&sl.dc) {
            *d += x[0] * dd + lobe_slope * dc;
        }
    }
    dm
}

/// Σ x·g over the 22 terms, in four interleaved partial sums: independent chains the compiler
/// keeps in SIMD lanes (a single running sum is one dependent chain of 22 adds, and this dot
/// product is the inner loop of every cost and Jacobian evaluation).
#[inline]
fn dot22(x: &Basis, g: &Basis) -> f64 {
    let (x, g) = (x.as_flattened(), g.as_flattened());
    let mut acc = [0.0f64; 4];
    for (xs, gs) in x.chunks_exact(4).zip(g.chunks_exact(4)) {
        for l in 0..4 {
            acc[l] += xs[l] * gs[l];
        }
    }
    let tail = x.len() - x.len() % 4;
    for k in tail..x.len() {
        acc[k % 4] += x[k] * g[k];
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3])
}
