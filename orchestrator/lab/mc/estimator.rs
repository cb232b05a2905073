//! Scatter and consistency of one estimator over a Monte-Carlo value's noisy runs: RMS about
//! p₀ (or its copy) on the bound's observable directions, efficiency against the CRB and the
//! two-stage bound, NEES, and the runs counted apart (other sense, no rate).

use super::{distance, finite, has_sense, mirror, observable_bound, Bound};
use crate::report::inversion::Stage3Report;
use crate::report::score_debris::chi2_mean_bounds;
use glint_inversion::observability::symmetric_eigen;
use serde_json::{json, Value};

/// What the estimator reads of one run's fit.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Fit {
    /// The rate \[deg/frame\], when determined (and finite).
    pub p: Option<[f64; 3]>,
    /// The fit used the model with the widest lobes re-fitted.
    pub widest_lobe_refit: bool,
    /// The mirror that fits as well, when the fit named one.
    pub mirror: Option<[f64; 3]>,
    /// Cov(p̂) \[(deg/frame)²\], when reported (and finite).
    pub covariance: Option<[[f64; 3]; 3]>,
}

impl Fit {
    /// glint's answer (the joint fit) of a run's stage 3.
    pub(super) fn answer(s3: Option<&Stage3Report>) -> Fit {
        let Some(s3) = s3 else {
            return Fit::default();
        };
        Fit {
            p: s3
                .p_deg_per_frame
                .filter(|p| p.iter().all(|x| x.is_finite())),
            widest_lobe_refit: s3.widest_lobe_refit,
            mirror: s3.mirror_deg_per_frame,
            covariance: s3.covariance.and_then(|c| {
                let m = [[c[0], c[1], c[2]], [c[3], c[4], c[5]], [c[6], c[7], c[8]]];
                m.iter().flatten().all(|x| x.is_finite()).then_some(m)
            }),
        }
    }

    /// λ*'s own fit (the paper's stage 3): its rate alone.
    pub(super) fn lambda_star(s3: Option<&Stage3Report>) -> Fit {
        Fit {
            p: (s3.and_then(|s3| s3.lambda_star.p_deg_per_frame))
                .filter(|p| p.iter().all(|x| x.is_finite())),
            ..Fit::default()
        }
    }
}

/// Scatter and consistency of one estimator over the noisy runs.
pub(super) struct Estimator {
    bound: Bound,
    /// Σ_obs (d·v_i)² per determined run.
    dev2_observable: Vec<f64>,
    /// (d·v_i)² per run, per CRB direction.
    dev2_along: Vec<[f64; 3]>,
    /// (NEES, dof) per run with a reported covariance.
    nees: Vec<(f64, usize)>,
    /// The same with the deviation measured in speed and axis ([`curvilinear_deviation`]).
    nees_curvilinear: Vec<(f64, usize)>,
    /// Runs without a determined rate.
    undetermined: usize,
    /// Runs nearer the mirror of p₀ than p₀ (the other sense of rotation): a global ambiguity,
    /// outside what a local bound describes, counted and kept out of RMS and NEES.
    other_sense: usize,
    /// Of those, the runs whose answer named the mirror as fitting as well (the sense reported
    /// as not determined, rather than the other sense claimed).
    other_sense_flagged: usize,
    /// Runs nearer p₀'s copy than p₀: their deviation is taken from the copy.
    on_copy: usize,
}

