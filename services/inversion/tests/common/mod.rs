//! Synthetic seed-000 scenarios generated with the physics crate's two-facet model (an
//! independent forward model: `q_two_facet` + `AttitudeConvention::matrix`).
#![allow(dead_code)]

use glint_inversion::{Observation, ObservationSet, PanelNormalMode, RateBand};
use glint_physics::two_facet::{
    panel_normal, q_two_facet, AttitudeConvention, TwoFacetCoefficients,
};
use nalgebra::Vector3;

/// Bands 400, 450, …, 750 nm.
pub const BANDS_NM: [f64; 8] = [400.0, 450.0, 500.0, 550.0, 600.0, 650.0, 700.0, 750.0];

/// Sun declination in the body frame (s_y ≈ 0.05 as in §7.3d) \[rad\].
pub const SUN_DECLINATION_RAD: f64 = 0.050_02;

/// Observer direction (co-orbital leader, slightly above): normalize(0.999, 0, −0.045).
pub fn observer() -> Vector3<f64> {
    Vector3::new(0.999, 0.0, -0.045).normalize()
}

/// Sun unit vector with in-plane angle α (from +X towards +Z) \[deg\].
pub fn sun_at(alpha_deg: f64) -> Vector3<f64> {
    let (a, d) = (alpha_deg.to_radians(), SUN_DECLINATION_RAD);
    Vector3::new(d.cos() * a.cos(), d.sin(), d.cos() * a.sin())
}

/// In-plane Sun angle of §7.3d's s = normalize(0.95, 0.05, −0.30) (phase ≈ 15.2°) \[deg\].
pub fn alpha_phase15_deg() -> f64 {
    (-0.30f64).atan2(0.95).to_degrees()
}

/// Range with a slow ±1 % variation \[m\].
pub fn range_m(frame: f64) -> f64 {
    2.17e6 * (1.0 + 0.01 * (frame * 0.003).sin())
}

/// `E_sun Δλ A_ap` per band \[W\]: a smooth solar-like irradiance × 10 nm × 0.017789 m².
pub fn band_scale_w(wavelength_nm: f64) -> f64 {
    let e_sun = 1.9 - 0.6 * ((wavelength_nm - 480.0) / 300.0).powi(2);
    e_sun * 10.0 * 0.017_789
}

/// Area×BRDF coefficients per band \[m²\]: Table 4 at 650 nm; other bands move a fraction
/// |λ − 650|/350 of each body lobe's weight to the next wider lobe and scale the panel.
pub fn band_coeffs(wavelength_nm: f64) -> TwoFacetCoefficients {
    let t4 = TwoFacetCoefficients::table4();
    let f = (wavelength_nm - 650.0).abs() / 350.0;
    let mut body = [0.0; 11];
    for m in 1..11 {
        body[m] += (1.0 - f) * t4.body[m];
        let to = (m + 1).min(10);
        body[to] += f * t4.body[m];
    }
    let k = 0.8 + 0.4 * (wavelength_nm - 400.0) / 350.0;
    TwoFacetCoefficients {
        panel: t4.panel.map(|v| v * k),
        body,
    }
}

/// Scales every coefficient by `k`.
pub fn scaled(c: &TwoFacetCoefficients, k: f64) -> TwoFacetCoefficients {
    TwoFacetCoefficients {
        panel: c.panel.map(|v| v * k),
        body: c.body.map(|v| v * k),
    }
}

/// Noise-free band flux \[W\] of the two-facet model at (s, o) with normals (n_p, n_b).
pub fn flux_w(
    c: &TwoFacetCoefficients,
    scale_w: f64,
    n_p: Vector3<f64>,
    s: Vector3<f64>,
    o: Vector3<f64>,
    range_m: f64,
) -> f64 {
    let (q_p, q_b) = q_two_facet(c, n_p, Vector3::x(), s, o);
    scale_w * (q_p + q_b) / (range_m * range_m)
}

