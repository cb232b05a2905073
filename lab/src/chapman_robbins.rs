//! The Hammersley–Chapman–Robbins bound: the variance floor of an unbiased rate estimator when
//! the light curve is not locally linear in p over the scatter the noise allows.
//!
//! The Cramér–Rao bound sees only the slope of the light curve at p₀. In the co-orbital geometry
//! the light curve of (w_x, w_y, w_z) and of its mirror (−w_x, w_y, −w_z) differ only through
//! the small out-of-plane components of the Sun and observer vectors (math.md §1.6), so near a
//! rate that is nearly its own mirror (a Y rotation) the light curve is almost even in w_z: the
//! slope is small, the curvature is not, and p₀ + h for h of a few CRBs fits the noise-free data
//! within one noise variance. No estimator reaches the CRB there. For a test offset h and
//! Gaussian noise (whitened residuals r), the χ² divergence between the data distributions at
//! p₀ + h and p₀ is `exp(Δ(h)) − 1`, `Δ(h) = ‖r(p₀ + h) − r(p₀)‖²`, and every unbiased
//! estimator of `v·p` obeys (Hammersley 1950; Chapman & Robbins 1951)
//!
//! ```text
//! Var(v·p̂) ≥ sup_h (v·h)² / (exp(Δ(h)) − 1)
//! ```
//!
//! The stage-1 coefficients are parameters too when the problem carries their covariance
//! ([`RateProblem::with_coefficient_covariance`]): a test point then moves them as well, to
//! where p₀ + h fits p₀'s light curve best at the price the stable window charges, and
//!
//! ```text
//! Δ(h) = dᵀ M d,   d = r(p₀ + h) − r(p₀),   M = I − Σ_b B_b (S_b + B_bᵀB_b)⁻¹ B_bᵀ
//! ```
//!
//! (S_b the stable window's information about band b's coefficients, B_b the motion residuals'
//! sensitivity to them, as in `model::coefficients`). Two rates whose light curves differ by
//! what the stable window's noise could have put into the coefficients are then as hard to
//! tell apart as that noise makes them.
//!
//! As h → 0 the ratio tends to the CRB along v of the sub-problem the searched directions span
//! (v and the `free` ones, the rest held; with the coefficients unknown, (JᵀJ − L)⁻¹), so a
//! bound well above the CRB means the light curve is not linear over the offsets that matter.
//! [`chapman_robbins`] evaluates the supremum on the profile: for offsets `c` along v on a
//! geometric grid, Δ is minimised over the `free` directions by Gauss–Newton (continued from
//! the previous offset), and the largest `c²/expm1(Δ)` is kept.

use glint_inversion::InversionError;
use glint_inversion::RateProblem;

/// The bound along one direction and where the supremum was found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChapmanRobbins {
    /// Largest `c²/(exp(Δ) − 1)` over the offsets searched \[(deg/frame)²\] (∞ when some
    /// offset fits exactly as well as p₀).
    pub variance: f64,
    /// The offset c along v that attains it \[deg/frame\].
    pub offset_deg_per_frame: f64,
    /// Δ there (noise variances).
    pub divergence: f64,
    /// The test point p₀ + c v + Σ a_k u_k there \[deg/frame\].
    pub point_deg_per_frame: [f64; 3],
    /// A copy of p₀ along v, if the search met one: see [`RateCopy`].
    pub copy: Option<RateCopy>,
}

/// A rate the data cannot tell from p₀: beyond p₀'s local scatter (|c| ≥ 2 CRB along v), yet
/// fitting p₀'s noise-free light curve within one noise variance, and far better than the
/// light curve's slope at p₀ predicts: Δ < min(1, ¼ (c/CRB)²). The smallest Δ found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RateCopy {
    /// The rate \[deg/frame\].
    pub point_deg_per_frame: [f64; 3],
    /// Its offset along v \[deg/frame\].
    pub offset_deg_per_frame: f64,
    /// Δ there (noise variances).
    pub divergence: f64,
}

