//! Stage 1 on noise-free two-facet data from the physics model.

mod common;

use common::*;
use glint_inversion::stage1::{design_matrix, run_stage1};
use glint_inversion::{InversionError, Observation};
use glint_physics::two_facet::panel_normal;
use nalgebra::Vector3;

#[test]
fn hover_stable_window_is_reconstructed() {
    let obs = stable_window(720, -40.0, 25.0, &BANDS_NM);
    let scales: Vec<f64> = BANDS_NM.iter().map(|&l| band_scale_w(l)).collect();
    let bands = run_stage1(&obs, &BANDS_NM, Vector3::x(), Some(&scales)).expect("stage 1");
    assert_eq!(bands.len(), 8);
    for (b, band) in bands.iter().enumerate() {
        assert_eq!(band.wavelength_nm, BANDS_NM[b]);
        assert!(
            band.recon_err < 1e-6,
            "{} nm: {:e}",
            band.wavelength_nm,
            band.recon_err
        );
        let m2 = band.coeffs_m2.expect("scaled coefficients");
        for m in 0..11 {
            assert!(band.coeffs.panel[m] >= 0.0 && band.coeffs.body[m] >= 0.0);
            assert!((m2.panel[m] * scales[b] - band.coeffs.panel[m]).abs() <= 1e-12);
        }
    }
}

/// Multi-pass geometry: the Sun sweeps α ∈ [−60°, 60°] on five passes with different observer
/// elevations and azimuths, so the 22 columns are well conditioned and x itself is identifiable
/// (a single hover pass is not: its column-scaled condition number is ~4e7).
fn multi_pass_window(wavelength_nm: f64) -> Vec<Observation> {
    let c = band_coeffs(wavelength_nm);
    let mut out = Vec::new();
    for (k, elevation_deg) in [-8.0f64, -2.58, 3.0, 9.0, 15.0].iter().enumerate() {
        let (e, az) = (
            elevation_deg.to_radians(),
            (4.0 * k as f64 - 8.0).to_radians(),
        );
        let o = Vector3::new(e.cos() * az.cos(), e.cos() * az.sin(), e.sin());
        for j in 0..600 {
            let s = sun_at(-60.0 + 120.0 * j as f64 / 599.0);
            let n_p = panel_normal(s, Vector3::x());
            out.push(Observation {
                frame_index: (k * 600 + j) as u64,
                t_s: 0.0,
                sun_body: s,
                observer_body: o,
                range_m: 2.0e6,
                flux_w: vec![flux_w(&c, 1.0, n_p, s, o, 2.0e6)],
                sigma_w: vec![],
            });
        }
    }
    out
}

fn column_scaled_condition(obs: &[Observation]) -> f64 {
    let g = design_matrix(obs, Vector3::x());
    let norm = |j: usize| {
        (0..g.nrows())
            .map(|i| g[(i, j)].powi(2))
            .sum::<f64>()
            .sqrt()
    };
    let norms: Vec<f64> = (0..g.ncols()).map(norm).collect();
    let a = faer::Mat::from_fn(g.nrows(), g.ncols(), |i, j| g[(i, j)] / norms[j]);
    let sv = a.singular_values().expect("svd");
    sv[0] / sv[sv.len() - 1]
}

#[test]
fn coefficients_are_recovered_when_identifiable() {
    let obs = multi_pass_window(650.0);
    let cond = column_scaled_condition(&obs);
    assert!(cond < 1e5, "design condition number {cond:e}");
    let bands = run_stage1(&obs, &[650.0], Vector3::x(), None).expect("stage 1");
    let truth = band_coeffs(650.0);
    let got = bands[0].coeffs;
    assert!(bands[0].recon_err < 1e-9);
    for m in 0..11 {
        assert!((got.panel[m] - truth.panel[m]).abs() < 1e-8, "P_{m}");
        assert!((got.body[m] - truth.body[m]).abs() < 1e-8, "B_{m}");
    }
}

#[test]
fn single_hover_pass_is_poorly_conditioned() {
    let cond = column_scaled_condition(&stable_window(720, -40.0, 25.0, &[650.0]));
    assert!(cond > 1e6, "{cond:e}");
}

#[test]
fn rejects_short_or_dark_windows() {
    let obs = stable_window(21, -40.0, 25.0, &[650.0]);
    assert!(matches!(
        run_stage1(&obs, &[650.0], Vector3::x(), None),
        Err(InversionError::TooFewSamples {
            need: 22,
            got: 21,
            ..
        })
    ));
    let mut obs = stable_window(40, -40.0, 25.0, &[650.0]);
    obs.iter_mut().for_each(|o| o.flux_w[0] = 0.0);
    assert!(matches!(
        run_stage1(&obs, &[650.0], Vector3::x(), None),
        Err(InversionError::NoFlux { .. })
    ));
}
