use super::*;

/// docs/math.md §7.4, n = 20.
const SAMPLE: [f64; 20] = [
    10.12, 9.87, 10.05, 9.96, 10.31, 9.74, 10.02, 10.08, 9.91, 10.44, 9.99, 10.15, 9.82, 10.01,
    9.58, 10.06, 9.95, 10.23, 9.89, 10.97,
];
/// docs/math.md §7.4, the heavy-tailed sample.
const HEAVY: [f64; 20] = [
    4.92, 5.03, 4.97, 5.11, 4.88, 5.02, 4.99, 5.06, 4.95, 5.01, 5.04, 4.93, 5.00, 5.08, 4.97, 5.35,
    4.60, 5.02, 4.98, 5.90,
];

/// t-distributed samples (ν an integer) from a splitmix64 stream: Box–Muller normals, T = Z /
/// √(χ²_ν/ν).
fn t_samples(n: usize, nu: usize, mu: f64, sigma: f64, seed: u64) -> Vec<f64> {
    let mut state = seed;
    let mut uniform = move || {
        state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64 + 0.5 / (1u64 << 53) as f64
    };
    let mut normal = move || {
        let (u1, u2) = (uniform(), uniform());
        (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
    };
    (0..n)
        .map(|_| {
            let z = normal();
            let chi2: f64 = (0..nu).map(|_| normal().powi(2)).sum();
            mu + sigma * z / (chi2 / nu as f64).sqrt()
        })
        .collect()
}

#[test]
fn the_fit_is_the_high_precision_mle_of_math_md_7_4() {
    let f = fit(&SAMPLE).unwrap();
    assert!((f.mu - 10.0087229834).abs() < 1e-8, "{f:?}");
    assert!((f.sigma - 0.142487934787).abs() < 1e-9, "{f:?}");
    assert!((f.nu - 2.03295355610).abs() < 1e-7, "{f:?}");
    assert!((f.nll - 0.0524515737191).abs() < 1e-10, "{f:?}");
    assert_eq!(f.n, 20);
    let h = fit(&HEAVY).unwrap();
    assert!((h.mu - 5.00004487).abs() < 1e-7, "{h:?}");
    assert!((h.sigma - 0.04754698).abs() < 1e-7, "{h:?}");
    assert!((h.nu - 1.10084225).abs() < 1e-7, "{h:?}");
}

#[test]
fn the_score_equations_14_to_16_vanish_at_the_optimum() {
    for x in [
        SAMPLE.to_vec(),
        HEAVY.to_vec(),
        t_samples(1000, 5, 3.0, 0.2, 7),
    ] {
        let f = fit(&x).unwrap();
        let s = score(&x, f.mu, f.sigma, f.nu);
        // Relative to the size of the terms: n/σ for μ and σ, n for ν.
        let n = x.len() as f64;
        assert!(s[0].abs() * f.sigma / n < 1e-9, "{s:?} {f:?}");
        assert!(s[1].abs() * f.sigma / n < 1e-9, "{s:?} {f:?}");
        assert!(s[2].abs() * f.nu / n < 1e-9, "{s:?} {f:?}");
        // A maximum: every nearby point is worse.
        let ll = log_likelihood_at(&x, f.mu, f.sigma, f.nu);
        assert!((ll + f.nll).abs() < 1e-9 * ll.abs().max(1.0));
        for (dm, ds, dn) in [(1e-4, 0.0, 0.0), (0.0, 1e-4, 0.0), (0.0, 0.0, 1e-3)] {
            for sign in [-1.0, 1.0] {
                let other = log_likelihood_at(
                    &x,
                    f.mu + sign * dm * f.sigma,
                    f.sigma * (1.0 + sign * ds),
                    f.nu * (1.0 + sign * dn),
                );
                assert!(other < ll, "({dm}, {ds}, {dn}) × {sign}");
            }
        }
    }
}

#[test]
fn the_analytic_gradient_and_hessian_match_finite_differences() {
    let x = t_samples(200, 4, 1.0, 0.5, 3);
    let p = Params {
        mu: 1.1,
        ln_sigma: 0.6_f64.ln(),
        ln_nu: 3.0_f64.ln(),
    };
    let d = derivatives(&x, p);
    let shift = |p: Params, i: usize, h: f64| {
        let mut v = [p.mu, p.ln_sigma, p.ln_nu];
        v[i] += h;
        Params {
            mu: v[0],
            ln_sigma: v[1],
            ln_nu: v[2],
        }
    };
    let h = 1e-5;
    for i in 0..3 {
        let g =
            (log_likelihood(&x, shift(p, i, h)) - log_likelihood(&x, shift(p, i, -h))) / (2.0 * h);
        assert!(
            (g - d.g[i]).abs() < 1e-5 * g.abs().max(1.0),
            "g[{i}] {g} vs {}",
            d.g[i]
        );
        let (up, down) = (
            derivatives(&x, shift(p, i, h)),
            derivatives(&x, shift(p, i, -h)),
        );
        for j in 0..3 {
            let hij = (up.g[j] - down.g[j]) / (2.0 * h);
            assert!(
                (hij - d.h[i][j]).abs() < 1e-5 * hij.abs().max(1.0),
                "h[{i}][{j}] {hij} vs {}",
                d.h[i][j]
            );
        }
    }
}

/// The case: angles in radians of scale 3e-5, ν = 15. The fit in degrees, in radians
/// and shifted gives one ν, and μ, σ that map with the units.
#[test]
fn the_fit_does_not_depend_on_the_units() {
    let deg = t_samples(1000, 15, 5.0, 3e-5_f64.to_degrees(), 11);
    let rad: Vec<f64> = deg.iter().map(|v| v.to_radians()).collect();
    let shifted: Vec<f64> = rad.iter().map(|v| v * 1e3 + 42.0).collect();
    let (a, b, c) = (
        fit(&deg).unwrap(),
        fit(&rad).unwrap(),
        fit(&shifted).unwrap(),
    );
    assert!(
        (a.nu - b.nu).abs() < 1e-6 * a.nu && (a.nu - c.nu).abs() < 1e-6 * a.nu,
        "{a:?} {b:?} {c:?}"
    );
    assert!((a.mu.to_radians() - b.mu).abs() < 1e-6 * b.sigma);
    assert!((a.sigma.to_radians() - b.sigma).abs() < 1e-6 * b.sigma);
    assert!(((c.mu - 42.0) / 1e3 - b.mu).abs() < 1e-6 * b.sigma);
    // The log-likelihood moves by n ln(scale) with the units, nothing else.
    let n = deg.len() as f64;
    assert!((a.nll - (b.nll + n * 180f64.ln() - n * std::f64::consts::PI.ln())).abs() < 1e-6 * n);
    // And it finds the sample's ν: a t_15 sample of 1000 gives ν̂ well away from 2.
    assert!((6.0..60.0).contains(&b.nu), "{b:?}");
}

#[test]
fn a_normal_sample_has_its_optimum_at_large_nu() {
    // ν → ∞ is the normal: the likelihood keeps rising with ν, so ν̂ ends high and μ, σ are
    // those of the normal MLE (mean, √(mean square)).
    let x: Vec<f64> = t_samples(2000, 400, 0.0, 1.0, 5);
    let f = fit(&x).unwrap();
    assert!(f.nu > 50.0, "{f:?}");
    let n = x.len() as f64;
    let mean = x.iter().sum::<f64>() / n;
    assert!((f.mu - mean).abs() < 0.01, "{f:?} mean {mean}");
}

#[test]
fn bad_samples_are_errors() {
    assert_eq!(fit(&[1.0, 2.0]), Err(TFitError::TooFew(2)));
    assert_eq!(fit(&[3.0; 10]), Err(TFitError::Degenerate(10)));
    assert!(matches!(
        fit(&[1.0, f64::NAN, 2.0]),
        Err(TFitError::NotFinite { index: 1, .. })
    ));
}

#[test]
fn the_nu_root_solves_eq_19() {
    for c in [-1e-6, -1e-3, -0.05, -0.5, -3.0] {
        let nu = nu_root(c);
        let g = (0.5 * nu).ln() - digamma(0.5 * nu) + c;
        assert!(
            g.abs() < 1e-12 || nu == NU_MAX || nu == NU_MIN,
            "c {c}: ν {nu}, g {g}"
        );
    }
}
