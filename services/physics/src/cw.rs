//! Clohessy–Wiltshire relative motion about a circular reference orbit (docs/math.md §3.8, §7.1).
//!
//! State `X = [x, y, z, ẋ, ẏ, ż]` [m, m/s], mean motion n \[rad/s\], `θ = nΔt`, `S = sin θ`,
//! `C = cos θ`.
//!
//! LVLH_N frame (x along-track, y = −orbit normal, z nadir; seed 002 eq 22–25):
//! `ẍ = 2n ż`, `ÿ = −n² y`, `z̈ = 3n² z − 2n ẋ`, and the seed's eq (25), verified exact:
//!
//! ```text
//! [ 1   0    6(θ−S)     (4S−3θ)/n   0     2(1−C)/n ]
//! [ 0   C    0           0          S/n   0        ]
//! [ 0   0    4−3C        2(C−1)/n   0     S/n      ]
//! [ 0   0    6n(1−C)     4C−3       0     2S       ]
//! [ 0  −nS   0           0          C     0        ]
//! [ 0   0    3nS        −2S         0     C        ]
//! ```
//!
//! RSW (Hill) frame (x radial, y along-track, z orbit normal; §7.1):
//! `ẍ = 3n² x + 2n ẏ`, `ÿ = −2n ẋ`, `z̈ = −n² z`, with the classical Hill STM.
//!
//! `S/n` and `(1−C)/n` are evaluated in forms that stay finite as n → 0 (free motion).

use nalgebra::{Matrix6, Vector6};

/// The trigonometric pieces shared by both STMs, stable for small θ.
struct CwTerms {
    theta: f64,
    s: f64,
    c: f64,
    /// 1 − C = 2 sin²(θ/2), without cancellation.
    one_minus_c: f64,
    /// S/n \[s\]; → Δt as n → 0.
    s_over_n: f64,
    /// (1 − C)/n \[s\]; → n Δt²/2 as n → 0.
    one_minus_c_over_n: f64,
    /// (4S − 3θ)/n \[s\].
    four_s_minus_three_theta_over_n: f64,
}

impl CwTerms {
    fn new(n_rad_s: f64, dt_s: f64) -> Self {
        let theta = n_rad_s * dt_s;
        let (s, c) = theta.sin_cos();
        let half_sin = (0.5 * theta).sin();
        let one_minus_c = 2.0 * half_sin * half_sin;
        // sin θ/θ and (1 − cos θ)/θ, with series near 0.
        let (sinc, versc) = if theta.abs() < 1e-4 {
            let t2 = theta * theta;
            (1.0 - t2 / 6.0, 0.5 * theta * (1.0 - t2 / 12.0))
        } else {
            (s / theta, one_minus_c / theta)
        };
        Self {
            theta,
            s,
            c,
            one_minus_c,
            s_over_n: sinc * dt_s,
            one_minus_c_over_n: versc * dt_s,
            four_s_minus_three_theta_over_n: (4.0 * sinc - 3.0) * dt_s,
        }
    }
}

/// Continuous-time CW system matrix A in LVLH_N (§3.8): `Ẋ = A X`.
pub fn cw_a_matrix_lvlhn(n_rad_s: f64) -> Matrix6<f64> {
    let n = n_rad_s;
    let mut a = Matrix6::zeros();
    for i in 0..3 {
        a[(i, i + 3)] = 1.0;
    }
    a[(4, 1)] = -n * n;
    a[(5, 2)] = 3.0 * n * n;
    a[(3, 5)] = 2.0 * n;
    a[(5, 3)] = -2.0 * n;
    a
}

/// Continuous-time CW system matrix A in RSW (§7.1): `Ẋ = A X`.
pub fn cw_a_matrix_rsw(n_rad_s: f64) -> Matrix6<f64> {
    let n = n_rad_s;
    let mut a = Matrix6::zeros();
    for i in 0..3 {
        a[(i, i + 3)] = 1.0;
    }
    a[(3, 0)] = 3.0 * n * n;
    a[(5, 2)] = -n * n;
    a[(3, 4)] = 2.0 * n;
    a[(4, 3)] = -2.0 * n;
    a
}

