//! Is stage 3 efficient and honest? 50 noisy fits of the paper's Y case at SNR 20 with exact
//! coefficients (stage 3 alone): the scatter about the truth along every determined Fisher
//! direction against the Cramér–Rao bound, and the NEES of the reported covariances over their
//! determined directions against its 95 % χ² interval, with the local covariance and with the
//! profile-likelihood intervals (`stage3.profile_intervals`).
//!
//! At SNR 10 the single-band cost has, in a few runs in ten, a second minimum as deep as the
//! true one ([0.023, 0.232, 0.094] beside [0, 0.25, 0]); those runs are ambiguous, not
//! inefficient, and `campaign-efficiency.toml` shows the figures.

mod common;

use common::*;
use glint_inversion::lm::normal_equations;
use glint_inversion::observability::symmetric_eigen;
use glint_inversion::{
    fit_within_horizon, rate_error_metric, MotionModelConfig, Observation, PanelNormalMode,
    RateBand, RateProblem, Stage3Config,
};
use glint_physics::two_facet::AttitudeConvention;

const SEEDS: u64 = 50;
const SNR: f64 = 20.0;
/// 1σ above which a direction is unobservable (stage 3's default threshold) \[deg/frame\].
const BOUND: f64 = 0.25;

fn noisy(clean: &[Observation], seed: u64) -> Vec<Observation> {
    let mean = clean.iter().map(|o| o.flux_w[0]).sum::<f64>() / clean.len() as f64;
    let sigma = mean / SNR;
    let mut g = Gauss::new(seed);
    clean
        .iter()
        .map(|o| {
            let mut o = o.clone();
            o.sigma_w = vec![sigma];
            o.flux_w[0] += sigma * g.gaussian();
            o
        })
        .collect()
}

/// The paper's Y case: the noise-free window, its band and the true rate.
fn y_case() -> (Vec<Observation>, RateBand, [f64; 3]) {
    let p_true = [0.0, 0.25, 0.0];
    let clean = motion_window(
        360,
        alpha_phase15_deg(),
        0.004_167,
        p_true,
        AttitudeConvention::Verbatim,
        PanelNormalMode::Literal,
        &[650.0],
        &band_coeffs,
    );
    let band = RateBand {
        band_index: 0,
        wavelength_nm: 650.0,
        coeffs: scaled(&band_coeffs(650.0), band_scale_w(650.0)),
    };
    (clean, band, p_true)
}

/// The CRB at the truth on the frames a fit at the true rate uses (its horizon), for the model
/// `model`, within the plane e·p = 0 when the fit holds e: (1σ, direction) per eigen-pair.
fn bound(
    clean: &[Observation],
    band: RateBand,
    p_true: [f64; 3],
    model: &MotionModelConfig,
    held: Option<[f64; 3]>,
) -> ([f64; 3], [[f64; 3]; 3]) {
    let speed = p_true.iter().map(|v| v * v).sum::<f64>().sqrt();
    let horizon = (30.0 / speed) as usize + 1;
    let with_sigma = noisy(clean, 0);
    let problem = RateProblem::new(&with_sigma[..horizon], &[band], model).expect("problem");
    let n = problem.residual_count();
    let (mut r, mut jac) = (vec![0.0; n], vec![[0.0; 3]; n]);
    problem.residuals_and_jacobian(p_true, &mut r, &mut jac);
    let (mut fisher, _) = normal_equations(&jac, &r);
    if let Some(e) = held {
        // P F P with P = I − e eᵀ: the information within the plane the fit is held on.
        let p: [[f64; 3]; 3] = std::array::from_fn(|i| {
            std::array::from_fn(|j| f64::from(u8::from(i == j)) - e[i] * e[j])
        });
        let pf: [[f64; 3]; 3] = std::array::from_fn(|i| {
            std::array::from_fn(|j| (0..3).map(|k| p[i][k] * fisher[k][j]).sum())
        });
        fisher = std::array::from_fn(|i| {
            std::array::from_fn(|j| (0..3).map(|k| pf[i][k] * p[k][j]).sum())
        });
    }
    let (info, dirs) = symmetric_eigen(&fisher).expect("eigen");
    (
        info.map(|l| {
            if l > 0.0 {
                l.sqrt().recip()
            } else {
                f64::INFINITY
            }
        }),
        dirs,
    )
}

