//! What stage 3 owes to the stage-1 coefficients' uncertainty: its propagation into the rates'
//! covariance (against a Monte Carlo) and the information about p lost to unknown coefficients
//! (against the whole Fisher matrix).

mod common;

use common::*;
use glint_inversion::stage3::Stage3Config;
use glint_inversion::{MotionModelConfig, RateProblem};

#[test]
fn coefficient_uncertainty_propagates_into_the_rate_covariance() {
    let p_true = [0.0, 0.25, 0.0];
    let obs = with_noise(y_window(120), 50.0, None); // σ given, no noise added
    let b = band();
    let x = glint_inversion::stage1::coefficients_to_array(&b.coeffs);
    // 3 % 1σ on every active coefficient, independent.
    let n = x.len();
    let mut cov = vec![0.0; n * n];
    for m in 0..n {
        cov[m * n + m] = (REL * x[m]).powi(2);
    }
    let config = MotionModelConfig::default();
    let plain = RateProblem::new(&obs, &[b], &config).expect("problem");
    let with = plain
        .clone()
        .with_coefficient_covariance(vec![Some(cov.clone())]);
    let obs_cfg = glint_inversion::observability::ObservabilityConfig::default();
    let a0 = glint_inversion::observability::analyse(&plain, p_true, &obs_cfg).expect("a0");
    let a1 = glint_inversion::observability::analyse(&with, p_true, &obs_cfg).expect("a1");
    let term: [[f64; 3]; 3] =
        std::array::from_fn(|i| std::array::from_fn(|j| a1.covariance[i][j] - a0.covariance[i][j]));
    // Monte Carlo over coefficient draws (LM from the truth; the data stay exact). The flat
    // bisector is held as stage 3 holds it: free, a coefficient change would swing the fit far
    // along it, out of the linear regime the propagation describes.
    let hold = glint_inversion::lm::Prior {
        directions: vec![a0.observability.eigenvectors[0]],
        weight: 1e6 * a0.observability.information_eigenvalues[2],
    };
    let mut g = Gauss::new(7);
    let draws = 200;
    let mut second = [[0.0; 3]; 3];
    let lm = Stage3Config::default().lm;
    for _ in 0..draws {
        let mut drawn = b;
        for m in 0..11 {
            drawn.coeffs.panel[m] *= 1.0 + REL * g.gaussian();
            drawn.coeffs.body[m] *= 1.0 + REL * g.gaussian();
        }
        let problem = RateProblem::new(&obs, &[drawn], &config).expect("problem");
        let p = glint_inversion::lm::levenberg_marquardt_prior(
            &problem,
            p_true,
            &lm,
            &hold,
            |_, _, _| false,
        )
        .expect("lm")
        .p_deg_per_frame;
        for i in 0..3 {
            for j in 0..3 {
                second[i][j] += (p[i] - p_true[i]) * (p[j] - p_true[j]) / draws as f64;
            }
        }
    }
    // Along the best-determined direction v: linearised propagation against the scatter,
    // within the Monte-Carlo error of 200 draws (≈ 10 % on a variance).
    let v = a0.observability.eigenvectors[2];
    let quad = |m: &[[f64; 3]; 3]| -> f64 {
        (0..3)
            .map(|i| (0..3).map(|j| v[i] * m[i][j] * v[j]).sum::<f64>())
            .sum()
    };
    let (lin, mc) = (quad(&term), quad(&second));
    assert!(lin > 0.0 && mc > 0.0, "{term:?} {second:?}");
    assert!(
        (lin / mc - 1.0).abs() < 0.3,
        "propagated {lin:e} vs Monte Carlo {mc:e}"
    );
}

/// Relative 1σ of every coefficient in the propagation test.
const REL: f64 = 0.03;