/// Stable window: `n` samples with α sweeping `alpha_from..alpha_to` \[deg\].
pub fn stable_window(
    n: usize,
    alpha_from_deg: f64,
    alpha_to_deg: f64,
    bands_nm: &[f64],
) -> Vec<Observation> {
    stable_window_of(n, alpha_from_deg, alpha_to_deg, bands_nm, &band_coeffs)
}

/// [`stable_window`] of a body with coefficients `coeffs(λ)` \[m²\].
pub fn stable_window_of(
    n: usize,
    alpha_from_deg: f64,
    alpha_to_deg: f64,
    bands_nm: &[f64],
    coeffs: &dyn Fn(f64) -> TwoFacetCoefficients,
) -> Vec<Observation> {
    (0..n)
        .map(|j| {
            let alpha =
                alpha_from_deg + (alpha_to_deg - alpha_from_deg) * j as f64 / (n - 1) as f64;
            let (s, o) = (sun_at(alpha), observer());
            let range = range_m(j as f64);
            let n_p = panel_normal(s, Vector3::x());
            Observation {
                frame_index: j as u64,
                t_s: 30.0 * j as f64,
                sun_body: s,
                observer_body: o,
                range_m: range,
                flux_w: bands_nm
                    .iter()
                    .map(|&l| flux_w(&coeffs(l), band_scale_w(l), n_p, s, o, range))
                    .collect(),
                sigma_w: vec![],
            }
        })
        .collect()
}

/// Motion window of `n` frames (t = 0..n−1) starting at in-plane Sun angle `alpha0_deg`; the
/// Sun turns about body Y by `sun_rate_deg_per_frame`; the body rotates at `p_true`.
#[allow(clippy::too_many_arguments)]
pub fn motion_window(
    n: usize,
    alpha0_deg: f64,
    sun_rate_deg_per_frame: f64,
    p_true: [f64; 3],
    conv: AttitudeConvention,
    mode: PanelNormalMode,
    bands_nm: &[f64],
    coeffs: &dyn Fn(f64) -> TwoFacetCoefficients,
) -> Vec<Observation> {
    let first_frame = 10_000u64;
    let s0 = sun_at(alpha0_deg);
    let n_p0 = panel_normal(s0, Vector3::x());
    (0..n)
        .map(|t| {
            let tf = t as f64;
            let (s, o) = (sun_at(alpha0_deg + sun_rate_deg_per_frame * tf), observer());
            let r = conv.matrix(p_true, tf);
            let (s_rot, o_rot) = (r * s, r * o);
            let n_p = match mode {
                PanelNormalMode::Literal => panel_normal(s, Vector3::x()),
                PanelNormalMode::Frozen => n_p0,
                PanelNormalMode::Tracking => panel_normal(s_rot, Vector3::x()),
            };
            let range = range_m(tf);
            Observation {
                frame_index: first_frame + t as u64,
                t_s: tf,
                sun_body: s,
                observer_body: o,
                range_m: range,
                flux_w: bands_nm
                    .iter()
                    .map(|&l| flux_w(&coeffs(l), band_scale_w(l), n_p, s_rot, o_rot, range))
                    .collect(),
                sigma_w: vec![],
            }
        })
        .collect()
}

/// The full 8-band scenario: stable window over α ∈ [−40°, 25°], motion window at phase 15°.
pub fn scenario(stable_n: usize, motion_n: usize, p_true: [f64; 3]) -> ObservationSet {
    ObservationSet {
        wavelengths_nm: BANDS_NM.to_vec(),
        stable: stable_window(stable_n, -40.0, 25.0, &BANDS_NM),
        motion: motion_window(
            motion_n,
            alpha_phase15_deg(),
            0.004_167,
            p_true,
            AttitudeConvention::Verbatim,
            PanelNormalMode::Literal,
            &BANDS_NM,
            &band_coeffs,
        ),
    }
}

/// Deterministic Gaussian noise (`glint_physics::rng`: seeded xoshiro256++, ziggurat normals).
#[allow(unused_imports)] // not every test binary draws noise
pub use glint_physics::rng::SeededRng as Gauss;

