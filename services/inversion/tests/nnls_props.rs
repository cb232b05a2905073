//! NNLS properties over random problems (proptest).

use faer::Mat;
use glint_inversion::nnls::nnls;
use proptest::prelude::*;

fn problem() -> impl Strategy<Value = (usize, usize, Vec<f64>, Vec<f64>)> {
    (2usize..40, 1usize..12).prop_flat_map(|(rows, cols)| {
        (
            Just(rows),
            Just(cols),
            proptest::collection::vec(-1.0f64..1.0, rows * cols),
            proptest::collection::vec(-1.0f64..1.0, rows),
        )
    })
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 64,
        // Deterministic suite: the same cases on every run (shrunk failures are kept in the
        // proptest-regressions files).
        rng_seed: proptest::test_runner::RngSeed::Fixed(0x0067_6c69_6e74),
        ..ProptestConfig::default()
    })]

    /// KKT: x ≥ 0, w = Aᵀ(q − Gx) ≤ tol on the zero set, |w| ≈ 0 on the positive set
    /// (A = column-normalised G), and the residual never exceeds ‖q‖ (x = 0 is feasible).
    #[test]
    fn kkt_conditions_hold((rows, cols, g, q) in problem()) {
        let gm = Mat::from_fn(rows, cols, |i, j| g[i * cols + j]);
        let sol = nnls(gm.as_ref(), &q).expect("nnls");
        let res: Vec<f64> = (0..rows)
            .map(|i| q[i] - (0..cols).map(|j| gm[(i, j)] * sol.x[j]).sum::<f64>())
            .collect();
        let q_norm = q.iter().map(|v| v * v).sum::<f64>().sqrt();
        prop_assert!(sol.residual_norm <= q_norm * (1.0 + 1e-12) + 1e-14);
        let res_norm = res.iter().map(|v| v * v).sum::<f64>().sqrt();
        prop_assert!((res_norm - sol.residual_norm).abs() <= 1e-9 * (1.0 + q_norm));
        for j in 0..cols {
            prop_assert!(sol.x[j] >= 0.0);
            let cn = (0..rows).map(|i| gm[(i, j)].powi(2)).sum::<f64>().sqrt();
            let w = (0..rows).map(|i| gm[(i, j)] * res[i]).sum::<f64>() / cn;
            if sol.x[j] > 0.0 {
                prop_assert!(w.abs() <= 1e-9 * (1.0 + q_norm), "positive set w[{}] = {:e}", j, w);
            } else {
                prop_assert!(w <= 1e-9 * (1.0 + q_norm), "zero set w[{}] = {:e}", j, w);
            }
        }
    }
}