/// CW state-transition matrix in LVLH_N over `dt_s`, seed 002 eq (25) (§3.8).
pub fn cw_stm_lvlhn(n_rad_s: f64, dt_s: f64) -> Matrix6<f64> {
    let n = n_rad_s;
    let k = CwTerms::new(n, dt_s);
    #[rustfmt::skip]
    let phi = Matrix6::new(
        1.0, 0.0,      6.0 * (k.theta - k.s),     k.four_s_minus_three_theta_over_n, 0.0,        2.0 * k.one_minus_c_over_n,
        0.0, k.c,      0.0,                       0.0,                               k.s_over_n, 0.0,
        0.0, 0.0,      4.0 - 3.0 * k.c,           -2.0 * k.one_minus_c_over_n,       0.0,        k.s_over_n,
        0.0, 0.0,      6.0 * n * k.one_minus_c,   4.0 * k.c - 3.0,                   0.0,        2.0 * k.s,
        0.0, -n * k.s, 0.0,                       0.0,                               k.c,        0.0,
        0.0, 0.0,      3.0 * n * k.s,             -2.0 * k.s,                        0.0,        k.c,
    );
    phi
}

/// CW state-transition matrix in RSW over `dt_s` (§7.1).
pub fn cw_stm_rsw(n_rad_s: f64, dt_s: f64) -> Matrix6<f64> {
    let n = n_rad_s;
    let k = CwTerms::new(n, dt_s);
    #[rustfmt::skip]
    let phi = Matrix6::new(
        4.0 - 3.0 * k.c,          0.0, 0.0,      k.s_over_n,                  2.0 * k.one_minus_c_over_n,        0.0,
        6.0 * (k.s - k.theta),    1.0, 0.0,      -2.0 * k.one_minus_c_over_n, k.four_s_minus_three_theta_over_n, 0.0,
        0.0,                      0.0, k.c,      0.0,                         0.0,                               k.s_over_n,
        3.0 * n * k.s,            0.0, 0.0,      k.c,                         2.0 * k.s,                         0.0,
        -6.0 * n * k.one_minus_c, 0.0, 0.0,      -2.0 * k.s,                  4.0 * k.c - 3.0,                   0.0,
        0.0,                      0.0, -n * k.s, 0.0,                         0.0,                               k.c,
    );
    phi
}

/// Propagates an LVLH_N relative state over `dt_s`: `X(t + Δt) = Φ(Δt) X(t)`.
pub fn propagate_lvlhn(state_lvlhn: Vector6<f64>, n_rad_s: f64, dt_s: f64) -> Vector6<f64> {
    cw_stm_lvlhn(n_rad_s, dt_s) * state_lvlhn
}

