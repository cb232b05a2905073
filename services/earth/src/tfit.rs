//! The t location-scale fit by maximum likelihood (docs/math.md §4.5, eqs 12–19).
//!
//! The density (12) is `f(x; μ, σ, ν) = Γ((ν+1)/2) / (σ √(νπ) Γ(ν/2)) · [1 + d²/ν]^{−(ν+1)/2}`
//! with `d = (x − μ)/σ`. The fit:
//!
//! 1. **Units out.** The samples are standardised by their median and 1.4826·MAD (the sample
//!    standard deviation if the MAD is 0), the fit runs on the standardised samples, and μ, σ
//!    and the log-likelihood are mapped back. The answer does not depend on the data's units:
//!    degrees, radians and radians × 3e-5 give the same ν and the same μ, σ up to the scale
//!    (a fixed-tolerance optimiser on raw radians is what makes `scipy.stats.t.fit` stop at
//!    ν ≈ 2 where the MLE is ν ≈ 15).
//! 2. **EM first.** The paper's EM iteration (17)–(19) with the exact ν root (not the
//!    approximation (20)) from μ₀ = median, σ₀ = 1.4826·MAD and ν₀ from the excess kurtosis
//!    (math.md's ν₀ = 5 when it is not positive): every step raises the likelihood, which
//!    brings the start into Newton's basin.
//! 3. **Newton to the optimum.** Newton's method on (μ, ln σ, ln ν) with the analytic gradient
//!    and Hessian, each step checked to raise the likelihood (halved until it does; an EM step
//!    if the Hessian is not negative definite), until the step is below 1e-9 in standardised
//!    units. Quadratic convergence: the MLE to ~1e-10 in a handful of O(n) passes, where EM
//!    alone needs hundreds (math.md §7.4: 216 to 1e-13).
//!
//! ν is kept in [1e-3, 1e6]: a sample that is normal has its MLE at ν → ∞, reported as 1e6.

use crate::special::{digamma, ln_gamma, trigamma};

/// ν's range (math.md §4.5: the bracket of the ν root).
pub const NU_MIN: f64 = 1e-3;
pub const NU_MAX: f64 = 1e6;
/// EM iterations before Newton takes over.
const EM_STEPS: usize = 4;
/// Newton (or fallback EM) iterations at most.
const MAX_ITERATIONS: usize = 500;
/// Convergence: the largest step in standardised units (μ/s, ln σ, ln ν). Newton's steps
/// shrink quadratically (5e-4, 5e-7, 2e-11, …) down to the rounding floor of ℓ's flat ν
/// direction (~1e-11 at ν ≈ 50), so a step below 1e-9 means the optimum to ~1e-15.
const STEP_TOL: f64 = 1e-9;

/// The maximum-likelihood t location-scale parameters of a sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TFit {
    pub n: usize,
    pub mu: f64,
    pub sigma: f64,
    pub nu: f64,
    /// The negative log-likelihood at the optimum (natural log, in the data's units).
    pub nll: f64,
    /// EM and Newton iterations taken.
    pub iterations: usize,
}

/// Why a sample cannot be fitted.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum TFitError {
    #[error("the t fit needs at least 3 samples, got {0}")]
    TooFew(usize),
    #[error("sample {index} is not a finite number ({value})")]
    NotFinite { index: usize, value: f64 },
    #[error("all {0} samples are equal: the scale is 0")]
    Degenerate(usize),
}

/// Fits (μ, σ, ν) to `x` by maximum likelihood.
pub fn fit(x: &[f64]) -> Result<TFit, TFitError> {
    if x.len() < 3 {
        return Err(TFitError::TooFew(x.len()));
    }
    if let Some((index, &value)) = x.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(TFitError::NotFinite { index, value });
    }
    let (center, scale) = robust_location_scale(x).ok_or(TFitError::Degenerate(x.len()))?;
    let z: Vec<f64> = x.iter().map(|v| (v - center) / scale).collect();
    let (p, iterations) = fit_standardised(&z);
    let n = x.len() as f64;
    Ok(TFit {
        n: x.len(),
        mu: center + scale * p.mu,
        sigma: scale * p.sigma(),
        nu: p.nu(),
        nll: -log_likelihood(&z, p) + n * scale.ln(),
        iterations,
    })
}

/// The log-likelihood (13) of the sample `x` at (μ, σ, ν).
pub fn log_likelihood_at(x: &[f64], mu: f64, sigma: f64, nu: f64) -> f64 {
    log_likelihood(
        x,
        Params {
            mu,
            ln_sigma: sigma.ln(),
            ln_nu: nu.ln(),
        },
    )
}

