//! The inversion service's core: the session of one deployment (the spectra of both windows)
//! and the answer to one solve request, stage by stage, as the wire message. No IPC: the node
//! ([`crate::node`]) calls it on its solve thread, a test calls it directly. A stage whose
//! window is incomplete answers `NotReady`, never a guess.

use nalgebra::Vector3;
use shared_types::scenario::{AttitudeConvention, SpectraScenario};
use shared_types::{SolveRequest, SolveResponse, SolveStatus, Spectrum};

use crate::model::MotionModelConfig;
use crate::rotation::AttitudeModel;
use crate::session::{Session, StageOutcome};
use crate::stage1::{coefficients_to_array, Stage1Band, DESIGN_COLUMNS};
use crate::stage3::{RateSolution, Stage3Config};
use crate::{Answer, AnswerFit, Observation};

const _: () = assert!(DESIGN_COLUMNS == shared_types::TWO_FACET_TERMS);

/// The session of a deployment's spectra scenario.
pub fn session(sp: &SpectraScenario) -> Session {
    Session::new(
        sp.wavelengths_nm(),
        sp.stable_samples as usize,
        sp.motion_frames as usize,
        model_config(sp),
        stage3_config(sp),
    )
}

/// The motion model the scenario's simulator used (attitude convention; n_b = +X; panel (a)).
pub fn model_config(sp: &SpectraScenario) -> MotionModelConfig {
    MotionModelConfig {
        attitude: match sp.attitude_convention {
            AttitudeConvention::Verbatim => AttitudeModel::Verbatim,
            AttitudeConvention::Consistent => AttitudeModel::Consistent,
        },
        ..Default::default()
    }
}

/// The stage-3 settings of a deployment: the defaults.
pub fn stage3_config(_sp: &SpectraScenario) -> Stage3Config {
    Stage3Config::default()
}

/// One received spectrum as an observation of the solve.
pub fn observation(sp: &Spectrum) -> Observation {
    let n = (sp.n_bands as usize).min(sp.flux_w.len());
    let sigma: Vec<f64> = sp.sigma_w[..n].to_vec();
    Observation {
        frame_index: sp.frame_index,
        t_s: sp.meta.t_ns as f64 * 1e-9,
        sun_body: Vector3::from(sp.sun_body),
        observer_body: Vector3::from(sp.observer_body),
        range_m: sp.range_m,
        flux_w: sp.flux_w[..n].to_vec(),
        // Noise-free data carry σ = 0: leave the weighting to the residuals.
        sigma_w: if sigma.iter().all(|s| *s > 0.0) {
            sigma
        } else {
            vec![]
        },
    }
}

/// `SolveResponse::held_axes` of the directions a prior held.
fn held_axes(directions: &[[f64; 3]]) -> u32 {
    directions
        .iter()
        .map(|e| match e {
            [1.0, 0.0, 0.0] => 1,
            [0.0, 1.0, 0.0] => 2,
            [0.0, 0.0, 1.0] => 4,
            _ => SolveResponse::HELD_OTHER,
        })
        .fold(0, |bits, b| bits | b)
}

