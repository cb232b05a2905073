//! The inversion's node loop: it keeps the spectra of both windows as they arrive and answers
//! solve calls (request/response with event wake-ups) stage by stage, as the orchestrator
//! sequences them. A stage whose window is incomplete answers `NotReady`, never a guess.

use std::time::Duration;

use anyhow::{Context, Result};
use glint_runtime::ports::Inbox;
use glint_runtime::rpc::{RpcServer, Solve};
use glint_runtime::{open_node, run_loop, Exit, Housekeeping, Step, Wake};
use nalgebra::Vector3;
use shared_types::scenario::{AttitudeConvention, HeldCoefficientsName, SpectraScenario};
use shared_types::topics::spectrum_service;
use shared_types::{
    Heartbeat, Scenario, ServiceId, SolveRequest, SolveResponse, SolveStatus, Spectrum, TopicId,
    Window,
};

use crate::model::MotionModelConfig;
use crate::observability::CovarianceSource;
use crate::rotation::AttitudeModel;
use crate::session::{Session, StageOutcome};
use crate::stage3::{HeldCoefficients, RateSolution, Stage3Config};
use crate::Observation;

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

/// The stage-3 settings the scenario chooses (defaults but for `spectra.held_coefficients`).
pub fn stage3_config(sp: &SpectraScenario) -> Stage3Config {
    Stage3Config {
        held_coefficients: match sp.held_coefficients {
            HeldCoefficientsName::None => HeldCoefficients::None,
            HeldCoefficientsName::SingleBand => HeldCoefficients::SingleBand,
            HeldCoefficientsName::All => HeldCoefficients::All,
        },
        ..Default::default()
    }
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

/// `SolveResponse::stage3_held_axes` of the directions a prior held.
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

fn fill_rate(out: &mut SolveResponse, rate: &RateSolution, joint: Option<&RateSolution>) {
    let obs = match rate {
        RateSolution::Determined(fit) => {
            out.status = SolveStatus::Ok as u32;
            out.p_deg_per_frame = fit.rate_deg_per_frame;
            for r in 0..3 {
                for c in 0..3 {
                    out.p_covariance[3 * r + c] = fit.covariance_deg2_per_frame2[r][c];
                }
            }
            out.cost = fit.cost;
            if fit.refit.is_some_and(|r| r.held_coefficients) {
                out.stage3_flags |= SolveResponse::HELD_COEFFICIENTS;
            }
            if let Some(m) = fit.mirror_deg_per_frame {
                out.p_mirror_deg_per_frame = m;
            }
            if let Some(n) = fit.neighbours.first() {
                out.p_neighbour_deg_per_frame = n.rate_deg_per_frame;
                out.stage3_neighbour_delta_chi2 = n.delta_chi2;
            }
            out.iterations = fit.total_iterations as u32;
            out.starts = fit.starts_polished as u32;
            out.stage3_held_axes = held_axes(&fit.held_directions);
            out.stage3_covariance_source = match fit.covariance_source {
                CovarianceSource::GivenSigma => 1,
                CovarianceSource::GivenSigmaScaled { .. } => 2,
                CovarianceSource::ResidualVariance { .. } => 3,
            };
            &fit.observability
        }
        RateSolution::Unobservable {
            observability,
            reason,
            ..
        } => {
            out.status = SolveStatus::Unobservable as u32;
            out.unobservable_reason = reason.code();
            observability
        }
    };
    out.fisher_eigenvalues = obs.information_eigenvalues;
    for (i, v) in obs.eigenvectors.iter().enumerate() {
        for (r, component) in v.iter().enumerate() {
            out.fisher_eigenvectors[3 * r + i] = *component;
        }
    }
    out.bound_1sigma_deg_per_frame = obs.bounds_1sigma_deg_per_frame;
    out.observable_mask = obs
        .unobservable
        .iter()
        .enumerate()
        .filter(|(_, u)| !**u)
        .map(|(i, _)| 1u32 << i)
        .sum();
    if let Some(RateSolution::Unobservable { reason, .. }) = joint {
        out.joint_unobservable_reason = reason.code();
    }
    if let Some(RateSolution::Determined(fit)) = joint {
        if let Some(refit) = fit.refit {
            if refit.widest_lobe {
                out.stage3_flags |= SolveResponse::JOINT_LOBE_REFIT;
            }
            if refit.glint_lobes_only {
                out.stage3_flags |= SolveResponse::JOINT_GLINT_LOBES_ONLY;
            }
            if refit.held_coefficients {
                out.stage3_flags |= SolveResponse::JOINT_HELD_COEFFICIENTS;
            }
            if let Some(test) = refit.lobe_test {
                out.stage3_joint_lobe_test_chi2 = test.chi2;
                if let Some(other) = test.other_rate_deg_per_frame {
                    out.p_joint_lobe_other_deg_per_frame = other;
                    out.stage3_joint_lobe_other_weight = test.other_weight;
                }
                if test.rate_traded {
                    out.stage3_flags |= SolveResponse::JOINT_LOBE_RATE_TRADED;
                }
                if test.kept_off_minimum {
                    out.stage3_flags |= SolveResponse::JOINT_LOBE_KEPT_OFF_MINIMUM;
                }
            }
        }
        out.p_joint_deg_per_frame = fit.rate_deg_per_frame;
        if let Some(m) = fit.mirror_deg_per_frame {
            out.p_joint_mirror_deg_per_frame = m;
        }
        if let Some(n) = fit.neighbours.first() {
            out.p_joint_neighbour_deg_per_frame = n.rate_deg_per_frame;
            out.stage3_joint_neighbour_delta_chi2 = n.delta_chi2;
        }
        for r in 0..3 {
            for c in 0..3 {
                out.p_joint_covariance[3 * r + c] = fit.covariance_deg2_per_frame2[r][c];
            }
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
        motion_samples: session.set.motion.len() as u32,
        ..Default::default()
    };
    for (slot, w) in out
        .wavelength_nm
        .iter_mut()
        .zip(&session.set.wavelengths_nm)
    {
        *slot = *w;
    }
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
            *slot = b.recon_err;
        }
        let pooling = &s1.pooling;
        out.stage1_spectral_window_nm = if pooling.applied {
            pooling.window_nm
        } else {
            0.0
        };
        out.stage1_spectral_bias_to_noise = pooling.bias_to_noise.unwrap_or(f64::NAN);
        let basis = &s1.basis;
        out.stage1_widest_lobe_mu = basis.widest_lobe_mu;
        out.stage1_basis_delta_chi2 = basis.delta_chi2;
        out.stage1_basis_dof = basis.dof as u32;
        out.stage1_lobes_kept = basis.lobes_kept as u32;
    }
    if let Some(s2) = &session.stage2 {
        for (i, b) in s2.bands.iter().enumerate().take(out.separation.len()) {
            out.separation[i] = b.sigma;
            out.specular_share[i] = b.specular_share;
        }
        out.chosen_band = s2.chosen_index as u32;
        out.separation_band = s2.separation_index as u32;
    }
    if req.stage == 3 {
        if let Some(rate) = &session.rate {
            fill_rate(&mut out, rate, session.joint_rate.as_ref());
            out.fitted_frames = session.fitted_frames as u32;
            if session.sense_from_joint {
                out.stage3_flags |= SolveResponse::SENSE_FROM_JOINT;
            }
            out.stage3_band = session.rate_band as u32;
            out.stage3_set_aside = session.set_aside.len() as u32;
            out.stage3_joint_disagreement_sigma =
                session.joint_disagreement_sigma.unwrap_or(f64::NAN);
            out.stage3_covariance_scale = session.covariance_scale.unwrap_or(f64::NAN);
            if !session.set_aside.is_empty() {
                out.stage3_flags |= SolveResponse::LAMBDA_REJECTED;
            }
        }
    }
    out
}

