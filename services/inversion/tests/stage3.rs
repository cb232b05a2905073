//! Stage 3: model vs the physics forward model, analytic Jacobian, global recovery of p.

mod common;

use common::*;
use glint_inversion::stage3::{
    fit_from_starts, fit_multistart, fit_single_start, grid_candidates, neighbouring_minima,
    Stage3Config,
};
use glint_inversion::{
    rate_error_metric, AttitudeModel, MotionModelConfig, Observation, PanelNormalMode, RateBand,
    RateProblem, RateSolution,
};
use glint_physics::two_facet::AttitudeConvention;

const MOTION_FRAMES: usize = 360;

fn table4_band() -> RateBand {
    RateBand {
        band_index: 0,
        wavelength_nm: 650.0,
        coeffs: scaled(&band_coeffs(650.0), band_scale_w(650.0)),
    }
}

fn window(p_true: [f64; 3], model: AttitudeModel, mode: PanelNormalMode) -> Vec<Observation> {
    motion_window(
        MOTION_FRAMES,
        alpha_phase15_deg(),
        0.004_167,
        p_true,
        AttitudeConvention::from(model),
        mode,
        &[650.0],
        &band_coeffs,
    )
}

fn config(model: AttitudeModel, mode: PanelNormalMode) -> MotionModelConfig {
    MotionModelConfig {
        attitude: model,
        panel_normal: mode,
        ..MotionModelConfig::default()
    }
}

/// The paper's stage-3 model (every coefficient from stage 1) and, except with the tracking
/// panel, the diffuse re-fit. (A tracking panel's diffuse term is almost constant, collinear
/// with the re-fit's constant column; the re-fit's Jacobian is checked on a well-conditioned
/// problem in `nuisance`'s unit tests.)
fn both_refits(base: MotionModelConfig) -> Vec<MotionModelConfig> {
    // (re-fit the diffuse terms, and also each facet's widest lobe)
    let refits: &[(bool, bool)] = if base.panel_normal == PanelNormalMode::Tracking {
        &[(false, false)]
    } else {
        &[(false, false), (true, false), (true, true)]
    };
    refits
        .iter()
        .map(|&(refit_diffuse, refit_widest_lobe)| MotionModelConfig {
            refit_diffuse,
            refit_widest_lobe,
            ..base.clone()
        })
        .collect()
}

const MODES: [PanelNormalMode; 3] = [
    PanelNormalMode::Literal,
    PanelNormalMode::Frozen,
    PanelNormalMode::Tracking,
];
const MODELS: [AttitudeModel; 2] = [AttitudeModel::Verbatim, AttitudeModel::Consistent];

#[test]
fn model_reproduces_the_physics_forward_model() {
    let p = [0.05, 0.2, -0.15];
    for model in MODELS {
        for mode in MODES {
            let obs = window(p, model, mode);
            let problem =
                RateProblem::new(&obs, &[table4_band()], &config(model, mode)).expect("problem");
            let flux = problem.model_flux_w(p);
            let peak = obs.iter().map(|o| o.flux_w[0]).fold(0.0, f64::max);
            for (o, f) in obs.iter().zip(&flux[0]) {
                assert!(
                    (o.flux_w[0] - f).abs() <= 1e-11 * peak,
                    "{model:?} {mode:?}: {} vs {f}",
                    o.flux_w[0]
                );
            }
            // Exact data ⇒ zero cost at the truth.
            assert!(problem.cost(p) < 1e-20);
        }
    }
}