/// The 650-nm band of [`band_coeffs`] in x̃ units.
pub fn band() -> RateBand {
    RateBand {
        band_index: 0,
        wavelength_nm: 650.0,
        coeffs: scaled(&band_coeffs(650.0), band_scale_w(650.0)),
    }
}

/// The paper's Y case at 650 nm: `frames` frames at 0.25 deg/frame from phase 15°.
pub fn y_window(frames: usize) -> Vec<Observation> {
    motion_window(
        frames,
        alpha_phase15_deg(),
        0.004_167,
        [0.0, 0.25, 0.0],
        AttitudeConvention::Verbatim,
        PanelNormalMode::Literal,
        &[650.0],
        &band_coeffs,
    )
}

/// σ = mean flux / SNR on every frame; noise added when `seed` is given.
pub fn with_noise(mut obs: Vec<Observation>, snr: f64, seed: Option<u64>) -> Vec<Observation> {
    let mean = obs.iter().map(|o| o.flux_w[0]).sum::<f64>() / obs.len() as f64;
    let sigma = mean / snr;
    let mut g = Gauss::new(seed.unwrap_or(0));
    for o in &mut obs {
        o.sigma_w = vec![sigma];
        if seed.is_some() {
            o.flux_w[0] += sigma * g.gaussian();
        }
    }
    obs
}

/// A Y-dominated rotation with the Sun and the observer exactly in the body XZ plane.
pub fn in_plane_window(p_true: [f64; 3], frames: usize) -> Vec<Observation> {
    let o = Vector3::new(1.0, 0.0, -0.045).normalize();
    let alpha0 = alpha_phase15_deg();
    (0..frames)
        .map(|t| {
            let tf = t as f64;
            let a = (alpha0 + 0.004_167 * tf).to_radians();
            let s = Vector3::new(a.cos(), 0.0, a.sin());
            let r = AttitudeConvention::Verbatim.matrix(p_true, tf);
            let range = range_m(tf);
            let flux = flux_w(
                &band_coeffs(650.0),
                band_scale_w(650.0),
                panel_normal(s, Vector3::x()),
                r * s,
                r * o,
                range,
            );
            Observation {
                frame_index: 10_000 + t as u64,
                t_s: tf,
                sun_body: s,
                observer_body: o,
                range_m: range,
                flux_w: vec![flux],
                sigma_w: vec![],
            }
        })
        .collect()
}

/// Eleven 10-nm bands around 650 nm of a body whose reflectance only scales with wavelength
/// (so neighbouring bands' normalised light curves coincide), both windows carrying σ = mean /
/// `snr`, noise added to the stable window only (seeded).
pub fn fine_bands(snr: f64, seed: u64) -> (ObservationSet, ObservationSet) {
    let bands: Vec<f64> = (0..11).map(|k| 600.0 + 10.0 * k as f64).collect();
    let coeffs = |l: f64| scaled(&band_coeffs(650.0), 1.0 + 0.004 * (l - 650.0));
    let clean = ObservationSet {
        stable: stable_window_of(720, -40.0, 25.0, &bands, &coeffs),
        motion: motion_window(
            240,
            alpha_phase15_deg(),
            0.004_167,
            [0.0, 0.25, 0.0],
            glint_physics::two_facet::AttitudeConvention::Verbatim,
            glint_inversion::PanelNormalMode::Literal,
            &bands,
            &coeffs,
        ),
        wavelengths_nm: bands,
    };
    let mut noisy = clean.clone();
    let mut g = Gauss::new(seed);
    for window in [&mut noisy.stable, &mut noisy.motion] {
        let n = window.len() as f64;
        let sigma: Vec<f64> = (0..11)
            .map(|b| window.iter().map(|o| o.flux_w[b]).sum::<f64>() / n / snr)
            .collect();
        for o in window.iter_mut() {
            o.sigma_w = sigma.clone();
        }
    }
    for o in &mut noisy.stable {
        for (f, s) in o.flux_w.iter_mut().zip(&o.sigma_w) {
            *f += s * g.gaussian();
        }
    }
    (clean, noisy)
}
