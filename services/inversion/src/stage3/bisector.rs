//! The sun–observer bisector held throughout a fit whose diffuse terms are re-estimated at every
//! p (the polish of [`super::Stage3Config::refit_diffuse`], ADR 0010).

use super::weak::{onto_prior_planes, PRIOR_WEIGHT_FACTOR};
use super::Stage3Config;
use crate::error::InversionError;
use crate::lm::{levenberg_marquardt_prior, LmOutcome, Prior};
use crate::model::RateProblem;
use crate::observability::{inverse_from_eigen, symmetric_eigen, Analysis, UnobservableReason};

/// The bisector held throughout a fit whose diffuse terms are re-estimated at every p.
///
/// A rotation about the sun–observer bisector u leaves every Beckmann lobe unchanged; only the
/// diffuse terms see it (math.md §1.6). When stage 3 re-fits those terms
/// ([`crate::model::MotionModelConfig::refit_diffuse`]) they absorb what little the light
/// curve says about u, and an unconstrained LM slides along it (by 0.04–1.4 deg/frame)
/// to wherever the mismatch gives it apparent curvature. So u is unobservable by
/// construction: every LM run of such a fit carries the stated prior ([`WeakPrior`]) from its
/// start, and u is reported unobservable.
pub(super) struct BisectorHold {
    /// u, the bisector at the epoch.
    weak: [f64; 3],
    /// The prior's direction e (u itself, or the body axis nearest it).
    prior: Prior,
}

impl BisectorHold {
    /// The hold for `problem`, weighted against the information at `p`.
    pub(super) fn new(problem: &RateProblem, p: [f64; 3], config: &Stage3Config) -> Self {
        let weak = problem.bisector_at_epoch();
        let n = problem.residual_count();
        let (mut r, mut jac) = (vec![0.0; n], vec![[0.0; 3]; n]);
        problem.residuals_and_jacobian(p, &mut r, &mut jac);
        // The trace bounds the largest eigenvalue of JᵀJ.
        let trace: f64 = jac.iter().flat_map(|row| row.iter().map(|v| v * v)).sum();
        let weight = PRIOR_WEIGHT_FACTOR
            * if trace.is_finite() {
                trace.max(1.0)
            } else {
                1.0
            };
        let directions = config.weak_prior.directions(&[weak]);
        BisectorHold {
            weak,
            prior: Prior { directions, weight },
        }
    }

    /// The direction held at the prior (e).
    pub(super) fn held_direction(&self) -> [f64; 3] {
        self.prior.directions[0]
    }

    /// `p` moved along u onto the prior's plane (the other combinations keep their values).
    pub(super) fn onto_plane(&self, p: [f64; 3]) -> [f64; 3] {
        onto_prior_planes(p, &[self.weak], &self.prior.directions)
    }

    /// Starts about `p` within the prior's plane: `p` itself, then `p` ± k·`step`, k = 1 … `reach`,
    /// along the plane's two directions (the rate's own within the plane, and the one across it).
    pub(super) fn plane_starts(&self, p: [f64; 3], step: f64, reach: usize) -> Vec<[f64; 3]> {
        let e = self.prior.directions[0];
        let p = self.onto_plane(p);
        let along_e: f64 = (0..3).map(|i| p[i] * e[i]).sum();
        let in_plane: [f64; 3] = std::array::from_fn(|i| p[i] - along_e * e[i]);
        let norm = in_plane.iter().map(|v| v * v).sum::<f64>().sqrt();
        // A rate along e has no direction of its own in the plane: any unit vector across e.
        let d1 = if norm > 0.0 {
            in_plane.map(|v| v / norm)
        } else {
            let k = (0..3)
                .min_by(|&a, &b| e[a].abs().total_cmp(&e[b].abs()))
                .unwrap_or(0);
            let mut a = [0.0; 3];
            a[k] = 1.0;
            let d: f64 = (0..3).map(|i| a[i] * e[i]).sum();
            let v: [f64; 3] = std::array::from_fn(|i| a[i] - d * e[i]);
            let n = v.iter().map(|x| x * x).sum::<f64>().sqrt();
            v.map(|x| x / n)
        };
        let d2 = [
            e[1] * d1[2] - e[2] * d1[1],
            e[2] * d1[0] - e[0] * d1[2],
            e[0] * d1[1] - e[1] * d1[0],
        ];
        let mut starts = vec![p];
        for k in 1..=reach {
            for d in [d1, d2] {
                for sign in [1.0, -1.0] {
                    let h = sign * step * k as f64;
                    starts.push(std::array::from_fn(|i| p[i] + h * d[i]));
                }
            }
        }
        starts
    }

