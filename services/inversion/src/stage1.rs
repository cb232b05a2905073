//! Stage 1: per-band area×BRDF products from the three-axis-stable window by NNLS (docs/math.md
//! §1.4, eqs 7–12).
//!
//! ```text
//! Q_j = Φ_j ‖T0_j‖² = G_j x,   x = [P_0..P_10, B_0..B_10] ≥ 0                (7–12)
//! G_{j,m}    = [n_p·s_j]_+[n_p·o_j]_+ β_m(n_p, o_j, s_j),   n_p = normalize(s_j − (s_j·Y)Y)  (4)
//! G_{j,11+m} = [n_b·s_j]_+[n_b·o_j]_+ β_m(n_b, o_j, s_j)
//! ε_rec = ‖Φ − Φ_rec‖₂ / ‖Φ‖₂,   Φ_rec,j = G_j x / ‖T0_j‖²
//! ```
//!
//! Units: the pupil factor is `K = E_sun(λ) Δλ A_ap/‖T0‖²`. `E_sun Δλ A_ap` is constant per band,
//! so it is absorbed: the fitted coefficients are `x̃ = (E_sun Δλ A_ap)·x`, i.e.
//! "area × BRDF × (E_sun A_ap Δλ)" \[W·m²\] when Φ is in W and the range in m (Q̃ = Φ‖T0‖²).
//! Stage 2 ranks bands by ratios, so the factor cancels there, and stage 3 uses x̃ with
//! `Φ_model = Σ G x̃/‖T0‖²` directly. Given a per-band scale `E_sun Δλ A_ap` \[W/m²·m² = W\],
//! `x = x̃/scale` is reported too, in m².
//!
//! All bands share one design matrix, so the column scaling and the QR compression of the NNLS
//! are done once ([`NnlsSystem`]).

use crate::error::InversionError;
use crate::nnls::NnlsSystem;
use crate::observation::Observation;
use crate::serde_coeffs;
use faer::linalg::solvers::Solve;
use faer::Mat;
use glint_physics::two_facet::{design_row, panel_normal, TwoFacetCoefficients, TERMS_PER_FACET};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// Columns of G: 2(M + 1) = 22.
pub const DESIGN_COLUMNS: usize = 2 * TERMS_PER_FACET;

/// Stage-1 result of one band.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Stage1Band {
    /// Band centre \[nm\].
    pub wavelength_nm: f64,
    /// Fitted `x̃ = (E_sun Δλ A_ap)·[P; B]` \[W·m²\] (see the module doc).
    #[serde(with = "serde_coeffs::Coeffs")]
    pub coeffs: TwoFacetCoefficients,
    /// `x̃ / (E_sun Δλ A_ap)` \[m²\] when a band scale was given.
    #[serde(with = "serde_coeffs::option")]
    pub coeffs_m2: Option<TwoFacetCoefficients>,
    /// Relative reconstruction error ‖Φ − Φ_rec‖₂/‖Φ‖₂.
    pub recon_err: f64,
    /// Covariance of x̃ (22 × 22, row-major) from the stable window's σ, on the NNLS passive set
    /// (coefficients at their bound 0 are held there): `(G_Pᵀ W G_P)⁻¹`, W = 1/(σ‖T0‖²)².
    /// `None` without σ.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub coeff_covariance: Option<Vec<f64>>,
    /// NNLS outer iterations.
    pub nnls_iterations: usize,
}

/// Eq (4) on each nominal Sun vector; keeps the previous normal when |s·Y| = 1 (starting from
/// `body_normal`).
pub fn panel_normals(obs: &[Observation], body_normal: Vector3<f64>) -> Vec<Vector3<f64>> {
    let mut prev = body_normal;
    obs.iter()
        .map(|o| {
            prev = panel_normal(o.sun_body, prev);
            prev
        })
        .collect()
}

/// The T × 22 design matrix G of eqs (11)–(12) \[sr⁻¹\].
pub fn design_matrix(obs: &[Observation], body_normal: Vector3<f64>) -> Mat<f64> {
    let n_p = panel_normals(obs, body_normal);
    let mut g = Mat::zeros(obs.len(), DESIGN_COLUMNS);
    let mut row = [0.0; DESIGN_COLUMNS];
    for (j, (o, n_p)) in obs.iter().zip(&n_p).enumerate() {
        design_row(*n_p, body_normal, o.sun_body, o.observer_body, &mut row);
        for (m, v) in row.iter().enumerate() {
            g[(j, m)] = *v;
        }
    }
    g
}