/// Offsets are searched on `start·GROWTH^k` on each side.
const GROWTH: f64 = 1.15;
/// Gauss–Newton iterations of the profile at each offset, at most.
const PROFILE_ITERATIONS: usize = 8;
/// A copy lies at least this many CRB standard deviations from p₀ along v.
const COPY_MIN_CRB: f64 = 2.0;
/// A copy fits p₀'s light curve within this many noise variances.
const COPY_MAX_DIVERGENCE: f64 = 1.0;
/// Golden-section steps refining the supremum between two grid offsets.
const REFINE_STEPS: usize = 24;
/// 1/φ.
const GOLDEN: f64 = 0.618_033_988_749_894_8;

/// One profiled offset.
#[derive(Debug, Clone, Copy)]
struct Sample {
    /// |c| \[deg/frame\].
    c: f64,
    /// The free coordinates minimising Δ there.
    a: [f64; 2],
    delta: f64,
    ratio: f64,
}

/// The Hammersley–Chapman–Robbins bound on `Var(v·p̂)` at `p0` (`v` a unit vector), profiled
/// over the unit directions `free` (orthogonal to v; at most two), searching offsets
/// `|c| ∈ [crb_sd/10, max_offset]` \[deg/frame\], with `crb_sd` the CRB's 1σ along v. The
/// problem must carry σ (whitened residuals).
pub fn chapman_robbins(
    problem: &RateProblem,
    p0: [f64; 3],
    v: [f64; 3],
    free: &[[f64; 3]],
    crb_sd: f64,
    max_offset: f64,
) -> Result<ChapmanRobbins, InversionError> {
    let start = 0.1 * crb_sd;
    if !problem.sigma_given() {
        return Err(InversionError::MissingSigma {
            what: "the Chapman–Robbins bound",
        });
    }
    let n = problem.residual_count();
    let mut r0 = vec![0.0; n];
    problem.residuals(p0, &mut r0);
    let mut best = ChapmanRobbins {
        variance: 0.0,
        offset_deg_per_frame: 0.0,
        divergence: f64::NAN,
        point_deg_per_frame: p0,
        copy: None,
    };
    if !(start > 0.0 && start <= max_offset) {
        return Ok(best);
    }
    let mut profile = Profile::new(problem, p0, &r0, free);
    for side in [1.0, -1.0] {
        let mut sample = |c: f64, a: [f64; 2]| {
            let mut a = a;
            let delta = profile.minimise(side * c, v, &mut a);
            let ratio = if delta > 0.0 {
                c * c / delta.exp_m1()
            } else {
                f64::INFINITY
            };
            Sample { c, a, delta, ratio }
        };
        let mut grid: Vec<Sample> = Vec::new();
        let mut c = start;
        while c <= max_offset {
            // Continued from the previous offset's free coordinates.
            let a = grid.last().map_or([0.0; 2], |g| g.a);
            grid.push(sample(c, a));
            c *= GROWTH;
        }
        let Some(k) = (0..grid.len()).max_by(|&i, &j| grid[i].ratio.total_cmp(&grid[j].ratio))
        else {
            continue;
        };
        // Golden-section refinement between the neighbours of the best grid offset: a
        // near-copy of the light curve (the mirror) is a narrow peak of the ratio.
        let mut top = grid[k];
        let (mut x0, mut x1) = (
            if k == 0 {
                0.5 * grid[0].c
            } else {
                grid[k - 1].c
            },
            grid.get(k + 1).map_or(grid[k].c, |g| g.c),
        );
        for _ in 0..REFINE_STEPS {
            let s1 = sample(x1 - GOLDEN * (x1 - x0), grid[k].a);
            let s2 = sample(x0 + GOLDEN * (x1 - x0), grid[k].a);
            for s in [s1, s2] {
                if s.ratio > top.ratio {
                    top = s;
                }
            }
            if s1.ratio >= s2.ratio {
                x1 = s2.c;
            } else {
                x0 = s1.c;
            }
        }
        // The copy: the smallest Δ among offsets the slope at p₀ says should be clearly
        // rejected. Each dip of Δ along the grid is refined between its grid neighbours: at
        // high SNR a copy's well is narrower than the grid's ×1.15 step, so no grid point need
        // lie inside it.
        let is_copy = |s: &Sample| {
            s.c >= COPY_MIN_CRB * crb_sd
                && s.delta < COPY_MAX_DIVERGENCE.min(0.25 * (s.c / crb_sd).powi(2))
        };
        let dips = (0..grid.len()).filter(|&j| {
            let below = |i: Option<usize>| {
                i.and_then(|i| grid.get(i))
                    .is_none_or(|g| grid[j].delta <= g.delta)
            };
            is_copy(&grid[j]) || (j > 0 && below(Some(j - 1)) && below(Some(j + 1)))
        });
        let mut found: Option<Sample> = None;
        for j in dips {
            if is_copy(&grid[j]) && found.is_none_or(|f| grid[j].delta < f.delta) {
                found = Some(grid[j]);
            }
            let (mut x0, mut x1) = (
                grid[j.saturating_sub(1)].c,
                grid.get(j + 1).map_or(grid[j].c, |g| g.c),
            );
            for _ in 0..REFINE_STEPS {
                let s1 = sample(x1 - GOLDEN * (x1 - x0), grid[j].a);
                let s2 = sample(x0 + GOLDEN * (x1 - x0), grid[j].a);
                for s in [s1, s2] {
                    if is_copy(&s) && found.is_none_or(|f| s.delta < f.delta) {
                        found = Some(s);
                    }
                    // A well the grid missed can hold the supremum too.
                    if s.ratio > top.ratio {
                        top = s;
                    }
                }
                if s1.delta <= s2.delta {
                    x1 = s2.c;
                } else {
                    x0 = s1.c;
                }
            }
        }
        if top.ratio > best.variance {
            best.variance = top.ratio;
            best.offset_deg_per_frame = side * top.c;
            best.divergence = top.delta;
            best.point_deg_per_frame = profile.point(side * top.c, v, &top.a);
        }
        if let Some(f) = found.filter(|f| best.copy.is_none_or(|b| f.delta < b.divergence)) {
            best.copy = Some(RateCopy {
                point_deg_per_frame: profile.point(side * f.c, v, &f.a),
                offset_deg_per_frame: side * f.c,
                divergence: f.delta,
            });
        }
    }
    Ok(best)
}

