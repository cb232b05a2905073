//! The minima a frame's shift from an answer (docs/adr/0019): found by LM from the answer's
//! neighbours, and carried in its covariance in proportion to how well they fit.

use super::bisector::BisectorHold;
use super::weak::{distance, noise_variance, MIRROR_MAX_DELTA_CHI2};
use super::{
    fit_from_starts, polish, RateFit, RateSolution, Stage3Config, SAME_SOLUTION_DEG_PER_FRAME,
};
use crate::error::InversionError;
use crate::model::RateProblem;
use crate::observability::symmetric_eigen;
use serde::{Deserialize, Serialize};
use std::cmp::Ordering;

/// Shifts of one and two frames each way, along the rate and across it.
const NEIGHBOUR_REACH_FRAMES: usize = 2;

/// A minimum of the answer's cost apart from the answer.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Neighbour {
    /// Where it is \[deg/frame\].
    pub rate_deg_per_frame: [f64; 3],
    /// Its cost minus the answer's, in noise variances (negative: it fits better).
    pub delta_chi2: f64,
}

/// One frame's shift of `p` on `problem`: the rate change δ = |p|/T that moves the last of its T
/// frames by one sample, where a narrow glint falls on the next one \[deg/frame\].
fn frame_shift(problem: &RateProblem, p: [f64; 3]) -> f64 {
    distance(p, [0.0; 3]) / problem.frame_count().max(1) as f64
}

/// LM from `p` and from its neighbours one and two frames' shift away (`p` ± k |p|/T along the
/// two directions of the fitted plane, T the frames fitted): the polish of a model that re-fits
/// the diffuse terms ([`RateProblem::refits_diffuse`]). Its cost has minima about one frame's
/// shift apart, where a narrow glint moves from one sample to the next, and the search's rate
/// (on stage 1's coefficients) need not lie in the lowest one's basin. A neighbouring minimum
/// is taken only when it fits clearly better, by more than Δχ² = 4 in units of the noise
/// variance: two minima within that are the mirror pair the fit reports as such
/// (`mirror_deg_per_frame`), and the search's sense decides between them. A problem that
/// re-fits nothing is polished from `p` alone.
pub fn fit_from_neighbourhood(
    problem: &RateProblem,
    p: [f64; 3],
    config: &Stage3Config,
) -> Result<RateSolution, InversionError> {
    if !problem.refits_diffuse() || config.polish_reach_frames == 0 {
        return fit_from_starts(problem, &[p], config);
    }
    let hold = BisectorHold::new(problem, p, config);
    let starts = hold.plane_starts(p, frame_shift(problem, p), config.polish_reach_frames);
    let best = polish(problem, &starts, (0, 0), config)?;
    let Some(found) = best.fit().filter(|f| f.start_deg_per_frame != starts[0]) else {
        return Ok(best);
    };
    // A neighbour's minimum won: it stands if it fits clearly better than p's own.
    let own = fit_from_starts(problem, &[p], config)?;
    let Some(own_fit) = own.fit() else {
        return Ok(best);
    };
    let variance = noise_variance(problem, own_fit.rate_deg_per_frame, config);
    let gain = (own_fit.cost - found.cost) / variance;
    Ok(if gain > MIRROR_MAX_DELTA_CHI2 {
        best
    } else {
        own
    })
}

/// The distinct minima LM reaches from `fit`'s neighbours one and two frames' shift away
/// (`p` ± k |p|/T in the held plane, [`BisectorHold::plane_starts`]), lowest first. Only for a
/// problem that re-fits the diffuse terms (the polish's; none otherwise).
pub(super) fn neighbouring_minima(
    problem: &RateProblem,
    fit: &RateFit,
    config: &Stage3Config,
) -> Result<Vec<Neighbour>, InversionError> {
    if !problem.refits_diffuse() {
        return Ok(vec![]);
    }
    let p = fit.rate_deg_per_frame;
    let hold = BisectorHold::new(problem, p, config);
    let step = frame_shift(problem, p);
    let variance = noise_variance(problem, p, config);
    let mut found: Vec<Neighbour> = Vec::new();
    for start in hold
        .plane_starts(p, step, NEIGHBOUR_REACH_FRAMES)
        .into_iter()
        .skip(1)
    {
        // A start that rejoins the answer or a minimum already found is dropped there.
        let known: Vec<[f64; 3]> = std::iter::once(p)
            .chain(found.iter().map(|n| n.rate_deg_per_frame))
            .collect();
        let rejoined = |q: &[f64; 3], _cost: f64, _k: usize| {
            known
                .iter()
                .any(|&k| distance(*q, k) < SAME_SOLUTION_DEG_PER_FRAME)
        };
        let out = hold.fit(problem, start, config, rejoined)?;
        let q = out.p_deg_per_frame;
        if !out.cost.is_finite()
            || known
                .iter()
                .any(|&k| distance(q, k) < SAME_SOLUTION_DEG_PER_FRAME)
        {
            continue;
        }
        found.push(Neighbour {
            rate_deg_per_frame: q,
            delta_chi2: (out.cost - fit.cost) / variance,
        });
    }
    found.sort_by(|a, b| a.delta_chi2.total_cmp(&b.delta_chi2));
    Ok(found)
}