pub mod basis;
pub mod spectral;

pub use basis::BasisChoice;

/// Stage-1 settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Stage1Config {
    /// Drop the broad lobes the stable window cannot tell from the diffuse term ([`basis`]);
    /// `false` fits the paper's whole basis.
    pub basis_selection: bool,
    /// z of the nested test's threshold `k + z·sqrt(2k)` (allowed: > 0).
    pub basis_test_sigmas: f64,
    /// A lobe may leave the basis only when its variance inflation against the diffuse column
    /// is at least this (allowed: ≥ 1; 10, the usual rule of thumb for collinearity).
    pub basis_min_vif: f64,
    /// Half-width \[nm\] of the spectral window pooled for stage 2 and the single-band fit
    /// ([`spectral`]; allowed: ≥ 0, 0 = never pool).
    pub spectral_window_nm: f64,
    /// Pool only while the pooled curves' RMS bias is at most this fraction of the noise
    /// (allowed: > 0; `inf` pools whenever σ is given).
    pub spectral_max_bias_to_noise: f64,
}

impl Default for Stage1Config {
    fn default() -> Self {
        Self {
            basis_selection: true,
            basis_test_sigmas: 3.0,
            basis_min_vif: 10.0,
            spectral_window_nm: 20.0,
            spectral_max_bias_to_noise: 1.0 / 3.0,
        }
    }
}

impl Stage1Config {
    /// The paper's stage 1: every column of G, each band on its own.
    pub fn paper() -> Self {
        Self {
            basis_selection: false,
            spectral_window_nm: 0.0,
            ..Self::default()
        }
    }

    /// Checks the ranges above.
    pub fn validate(&self) -> Result<(), InversionError> {
        if !(self.basis_test_sigmas.is_finite() && self.basis_test_sigmas > 0.0) {
            return Err(InversionError::InvalidConfig {
                field: "stage1.basis_test_sigmas",
                reason: "must be a finite number > 0",
            });
        }
        if !(self.basis_min_vif.is_finite() && self.basis_min_vif >= 1.0) {
            return Err(InversionError::InvalidConfig {
                field: "stage1.basis_min_vif",
                reason: "must be a finite number ≥ 1",
            });
        }
        if !(self.spectral_window_nm.is_finite() && self.spectral_window_nm >= 0.0) {
            return Err(InversionError::InvalidConfig {
                field: "stage1.spectral_window_nm",
                reason: "must be a finite number ≥ 0",
            });
        }
        if self.spectral_max_bias_to_noise.is_nan() || self.spectral_max_bias_to_noise <= 0.0 {
            return Err(InversionError::InvalidConfig {
                field: "stage1.spectral_max_bias_to_noise",
                reason: "must be a number > 0 (inf allowed)",
            });
        }
        Ok(())
    }
}

/// Runs the paper's stage 1 (whole basis) on every band. `band_scale_w[b] = E_sun Δλ A_ap` of
/// band b, if known.
pub fn run_stage1(
    stable: &[Observation],
    wavelengths_nm: &[f64],
    body_normal: Vector3<f64>,
    band_scale_w: Option<&[f64]>,
) -> Result<Vec<Stage1Band>, InversionError> {
    run_stage1_with(
        stable,
        wavelengths_nm,
        body_normal,
        band_scale_w,
        &Stage1Config::paper(),
    )
    .map(|(bands, _)| bands)
}