/// Δ(c v + Σ a_k u_k) minimised over a (and over the stage-1 coefficients when the problem
/// carries their covariance), with scratch buffers.
struct Profile<'a> {
    problem: &'a RateProblem,
    p0: [f64; 3],
    r0: &'a [f64],
    free: &'a [[f64; 3]],
    r: Vec<f64>,
    jac: Vec<[f64; 3]>,
    /// Per residual: J u_1, J u_2 (0 where there is no such free direction) and r − r₀.
    columns: Vec<[f64; 3]>,
}

/// Δ at one test point and the Gauss–Newton system of its profile over the free directions.
struct Evaluation {
    delta: f64,
    /// UᵀJᵀMJU.
    normal: [[f64; 2]; 2],
    /// UᵀJᵀM(r − r₀).
    gradient: [f64; 2],
}

impl<'a> Profile<'a> {
    fn new(problem: &'a RateProblem, p0: [f64; 3], r0: &'a [f64], free: &'a [[f64; 3]]) -> Self {
        let n = r0.len();
        Profile {
            problem,
            p0,
            r0,
            free: &free[..free.len().min(2)],
            r: vec![0.0; n],
            jac: vec![[0.0; 3]; n],
            columns: vec![[0.0; 3]; n],
        }
    }

    fn point(&self, c: f64, v: [f64; 3], a: &[f64; 2]) -> [f64; 3] {
        std::array::from_fn(|i| {
            self.p0[i]
                + c * v[i]
                + self
                    .free
                    .iter()
                    .zip(a)
                    .map(|(u, ak)| u[i] * ak)
                    .sum::<f64>()
        })
    }