    /// LM from `p0` (moved onto the plane) under the prior; the outcome's cost is the data's.
    pub(super) fn fit(
        &self,
        problem: &RateProblem,
        p0: [f64; 3],
        config: &Stage3Config,
        abandon: impl FnMut(&[f64; 3], f64, usize) -> bool,
    ) -> Result<LmOutcome, InversionError> {
        let out = levenberg_marquardt_prior(
            problem,
            self.onto_plane(p0),
            &config.lm,
            &self.prior,
            abandon,
        )?;
        Ok(LmOutcome {
            cost: problem.cost(out.p_deg_per_frame),
            ..out
        })
    }

    /// Restates `analysis` for a fit held on the plane e·p = 0: the information within the
    /// plane (`P F P`, P = I − e eᵀ) gives the determined directions and their covariance
    /// (conditional on the prior), and e itself is reported unobservable with the start box's
    /// half-width as its 1σ: the data say nothing about it that the fit used.
    pub(super) fn restate(
        &self,
        analysis: &mut Analysis,
        config: &Stage3Config,
    ) -> Result<(), InversionError> {
        let e = self.prior.directions[0];
        let obs = &mut analysis.observability;
        let info: [[f64; 3]; 3] = std::array::from_fn(|i| {
            std::array::from_fn(|j| {
                (0..3)
                    .map(|k| {
                        obs.information_eigenvalues[k]
                            * obs.eigenvectors[k][i]
                            * obs.eigenvectors[k][j]
                    })
                    .sum()
            })
        });
        let project = |v: [f64; 3]| -> [f64; 3] {
            let d: f64 = (0..3).map(|i| v[i] * e[i]).sum();
            std::array::from_fn(|i| v[i] - d * e[i])
        };
        let rows: [[f64; 3]; 3] = std::array::from_fn(|i| project(info[i]));
        let cols: [[f64; 3]; 3] =
            std::array::from_fn(|j| project([rows[0][j], rows[1][j], rows[2][j]]));
        let in_plane: [[f64; 3]; 3] = std::array::from_fn(|i| std::array::from_fn(|j| cols[j][i]));
        let (vals, vecs) = symmetric_eigen(&in_plane)?;
        // The eigen-pair nearest e is the plane's normal (eigenvalue ≈ 0): replace it by e.
        let along = |k: usize| (0..3).map(|i| vecs[k][i] * e[i]).sum::<f64>().abs();
        let normal = (0..3)
            .max_by(|&a, &b| along(a).total_cmp(&along(b)))
            .unwrap_or(0);
        let held_sigma = config.start.half_width_deg_per_frame;
        let mut pairs: Vec<(f64, [f64; 3])> = (0..3)
            .map(|k| {
                if k == normal {
                    (held_sigma.powi(-2), e)
                } else {
                    (vals[k], vecs[k])
                }
            })
            .collect();
        pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
        obs.information_eigenvalues = std::array::from_fn(|k| pairs[k].0);
        obs.eigenvectors = std::array::from_fn(|k| pairs[k].1);
        obs.bounds_1sigma_deg_per_frame = obs.information_eigenvalues.map(|v| {
            if v > 0.0 {
                v.sqrt().recip()
            } else {
                f64::INFINITY
            }
        });
        let threshold = obs.threshold_deg_per_frame;
        obs.unobservable = std::array::from_fn(|k| {
            let bound = obs.bounds_1sigma_deg_per_frame[k];
            pairs[k].1 == e || bound.is_nan() || bound > threshold
        });
        analysis.covariance = inverse_from_eigen(&obs.information_eigenvalues, &obs.eigenvectors);
        if analysis.unobservable.is_none() && obs.unobservable.iter().all(|&u| u) {
            analysis.unobservable = Some(UnobservableReason::AllDirectionsAboveThreshold);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::observability::{CovarianceSource, Observability};

    #[test]
    fn restated_covariance_is_conditional_on_the_held_axis() {
        // Information coupling X to Y and Z; X held.
        let info = [
            [400.0, 100.0, 50.0],
            [100.0, 900.0, 200.0],
            [50.0, 200.0, 1600.0],
        ];
        let (vals, vecs) = symmetric_eigen(&info).unwrap();
        let mut analysis = Analysis {
            covariance: inverse_from_eigen(&vals, &vecs),
            source: CovarianceSource::GivenSigma,
            observability: Observability {
                information_eigenvalues: vals,
                eigenvectors: vecs,
                bounds_1sigma_deg_per_frame: vals.map(|v| v.sqrt().recip()),
                unobservable: [false; 3],
                threshold_deg_per_frame: 0.25,
                condition_number: vals[2] / vals[0],
                rms_sensitivity_per_deg_per_frame: 1.0,
            },
            unobservable: None,
        };
        let hold = BisectorHold {
            weak: [0.9, 0.0, 0.436],
            prior: Prior {
                directions: vec![[1.0, 0.0, 0.0]],
                weight: 1.0,
            },
        };
        let config = Stage3Config::default();
        hold.restate(&mut analysis, &config).unwrap();
        // Y–Z: the inverse of the Y–Z block of the information (X fixed, not marginalised).
        let det = 900.0 * 1600.0 - 200.0 * 200.0;
        let expected = [[1600.0 / det, -200.0 / det], [-200.0 / det, 900.0 / det]];
        let c = analysis.covariance;
        for (i, row) in expected.iter().enumerate() {
            for (j, v) in row.iter().enumerate() {
                assert!((c[i + 1][j + 1] - v).abs() < 1e-12, "{c:?}");
            }
        }
        // X: reported unobservable at the start box's half-width, uncorrelated with the rest.
        let h = config.start.half_width_deg_per_frame;
        assert!((c[0][0] - h * h).abs() < 1e-12, "{c:?}");
        assert!(c[0][1].abs() < 1e-12 && c[0][2].abs() < 1e-12, "{c:?}");
        let obs = &analysis.observability;
        assert_eq!(obs.eigenvectors[0], [1.0, 0.0, 0.0]);
        assert_eq!(obs.unobservable, [true, false, false]);
        assert!(analysis.unobservable.is_none());
    }

    #[test]
    fn plane_starts_step_along_the_rate_and_across_it_within_the_plane() {
        let hold = BisectorHold {
            weak: [0.9, 0.0, 0.436],
            prior: Prior {
                directions: vec![[1.0, 0.0, 0.0]],
                weight: 1.0,
            },
        };
        let dot = |a: [f64; 3], b: [f64; 3]| (0..3).map(|i| a[i] * b[i]).sum::<f64>();
        // The start is moved onto the plane w_x = 0 along u first: [0, 0.03, 0.25 − 0.436/0.9·0.1].
        let p = [0.1, 0.03, 0.2];
        let starts = hold.plane_starts(p, 0.002, 2);
        assert_eq!(starts.len(), 9);
        let centre = starts[0];
        assert!(centre[0].abs() < 1e-15, "{centre:?}");
        assert!(
            (centre[2] - (0.2 - 0.436 / 0.9 * 0.1)).abs() < 1e-12,
            "{centre:?}"
        );
        let rate_dir = {
            let n = dot(centre, centre).sqrt();
            centre.map(|v| v / n)
        };
        for (i, s) in starts[1..].iter().enumerate() {
            let d: [f64; 3] = std::array::from_fn(|k| s[k] - centre[k]);
            let k = (i / 4 + 1) as f64;
            assert!(s[0].abs() < 1e-15, "every start on the plane: {s:?}");
            assert!((dot(d, d).sqrt() - 0.002 * k).abs() < 1e-12, "{i}: {d:?}");
            // First along the rate (±), then across it (±).
            let along = dot(d, rate_dir).abs() / (0.002 * k);
            let expected = if i % 4 < 2 { 1.0 } else { 0.0 };
            assert!((along - expected).abs() < 1e-12, "{i}: {along}");
        }
        // A rate along the held direction has no direction of its own: still four directions
        // across it, on the plane.
        let starts = hold.plane_starts([0.0; 3], 0.001, 1);
        assert_eq!(starts.len(), 5);
        for s in &starts[1..] {
            assert!(s[0].abs() < 1e-15 && (dot(*s, *s).sqrt() - 0.001).abs() < 1e-12);
        }
    }
}