/// Runs stage 1 on every band with `config`; returns the bands and the basis used.
pub fn run_stage1_with(
    stable: &[Observation],
    wavelengths_nm: &[f64],
    body_normal: Vector3<f64>,
    band_scale_w: Option<&[f64]>,
    config: &Stage1Config,
) -> Result<(Vec<Stage1Band>, BasisChoice), InversionError> {
    config.validate()?;
    if stable.len() < DESIGN_COLUMNS {
        return Err(InversionError::TooFewSamples {
            stage: "stage 1",
            got: stable.len(),
            need: DESIGN_COLUMNS,
        });
    }
    if let Some(scale) = band_scale_w {
        if scale.len() != wavelengths_nm.len() || !scale.iter().all(|s| s.is_finite() && *s > 0.0) {
            return Err(InversionError::InvalidConfig {
                field: "band_scale_w",
                reason: "needs one positive finite value per band",
            });
        }
    }
    let g = design_matrix(stable, body_normal);
    let q = Mat::from_fn(stable.len(), wavelengths_nm.len(), |j, b| {
        stable[j].flux_w[b] * stable[j].range_m.powi(2)
    });
    let system =
        NnlsSystem::new(g.as_ref(), q.as_ref()).map_err(|source| InversionError::Nnls {
            wavelength_nm: wavelengths_nm.first().copied().unwrap_or(f64::NAN),
            source,
        })?;

    let nnls_error = |b: usize| {
        let wavelength_nm = wavelengths_nm[b];
        move |source| InversionError::Nnls {
            wavelength_nm,
            source,
        }
    };
    let mut solutions = Vec::with_capacity(wavelengths_nm.len());
    for b in 0..wavelengths_nm.len() {
        solutions.push(system.solve(b).map_err(nnls_error(b))?);
    }
    let (choice, solutions) = if config.basis_selection {
        let candidates =
            basis::candidate_count(&basis::diffuse_vif(g.as_ref()), config.basis_min_vif);
        basis::select(
            &system,
            solutions,
            stable.len(),
            candidates,
            config.basis_test_sigmas,
        )
        .map_err(|(b, source)| nnls_error(b)(source))?
    } else {
        (BasisChoice::full(), solutions)
    };

    let mut out = Vec::with_capacity(wavelengths_nm.len());
    for (b, &wavelength_nm) in wavelengths_nm.iter().enumerate() {
        let flux_norm = stable
            .iter()
            .map(|o| o.flux_w[b].powi(2))
            .sum::<f64>()
            .sqrt();
        if flux_norm <= 0.0 {
            return Err(InversionError::NoFlux {
                wavelength_nm,
                window: "stable",
            });
        }
        let sol = &solutions[b];
        let err_sq: f64 = stable
            .iter()
            .enumerate()
            .map(|(j, o)| {
                let q_rec: f64 = (0..DESIGN_COLUMNS).map(|m| g[(j, m)] * sol.x[m]).sum();
                (o.flux_w[b] - q_rec / o.range_m.powi(2)).powi(2)
            })
            .sum();
        let coeffs = coefficients_from_slice(&sol.x);
        let coeff_covariance = coefficient_covariance(stable, &g, &sol.x, b);
        let coeffs_m2 = band_scale_w.map(|scale| scaled(&coeffs, 1.0 / scale[b]));
        out.push(Stage1Band {
            wavelength_nm,
            coeffs,
            coeffs_m2,
            recon_err: err_sq.sqrt() / flux_norm,
            coeff_covariance,
            nnls_iterations: sol.iterations,
        });
    }
    Ok((out, choice))
}

/// What [`run_stage1_full`] decided about spectral pooling (default: not tested, not applied).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct SpectralPooling {
    /// Half-width of the window \[nm\] (the setting; 0 = off).
    pub window_nm: f64,
    /// ρ, the pooled curves' RMS bias in units of the noise ([`spectral`]); `None` when not
    /// tested (no σ, or no band has a neighbour within the window).
    pub bias_to_noise: Option<f64>,
    /// Whether stage 2 and the single-band fit use the pooled window.
    pub applied: bool,
}

/// Stage 1 as the solve uses it: every band on its own (the joint fit, the reported
/// reconstruction), and, when the spectral test accepts it, every band on the pooled stable
/// window (stage 2 and the single-band fit; [`spectral`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Stage1Output {
    pub bands: Vec<Stage1Band>,
    pub basis: BasisChoice,
    /// The bands fitted on the pooled window, when pooling applies.
    pub pooled: Option<Vec<Stage1Band>>,
    pub pooling: SpectralPooling,
}

impl Stage1Output {
    /// The coefficients stage 2 and the single-band fit use.
    pub fn single_band(&self) -> &[Stage1Band] {
        self.pooled.as_deref().unwrap_or(&self.bands)
    }
}