#[test]
fn analytic_jacobian_matches_central_differences() {
    let p_data = [0.0, 0.25, 0.0];
    for model in MODELS {
        for mode in MODES {
            let obs = window(p_data, model, mode);
            for cfg in both_refits(config(model, mode)) {
                // Table 4 has no diffuse terms; add some so their derivatives are tested too.
                let mut band = table4_band();
                band.coeffs.panel[0] = 0.2 * band.coeffs.panel[5];
                band.coeffs.body[0] = 0.3 * band.coeffs.body[1];
                let problem = RateProblem::new(&obs, &[band], &cfg).expect("problem");
                let n = problem.residual_count();
                // At p = 0 the geometry barely changes over the window, so the re-fit's diffuse
                // columns are collinear with the constant one and c is not determined.
                let points: &[[f64; 3]] = if cfg.refit_diffuse {
                    &[[0.01, 0.23, -0.02], [0.1, -0.2, 0.3], [-0.05, 0.02, 0.2]]
                } else {
                    &[[0.01, 0.23, -0.02], [0.1, -0.2, 0.3], [0.0, 0.0, 0.0]]
                };
                // The re-fit's columns are nearly collinear over this short window, so c is large
                // and the differences lose about a digit to rounding. (A wider step would
                // straddle the horizon kinks of the diffuse terms, which move c and every row.)
                let h = 1e-6;
                let tol = if cfg.refit_diffuse { 1e-5 } else { 1e-6 };
                let mut skipped = 0;
                for &p in points {
                    let mut r = vec![0.0; n];
                    let mut jac = vec![[0.0; 3]; n];
                    problem.residuals_and_jacobian(p, &mut r, &mut jac);
                    let scale = jac.iter().flatten().fold(0.0_f64, |m, v| m.max(v.abs()));
                    for i in 0..3 {
                        let (mut pp, mut pm) = (p, p);
                        pp[i] += h;
                        pm[i] -= h;
                        let (mut rp, mut rm) = (vec![0.0; n], vec![0.0; n]);
                        problem.residuals(pp, &mut rp);
                        problem.residuals(pm, &mut rm);
                        // A row whose one-sided differences disagree straddles a horizon kink
                        // of the masked diffuse term; its derivative is one-sided. With the
                        // re-fit, c (and so every row) feels a kink anywhere in the window.
                        let at_kink = |t: usize| {
                            let (fwd, bwd) = (-(rp[t] - r[t]) / h, -(r[t] - rm[t]) / h);
                            (fwd - bwd).abs() > 1e3 * tol * scale
                        };
                        let kinks = (0..n).filter(|&t| at_kink(t)).count();
                        assert!(kinks <= 2, "{kinks} rows at a kink");
                        if cfg.refit_diffuse && kinks > 0 {
                            skipped += 1;
                            continue;
                        }
                        for t in 0..n {
                            // r = w(y − m) ⇒ ∂r/∂p = −J.
                            let fd = -(rp[t] - rm[t]) / (2.0 * h);
                            if at_kink(t) {
                                continue;
                            }
                            assert!(
                                (fd - jac[t][i]).abs() <= tol * scale,
                                "{model:?} {mode:?} refit {} {} p {p:?} row {t} axis {i}: {fd:e} vs {:e}",
                                cfg.refit_diffuse,
                                cfg.refit_widest_lobe,
                                jac[t][i]
                            );
                        }
                    }
                }
                assert!(skipped <= 2, "{skipped} of 9 checks skipped");
            }
        }
    }
}

fn determined(sol: &RateSolution) -> &glint_inversion::RateFit {
    match sol {
        RateSolution::Determined(f) => f,
        RateSolution::Unobservable { reason, .. } => panic!("unobservable: {reason:?}"),
    }
}

/// The default box (±0.5, 9 points) contains 0.25 exactly; the ±0.47 box puts every truth
/// between grid points, so the screen + polish has to do the work.
fn configs() -> [Stage3Config; 2] {
    let mut off_grid = Stage3Config::default();
    off_grid.start.half_width_deg_per_frame = 0.47;
    [Stage3Config::default(), off_grid]
}

fn problem_for(p_true: [f64; 3]) -> RateProblem {
    let obs = window(p_true, AttitudeModel::Verbatim, PanelNormalMode::Literal);
    RateProblem::new(&obs, &[table4_band()], &MotionModelConfig::default()).expect("problem")
}