impl Estimator {
    /// `models`: the noise-free solutions of the fit's two lobe models ([`Reference`]); a run
    /// is then measured from that of the model it reported.
    pub(super) fn from_runs(runs: &[Fit], bound: Bound, models: Option<&[Bound; 2]>) -> Self {
        let observable = bound.observable();
        let mut out = Estimator {
            dev2_observable: vec![],
            dev2_along: vec![],
            nees: vec![],
            nees_curvilinear: vec![],
            undetermined: 0,
            other_sense: 0,
            other_sense_flagged: 0,
            on_copy: 0,
            bound,
        };
        let Some(table_p0) = out.bound.p0 else {
            out.undetermined = runs.len();
            return out;
        };
        for fit in runs {
            let Some(p) = fit.p else {
                out.undetermined += 1;
                continue;
            };
            let own = models.map(|m| &m[usize::from(fit.widest_lobe_refit)]);
            let (p0, copy) = match own {
                Some(Bound {
                    p0: Some(p0), copy, ..
                }) => (*p0, *copy),
                _ => (table_p0, out.bound.copy),
            };
            let m0 = mirror(p0);
            // A rate mostly about Y is nearly its own mirror and has no sense to lose.
            if has_sense(p0) && distance(p, m0) < distance(p, p0) {
                out.other_sense += 1;
                out.other_sense_flagged += usize::from(fit.mirror.is_some());
                continue;
            }
            // The data cannot tell p₀ from its copy: scatter is measured from the nearer.
            let centre = match copy.map(|c| c.point_deg_per_frame) {
                Some(c) if distance(p, c) < distance(p, p0) => {
                    out.on_copy += 1;
                    c
                }
                _ => p0,
            };
            let d = [p[0] - centre[0], p[1] - centre[1], p[2] - centre[2]];
            let along = out
                .bound
                .directions
                .map(|v| (0..3).map(|i| v[i] * d[i]).sum::<f64>());
            let along2 = along.map(|x| x * x);
            out.dev2_along.push(along2);
            out.dev2_observable
                .push((0..3).filter(|&i| observable[i]).map(|i| along2[i]).sum());
            if let Some(cov) = fit.covariance {
                if let Some(n) = nees(&cov, &d) {
                    out.nees.push(n);
                }
                if let Some(n) = nees(&cov, &curvilinear_deviation(p, centre)) {
                    out.nees_curvilinear.push(n);
                }
            }
        }
        out
    }

    pub(super) fn json(&self) -> Value {
        let observable = self.bound.observable();
        let n = self.dev2_observable.len();
        // A bound's variance summed over the observable directions.
        let over_observable =
            |v: &[f64; 3]| -> f64 { (0..3).filter(|&i| observable[i]).map(|i| v[i]).sum() };
        let crb_obs = over_observable(&self.bound.variances);
        let known_obs = over_observable(&self.bound.known_variances);
        let two_stage_obs = over_observable(&self.bound.two_stage_variances);
        let hcr_obs = over_observable(&self.bound.hcr_variances);
        let rms_obs = (n > 0).then(|| (self.dev2_observable.iter().sum::<f64>() / n as f64).sqrt());
        let per_direction: Vec<Value> = (0..3)
            .map(|i| {
                let rms = (n > 0)
                    .then(|| (self.dev2_along.iter().map(|a| a[i]).sum::<f64>() / n as f64).sqrt());
                json!({
                    "direction": self.bound.directions[i],
                    "crb_1sigma_deg_per_frame": finite(self.bound.variances[i].sqrt()),
                    "two_stage_1sigma_deg_per_frame": finite(self.bound.two_stage_variances[i].sqrt()),
                    "hcr_1sigma_deg_per_frame": finite(self.bound.hcr_variances[i].sqrt()),
                    "rms_deg_per_frame": rms,
                    "observable": observable[i],
                })
            })
            .collect();
        let total_dof: usize = self.nees.iter().map(|(_, k)| k).sum();
        let mean_nees = (!self.nees.is_empty())
            .then(|| self.nees.iter().map(|(e, _)| e).sum::<f64>() / self.nees.len() as f64);
        let [lo, hi] = chi2_mean_bounds(total_dof, self.nees.len());
        let mean_nees_curvilinear = (!self.nees_curvilinear.is_empty()).then(|| {
            self.nees_curvilinear.iter().map(|(e, _)| e).sum::<f64>()
                / self.nees_curvilinear.len() as f64
        });
        json!({
            "p0_deg_per_frame": self.bound.p0,
            "determined": n + self.other_sense,
            "undetermined": self.undetermined,
            "other_sense": self.other_sense,
            "other_sense_flagged": self.other_sense_flagged,
            "copy_deg_per_frame": self.bound.copy.map(|c| c.point_deg_per_frame),
            "copy_divergence": self.bound.copy.map(|c| c.divergence),
            "on_copy": self.on_copy,
            "observable_directions": observable.iter().filter(|o| **o).count(),
            "crb_observable_deg_per_frame": finite(crb_obs.sqrt()),
            "crb_known_coefficients_observable_deg_per_frame": finite(known_obs.sqrt()),
            "rms_observable_deg_per_frame": rms_obs,
            "efficiency": rms_obs.map(|r| r / crb_obs.sqrt()).filter(|e| e.is_finite()),
            "two_stage_observable_deg_per_frame": finite(two_stage_obs.sqrt()),
            "efficiency_two_stage": rms_obs.map(|r| r / two_stage_obs.sqrt()).filter(|e| e.is_finite()),
            "hcr_observable_deg_per_frame": finite(hcr_obs.sqrt()),
            // The bound a campaign can check the target against: above 1.25 × CRB, no unbiased
            // estimator meets "RMS ≤ 1.25 × CRB" (the issue: where the bound says the target is
            // impossible, show the bound).
            "hcr_over_crb": finite((hcr_obs / crb_obs).sqrt()),
            "efficiency_hcr": rms_obs.map(|r| r / hcr_obs.sqrt()).filter(|e| e.is_finite()),
            "directions": per_direction,
            "nees_mean": mean_nees,
            "nees_dof_mean": (!self.nees.is_empty()).then(|| total_dof as f64 / self.nees.len() as f64),
            "nees_bounds_95": [finite(lo), finite(hi)],
            "nees_mean_curvilinear": mean_nees_curvilinear,
        })
    }
}