/// The score (14)–(16), ∂ℓ/∂(μ, σ, ν), of `x` at (μ, σ, ν).
pub fn score(x: &[f64], mu: f64, sigma: f64, nu: f64) -> [f64; 3] {
    let p = Params {
        mu,
        ln_sigma: sigma.ln(),
        ln_nu: nu.ln(),
    };
    let d = derivatives(x, p);
    // d holds ∂ℓ/∂(μ, ln σ, ln ν): divide by σ and ν for ∂ℓ/∂σ, ∂ℓ/∂ν.
    [d.g[0], d.g[1] / sigma, d.g[2] / nu]
}

/// Median and 1.4826·MAD (the standard deviation if the MAD is 0); None if every sample is
/// equal.
fn robust_location_scale(x: &[f64]) -> Option<(f64, f64)> {
    let median = median(&mut x.to_vec());
    let mad = median_of(x.iter().map(|v| (v - median).abs()).collect());
    if mad > 0.0 {
        return Some((median, 1.4826 * mad));
    }
    let n = x.len() as f64;
    let mean = x.iter().sum::<f64>() / n;
    let sd = (x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt();
    (sd > 0.0).then_some((median, sd))
}

fn median_of(mut v: Vec<f64>) -> f64 {
    median(&mut v)
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_unstable_by(f64::total_cmp);
    let m = v.len() / 2;
    if v.len() % 2 == 1 {
        v[m]
    } else {
        0.5 * (v[m - 1] + v[m])
    }
}

/// The parameters in the coordinates Newton works in.
#[derive(Clone, Copy, Debug)]
struct Params {
    mu: f64,
    ln_sigma: f64,
    ln_nu: f64,
}

impl Params {
    fn sigma(self) -> f64 {
        self.ln_sigma.exp()
    }
    fn nu(self) -> f64 {
        self.ln_nu.exp()
    }
}

/// ℓ (13) at `p`.
fn log_likelihood(x: &[f64], p: Params) -> f64 {
    let (sigma, nu) = (p.sigma(), p.nu());
    let n = x.len() as f64;
    let inv = 1.0 / (sigma * sigma * nu);
    let sum: f64 = x.iter().map(|v| ((v - p.mu).powi(2) * inv).ln_1p()).sum();
    n * (ln_gamma(0.5 * (nu + 1.0))
        - ln_gamma(0.5 * nu)
        - 0.5 * (nu * std::f64::consts::PI).ln()
        - p.ln_sigma)
        - 0.5 * (nu + 1.0) * sum
}

/// ℓ with its gradient and Hessian in (μ, ln σ, ln ν).
struct Derivatives {
    ll: f64,
    g: [f64; 3],
    h: [[f64; 3]; 3],
}

/// One pass over the sample: with r = x − μ, d² = r²/σ², u = ν + d², w = (ν + 1)/u,
///
/// - ∂ℓ/∂μ = Σ w r/σ², ∂ℓ/∂lnσ = −n + Σ w d²,
///   ∂ℓ/∂ν = n/2 [ψ((ν+1)/2) − ψ(ν/2) − 1/ν] − ½ Σ ln(u/ν) + (ν+1)/(2ν) Σ d²/u (eq 16);
/// - ∂²/∂μ² = Σ w (2d²/u − 1)/σ², ∂²/∂μ∂lnσ = Σ (w r/σ²)(2d²/u − 2),
///   ∂²/∂μ∂ν = Σ (r/σ²)(d² − 1)/u², ∂²/∂lnσ² = −2ν Σ w d²/u, ∂²/∂lnσ∂ν = Σ d²(d² − 1)/u²,
///   ∂²/∂ν² = n/4 [ψ'((ν+1)/2) − ψ'(ν/2)] + n/(2ν²) + Σ d²/(2νu) − Σ d²/u /(2ν²)
///   − (ν+1)/(2ν) Σ d²/u²;
///
/// then the chain rule to ln ν: ∂/∂lnν = ν ∂/∂ν, ∂²/∂lnν² = ν² ∂²/∂ν² + ν ∂/∂ν.
fn derivatives(x: &[f64], p: Params) -> Derivatives {
    let (sigma, nu) = (p.sigma(), p.nu());
    let s2 = sigma * sigma;
    let n = x.len() as f64;
    let (mut g_mu, mut g_a, mut s_ln, mut s_du) = (0.0, 0.0, 0.0, 0.0);
    let (mut h_mumu, mut h_mua, mut h_munu, mut h_aa, mut h_anu, mut s_du2) =
        (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    // One division and one logarithm per sample; the rest multiplies by inverses.
    let (inv_s2, inv_nu) = (1.0 / s2, 1.0 / nu);
    for v in x {
        let r = v - p.mu;
        let rs = r * inv_s2;
        let d2 = r * rs;
        let inv_u = 1.0 / (nu + d2);
        let w = (nu + 1.0) * inv_u;
        let wr = w * rs;
        let d2u = d2 * inv_u;
        g_mu += wr;
        g_a += w * d2;
        s_ln += (d2 * inv_nu).ln_1p();
        s_du += d2u;
        h_mumu += w * (2.0 * d2u - 1.0) * inv_s2;
        h_mua += wr * (2.0 * d2u - 2.0);
        let du2 = (d2 - 1.0) * inv_u * inv_u;
        h_munu += rs * du2;
        h_aa += w * d2u;
        h_anu += d2 * du2;
        s_du2 += d2u * inv_u;
    }
    g_a -= n;
    h_aa *= -2.0 * nu;
    let a = 0.5 * (nu + 1.0);
    let g_nu = 0.5 * n * (digamma(a) - digamma(0.5 * nu) - 1.0 / nu) - 0.5 * s_ln
        + (nu + 1.0) / (2.0 * nu) * s_du;
    let h_nunu =
        0.25 * n * (trigamma(a) - trigamma(0.5 * nu)) + n / (2.0 * nu * nu) + s_du / (2.0 * nu)
            - s_du / (2.0 * nu * nu)
            - (nu + 1.0) / (2.0 * nu) * s_du2;
    let g_b = nu * g_nu;
    let h_bb = nu * nu * h_nunu + g_b;
    let (h_mub, h_ab) = (nu * h_munu, nu * h_anu);
    let ll = n
        * (ln_gamma(a) - ln_gamma(0.5 * nu) - 0.5 * (nu * std::f64::consts::PI).ln() - p.ln_sigma)
        - a * s_ln;
    Derivatives {
        ll,
        g: [g_mu, g_a, g_b],
        h: [
            [h_mumu, h_mua, h_mub],
            [h_mua, h_aa, h_ab],
            [h_mub, h_ab, h_bb],
        ],
    }
}

/// One EM step (17)–(19) with the exact ν root.
fn em_step(x: &[f64], p: Params) -> Params {
    let (sigma, nu) = (p.sigma(), p.nu());
    let n = x.len() as f64;
    let w: Vec<f64> = (x.iter())
        .map(|v| (nu + 1.0) / (nu + ((v - p.mu) / sigma).powi(2)))
        .collect();
    let sw: f64 = w.iter().sum();
    let mu = x.iter().zip(&w).map(|(v, w)| w * v).sum::<f64>() / sw;
    let var = x
        .iter()
        .zip(&w)
        .map(|(v, w)| w * (v - mu).powi(2))
        .sum::<f64>()
        / n;
    let c = 1.0 + w.iter().map(|w| w.ln() - w).sum::<f64>() / n + digamma(0.5 * (nu + 1.0))
        - (0.5 * (nu + 1.0)).ln();
    Params {
        mu,
        ln_sigma: 0.5 * var.max(f64::MIN_POSITIVE).ln(),
        ln_nu: nu_root(c).ln(),
    }
}

/// The root of g(ν) = ln(ν/2) − ψ(ν/2) + c (eq 19), c < 0, by bracketed Newton on
/// [NU_MIN, NU_MAX]; g decreases in ν, so a root outside the bracket is clamped to its end.
fn nu_root(c: f64) -> f64 {
    let g = |nu: f64| (0.5 * nu).ln() - digamma(0.5 * nu) + c;
    let (mut lo, mut hi) = (NU_MIN, NU_MAX);
    if g(hi) >= 0.0 {
        return NU_MAX;
    }
    if g(lo) <= 0.0 {
        return NU_MIN;
    }
    // Newton in ln ν (g is smooth and convex there), kept inside the bracket.
    let mut b = 1.0_f64.ln().clamp(lo.ln(), hi.ln());
    for _ in 0..200 {
        let nu = b.exp();
        let gv = g(nu);
        if gv > 0.0 {
            lo = nu;
        } else {
            hi = nu;
        }
        // dg/dlnν = ν (1/ν − ½ ψ'(ν/2)) = 1 − ν ψ'(ν/2)/2.
        let slope = 1.0 - 0.5 * nu * trigamma(0.5 * nu);
        let mut next = b - gv / slope;
        if !(next.is_finite() && next > lo.ln() && next < hi.ln()) {
            next = 0.5 * (lo.ln() + hi.ln());
        }
        if (next - b).abs() < 1e-14 {
            return next.exp();
        }
        b = next;
    }
    b.exp()
}

/// Solves H δ = −g for a negative-definite H (Cholesky of −H); None if it is not.
fn newton_step(d: &Derivatives) -> Option<[f64; 3]> {
    let a: [[f64; 3]; 3] = std::array::from_fn(|i| std::array::from_fn(|j| -d.h[i][j]));
    let mut l = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..=i {
            let s: f64 = a[i][j] - (0..j).map(|k| l[i][k] * l[j][k]).sum::<f64>();
            if i == j {
                if s.is_nan() || s <= 0.0 {
                    return None;
                }
                l[i][i] = s.sqrt();
            } else {
                l[i][j] = s / l[j][j];
            }
        }
    }
    // (−H) δ = g: forward then back substitution.
    let mut y = [0.0; 3];
    for i in 0..3 {
        y[i] = (d.g[i] - (0..i).map(|k| l[i][k] * y[k]).sum::<f64>()) / l[i][i];
    }
    let mut delta = [0.0; 3];
    for i in (0..3).rev() {
        delta[i] = (y[i] - (i + 1..3).map(|k| l[k][i] * delta[k]).sum::<f64>()) / l[i][i];
    }
    delta.iter().all(|v| v.is_finite()).then_some(delta)
}

fn clamp_nu(p: Params) -> Params {
    Params {
        ln_nu: p.ln_nu.clamp(NU_MIN.ln(), NU_MAX.ln()),
        ..p
    }
}

/// ν₀ from the sample's excess kurtosis κ (t_ν has κ = 6/(ν − 4)): 4 + 6/κ, within [2, 200];
/// 5 (math.md's start) when κ is not positive. Starting near the answer saves Newton the long
/// walk along ℓ's flat ν direction.
fn initial_nu(z: &[f64]) -> f64 {
    let n = z.len() as f64;
    let mean = z.iter().sum::<f64>() / n;
    let (m2, m4) = z.iter().fold((0.0, 0.0), |(a, b), v| {
        let d2 = (v - mean).powi(2);
        (a + d2, b + d2 * d2)
    });
    let kurtosis = (m4 / n) / (m2 / n).powi(2) - 3.0;
    if kurtosis > 0.0 {
        (4.0 + 6.0 / kurtosis).clamp(2.0, 200.0)
    } else {
        5.0
    }
}

/// The fit on standardised samples (median 0, robust scale 1); returns the optimum and the
/// iterations taken.
fn fit_standardised(z: &[f64]) -> (Params, usize) {
    let mut p = Params {
        mu: 0.0,
        ln_sigma: 0.0,
        ln_nu: initial_nu(z).ln(),
    };
    let mut iterations = 0;
    for _ in 0..EM_STEPS {
        p = em_step(z, p);
        iterations += 1;
    }
    // Each pass gives ℓ and its derivatives together: an accepted trial's pass is the next
    // iteration's.
    let mut d = derivatives(z, p);
    while iterations < MAX_ITERATIONS {
        iterations += 1;
        let Some(delta) = newton_step(&d) else {
            let next = em_step(z, p);
            let moved = (next.mu - p.mu)
                .abs()
                .max((next.ln_sigma - p.ln_sigma).abs())
                .max((next.ln_nu - p.ln_nu).abs());
            p = next;
            d = derivatives(z, p);
            if moved < STEP_TOL {
                break;
            }
            continue;
        };
        // Halve the step until the likelihood does not fall (rounding aside).
        let mut t = 1.0;
        let mut accepted = None;
        for _ in 0..40 {
            let trial = clamp_nu(Params {
                mu: p.mu + t * delta[0],
                ln_sigma: p.ln_sigma + t * delta[1],
                ln_nu: p.ln_nu + t * delta[2],
            });
            let dt = derivatives(z, trial);
            if dt.ll >= d.ll - 1e-12 * d.ll.abs().max(1.0) {
                accepted = Some((trial, dt));
                break;
            }
            t *= 0.5;
        }
        let Some((next, next_d)) = accepted else {
            break;
        };
        let moved = (next.mu - p.mu)
            .abs()
            .max((next.ln_sigma - p.ln_sigma).abs())
            .max((next.ln_nu - p.ln_nu).abs());
        p = next;
        d = next_d;
        if moved < STEP_TOL {
            break;
        }
    }
    (p, iterations)
}

#[cfg(test)]
#[path = "tfit_tests.rs"]
mod tests;
