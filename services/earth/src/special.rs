//! Digamma ψ = d lnΓ/dx and trigamma ψ' for x > 0 (docs/math.md §4.5): recurrence up to
//! x ≥ 12, then the asymptotic series (truncation error below 3e-15 there).

/// Where the recurrence hands over to the asymptotic series (math.md says 6; at 6 the first
/// omitted term is 1e-11, at 12 it is 2e-15).
const RECUR_TO: f64 = 12.0;

/// ψ(x) for x > 0; NaN otherwise.
pub fn digamma(mut x: f64) -> f64 {
    if x.is_nan() || x <= 0.0 || x == f64::INFINITY {
        return if x == f64::INFINITY {
            f64::INFINITY
        } else {
            f64::NAN
        };
    }
    let mut acc = 0.0;
    while x < RECUR_TO {
        acc -= 1.0 / x;
        x += 1.0;
    }
    let r = 1.0 / (x * x);
    let series =
        r * (1.0 / 12.0 - r * (1.0 / 120.0 - r * (1.0 / 252.0 - r * (1.0 / 240.0 - r / 132.0))));
    acc + x.ln() - 0.5 / x - series
}

/// ψ'(x) for x > 0; NaN otherwise.
pub fn trigamma(mut x: f64) -> f64 {
    if x.is_nan() || x <= 0.0 || x == f64::INFINITY {
        return if x == f64::INFINITY { 0.0 } else { f64::NAN };
    }
    let mut acc = 0.0;
    while x < RECUR_TO {
        acc += 1.0 / (x * x);
        x += 1.0;
    }
    let r = 1.0 / (x * x);
    let series = 1.0 / x
        + r / 2.0
        + r / x
            * (1.0 / 6.0 - r * (1.0 / 30.0 - r * (1.0 / 42.0 - r * (1.0 / 30.0 - r * 5.0 / 66.0))));
    acc + series
}

/// lnΓ(x) for x > 0 (musl's lgamma through `libm`).
pub fn ln_gamma(x: f64) -> f64 {
    libm::lgamma(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    const EULER_GAMMA: f64 = 0.577_215_664_901_532_9;

    #[test]
    fn digamma_matches_closed_forms() {
        // ψ(1) = −γ, ψ(½) = −γ − 2 ln 2, ψ(n+1) = ψ(n) + 1/n.
        assert!((digamma(1.0) + EULER_GAMMA).abs() < 1e-14);
        assert!((digamma(0.5) + EULER_GAMMA + 2.0 * std::f64::consts::LN_2).abs() < 1e-14);
        let h10: f64 = (1..10).map(|k| 1.0 / k as f64).sum();
        assert!((digamma(10.0) - (h10 - EULER_GAMMA)).abs() < 1e-14);
        assert!(digamma(0.0).is_nan() && digamma(-1.0).is_nan());
    }

    #[test]
    fn trigamma_matches_closed_forms() {
        // ψ'(1) = π²/6, ψ'(½) = π²/2, ψ'(n+1) = ψ'(n) − 1/n².
        let pi2 = std::f64::consts::PI.powi(2);
        assert!((trigamma(1.0) - pi2 / 6.0).abs() < 1e-14);
        assert!((trigamma(0.5) - pi2 / 2.0).abs() < 1e-13);
        let s: f64 = (1..20).map(|k| 1.0 / (k * k) as f64).sum();
        assert!((trigamma(20.0) - (pi2 / 6.0 - s)).abs() < 1e-14);
    }

    #[test]
    fn digamma_is_the_derivative_of_ln_gamma_and_trigamma_of_digamma() {
        for x in [0.01_f64, 0.3, 1.7, 5.9, 6.1, 42.0, 1e4] {
            let h = 1e-5 * x.max(1.0);
            let d = (ln_gamma(x + h) - ln_gamma(x - h)) / (2.0 * h);
            assert!(
                (d - digamma(x)).abs() < 1e-6 * digamma(x).abs().max(1.0),
                "{x}"
            );
            let t = (digamma(x + h) - digamma(x - h)) / (2.0 * h);
            assert!((t - trigamma(x)).abs() < 1e-6 * trigamma(x).max(1.0), "{x}");
        }
    }
}