/// The covariance of `fit` about its rate when the data's likelihood is shared with
/// `neighbours`: each minimum i, at offset d_i and Δχ²_i from the answer, weighs
/// w_i ∝ exp(−Δχ²_i / 2) (the answer w_0 ∝ 1), and C' = C + Σ_i w_i d_i d_iᵀ, the mean
/// squared error of reporting p̂ under that mixture (each mode with the answer's C). A
/// neighbour that fits clearly worse adds nothing; one that fits clearly better adds its whole
/// offset. Returns the weight the neighbours carry together.
fn cover_neighbours(fit: &mut RateFit, neighbours: &[Neighbour]) -> f64 {
    let weights: Vec<f64> = neighbours
        .iter()
        .map(|n| (-0.5 * n.delta_chi2).exp())
        .collect();
    let total = 1.0 + weights.iter().sum::<f64>();
    if !total.is_finite() {
        return 0.0;
    }
    let p = fit.rate_deg_per_frame;
    for (n, w) in neighbours.iter().zip(&weights) {
        let d: [f64; 3] = std::array::from_fn(|i| n.rate_deg_per_frame[i] - p[i]);
        for (row, di) in fit.covariance_deg2_per_frame2.iter_mut().zip(d) {
            for (c, dj) in row.iter_mut().zip(d) {
                *c += w / total * di * dj;
            }
        }
    }
    (total - 1.0) / total
}

/// `fit`'s observability restated from its covariance: the eigen-pairs of C, each direction's
/// 1σ the square root of its variance, not determined beyond the threshold; ordered as the
/// analysis orders them (least information first).
fn restate_from_covariance(fit: &mut RateFit) {
    let Ok((variances, vectors)) = symmetric_eigen(&fit.covariance_deg2_per_frame2) else {
        return;
    };
    let mut pairs: Vec<(f64, [f64; 3])> = (0..3).map(|k| (variances[k], vectors[k])).collect();
    pairs.sort_by(|a, b| b.0.total_cmp(&a.0));
    let obs = &mut fit.observability;
    obs.bounds_1sigma_deg_per_frame = std::array::from_fn(|k| pairs[k].0.max(0.0).sqrt());
    obs.information_eigenvalues = std::array::from_fn(|k| pairs[k].0.recip());
    obs.eigenvectors = std::array::from_fn(|k| pairs[k].1);
    let threshold = obs.threshold_deg_per_frame;
    // A NaN bound determines nothing.
    obs.unobservable = obs.bounds_1sigma_deg_per_frame.map(|b| {
        !matches!(
            b.partial_cmp(&threshold),
            Some(Ordering::Less | Ordering::Equal)
        )
    });
}

impl RateFit {
    /// Looks for the minima a frame's shift from this fit on `problem`, the one it was made on
    /// (LM from p̂ ± δ and ± 2δ, δ = |p̂|/T, along the rate and across it in the held plane),
    /// and holds them for [`RateFit::report_neighbours`].
    ///
    /// The fit's mirror, when it is one of them, is left out: the answer names it apart
    /// (`mirror_deg_per_frame`) as the sense of rotation the data cannot tell, and the
    /// covariance describes the scatter about the sense reported.
    pub fn attach_neighbours(
        &mut self,
        problem: &RateProblem,
        config: &Stage3Config,
    ) -> Result<(), InversionError> {
        let mirror = self.mirror_deg_per_frame;
        self.neighbours = neighbouring_minima(problem, self, config)?
            .into_iter()
            .filter(|n| {
                mirror.is_none_or(|m| {
                    distance(n.rate_deg_per_frame, m) >= SAME_SOLUTION_DEG_PER_FRAME
                })
            })
            .collect();
        Ok(())
    }