    /// Δ(p) = (r − r₀)ᵀ M (r − r₀) with M = I − Σ_b B_b (S_b + B_bᵀB_b)⁻¹ B_bᵀ: the divergence
    /// with each band's stage-1 coefficients moved to fit p₀'s light curve best, at the price
    /// δxᵀS_bδx the stable window charges for the move (S_b its information about them, B_b the
    /// motion residuals' sensitivity to them; the light curve is linear in the coefficients, so
    /// the minimum over δx is exact). M = I when the coefficients are known (no covariance).
    /// As h → 0 the ratio then tends to the Cramér–Rao bound with the coefficients unknown,
    /// (JᵀJ − L)⁻¹ (`RateProblem::coefficient_information_loss`).
    fn evaluate(&mut self, p: [f64; 3]) -> Evaluation {
        self.problem
            .residuals_and_jacobian(p, &mut self.r, &mut self.jac);
        for ((col, row), (ri, r0i)) in self
            .columns
            .iter_mut()
            .zip(&self.jac)
            .zip(self.r.iter().zip(self.r0))
        {
            let along = |q: usize| {
                self.free
                    .get(q)
                    .map_or(0.0, |u| (0..3).map(|i| row[i] * u[i]).sum())
            };
            *col = [along(0), along(1), ri - r0i];
        }
        let mut gram = [[0.0; 3]; 3];
        for col in &self.columns {
            for i in 0..3 {
                for j in 0..3 {
                    gram[i][j] += col[i] * col[j];
                }
            }
        }
        if let Some(loss) = self.problem.coefficient_information_loss(p, &self.columns) {
            for i in 0..3 {
                for j in 0..3 {
                    gram[i][j] -= loss[i][j];
                }
            }
        }
        Evaluation {
            delta: gram[2][2].max(0.0),
            normal: [[gram[0][0], gram[0][1]], [gram[1][0], gram[1][1]]],
            gradient: [gram[0][2], gram[1][2]],
        }
    }

    /// Δ at offset c, with a (the free coordinates, updated in place) minimising it.
    fn minimise(&mut self, c: f64, v: [f64; 3], a: &mut [f64; 2]) -> f64 {
        let k = self.free.len();
        let mut at = self.evaluate(self.point(c, v, a));
        if k == 0 {
            return at.delta;
        }
        for _ in 0..PROFILE_ITERATIONS {
            // d = r − r₀, ∂d/∂a_k = −J u_k: the step solves (UᵀJᵀMJU) δa = UᵀJᵀM d.
            let Some(step) = solve2(&at.normal, &at.gradient, k) else {
                break;
            };
            let trial = [a[0] + step[0], a[1] + step[1]];
            let next = self.evaluate(self.point(c, v, &trial));
            if next.delta.is_nan() || next.delta >= at.delta {
                break;
            }
            let gain = at.delta - next.delta;
            *a = trial;
            at = next;
            if gain <= 1e-9 * (1.0 + at.delta) {
                break;
            }
        }
        at.delta
    }
}

/// Solves the k × k (k ≤ 2) symmetric system; `None` when singular.
fn solve2(m: &[[f64; 2]; 2], g: &[f64; 2], k: usize) -> Option<[f64; 2]> {
    match k {
        1 => (m[0][0] > 0.0).then(|| [g[0] / m[0][0], 0.0]),
        _ => {
            let det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
            (det > 0.0 && det.is_finite()).then(|| {
                [
                    (g[0] * m[1][1] - g[1] * m[0][1]) / det,
                    (g[1] * m[0][0] - g[0] * m[1][0]) / det,
                ]
            })
        }
    }
}