/// 50 noisy fits with `config`: RMS about the truth along each determined bound direction
/// ≤ 1.25 CRB, and the mean NEES of the reported covariances over their determined
/// directions inside its 95 % interval.
fn assert_efficient_and_honest(config: &Stage3Config, crb: [f64; 3], dirs: [[f64; 3]; 3]) {
    let (clean, band, p_true) = y_case();
    let model = MotionModelConfig::default();
    let determined = crb.map(|b| b <= BOUND);
    let mut dev2 = [0.0; 3];
    let (mut nees_sum, mut nees_dof) = (0.0, 0);
    for seed in 1..=SEEDS {
        let obs = noisy(&clean, seed);
        let (sol, _) = fit_within_horizon(&obs, &[band], &[None], &model, config).expect("fit");
        let fit = sol.fit().expect("determined");
        // The Sun and the observer lie in the body XZ plane here, so p and its mirror
        // (−w_x, w_y, −w_z) fit equally well (and stage 3 says so): a fit that landed on
        // the mirror is mapped back, with its covariance, before comparing.
        let p = fit.rate_deg_per_frame;
        let mirror = [-1.0, 1.0, -1.0];
        let near_mirror =
            rate_error_metric([-p[0], p[1], -p[2]], p_true) < rate_error_metric(p, p_true);
        let m = if near_mirror { mirror } else { [1.0; 3] };
        let cov: [[f64; 3]; 3] = std::array::from_fn(|i| {
            std::array::from_fn(|j| m[i] * m[j] * fit.covariance_deg2_per_frame2[i][j])
        });
        let d: [f64; 3] = std::array::from_fn(|i| m[i] * p[i] - p_true[i]);
        for (acc, v) in dev2.iter_mut().zip(&dirs) {
            *acc += (0..3).map(|i| v[i] * d[i]).sum::<f64>().powi(2);
        }
        let (vals, vecs) = symmetric_eigen(&cov).expect("eigen");
        for (var, v) in vals.iter().zip(&vecs) {
            if var.sqrt() > BOUND {
                continue; // reported as unobservable: no claim to check
            }
            let x: f64 = (0..3).map(|i| v[i] * d[i]).sum();
            nees_sum += x * x / var;
            nees_dof += 1;
        }
    }
    for i in (0..3).filter(|&i| determined[i]) {
        let rms = (dev2[i] / SEEDS as f64).sqrt();
        assert!(
            rms <= 1.25 * crb[i],
            "direction {:?}: RMS {rms:.3e} vs CRB {:.3e}",
            dirs[i],
            crb[i]
        );
    }
    // Mean NEES of 50 two-dimensional errors: χ²(100)/50 ∈ [1.48, 2.59] at 95 %.
    let mean = nees_sum / SEEDS as f64;
    assert_eq!(nees_dof, 2 * SEEDS as usize);
    assert!((1.48..=2.59).contains(&mean), "mean NEES {mean:.2}");
}

#[test]
fn y_rates_are_fitted_at_the_cramer_rao_bound_with_honest_covariances() {
    // The paper's model throughout (no diffuse re-fit): every coefficient known.
    let (clean, band, p_true) = y_case();
    let config = Stage3Config {
        refit_diffuse: false,
        ..Stage3Config::default()
    };
    let (crb, dirs) = bound(&clean, band, p_true, &MotionModelConfig::default(), None);
    // The bisector is the one direction the data cannot determine.
    assert_eq!(crb.map(|b| b <= BOUND), [false, true, true], "{crb:?}");
    assert_efficient_and_honest(&config, crb, dirs);
}

#[test]
fn the_diffuse_re_fit_is_efficient_and_honest_for_its_own_model() {
    // The default polish re-estimates the diffuse terms and a constant, and holds the body
    // axis nearest the bisector (X here) at w_x = 0: its bound is that model's, within the
    // plane w_x = 0.
    let (clean, band, p_true) = y_case();
    let refit = MotionModelConfig {
        refit_diffuse: true,
        ..MotionModelConfig::default()
    };
    let (crb, dirs) = bound(&clean, band, p_true, &refit, Some([1.0, 0.0, 0.0]));
    let (paper, _) = bound(&clean, band, p_true, &MotionModelConfig::default(), None);
    assert_eq!(crb.map(|b| b <= BOUND), [false, true, true], "{crb:?}");
    // Re-fitting three terms per band costs information: its bound is wider.
    assert!(
        crb[1] >= paper[1] && crb[2] >= paper[2],
        "{crb:?} vs {paper:?}"
    );
    assert_efficient_and_honest(&Stage3Config::default(), crb, dirs);
}
