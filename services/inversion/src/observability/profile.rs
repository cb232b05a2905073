//! Profile-likelihood half-widths of the determined directions (docs/adr/0017).
//!
//! [`super::widen_to_likelihood_intervals`] looks along a straight line, the eigen-direction
//! v_i at p̂. Where the cost's valley bends, that line climbs the valley's wall and the interval
//! ends early. About Y the rate's near-mirror pair lies along such a valley: w_y moves by
//! ~1e-4 deg/frame as w_z crosses from one image to the other, about 5 of w_y's local σ at
//! SNR 50, and a fit that ends at the pair's centre reports a w_y interval that does not reach
//! either image.
//!
//! The profile interval of v_i is the range of v_i·(p − p̂) over the region where the cost is
//! within one noise variance of its minimum, `ε(p) − ε(p̂) ≤ s²`, moving the determined
//! directions only. It is found by walking that region's valleys: along each determined
//! eigen-direction v_j, in steps, the cost is minimised over the other determined directions
//! (Gauss–Newton from the last step's point), tracing the valley floor p*(t) until it rises by
//! s². Then
//! - j's own half-width is where the floor crosses s² (for a quadratic cost, the linearised
//!   bound: the v_i are conjugate);
//! - each other determined i gets `|v_i·(p*(t) − p̂)| + b_i·sqrt(1 − Δε(t)/s²)` at every step
//!   inside the region: how far the floor carries v_i, plus the cross-section left there (b_i
//!   its local bound).
//!
//! A floor that falls again has passed a saddle into another minimum's basin: the walk stops
//! there. The interval is the basin's; a second minimum is a copy of the rate (ADR 0005),
//! which the campaigns count apart, not scatter (without this rule the joint fit about Z at
//! SNR 5, whose runs sit either side of p₀'s copy, had a mean NEES of 1.08 against 1.48–2.60).
//!
//! This only widens. A direction the data do not determine is neither walked nor minimised
//! over: the fit does not wander along it (it sits where the fit ended, or where the prior holds
//! it), and profiling over it made the stage-3 fits of `tests/efficiency.rs` over-cover (mean
//! NEES 0.79 against 1.48–2.59).
//!
//! The profile is *reported*, never decided on: the joint gate, the lobe test, the copy rule
//! and the kept rate's widening read the local covariance (docs/adr/0016 measured what
//! happens otherwise). [`profiled_bounds`] is computed on the fits the solve may report
//! ([`crate::stage3::RateFit::attach_profile`]) and moved into the answer once every decision is
//! taken ([`crate::stage3::RateFit::report_profile`]).

use super::{CovarianceSource, Observability, INTERVAL_CAP_FACTOR};
use crate::model::RateProblem;
use std::cmp::Ordering;

/// Gauss–Newton steps of the minimisation over the other determined directions, per walk step.
const PROFILE_STEPS: usize = 1;

/// Walk steps per straight-line half-width of the walked direction.
const STEPS_PER_WIDTH: f64 = 3.0;

/// The step doubles after this many steps (a valley far longer than its straight-line width).
const STEPS_PER_DOUBLING: usize = 8;

/// Longest walk, per side.
const MAX_WALK_STEPS: usize = 40;

/// Bisections of the straight-line width that sets the walk's step.
const STRAIGHT_BISECTIONS: usize = 3;

/// Halvings of a bound in search of its straight-line width.
const MAX_HALVINGS: usize = 40;

/// A floor that falls by this fraction of s² from one step to the next has passed a saddle.
const SADDLE_FRACTION: f64 = 0.01;

/// Relative eigenvalue below which a Gauss–Newton step leaves a direction where it is.
const FLAT_RELATIVE: f64 = 1e-8;

/// A least-squares cost in p: the rate problem, or a closed form in the tests.
pub trait LeastSquares {
    /// Residuals per call.
    fn residual_count(&self) -> usize;
    /// Σ r² at p (by default from the residuals; the rate problem has a cheaper one).
    fn cost(&self, p: [f64; 3]) -> f64 {
        let n = self.residual_count();
        let (mut r, mut jac) = (vec![0.0; n], vec![[0.0; 3]; n]);
        self.residuals_and_jacobian(p, &mut r, &mut jac)
    }
    /// Residuals r and `J = −∂r/∂p` at p; returns Σ r².
    fn residuals_and_jacobian(&self, p: [f64; 3], r: &mut [f64], jac: &mut [[f64; 3]]) -> f64;
}