    /// Reports the neighbours in the covariance, C' = C + Σ_i w_i d_i d_iᵀ with
    /// w_i ∝ exp(−Δχ²_i / 2) against 1 for the fit (the mean squared error of reporting p̂ when
    /// the likelihood is shared), and restates the observability from it. The decisions read the local covariance, so the solve calls this
    /// once they are all taken. Returns the weight the neighbours carry.
    pub fn report_neighbours(&mut self) -> f64 {
        if self.neighbours.is_empty() {
            return 0.0;
        }
        let neighbours = self.neighbours.clone();
        let weight = cover_neighbours(self, &neighbours);
        restate_from_covariance(self);
        weight
    }
}

impl RateFit {
    /// Has the covariance carry the lobe model the joint fit did not report
    /// ([`other_rate_deg_per_frame`](super::LobeTest::other_rate_deg_per_frame)) as one more minimum, at the pseudo-Δχ² of
    /// [`alternative_excess`](super::LobeTest::alternative_excess): w = 1 / (1 + exp(excess / 2)), half its offset at the
    /// test's threshold, 12 % four below it (docs/adr/0023). Records the weight on the test,
    /// restates the observability, and returns the weight.
    pub fn report_lobe_alternative(&mut self) -> f64 {
        let Some(refit) = self.refit else {
            return 0.0;
        };
        let Some(test) = refit.lobe_test else {
            return 0.0;
        };
        let (Some(other), Some(excess)) = (
            test.other_rate_deg_per_frame,
            test.alternative_excess(refit.widest_lobe),
        ) else {
            return 0.0;
        };
        let alternative = Neighbour {
            rate_deg_per_frame: other,
            delta_chi2: excess,
        };
        let weight = cover_neighbours(self, &[alternative]);
        restate_from_covariance(self);
        if let Some(t) = self.refit.as_mut().and_then(|r| r.lobe_test.as_mut()) {
            t.other_weight = weight;
        }
        weight
    }
}

impl RateSolution {
    /// [`RateFit::attach_neighbours`] on a determined answer when `config.cover_neighbours`
    /// asks for it.
    pub(crate) fn attach_neighbours_if_asked(
        &mut self,
        problem: &RateProblem,
        config: &Stage3Config,
    ) -> Result<(), InversionError> {
        match self {
            RateSolution::Determined(fit) if config.cover_neighbours => {
                fit.attach_neighbours(problem, config)
            }
            _ => Ok(()),
        }
    }