/// p̂ − c measured in speed and axis instead of along a straight line: the speed difference
/// along p̂'s axis, plus the arc from p̂'s axis to c's, of length |p̂|·angle, in the plane of the
/// two axes. It equals p̂ − c to first order; where a run's axis wanders along a direction the
/// data hold under their prior (about Y, w_z), the straight line cuts the sphere of p̂'s speed
/// and puts |c|(1 − cos angle) of the held direction's wander on the determined speed.
pub(super) fn curvilinear_deviation(p: [f64; 3], c: [f64; 3]) -> [f64; 3] {
    let straight = [p[0] - c[0], p[1] - c[1], p[2] - c[2]];
    let norm = |v: [f64; 3]| distance(v, [0.0; 3]);
    let (n, n0) = (norm(p), norm(c));
    if !(n > 0.0 && n0 > 0.0) {
        return straight;
    }
    let (u, u0) = (p.map(|x| x / n), c.map(|x| x / n0));
    let cos = (0..3).map(|i| u[i] * u0[i]).sum::<f64>().clamp(-1.0, 1.0);
    // Toward c's axis, in the tangent plane at p̂'s.
    let t = [0, 1, 2].map(|i| u0[i] - cos * u[i]);
    let sin = norm(t);
    if sin == 0.0 {
        // The same axis (radial only), or opposite ones (no single arc): the straight line.
        return if cos > 0.0 {
            u.map(|x| (n - n0) * x)
        } else {
            straight
        };
    }
    let arc = n * cos.acos();
    [0, 1, 2].map(|i| (n - n0) * u[i] - arc * t[i] / sin)
}

/// NEES of deviation d under a reported covariance, over its observable eigen-directions.
fn nees(cov: &[[f64; 3]; 3], d: &[f64; 3]) -> Option<(f64, usize)> {
    let (vals, vecs) = symmetric_eigen(cov).ok()?;
    let mut sum = 0.0;
    let mut dof = 0;
    for (var, v) in vals.iter().zip(&vecs) {
        if !(*var > 0.0 && var.sqrt() <= observable_bound()) {
            continue;
        }
        let x: f64 = (0..3).map(|i| v[i] * d[i]).sum();
        sum += x * x / var;
        dof += 1;
    }
    (dof > 0).then_some((sum, dof))
}