impl LeastSquares for RateProblem {
    fn residual_count(&self) -> usize {
        RateProblem::residual_count(self)
    }
    fn cost(&self, p: [f64; 3]) -> f64 {
        RateProblem::cost(self, p)
    }
    fn residuals_and_jacobian(&self, p: [f64; 3], r: &mut [f64], jac: &mut [[f64; 3]]) -> f64 {
        RateProblem::residuals_and_jacobian(self, p, r, jac)
    }
}

/// The 1σ half-widths along the eigen-directions of `obs` (its bounds, already widened to
/// their straight-line likelihood intervals; `source` gives the noise variance), each
/// determined one widened to its profile-likelihood interval over the other determined ones;
/// an undetermined direction keeps its bound and is not walked. `None` when no direction is
/// determined.
pub fn profiled_bounds(
    problem: &impl LeastSquares,
    p: [f64; 3],
    obs: &Observability,
    source: &CovarianceSource,
) -> Option<[f64; 3]> {
    let bounds = obs.bounds_1sigma_deg_per_frame;
    let determined: Vec<usize> = (0..3)
        .filter(|&i| !obs.unobservable[i] && bounds[i] > 0.0 && bounds[i].is_finite())
        .collect();
    if determined.is_empty() {
        return None;
    }
    let region = Region {
        p,
        c0: problem.cost(p),
        s2: super::noise_variance(source),
        cap: INTERVAL_CAP_FACTOR * obs.threshold_deg_per_frame,
    };
    let mut scratch = Scratch::new(problem.residual_count());
    let mut widths = bounds;
    for &j in &determined {
        let u = obs.eigenvectors[j];
        let others: Vec<[f64; 3]> = determined
            .iter()
            .filter(|&&k| k != j)
            .map(|&k| obs.eigenvectors[k])
            .collect();
        // The step's scale: the straight-line half-width (the bound is the curvature's, far
        // beyond where a flat-bottomed cost rises).
        let rise = |d: f64| problem.cost(add(p, u, d)) - region.c0;
        let straight = [1.0, -1.0]
            .map(|side| region.straight_width(|d| rise(side * d), bounds[j]))
            .into_iter()
            .fold(0.0f64, f64::max);
        let step = straight / STEPS_PER_WIDTH;
        for side in [1.0, -1.0] {
            let walk = region.walk(problem, &mut scratch, u, side, step, &others);
            widths[j] = widths[j].max(walk.crossing);
            for &i in determined.iter().filter(|&&i| i != j) {
                let v = obs.eigenvectors[i];
                for &(floor, rise) in &walk.floor {
                    let off: [f64; 3] = std::array::from_fn(|c| floor[c] - p[c]);
                    let reach = dot(&v, &off).abs() + bounds[i] * (1.0 - rise / region.s2).sqrt();
                    widths[i] = widths[i].max(reach.min(region.cap));
                }
            }
        }
    }
    Some(widths)
}

/// `rise ≥ s2` (false for NaN: a cost that cannot be evaluated has not risen).
fn reaches(rise: f64, s2: f64) -> bool {
    matches!(
        rise.partial_cmp(&s2),
        Some(Ordering::Greater | Ordering::Equal)
    )
}

fn dot(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    (0..3).map(|i| a[i] * b[i]).sum()
}

fn add(p: [f64; 3], v: [f64; 3], d: f64) -> [f64; 3] {
    [p[0] + d * v[0], p[1] + d * v[1], p[2] + d * v[2]]
}

/// The region `ε(p) − ε(p̂) ≤ s²` about p̂, searched no further than `cap` along a direction.
struct Region {
    p: [f64; 3],
    c0: f64,
    s2: f64,
    cap: f64,
}

/// One side of a valley walk.
struct Walk {
    /// The valley floor's points inside the region, with their rise Δε, and its crossing of
    /// the region's edge (rise s²) when it has one.
    floor: Vec<([f64; 3], f64)>,
    /// Where the floor's rise crosses s² (linear interpolation between steps); `cap` if it
    /// never does.
    crossing: f64,
}

