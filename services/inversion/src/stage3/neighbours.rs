//! The minima a frame's shift from a fit: found by LM from the fit's neighbours. The joint
//! fit's lobe test reads them: a fit keeping stage 1's lobes with a clearly better minimum
//! beside it is not its own model's best fit, and its region is no reference for the test.

use super::bisector::BisectorHold;
use super::weak::{distance, noise_variance, MIRROR_MAX_DELTA_CHI2};
use super::{RateFit, Stage3Config, SAME_SOLUTION_DEG_PER_FRAME};
use crate::error::InversionError;
use crate::model::RateProblem;
use serde::{Deserialize, Serialize};

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

/// The distinct minima LM reaches from `fit`'s neighbours one and two frames' shift away
/// (`p` ± k |p|/T in the held plane, [`BisectorHold::plane_starts`]), lowest first. Only for a
/// problem that re-fits the diffuse terms (the polish's; none otherwise).
pub fn neighbouring_minima(
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

/// Whether `fit` has a minimum a frame's shift away (not its mirror) that fits better by more
/// than Δχ² = 4.
pub(crate) fn off_own_minimum(
    problem: &RateProblem,
    fit: &RateFit,
    config: &Stage3Config,
) -> Result<bool, InversionError> {
    let mirror = fit.mirror_deg_per_frame;
    Ok(neighbouring_minima(problem, fit, config)?.iter().any(|n| {
        n.delta_chi2 < -MIRROR_MAX_DELTA_CHI2
            && mirror
                .is_none_or(|m| distance(n.rate_deg_per_frame, m) >= SAME_SOLUTION_DEG_PER_FRAME)
    }))
}