pub fn run(prefix: &str, scenario: &Scenario) -> Result<()> {
    let sp = scenario
        .spectra
        .as_ref()
        .context("the inversion needs a [spectra] section")?;
    let node = open_node(prefix, "inversion")?;
    let (mut hk, control_l) = Housekeeping::open(&node, ServiceId::Inversion)?;
    let (mut spectra, spectra_l) =
        Inbox::<Spectrum>::open(&node, TopicId::Spectrum, &spectrum_service(&node)?)?;
    let (mut server, solve_l) = RpcServer::<Solve>::open(&node, ServiceId::Inversion)?;
    let mut session = Session::new(
        sp.wavelengths_nm(),
        sp.stable_samples as usize,
        sp.motion_frames as usize,
        model_config(sp),
        stage3_config(sp),
    );
    hk.state = Heartbeat::READY;

    let inputs = [(&control_l, None), (&spectra_l, None), (&solve_l, None)];
    let hb = Duration::from_millis(scenario.run.heartbeat_period_ms);
    let exit = run_loop(&inputs, hb, |wakes| {
        if hk.obey(&[&spectra.stats, &server.stats])? {
            return Ok(Step::Stop);
        }
        let mut last_t_ns = 0;
        spectra.drain(|r| {
            hk.last_latency_ns = r.latency_ns;
            last_t_ns = r.msg.meta.t_ns;
            session.push(r.msg.window == Window::Motion as u32, observation(r.msg));
            Ok(())
        })?;
        hk.ack(TopicId::Spectrum, spectra.stats.next_seq, last_t_ns)?;
        server.serve(|req| (answer(&mut session, req), req.meta.t_ns))?;
        if wakes.contains(&Wake::Tick) {
            hk.beat(last_t_ns, &[&spectra.stats, &server.stats])?;
        }
        Ok(Step::Wait)
    })?;
    if exit == Exit::Terminated {
        tracing::info!("inversion terminated by signal");
    }
    Ok(())
}