/// Propagates an RSW relative state over `dt_s`.
pub fn propagate_rsw(state_rsw: Vector6<f64>, n_rad_s: f64, dt_s: f64) -> Vector6<f64> {
    cw_stm_rsw(n_rad_s, dt_s) * state_rsw
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frames::{lvlhn_to_rsw_state, rsw_to_lvlhn_state};

    const N_GEO: f64 = 7.292115864164384e-05;

    fn assert_rel(got: Vector6<f64>, want: [f64; 6], rel: f64) {
        for i in 0..6 {
            let tol = rel * want[i].abs().max(1e-12);
            assert!(
                (got[i] - want[i]).abs() <= tol,
                "component {i}: got {:e}, want {:e}",
                got[i],
                want[i]
            );
        }
    }

    /// expm by scaling and squaring with a 24-term Taylor series (independent second method).
    fn expm(a: &Matrix6<f64>) -> Matrix6<f64> {
        let norm = a.abs().row_sum().max();
        let squarings = if norm > 0.25 {
            (norm / 0.25).log2().ceil() as i32
        } else {
            0
        };
        let scaled = a / 2f64.powi(squarings);
        let mut sum = Matrix6::identity();
        let mut term = Matrix6::identity();
        for k in 1..=24 {
            term = term * scaled / f64::from(k);
            sum += term;
        }
        for _ in 0..squarings {
            sum = sum * sum;
        }
        sum
    }

    /// Non-dimensionalises velocities (v/n) so that all STM entries are O(1) before comparing.
    fn nondim(phi: &Matrix6<f64>, n: f64) -> Matrix6<f64> {
        let mut d = Matrix6::identity();
        let mut d_inv = Matrix6::identity();
        for i in 3..6 {
            d[(i, i)] = 1.0 / n;
            d_inv[(i, i)] = n;
        }
        d * phi * d_inv
    }

    #[test]
    fn case_a_lvlhn_and_rsw() {
        let x0 = Vector6::new(10000.0, 600.0, 700.0, -60.0, -10.0, -100.0);
        let want = [
            3927.29213517,
            -400.007089947,
            -9256.10304055,
            -61.4520211385,
            -10.0000531733,
            -99.1211784514,
        ];
        assert_rel(propagate_lvlhn(x0, N_GEO, 100.0), want, 1e-9);
        let x0_rsw = Vector6::new(-700.0, 10000.0, -600.0, 100.0, -60.0, 10.0);
        let want_rsw = [
            9256.10304055,
            3927.29213517,
            400.007089947,
            99.1211784514,
            -61.4520211385,
            10.0000531733,
        ];
        assert_rel(propagate_rsw(x0_rsw, N_GEO, 100.0), want_rsw, 1e-9);
        // The two frames agree through the §6.3 map.
        let via_rsw = rsw_to_lvlhn_state(propagate_rsw(lvlhn_to_rsw_state(x0), N_GEO, 100.0));
        assert!((via_rsw - propagate_lvlhn(x0, N_GEO, 100.0)).norm() < 1e-8);
    }

    #[test]
    fn case_b_and_c() {
        let b = propagate_lvlhn(Vector6::new(0.0, 0.0, 100.0, 0.0, 0.0, 0.0), N_GEO, 100.0);
        let want_b = [
            3.87756893058e-05,
            0.0,
            100.007976208,
            1.16326861729e-06,
            0.0,
            1.59523447545e-04,
        ];
        assert_rel(b, want_b, 1e-9);
        let c = propagate_lvlhn(Vector6::new(0.0, 50.0, 0.0, 0.0, 0.0, 0.1), N_GEO, 100.0);
        let want_c = [
            7.29208355107e-02,
            49.9986706321,
            9.99991137531,
            1.45841024760e-03,
            -2.65872412575e-05,
            9.99973412641e-02,
        ];
        assert_rel(c, want_c, 1e-9);
    }

    #[test]
    fn stm_equals_matrix_exponential() {
        for dt in [100.0, 1000.0, 20000.0] {
            for (stm, a) in [
                (cw_stm_lvlhn(N_GEO, dt), cw_a_matrix_lvlhn(N_GEO)),
                (cw_stm_rsw(N_GEO, dt), cw_a_matrix_rsw(N_GEO)),
            ] {
                let e = expm(&(a * dt));
                let err = (nondim(&stm, N_GEO) - nondim(&e, N_GEO)).abs().max();
                assert!(err < 1e-10, "dt = {dt}: max error {err:e}");
            }
        }
    }

    #[test]
    fn stm_is_a_semigroup() {
        for (t1, t2) in [(100.0, 250.0), (3000.0, 17000.0), (-500.0, 1200.0)] {
            for stm in [cw_stm_lvlhn, cw_stm_rsw] {
                let lhs = stm(N_GEO, t1 + t2);
                let rhs = stm(N_GEO, t1) * stm(N_GEO, t2);
                let err = (nondim(&lhs, N_GEO) - nondim(&rhs, N_GEO)).abs().max();
                assert!(err < 1e-11, "t1 = {t1}, t2 = {t2}: {err:e}");
            }
        }
    }

    #[test]
    fn zero_mean_motion_is_free_motion() {
        let x0 = Vector6::new(1.0, 2.0, 3.0, 0.5, -0.25, 0.125);
        let x = propagate_lvlhn(x0, 0.0, 10.0);
        let want = [6.0, -0.5, 4.25, 0.5, -0.25, 0.125];
        assert_rel(x, want, 1e-15);
        assert!(cw_stm_rsw(0.0, 10.0).iter().all(|v| v.is_finite()));
    }

    #[test]
    fn small_step_series_matches_closed_form() {
        // Across the θ = 1e-4 switch the two evaluations agree.
        let n = 1e-3;
        let below = cw_stm_lvlhn(n, 0.099_999);
        let above = cw_stm_lvlhn(n, 0.100_001);
        assert!((below - above).abs().max() < 1e-5);
    }
}