/// The information about p lost to unknown coefficients, `L = Σ F_pb (S_b + BᵀB)⁻¹ F_bp`,
/// against a second method: the full Fisher matrix of (p, x) built from a Jacobian in x taken
/// by perturbing the coefficients (the model is linear in them), inverted whole; its p-block
/// is the Cramér–Rao bound `(JᵀJ − L)⁻¹`.
#[test]
fn coefficient_information_loss_is_the_schur_complement_of_the_full_fisher() {
    use nalgebra::DMatrix;
    let p = [0.0, 0.25, 0.0];
    let obs = with_noise(y_window(120), 50.0, None);
    let b = band();
    let x = glint_inversion::stage1::coefficients_to_array(&b.coeffs);
    let n = x.len();
    let free: Vec<usize> = (0..n).filter(|&m| x[m] > 0.0).collect();
    let mut cov = vec![0.0; n * n];
    for &m in &free {
        cov[m * n + m] = (REL * x[m]).powi(2);
    }
    let config = MotionModelConfig::default();
    let problem = RateProblem::new(&obs, &[b], &config)
        .expect("problem")
        .with_coefficient_covariance(vec![Some(cov.clone())]);
    let rows = problem.residual_count();
    let (mut r0, mut jac) = (vec![0.0; rows], vec![[0.0; 3]; rows]);
    problem.residuals_and_jacobian(p, &mut r0, &mut jac);
    let loss = problem.coefficient_information_loss(p, &jac).expect("loss");
    let fisher: [[f64; 3]; 3] = std::array::from_fn(|i| {
        std::array::from_fn(|j| jac.iter().map(|row| row[i] * row[j]).sum::<f64>())
    });
    let reduced = DMatrix::from_fn(3, 3, |i, j| fisher[i][j] - loss[i][j]);
    let crb = reduced.try_inverse().expect("invertible");

    // Second method: B by perturbation, K = [[JᵀJ, JᵀB], [BᵀJ, BᵀB + S]].
    let k = free.len();
    let mut big_b = DMatrix::zeros(rows, k);
    for (c, &m) in free.iter().enumerate() {
        let delta = 1e-3 * x[m];
        let mut moved = b;
        if m < 11 {
            moved.coeffs.panel[m] += delta;
        } else {
            moved.coeffs.body[m - 11] += delta;
        }
        let mut r = vec![0.0; rows];
        RateProblem::new(&obs, &[moved], &config)
            .expect("problem")
            .residuals(p, &mut r);
        for t in 0..rows {
            big_b[(t, c)] = -(r[t] - r0[t]) / delta;
        }
    }
    let big_j = DMatrix::from_fn(rows, 3, |t, i| jac[t][i]);
    let mut full = DMatrix::zeros(3 + k, 3 + k);
    full.view_mut((0, 0), (3, 3))
        .copy_from(&(big_j.transpose() * &big_j));
    let jb = big_j.transpose() * &big_b;
    full.view_mut((0, 3), (3, k)).copy_from(&jb);
    full.view_mut((3, 0), (k, 3)).copy_from(&jb.transpose());
    let mut bb = big_b.transpose() * &big_b;
    for (c, &m) in free.iter().enumerate() {
        bb[(c, c)] += 1.0 / cov[m * n + m];
    }
    full.view_mut((3, 3), (k, k)).copy_from(&bb);
    let inverse = full.try_inverse().expect("full Fisher invertible");
    for i in 0..3 {
        for j in 0..3 {
            let scale = (crb[(i, i)] * crb[(j, j)]).sqrt();
            assert!(
                (inverse[(i, j)] - crb[(i, j)]).abs() < 1e-6 * scale,
                "({i},{j}): full {:e} vs Schur {:e}",
                inverse[(i, j)],
                crb[(i, j)]
            );
        }
    }
    // Unknown coefficients cost information: the bound exceeds F⁻¹ along every direction.
    let known = DMatrix::from_fn(3, 3, |i, j| fisher[i][j])
        .try_inverse()
        .expect("F");
    for i in 0..3 {
        assert!(
            crb[(i, i)] > known[(i, i)],
            "{i}: {} vs {}",
            crb[(i, i)],
            known[(i, i)]
        );
    }
    // The two-stage covariance F⁻¹ + F⁻¹CF⁻¹ (coefficients from the stable window alone,
    // plugged in: the campaigns' two-stage bound) cannot beat the bound: its excess over the
    // CRB is positive semi-definite, and not zero, since the motion window informs the
    // coefficients too.
    let c = problem.coefficient_term(p, &jac).expect("term");
    let c = DMatrix::from_fn(3, 3, |i, j| c[i][j]);
    let two_stage = &known + &known * c * &known;
    let excess = (&two_stage - &crb).symmetric_eigen();
    let largest = excess.eigenvalues.amax();
    for e in excess.eigenvalues.iter() {
        assert!(*e >= -1e-9 * largest, "two-stage − CRB eigenvalue {e:e}");
    }
    assert!(largest > 1e-3 * crb.trace(), "{excess:?}");
}
