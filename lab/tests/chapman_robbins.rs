//! The Hammersley–Chapman–Robbins bound against its two closed forms: where the light curve is
//! linear in p over the offsets that matter it equals the Cramér–Rao bound, and where two rates
//! give the same light curve (a rate and its mirror, every geometry vector in the body XZ plane)
//! no unbiased estimator exists and it is unbounded.

#[path = "../../services/inversion/tests/common/mod.rs"]
mod common;

use common::*;
use glint_inversion::lm::normal_equations;
use glint_inversion::observability::symmetric_eigen;
use glint_inversion::stage3::mirror;
use glint_inversion::{MotionModelConfig, RateProblem};
use glint_lab::chapman_robbins::chapman_robbins;

/// Fisher eigenvalues and eigen-directions at p.
fn fisher_eigen(problem: &RateProblem, p: [f64; 3]) -> ([f64; 3], [[f64; 3]; 3]) {
    let n = problem.residual_count();
    let (mut r, mut jac) = (vec![0.0; n], vec![[0.0; 3]; n]);
    problem.residuals_and_jacobian(p, &mut r, &mut jac);
    let (fisher, _) = normal_equations(&jac, &r);
    symmetric_eigen(&fisher).expect("eigen")
}

#[test]
fn equals_the_cramer_rao_bound_where_the_light_curve_is_linear() {
    // SNR 10⁴: the offsets that matter are far below the scale of the light curve's curvature.
    let obs = with_noise(y_window(100), 1e4, None);
    let p = [0.0, 0.25, 0.0];
    let problem = RateProblem::new(&obs, &[band()], &MotionModelConfig::default()).expect("p");
    let (info, dirs) = fisher_eigen(&problem, p);
    // The two determined directions (the weakest, ≈ body X, is the bisector).
    for i in 1..3 {
        let crb = info[i].recip();
        let free: Vec<[f64; 3]> = (1..3).filter(|&k| k != i).map(|k| dirs[k]).collect();
        let hcr = chapman_robbins(&problem, p, dirs[i], &free, crb.sqrt(), 0.25).expect("b");
        let ratio = hcr.variance / crb;
        assert!(hcr.copy.is_none(), "{hcr:?}");
        assert!(
            (0.99..=1.01).contains(&ratio),
            "direction {:?}: HCR/CRB = {ratio} ({hcr:?})",
            dirs[i]
        );
    }
}

#[test]
fn is_unbounded_when_the_mirror_rate_gives_the_same_light_curve() {
    let p = [0.0, 0.25, 0.01];
    let obs = with_noise(in_plane_window(p, 100), 20.0, None);
    let problem = RateProblem::new(&obs, &[band()], &MotionModelConfig::default()).expect("p");
    // The mirror fits exactly as well: the premise of the closed form.
    let mut r0 = vec![0.0; problem.residual_count()];
    let mut r1 = r0.clone();
    problem.residuals(p, &mut r0);
    problem.residuals(mirror(p), &mut r1);
    let gap: f64 = r0.iter().zip(&r1).map(|(a, b)| (a - b).powi(2)).sum();
    assert!(gap < 1e-12, "Δ(mirror) = {gap}");
    let (info, dirs) = fisher_eigen(&problem, p);
    // Along the determined direction nearest Z (dirs[1]; dirs[0] is the bisector, ≈ body X),
    // profiled over the other determined one, as the campaigns do.
    assert!(dirs[1][2].abs() > 0.9 && dirs[0][0].abs() > 0.9, "{dirs:?}");
    let i = 1;
    let crb = info[i].recip();
    let free = [dirs[2]];
    let hcr = chapman_robbins(&problem, p, dirs[i], &free, crb.sqrt(), 0.05).expect("b");
    assert!(
        hcr.variance > 1e4 * crb,
        "HCR {:.3e} vs CRB {crb:.3e} ({hcr:?})",
        hcr.variance
    );
    // The mirror is found as a copy of p, at its offset along the direction.
    let copy = hcr.copy.expect("the mirror is a copy");
    assert!(copy.divergence < 1e-3, "{copy:?}");
    // The supremum sits at the mirror's offset along the direction.
    let to_mirror: f64 = (0..3).map(|k| dirs[i][k] * (mirror(p)[k] - p[k])).sum();
    for offset in [hcr.offset_deg_per_frame, copy.offset_deg_per_frame] {
        assert!(
            (offset - to_mirror).abs() < 0.2 * to_mirror.abs(),
            "offset {offset} vs mirror at {to_mirror}"
        );
    }
}