impl Region {
    /// Where the cost along a straight line first rises by s², searched down from `start`
    /// by halving (an undetermined direction's linearised bound can be orders of magnitude
    /// beyond it), then bisected.
    fn straight_width(&self, mut rise: impl FnMut(f64) -> f64, start: f64) -> f64 {
        let mut hi = start.min(self.cap);
        let mut halved = false;
        for _ in 0..MAX_HALVINGS {
            if !reaches(rise(0.5 * hi), self.s2) {
                break;
            }
            hi *= 0.5;
            halved = true;
        }
        if !halved {
            // Within a factor of 2 of the bound (the usual, near-quadratic case).
            return hi;
        }
        // Only the walk's step comes from it: a factor of 2^-3 is enough.
        let (mut lo, mut hi) = (0.5 * hi, hi);
        for _ in 0..STRAIGHT_BISECTIONS {
            let mid = 0.5 * (lo + hi);
            if rise(mid) >= self.s2 {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        hi
    }

    /// Walks from p̂ along `side`·u in steps of `step` (doubling every
    /// [`STEPS_PER_DOUBLING`]), the cost minimised over `others` at each step, until the floor
    /// leaves the region.
    fn walk(
        &self,
        problem: &impl LeastSquares,
        scratch: &mut Scratch,
        u: [f64; 3],
        side: f64,
        step: f64,
        others: &[[f64; 3]],
    ) -> Walk {
        let mut floor = Vec::new();
        let (mut at, mut t, mut h, mut prev_rise) = (self.p, 0.0f64, step, 0.0);
        if !matches!(step.partial_cmp(&0.0), Some(Ordering::Greater)) {
            return Walk {
                floor,
                crossing: 0.0,
            };
        }
        for k in 1..=MAX_WALK_STEPS {
            let next = (t + h).min(self.cap);
            let (point, cost) =
                scratch.minimise_over(problem, add(at, u, side * (next - t)), others);
            let rise = cost - self.c0;
            if !matches!(rise.partial_cmp(&self.s2), Some(Ordering::Less)) {
                let frac = ((self.s2 - prev_rise) / (rise - prev_rise)).clamp(0.0, 1.0);
                let frac = if frac.is_nan() { 0.0 } else { frac };
                // The floor where it crosses s² (interpolated): the region's edge.
                floor.push((
                    std::array::from_fn(|c| at[c] + frac * (point[c] - at[c])),
                    self.s2,
                ));
                return Walk {
                    floor,
                    crossing: t + frac * (next - t),
                };
            }
            if rise < prev_rise - SADDLE_FRACTION * self.s2 {
                // Past a saddle, into another minimum's basin: the interval is this basin's
                // (a second minimum is a copy of the rate, ADR 0005, not its scatter).
                return Walk { floor, crossing: t };
            }
            floor.push((point, rise.max(0.0)));
            (at, t, prev_rise) = (point, next, rise);
            if t >= self.cap {
                break;
            }
            if k % STEPS_PER_DOUBLING == 0 {
                h *= 2.0;
            }
        }
        Walk { floor, crossing: t }
    }
}

/// Buffers of the Gauss–Newton steps.
struct Scratch {
    r: Vec<f64>,
    jac: Vec<[f64; 3]>,
}

impl Scratch {
    fn new(n: usize) -> Self {
        Self {
            r: vec![0.0; n],
            jac: vec![[0.0; 3]; n],
        }
    }

    /// min over a of ε(q + Σ a_j u_j) by Gauss–Newton from a = 0, each step kept only if it
    /// lowers the cost (so the result is never above ε(q)); returns the point and its cost.
    /// `others` has at most two directions.
    fn minimise_over(
        &mut self,
        problem: &impl LeastSquares,
        q: [f64; 3],
        others: &[[f64; 3]],
    ) -> ([f64; 3], f64) {
        if others.is_empty() {
            return (q, problem.cost(q));
        }
        let mut at = q;
        let mut cost = problem.residuals_and_jacobian(at, &mut self.r, &mut self.jac);
        for step in 0..PROFILE_STEPS {
            // r(at + U δ) ≈ r − J U δ  ⇒  (UᵀJᵀJU) δ = UᵀJᵀ r.
            let k = others.len().min(2);
            let mut h = [[0.0; 2]; 2];
            let mut g = [0.0; 2];
            for (row, &res) in self.jac.iter().zip(&self.r) {
                let ju: [f64; 2] =
                    std::array::from_fn(|a| if a < k { dot(row, &others[a]) } else { 0.0 });
                for a in 0..k {
                    g[a] += ju[a] * res;
                    for b in 0..k {
                        h[a][b] += ju[a] * ju[b];
                    }
                }
            }
            let delta = solve_small(&h, &g, k);
            let mut trial = at;
            for (a, u) in others.iter().take(k).enumerate() {
                trial = add(trial, *u, delta[a]);
            }
            let last = step + 1 == PROFILE_STEPS;
            let trial_cost = if last {
                problem.cost(trial)
            } else {
                problem.residuals_and_jacobian(trial, &mut self.r, &mut self.jac)
            };
            if !matches!(trial_cost.partial_cmp(&cost), Some(Ordering::Less)) {
                break;
            }
            (at, cost) = (trial, trial_cost);
        }
        (at, cost)
    }
}

/// The minimum-norm solution of the k×k (k ≤ 2) symmetric system h δ = g over h's eigenvalues
/// above [`FLAT_RELATIVE`] of its largest: a flat direction is left where it is.
fn solve_small(h: &[[f64; 2]; 2], g: &[f64; 2], k: usize) -> [f64; 2] {
    match k {
        1 if h[0][0] > 0.0 => [g[0] / h[0][0], 0.0],
        2 => {
            // Eigen-decomposition of [[a, b], [b, d]].
            let (a, b, d) = (h[0][0], 0.5 * (h[0][1] + h[1][0]), h[1][1]);
            if b == 0.0 {
                let top = a.max(d);
                let one = |hh: f64, gg: f64| {
                    if hh > FLAT_RELATIVE * top {
                        gg / hh
                    } else {
                        0.0
                    }
                };
                return [one(a, g[0]), one(d, g[1])];
            }
            let mean = 0.5 * (a + d);
            let radius = (0.25 * (a - d).powi(2) + b * b).sqrt();
            let lambdas = [mean + radius, mean - radius];
            let mut out = [0.0; 2];
            for lambda in lambdas {
                if !matches!(
                    lambda.partial_cmp(&(FLAT_RELATIVE * lambdas[0])),
                    Some(Ordering::Greater)
                ) {
                    continue;
                }
                // Eigenvector of λ: (b, λ − a) or (λ − d, b), whichever is larger.
                let (x, y) = if (lambda - a).abs() + b.abs() >= (lambda - d).abs() + b.abs() {
                    (b, lambda - a)
                } else {
                    (lambda - d, b)
                };
                let norm = (x * x + y * y).sqrt();
                let (x, y) = if norm > 0.0 {
                    (x / norm, y / norm)
                } else if a >= d {
                    (1.0, 0.0)
                } else {
                    (0.0, 1.0)
                };
                let along = (x * g[0] + y * g[1]) / lambda;
                out[0] += along * x;
                out[1] += along * y;
            }
            out
        }
        _ => [0.0; 2],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Whitened residuals (x/a, (y − k x²)/b, z/c) about 0: a valley y = k x² that bends away
    /// from the x axis. The profile along x follows it, so its rise is exactly x²/a² and its
    /// half-width a; the straight line climbs the wall (rise x²/a² + k²x⁴/b²).
    struct Valley {
        a: f64,
        b: f64,
        c: f64,
        k: f64,
    }

    impl LeastSquares for Valley {
        fn residual_count(&self) -> usize {
            3
        }
        fn residuals_and_jacobian(&self, p: [f64; 3], r: &mut [f64], jac: &mut [[f64; 3]]) -> f64 {
            let [x, y, z] = p;
            r[0] = -x / self.a;
            r[1] = -(y - self.k * x * x) / self.b;
            r[2] = -z / self.c;
            jac[0] = [1.0 / self.a, 0.0, 0.0];
            jac[1] = [-2.0 * self.k * x / self.b, 1.0 / self.b, 0.0];
            jac[2] = [0.0, 0.0, 1.0 / self.c];
            r.iter().map(|v| v * v).sum()
        }
    }

    /// The eigen-analysis at 0 with the given bounds along x, y, z.
    fn analysis(bounds: [f64; 3], unobservable: [bool; 3]) -> Observability {
        Observability {
            information_eigenvalues: bounds.map(|b| b.powi(-2)),
            eigenvectors: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            bounds_1sigma_deg_per_frame: bounds,
            unobservable,
            threshold_deg_per_frame: 0.25,
            condition_number: 1.0,
            rms_sensitivity_per_deg_per_frame: 1.0,
        }
    }

    /// σ given: s² = 1.
    const SIGMA: CovarianceSource = CovarianceSource::GivenSigma;

    /// The straight-line half-width of the valley along x: x²/a² + k²x⁴/b² = 1.
    fn straight_width(v: &Valley) -> f64 {
        let (a2, q) = (v.a * v.a, (v.k / v.b).powi(2));
        let u = (-1.0 / a2 + (1.0 / (a2 * a2) + 4.0 * q).sqrt()) / (2.0 * q);
        u.sqrt()
    }

    #[test]
    fn the_profile_follows_a_bent_valley_to_its_closed_form_widths() {
        let v = Valley {
            a: 0.01,
            b: 0.001,
            c: 0.02,
            k: 30.0,
        };
        let straight = straight_width(&v);
        assert!(
            straight < 0.6 * v.a,
            "the wall cuts the line short: {straight}"
        );
        let bounds = profiled_bounds(
            &v,
            [0.0; 3],
            &analysis([straight, v.b, v.c], [false; 3]),
            &SIGMA,
        )
        .expect("determined");
        // Along x the floor y = k x² rises as x²/a²: half-width a (steps of a fifth of it).
        assert!((bounds[0] - v.a).abs() < 0.01 * v.a, "{bounds:?}");
        // Along y the valley carries y to k·a² = 0.003 (profile: c + k a² (1 − b²/(4k²a⁴)),
        // c = b²/(2 k a²)); the straight line stops at b = 0.001.
        let c = v.b.powi(2) / (2.0 * v.k * v.a.powi(2));
        let closed =
            c + v.k * v.a.powi(2) * (1.0 - v.b.powi(2) / (4.0 * v.k.powi(2) * v.a.powi(4)));
        assert!(
            (bounds[1] - closed).abs() < 0.06 * closed,
            "{bounds:?} against {closed}"
        );
        assert!((bounds[2] - v.c).abs() < 1e-3 * v.c, "{bounds:?}");
    }

    #[test]
    fn a_quadratic_cost_keeps_its_linearised_widths() {
        let v = Valley {
            a: 0.01,
            b: 0.001,
            c: 0.02,
            k: 0.0,
        };
        let start = [v.a, v.b, v.c];
        let bounds = profiled_bounds(&v, [0.0; 3], &analysis(start, [false; 3]), &SIGMA).unwrap();
        for (got, want) in bounds.iter().zip(start) {
            assert!((got - want).abs() < 1e-9 * want, "{bounds:?}");
        }
    }

    #[test]
    fn an_undetermined_direction_is_neither_walked_nor_profiled_over() {
        let v = Valley {
            a: 0.01,
            b: 0.001,
            c: 0.02,
            k: 30.0,
        };
        let straight = straight_width(&v);
        // y undetermined (its linearised bound 1.0): x stays on its straight line.
        let marked = analysis([straight, 1.0, v.c], [false, true, false]);
        let bounds = profiled_bounds(&v, [0.0; 3], &marked, &SIGMA).unwrap();
        assert!((bounds[0] - straight).abs() < 1e-9 * straight, "{bounds:?}");
        assert_eq!(bounds[1], 1.0, "an undetermined bound is left as it is");
        assert!(profiled_bounds(&v, [0.0; 3], &analysis([1.0; 3], [true; 3]), &SIGMA).is_none());
    }

    /// (√A·x(x − m)/m², y/b, z/c): minima at x = 0 and x = m, the saddle between at m/2 only
    /// A/16 high.
    struct TwoWells {
        a: f64,
        m: f64,
        b: f64,
        c: f64,
    }

    impl LeastSquares for TwoWells {
        fn residual_count(&self) -> usize {
            3
        }
        fn residuals_and_jacobian(&self, p: [f64; 3], r: &mut [f64], jac: &mut [[f64; 3]]) -> f64 {
            let [x, y, z] = p;
            let (sa, m2) = (self.a.sqrt(), self.m * self.m);
            r[0] = -sa * x * (x - self.m) / m2;
            r[1] = -y / self.b;
            r[2] = -z / self.c;
            jac[0] = [sa * (2.0 * x - self.m) / m2, 0.0, 0.0];
            jac[1] = [0.0, 1.0 / self.b, 0.0];
            jac[2] = [0.0, 0.0, 1.0 / self.c];
            r.iter().map(|v| v * v).sum()
        }
    }

    #[test]
    fn the_walk_stops_at_a_saddle_into_another_minimum() {
        // Saddle 8/16 = 0.5 noise variances high: the region ε ≤ s² spans both wells (to
        // 1.28 m), the first well's basin only to the saddle at m/2.
        let w = TwoWells {
            a: 8.0,
            m: 0.01,
            b: 0.001,
            c: 0.002,
        };
        let linear = w.m / w.a.sqrt();
        let bounds = profiled_bounds(
            &w,
            [0.0; 3],
            &analysis([linear, w.b, w.c], [false; 3]),
            &SIGMA,
        )
        .unwrap();
        assert!(
            (0.45 * w.m..=0.6 * w.m).contains(&bounds[0]),
            "{bounds:?}: the basin ends at the saddle, {}",
            0.5 * w.m
        );
    }
}