#[test]
fn multistart_recovers_exact_rates_about_y_and_z() {
    for p_true in [[0.0, 0.25, 0.0], [0.0, 0.0, 0.25]] {
        let problem = problem_for(p_true);
        for cfg in configs() {
            let sol = fit_multistart(&problem, &cfg).expect("fit");
            let fit = determined(&sol);
            let err = rate_error_metric(fit.rate_deg_per_frame, p_true) / 100.0;
            assert!(err < 1e-6, "p* {p_true:?}: p̂ {:?}", fit.rate_deg_per_frame);
            assert_eq!(fit.grid_points, 729);
            assert_eq!(fit.starts_screened, 16);
            assert!(fit.starts_polished >= 1 && fit.starts_polished <= 3);
        }
    }
}

/// The grid's candidates, best first, from every point's full cost: the stopped evaluation of
/// `grid_candidates` must give the same points in the same order.
fn brute_force_candidates(problem: &RateProblem, cfg: &Stage3Config) -> Vec<[f64; 3]> {
    let (n, h) = (
        cfg.start.points_per_axis,
        cfg.start.half_width_deg_per_frame,
    );
    let axis: Vec<f64> = (0..n)
        .map(|k| -h + 2.0 * h * k as f64 / (n - 1) as f64)
        .collect();
    let stride = problem.frame_count().div_ceil(cfg.start.max_grid_frames);
    let mut scored = Vec::new();
    for &x in &axis {
        for &y in &axis {
            for &z in &axis {
                let c = problem.cost_strided([x, y, z], stride);
                scored.push((if c.is_finite() { c } else { f64::INFINITY }, [x, y, z]));
            }
        }
    }
    scored.sort_by(|a, b| a.0.total_cmp(&b.0));
    scored.truncate(cfg.start.screen_starts);
    scored.into_iter().map(|(_, p)| p).collect()
}

#[test]
fn the_grid_stopping_early_keeps_the_full_costs_candidates() {
    for p_true in [[0.0, 0.25, 0.0], [0.0, 0.0, 0.25], [0.05, 0.2, -0.1]] {
        let problem = problem_for(p_true);
        for cfg in configs() {
            let want = brute_force_candidates(&problem, &cfg);
            let (candidates, evaluated) = grid_candidates(&problem, &cfg.start);
            assert_eq!(evaluated, 729);
            assert_eq!(candidates, want, "p* {p_true:?}");
        }
    }
}

#[test]
fn a_cost_within_its_bound_is_the_full_cost_and_one_beyond_stops_above_it() {
    let problem = problem_for([0.0, 0.25, 0.0]);
    for p in [[0.0, 0.25, 0.0], [0.1, -0.3, 0.2], [0.5, 0.5, 0.5]] {
        let full = problem.cost_strided(p, 3);
        let within = problem.cost_strided_within(p, 3, full);
        assert_eq!(within.to_bits(), full.to_bits());
        if full > 0.0 {
            let stopped = problem.cost_strided_within(p, 3, 0.5 * full);
            assert!(
                stopped > 0.5 * full && stopped <= full,
                "{stopped} of {full}"
            );
        }
    }
}