/// Stage 3 on the wire: glint's answer, and λ*'s fit beside it.
fn fill_answer(out: &mut SolveResponse, answer: &Answer, band: &RateSolution) {
    out.status = match answer.rate_deg_per_frame {
        Some(_) => SolveStatus::Ok,
        None => SolveStatus::Unobservable,
    } as u32;
    if matches!(answer.from, AnswerFit::Joint { .. }) {
        out.flags |= SolveResponse::JOINT;
    }
    if let Some(p) = answer.rate_deg_per_frame {
        out.rate_deg_per_frame = p;
    }
    if let Some(c) = answer.covariance_deg2_per_frame2 {
        out.covariance = std::array::from_fn(|k| c[k / 3][k % 3]);
    }
    if let Some(m) = answer.mirror_deg_per_frame {
        out.mirror_deg_per_frame = m;
        out.flags |= SolveResponse::SENSE_UNDETERMINED;
    }
    out.unobservable_reason = answer.unobservable.map_or(0, |r| r.code());
    out.held_axes = held_axes(&answer.held_axes);
    out.fitted_frames = answer.fitted_frames as u32;
    for (i, d) in answer.directions.iter().enumerate() {
        for (r, component) in d.axis.iter().enumerate() {
            out.fisher_eigenvectors[3 * r + i] = *component;
        }
        out.bound_1sigma_deg_per_frame[i] = d.sigma_deg_per_frame;
        if d.determined {
            out.observable_mask |= 1 << i;
        }
    }
    match band {
        RateSolution::Determined(fit) => {
            out.band_status = SolveStatus::Ok as u32;
            out.band_rate_deg_per_frame = fit.rate_deg_per_frame;
        }
        RateSolution::Unobservable { reason, .. } => {
            out.band_status = SolveStatus::Unobservable as u32;
            out.band_unobservable_reason = reason.code();
        }
    }
}

/// Runs the requested stage on the session and builds the answer.
pub fn answer(session: &mut Session, req: &SolveRequest) -> SolveResponse {
    let mut out = SolveResponse {
        request_id: req.request_id,
        stage: req.stage,
        n_bands: session.set.wavelengths_nm.len() as u32,
        stable_samples: session.set.stable.len() as u32,
        // The window a stage used: stages 1 and 2 the stable one only (how much of the motion
        // window had arrived by then is timing, not a result).
        motion_samples: if req.stage == 3 {
            session.set.motion.len() as u32
        } else {
            0
        },
        ..Default::default()
    };
    let outcome = match req.stage {
        1 => session.stage1(),
        2 => session.stage2(),
        _ => session.stage3(req.flags & SolveRequest::FLAG_JOINT != 0),
    };
    match outcome {
        Ok(StageOutcome::NotReady(why)) => {
            tracing::info!(stage = req.stage, ?why, "solve: not ready");
            out.status = SolveStatus::NotReady as u32;
            return out;
        }
        Err(e) => {
            tracing::warn!(stage = req.stage, error = %e, "solve failed");
            out.status = SolveStatus::Failed as u32;
            return out;
        }
        Ok(StageOutcome::Done) => out.status = SolveStatus::Ok as u32,
    }
    if let Some(s1) = &session.stage1 {
        for (slot, b) in out.recon_err.iter_mut().zip(&s1.bands) {
            *slot = b.recon_err as f32;
        }
    }
    if let Some(s2) = &session.stage2 {
        for (slot, b) in out.separation.iter_mut().zip(&s2.bands) {
            *slot = b.sigma as f32;
        }
        out.chosen_band = s2.chosen_index as u32;
        if let Some(s1) = &session.stage1 {
            let at_chosen = |bands: &[Stage1Band]| {
                bands
                    .get(s2.chosen_index)
                    .map(|b| coefficients_to_array(&b.coeffs))
            };
            if let (Some(recon), Some(rate)) = (at_chosen(&s1.bands), at_chosen(s1.single_band())) {
                out.recon_coefficients = recon;
                out.rate_coefficients = rate;
            }
        }
    }
    if req.stage == 3 {
        if let (Some(answer), Some(fits)) = (&session.answer, &session.fits) {
            fill_answer(&mut out, answer, &fits.rate);
            // The fit the answer is: its iterations, and whether it re-fitted the widest lobe.
            let from = match answer.from {
                AnswerFit::Joint { .. } => fits.joint_rate.as_ref(),
                AnswerFit::Band { .. } => Some(&fits.rate),
            };
            if let Some(fit) = from.and_then(RateSolution::fit) {
                out.iterations = fit.total_iterations as u32;
                if let Some(refit) = fit.refit.filter(|r| r.widest_lobe) {
                    out.flags |= SolveResponse::LOBE_REFIT;
                    out.refit_lobes = refit.lobes.map(|k| k as u32);
                }
            }
        }
    }
    out
}