/// [`run_stage1_with`] on the stable window, then on its spectrally pooled version when σ is
/// given and the pooled curves' bias is at most `spectral_max_bias_to_noise` of the noise.
pub fn run_stage1_full(
    stable: &[Observation],
    wavelengths_nm: &[f64],
    body_normal: Vector3<f64>,
    band_scale_w: Option<&[f64]>,
    config: &Stage1Config,
) -> Result<Stage1Output, InversionError> {
    let (bands, basis) =
        run_stage1_with(stable, wavelengths_nm, body_normal, band_scale_w, config)?;
    let weights = spectral::local_linear_weights(wavelengths_nm, config.spectral_window_nm);
    let bias_to_noise = (config.spectral_window_nm > 0.0 && spectral::pools(&weights))
        .then(|| spectral::bias_to_noise(stable, &weights))
        .flatten();
    let applied = bias_to_noise.is_some_and(|rho| rho <= config.spectral_max_bias_to_noise);
    let pooled = if applied {
        let window = spectral::pooled(stable, &weights);
        let (bands, _) =
            run_stage1_with(&window, wavelengths_nm, body_normal, band_scale_w, config)?;
        Some(bands)
    } else {
        None
    };
    Ok(Stage1Output {
        bands,
        basis,
        pooled,
        pooling: SpectralPooling {
            window_nm: config.spectral_window_nm,
            bias_to_noise,
            applied,
        },
    })
}

/// `(G_Pᵀ W G_P)⁻¹` on the passive set P = {m : x_m > 0} of band `b`, embedded in 22 × 22;
/// `None` unless every stable sample carries σ.
fn coefficient_covariance(
    stable: &[Observation],
    g: &Mat<f64>,
    x: &[f64],
    b: usize,
) -> Option<Vec<f64>> {
    let sigma: Vec<f64> = stable
        .iter()
        .map(|o| o.sigma_w.get(b).copied().filter(|s| *s > 0.0))
        .collect::<Option<_>>()?;
    let passive: Vec<usize> = (0..DESIGN_COLUMNS).filter(|&m| x[m] > 0.0).collect();
    let n = passive.len();
    if n == 0 {
        return None;
    }
    let normal = Mat::from_fn(n, n, |i, k| {
        stable
            .iter()
            .zip(&sigma)
            .enumerate()
            .map(|(j, (o, s))| {
                let w = (s * o.range_m.powi(2)).powi(-2);
                g[(j, passive[i])] * g[(j, passive[k])] * w
            })
            .sum::<f64>()
    });
    let inverse = normal
        .llt(faer::Side::Lower)
        .ok()?
        .solve(Mat::<f64>::identity(n, n));
    let inverse: Mat<f64> = inverse;
    let mut cov = vec![0.0; DESIGN_COLUMNS * DESIGN_COLUMNS];
    for (i, &mi) in passive.iter().enumerate() {
        for (k, &mk) in passive.iter().enumerate() {
            cov[mi * DESIGN_COLUMNS + mk] = inverse[(i, k)];
        }
    }
    cov.iter().all(|v: &f64| v.is_finite()).then_some(cov)
}

/// `x[0..11]` → panel, `x[11..22]` → body.
pub fn coefficients_from_slice(x: &[f64]) -> TwoFacetCoefficients {
    let mut c = TwoFacetCoefficients {
        panel: [0.0; TERMS_PER_FACET],
        body: [0.0; TERMS_PER_FACET],
    };
    for m in 0..TERMS_PER_FACET {
        c.panel[m] = x.get(m).copied().unwrap_or(0.0);
        c.body[m] = x.get(TERMS_PER_FACET + m).copied().unwrap_or(0.0);
    }
    c
}

/// `[panel; body]` as one 22-vector.
pub fn coefficients_to_array(c: &TwoFacetCoefficients) -> [f64; DESIGN_COLUMNS] {
    let mut x = [0.0; DESIGN_COLUMNS];
    x[..TERMS_PER_FACET].copy_from_slice(&c.panel);
    x[TERMS_PER_FACET..].copy_from_slice(&c.body);
    x
}

fn scaled(c: &TwoFacetCoefficients, k: f64) -> TwoFacetCoefficients {
    TwoFacetCoefficients {
        panel: c.panel.map(|v| v * k),
        body: c.body.map(|v| v * k),
    }
}