/// LM's trials stop once their cost passes the current one; a trial that does not stop must be
/// the full evaluation, bit for bit, and the re-fitting model (which projects at the end) never
/// stops.
#[test]
fn residuals_within_their_bound_are_the_full_evaluation() {
    let plain = problem_for([0.0, 0.25, 0.0]);
    let obs = window(
        [0.0, 0.25, 0.0],
        AttitudeModel::Verbatim,
        PanelNormalMode::Literal,
    );
    let refit = RateProblem::new(
        &obs,
        &[table4_band()],
        &MotionModelConfig {
            refit_diffuse: true,
            ..MotionModelConfig::default()
        },
    )
    .expect("problem");
    for problem in [&plain, &refit] {
        let n = problem.residual_count();
        for p in [[0.0, 0.25, 0.0], [0.1, -0.3, 0.2], [0.5, 0.5, 0.5]] {
            let (mut r, mut jac) = (vec![0.0; n], vec![[0.0; 3]; n]);
            let full = problem.residuals_and_jacobian(p, &mut r, &mut jac);
            let sum_sq: f64 = r.iter().map(|v| v * v).sum();
            assert_eq!(full.to_bits(), sum_sq.to_bits());
            let (mut r2, mut jac2) = (vec![0.0; n], vec![[0.0; 3]; n]);
            let within = problem.residuals_and_jacobian_within(p, &mut r2, &mut jac2, full);
            assert_eq!(within.to_bits(), full.to_bits());
            assert!(r2.iter().zip(&r).all(|(a, b)| a.to_bits() == b.to_bits()));
            assert!(jac2.iter().zip(&jac).all(|(a, b)| a == b));
            if full > 0.0 {
                let stopped =
                    problem.residuals_and_jacobian_within(p, &mut r2, &mut jac2, 0.5 * full);
                if problem.refits_diffuse() {
                    assert_eq!(stopped.to_bits(), full.to_bits());
                } else {
                    assert!(
                        stopped > 0.5 * full && stopped <= full,
                        "{stopped} of {full}"
                    );
                }
            }
        }
    }
}

#[test]
fn multistart_recovers_off_axis_rates() {
    for p_true in [
        [0.03, 0.21, -0.04],
        [0.0, -0.25, 0.0],
        [0.0, 0.0, -0.25],
        [-0.1, 0.15, 0.2],
    ] {
        let problem = problem_for(p_true);
        let sol = fit_multistart(&problem, &configs()[1]).expect("fit");
        let fit = determined(&sol);
        let err = rate_error_metric(fit.rate_deg_per_frame, p_true) / 100.0;
        assert!(err < 1e-6, "p* {p_true:?}: p̂ {:?}", fit.rate_deg_per_frame);
    }
}

#[test]
fn single_start_at_zero_falls_into_a_wrong_minimum() {
    // Rotation about Y at 0.25 deg/frame (§1.6 findings: p₀ = 0 fails in this geometry).
    let p_true = [0.0, 0.25, 0.0];
    let problem = problem_for(p_true);
    let cfg = Stage3Config::default();
    let single = fit_single_start(&problem, [0.0; 3], &cfg).expect("single");
    let single = determined(&single);
    let multi = fit_multistart(&problem, &configs()[1]).expect("multi");
    let multi = determined(&multi);
    assert_eq!(single.grid_points, 0);
    assert_eq!(single.starts_polished, 1);
    assert!(rate_error_metric(single.rate_deg_per_frame, p_true) > 5.0);
    assert!(
        single.cost > 1e-4,
        "a genuine minimum with a clearly worse cost"
    );
    assert!(rate_error_metric(multi.rate_deg_per_frame, p_true) < 1e-4);
    assert!(multi.cost < 1e-18);
}

/// Bands at `bands_nm` with their Table-4 coefficients, and a motion window of `frames` at
/// `p_true` (phase 15°, verbatim attitude, literal panel normal).
fn bands_and_window(
    bands_nm: &[f64],
    p_true: [f64; 3],
    frames: usize,
) -> (Vec<RateBand>, Vec<Observation>) {
    let bands = bands_nm
        .iter()
        .enumerate()
        .map(|(b, &l)| RateBand {
            band_index: b,
            wavelength_nm: l,
            coeffs: scaled(&band_coeffs(l), band_scale_w(l)),
        })
        .collect();
    let obs = motion_window(
        frames,
        alpha_phase15_deg(),
        0.004_167,
        p_true,
        AttitudeConvention::Verbatim,
        PanelNormalMode::Literal,
        bands_nm,
        &band_coeffs,
    );
    (bands, obs)
}