#[test]
fn finds_a_copy_whose_well_is_narrower_than_the_offset_grid() {
    // The exact mirror at SNR 10⁴: Δ < 1 only within about one CRB (≈ 1e-5 deg/frame) of the
    // mirror, while the offset grid steps by 15 % (≈ 3e-3 deg/frame there). The dip of Δ between
    // two grid points must still be refined into the copy, and the supremum found in it.
    let p = [0.0, 0.25, 0.01];
    let obs = with_noise(in_plane_window(p, 100), 1e4, None);
    let problem = RateProblem::new(&obs, &[band()], &MotionModelConfig::default()).expect("p");
    let (info, dirs) = fisher_eigen(&problem, p);
    let i = 1;
    let crb = info[i].recip();
    let hcr = chapman_robbins(&problem, p, dirs[i], &[dirs[2]], crb.sqrt(), 0.05).expect("b");
    let to_mirror: f64 = (0..3).map(|k| dirs[i][k] * (mirror(p)[k] - p[k])).sum();
    assert!(
        to_mirror.abs() > 1e3 * crb.sqrt(),
        "the well must be narrow: mirror at {to_mirror}, CRB 1σ {:.1e}",
        crb.sqrt()
    );
    let copy = hcr.copy.expect("the mirror is a copy");
    assert!(copy.divergence < 1.0, "{copy:?}");
    assert!(
        (copy.offset_deg_per_frame - to_mirror).abs() < 1e-2 * to_mirror.abs(),
        "copy at {} vs mirror at {to_mirror}",
        copy.offset_deg_per_frame
    );
    // The bound sees it: (v·h)²/(e^Δ − 1) at the copy dwarfs the CRB.
    assert!(
        hcr.variance > 1e4 * crb,
        "HCR {:.3e} vs CRB {crb:.3e}",
        hcr.variance
    );
}

#[test]
fn with_the_coefficients_unknown_tends_to_their_cramer_rao_bound() {
    // A stage-1 covariance (3 % 1σ on every active coefficient) makes the coefficients
    // parameters of the test points too: where the light curve is linear the bound is then the
    // Cramér–Rao bound with them unknown, (JᵀJ − L)⁻¹, not (JᵀJ)⁻¹.
    let obs = with_noise(y_window(100), 1e4, None);
    let p = [0.0, 0.25, 0.0];
    let b = band();
    let x = glint_inversion::stage1::coefficients_to_array(&b.coeffs);
    let n = x.len();
    let mut cov = vec![0.0; n * n];
    for m in (0..n).filter(|&m| x[m] > 0.0) {
        cov[m * n + m] = (0.03 * x[m]).powi(2);
    }
    let problem = RateProblem::new(&obs, &[b], &MotionModelConfig::default())
        .expect("p")
        .with_coefficient_covariance(vec![Some(cov)]);
    let rows = problem.residual_count();
    let (mut r, mut jac) = (vec![0.0; rows], vec![[0.0; 3]; rows]);
    problem.residuals_and_jacobian(p, &mut r, &mut jac);
    let (fisher, _) = normal_equations(&jac, &r);
    let loss = problem.coefficient_information_loss(p, &jac).expect("loss");
    let reduced: [[f64; 3]; 3] =
        std::array::from_fn(|i| std::array::from_fn(|j| fisher[i][j] - loss[i][j]));
    let (info, dirs) = symmetric_eigen(&reduced).expect("eigen");
    let known_along = |v: [f64; 3]| -> f64 {
        (0..3)
            .map(|i| (0..3).map(|j| v[i] * fisher[i][j] * v[j]).sum::<f64>())
            .sum()
    };
    for i in 1..3 {
        let crb = info[i].recip();
        // The coefficients matter along this direction: the bound with them known is tighter.
        assert!(
            known_along(dirs[i]) > 1.1 * info[i],
            "direction {:?}: information {:.3e} known vs {:.3e} unknown",
            dirs[i],
            known_along(dirs[i]),
            info[i]
        );
        let free: Vec<[f64; 3]> = (1..3).filter(|&k| k != i).map(|k| dirs[k]).collect();
        let hcr = chapman_robbins(&problem, p, dirs[i], &free, crb.sqrt(), 0.25).expect("b");
        let ratio = hcr.variance / crb;
        assert!(
            (0.98..=1.02).contains(&ratio),
            "direction {:?}: HCR/CRB = {ratio} ({hcr:?})",
            dirs[i]
        );
    }
}