    /// [`RateFit::report_neighbours`] on a determined answer.
    pub(crate) fn report_neighbours(&mut self) {
        if let RateSolution::Determined(fit) = self {
            fit.report_neighbours();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stage3::fixtures::with_covariance;

    fn neighbour(q: [f64; 3], delta_chi2: f64) -> Neighbour {
        Neighbour {
            rate_deg_per_frame: q,
            delta_chi2,
        }
    }

    #[test]
    fn each_neighbour_adds_its_offset_weighted_by_its_likelihood() {
        let c = [[0.25, 0.0, 0.0], [0.0, 4e-8, 0.0], [0.0, 0.0, 1e-6]];
        let p = [0.0, -0.0006, 0.2528];
        let d = [0.0, -0.0028, -0.0026];
        let q = [p[0] + d[0], p[1] + d[1], p[2] + d[2]];
        // Δχ² = 0: the two fit alike, w = ½. Far better: all of it. Far worse: nothing.
        for (delta, w) in [(0.0, 0.5), (-60.0, 1.0), (60.0, 0.0)] {
            let mut fit = with_covariance(p, c);
            fit.neighbours = vec![neighbour(q, delta)];
            let weight = fit.report_neighbours();
            assert!((weight - w).abs() < 1e-12, "{delta}: {weight}");
            let got = fit.covariance_deg2_per_frame2;
            for i in 0..3 {
                for j in 0..3 {
                    let expected = c[i][j] + w * d[i] * d[j];
                    assert!((got[i][j] - expected).abs() < 1e-15, "{delta}: {got:?}");
                }
            }
        }
        // Two neighbours at Δχ² = 0 each: a third each.
        let mut fit = with_covariance(p, c);
        let other = [p[0], p[1] - d[1], p[2] - d[2]];
        fit.neighbours = vec![neighbour(q, 0.0), neighbour(other, 0.0)];
        assert!((fit.report_neighbours() - 2.0 / 3.0).abs() < 1e-12);
        let expected_yy = c[1][1] + 2.0 / 3.0 * d[1] * d[1];
        assert!((fit.covariance_deg2_per_frame2[1][1] - expected_yy).abs() < 1e-15);
        // Opposite offsets do not cancel: about p̂ each adds its own d dᵀ.
        assert!(fit.covariance_deg2_per_frame2[1][2] > 0.0);
    }

    #[test]
    fn the_observability_is_restated_from_the_covered_covariance() {
        let c = [[0.25, 0.0, 0.0], [0.0, 4e-8, 0.0], [0.0, 0.0, 1e-6]];
        let mut fit = with_covariance([0.0, 0.0, 0.25], c);
        fit.neighbours = vec![neighbour([0.0, 0.003, 0.25], -60.0)];
        fit.report_neighbours();
        let obs = &fit.observability;
        // Least information first: X (held, 0.5), Z (1e-3), then Y covered to its offset.
        let expected_y = (4e-8f64 + 9e-6).sqrt();
        assert_eq!(obs.eigenvectors[0].map(f64::abs), [1.0, 0.0, 0.0]);
        assert!((obs.bounds_1sigma_deg_per_frame[0] - 0.5).abs() < 1e-12);
        assert!((obs.bounds_1sigma_deg_per_frame[1] - expected_y).abs() < 1e-12);
        assert!((obs.bounds_1sigma_deg_per_frame[2] - 1e-3).abs() < 1e-12);
        assert_eq!(obs.unobservable, [true, false, false]);
        assert!((obs.information_eigenvalues[1] * expected_y * expected_y - 1.0).abs() < 1e-9);
        // Nothing to report: nothing changes.
        let mut plain = with_covariance([0.0, 0.0, 0.25], c);
        let before = plain.clone();
        assert_eq!(plain.report_neighbours(), 0.0);
        assert_eq!(plain, before);
    }

    #[test]
    fn the_lobe_model_not_reported_is_carried_by_how_near_the_test_came() {
        use crate::stage3::{LobeTest, Refit};
        let c = [[0.25, 0.0, 0.0], [0.0, 4e-8, 0.0], [0.0, 0.0, 1e-6]];
        let p = [0.0, -0.0006, 0.2528];
        let d = [0.0, 0.0014, -0.0021];
        let q = [p[0] + d[0], p[1] + d[1], p[2] + d[2]];
        let threshold = 9.21;
        let fit_with = |widest_lobe: bool, chi2: f64, traded: bool, off: bool| {
            let mut fit = with_covariance(p, c);
            fit.refit = Some(Refit {
                widest_lobe,
                held_direction: [1.0, 0.0, 0.0],
                lobe_test: Some(LobeTest {
                    chi2,
                    threshold,
                    rate_traded: traded,
                    kept_off_minimum: off,
                    other_rate_deg_per_frame: Some(q),
                    other_weight: 0.0,
                }),
                glint_lobes_only: false,
                held_coefficients: false,
            });
            fit
        };
        // w = 1 / (1 + exp(excess / 2)): ½ at the threshold, 1 / (1 + e²) four from it on
        // either side of the decision, nothing far from it.
        let near = 1.0 / (1.0 + 2f64.exp());
        for (refit, chi2, w) in [
            (false, threshold, 0.5),
            (false, threshold - 4.0, near),
            (true, threshold + 4.0, near),
            (false, 0.0, 1.0 / (1.0 + (threshold / 2.0).exp())),
            (true, 400.0, 0.0),
        ] {
            let mut fit = fit_with(refit, chi2, false, false);
            let weight = fit.report_lobe_alternative();
            assert!((weight - w).abs() < 1e-12, "{refit} {chi2}: {weight}");
            let recorded = fit.refit.and_then(|r| r.lobe_test).map(|t| t.other_weight);
            assert_eq!(recorded, Some(weight));
            for i in 0..3 {
                for j in 0..3 {
                    let expected = c[i][j] + w * d[i] * d[j];
                    let got = fit.covariance_deg2_per_frame2[i][j];
                    assert!(
                        (got - expected).abs() < 1e-15,
                        "{chi2}: {got} vs {expected}"
                    );
                }
            }
            // The observability is restated from it: the determined 1σ grow.
            let b = fit.observability.bounds_1sigma_deg_per_frame;
            assert!(w == 0.0 || b[1] > 1e-3, "{b:?}");
        }
        // No alternative: a re-fit that traded the rate, a kept fit off its own minimum, a
        // singular test; or no other rate on record. Nothing changes.
        for (traded, off, chi2) in [
            (true, false, 1.0),
            (false, true, 1.0),
            (false, false, f64::INFINITY),
        ] {
            let mut fit = fit_with(false, chi2, traded, off);
            let before = fit.clone();
            assert_eq!(fit.report_lobe_alternative(), 0.0);
            assert_eq!(fit, before);
        }
        let mut untested = with_covariance(p, c);
        assert_eq!(untested.report_lobe_alternative(), 0.0);
    }
}