#[test]
fn analytic_jacobian_matches_central_differences_in_a_joint_fit() {
    let (bands, obs) = bands_and_window(&[600.0, 650.0, 700.0], [0.0, 0.0, 0.25], 120);
    let problem = RateProblem::new(&obs, &bands, &MotionModelConfig::default()).expect("joint");
    assert_eq!(problem.residual_count(), 360);
    let p = [0.02, -0.05, 0.2];
    let n = problem.residual_count();
    let (mut r, mut jac) = (vec![0.0; n], vec![[0.0; 3]; n]);
    problem.residuals_and_jacobian(p, &mut r, &mut jac);
    let scale = jac.iter().flatten().fold(0.0_f64, |m, v| m.max(v.abs()));
    for i in 0..3 {
        let (mut pp, mut pm) = (p, p);
        pp[i] += 1e-6;
        pm[i] -= 1e-6;
        let (mut rp, mut rm) = (vec![0.0; n], vec![0.0; n]);
        problem.residuals(pp, &mut rp);
        problem.residuals(pm, &mut rm);
        for t in 0..n {
            let fd = -(rp[t] - rm[t]) / 2e-6;
            assert!((fd - jac[t][i]).abs() <= 1e-6 * scale, "row {t} axis {i}");
        }
    }
    // The joint fit recovers the truth too.
    let sol = fit_multistart(&problem, &configs()[1]).expect("fit");
    let fit = determined(&sol);
    assert!(rate_error_metric(fit.rate_deg_per_frame, [0.0, 0.0, 0.25]) < 1e-4);
    assert_eq!(fit.wavelengths_nm, vec![600.0, 650.0, 700.0]);
}

#[test]
fn model_matches_math_md_7_3d() {
    // §7.3d: Table-4 coefficients, n_p held, 10 frames at p = [0, 0, 0.25] (verbatim R).
    let s = nalgebra::Vector3::new(0.95, 0.05, -0.30).normalize();
    let o = nalgebra::Vector3::new(0.999, 0.0, -0.045).normalize();
    let obs: Vec<Observation> = (0..=10)
        .map(|t| Observation {
            frame_index: t,
            t_s: t as f64,
            sun_body: s,
            observer_body: o,
            range_m: 1.0,
            flux_w: vec![1.0],
            sigma_w: vec![],
        })
        .collect();
    let band = RateBand {
        band_index: 0,
        wavelength_nm: 650.0,
        coeffs: glint_physics::two_facet::TwoFacetCoefficients::table4(),
    };
    let cfg = config(AttitudeModel::Verbatim, PanelNormalMode::Frozen);
    let problem = RateProblem::new(&obs, &[band], &cfg).expect("problem");
    let q = problem.model_flux_w([0.0, 0.0, 0.25]);
    assert!((q[0][0] - 0.576001335733).abs() < 1e-11);
    assert!((q[0][10] - (0.593846662657 + 0.0139996787073)).abs() < 1e-11);
}

/// A re-fitting polish started half a frame's shift from the truth (δ = |p|/T for T frames;
/// noise-free data of the same model, every band's diffuse terms and widest lobe re-fitted):
/// LM alone ends in a neighbouring minimum, where a narrow glint falls on the next sample; the
/// neighbour search (which the joint fit's lobe test reads) finds the truth a frame's shift
/// away, fitting clearly better.
#[test]
fn the_neighbour_search_finds_the_lower_minimum_a_frame_s_shift_away() {
    let (p_true, frames) = ([0.0, 0.0, 0.25], 100);
    let (bands, obs) = bands_and_window(&[450.0, 550.0, 650.0, 750.0], p_true, frames);
    let model = MotionModelConfig {
        refit_diffuse: true,
        refit_widest_lobe: true,
        ..MotionModelConfig::default()
    };
    let problem = RateProblem::new(&obs, &bands, &model).expect("problem");
    let step = 0.25 / frames as f64;
    let start = [0.0, 0.5 * step, 0.25 + 0.5 * step];
    let cfg = Stage3Config::default();
    let single = fit_from_starts(&problem, &[start], &cfg).expect("single");
    let stuck = determined(&single);
    assert!(
        rate_error_metric(stuck.rate_deg_per_frame, p_true) > 0.1 && stuck.cost > 1e-3,
        "LM alone stays in the neighbouring minimum: {:?}, cost {:e}",
        stuck.rate_deg_per_frame,
        stuck.cost
    );
    let neighbours = neighbouring_minima(&problem, stuck, &cfg).expect("neighbours");
    let truth = neighbours
        .iter()
        .find(|n| rate_error_metric(n.rate_deg_per_frame, p_true) < 1e-6)
        .copied()
        .expect("the truth among the neighbours");
    assert!(truth.delta_chi2 < -4.0, "{truth:?}");
    assert_eq!(neighbours[0], truth, "the best first");
}

/// λ*'s curve of a joint answer, evaluated on λ* alone with the lobes the joint fit re-fitted
/// (what a solve response carries, and what the report draws), is the joint model's row for
/// λ*; choosing the lobes from λ* alone is not.
#[test]
fn one_band_with_the_joint_fits_lobes_is_the_joint_models_row() {
    let p = [0.0, 0.25, 0.0];
    let wavelengths = [650.0, 500.0];
    let obs = motion_window(
        120,
        alpha_phase15_deg(),
        0.004_167,
        p,
        AttitudeConvention::from(AttitudeModel::Verbatim),
        PanelNormalMode::Literal,
        &wavelengths,
        &band_coeffs,
    );
    let band = |i: usize| RateBand {
        band_index: i,
        wavelength_nm: wavelengths[i],
        coeffs: scaled(&band_coeffs(wavelengths[i]), band_scale_w(wavelengths[i])),
    };
    // λ* (band 0) without each facet's widest lobe: over both bands the widest in use is band
    // 1's, over λ* alone a narrower one.
    let mut chosen = band(0);
    for c in [&mut chosen.coeffs.panel, &mut chosen.coeffs.body] {
        if let Some(k) = (1..c.len()).rev().find(|&k| c[k] != 0.0) {
            c[k] = 0.0;
        }
    }
    let model = MotionModelConfig {
        refit_diffuse: true,
        refit_widest_lobe: true,
        ..config(AttitudeModel::Verbatim, PanelNormalMode::Literal)
    };
    let joint = RateProblem::new(&obs, &[chosen, band(1)], &model).expect("joint");
    assert!(
        joint.refits_widest_lobe(),
        "the case needs a broad lobe re-fitted"
    );
    let row = joint.model_flux_w(p).swap_remove(0);
    let alone = |widest_lobes| {
        let m = MotionModelConfig {
            widest_lobes,
            ..model.clone()
        };
        let problem = RateProblem::new(&obs, std::slice::from_ref(&chosen), &m).expect("one band");
        (
            problem.refit_lobes(),
            problem.model_flux_w(p).swap_remove(0),
        )
    };
    let max_rel = |curve: &[f64]| {
        row.iter()
            .zip(curve)
            .map(|(a, b)| ((a - b) / a.abs().max(1e-300)).abs())
            .fold(0.0, f64::max)
    };
    let (lobes, curve) = alone(Some(joint.refit_lobes()));
    assert_eq!(lobes, joint.refit_lobes());
    assert!(max_rel(&curve) < 1e-12, "{}", max_rel(&curve));
    let (own_lobes, own_curve) = alone(None);
    assert_ne!(own_lobes, joint.refit_lobes());
    assert!(max_rel(&own_curve) > 1e-6, "{}", max_rel(&own_curve));
}
