//! The inversion's node loop: it keeps the spectra of both windows as they arrive and answers
//! solve calls (request/response with event wake-ups) stage by stage, as the orchestrator
//! sequences them. A stage whose window is incomplete answers `NotReady`, never a guess.

use std::time::Duration;

use anyhow::{Context, Result};
use glint_runtime::ports::Inbox;
use glint_runtime::rpc::{Request, RpcServer, Solve};
use glint_runtime::{open_node, run_loop, Exit, Housekeeping, Step, Wake};
use nalgebra::Vector3;
use shared_types::scenario::{AttitudeConvention, SpectraScenario};
use shared_types::topics::spectrum_service;
use shared_types::{
    Heartbeat, Scenario, ServiceId, SolveRequest, SolveResponse, SolveStatus, Spectrum, TopicId,
    Window,
};
use std::thread::JoinHandle;

use crate::model::MotionModelConfig;
use crate::rotation::AttitudeModel;
use crate::session::{Session, StageOutcome};
use crate::stage3::{RateSolution, Stage3Config};
use crate::{Answer, AnswerFit, Observation};

/// A stage being solved: its request, and the thread that gives the session back with the
/// answer.
type Solving = (Request<Solve>, JoinHandle<(Session, SolveResponse)>);

/// Stack of the solve thread (the main thread's size: the solves were written for it).
const SOLVE_STACK_BYTES: usize = 8 << 20;
/// How often the loop looks for the end of a solve.
const SOLVE_POLL: Duration = Duration::from_millis(2);

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
                if fit.refit.is_some_and(|r| r.widest_lobe) {
                    out.flags |= SolveResponse::LOBE_REFIT;
                }
            }
        }
    }
    out
}

pub fn run(prefix: &str, scenario: &Scenario, restarted: bool) -> Result<()> {
    let sp = scenario
        .spectra
        .as_ref()
        .context("the inversion needs a [spectra] section")?;
    let node = open_node(prefix, "inversion")?;
    let (mut hk, control_l) = Housekeeping::open(&node, ServiceId::Inversion)?;
    hk.faults_enabled = scenario.faults.enabled;
    hk.heartbeat_period = Duration::from_millis(scenario.run.heartbeat_period_ms);
    let (mut spectra, spectra_l) =
        Inbox::<Spectrum>::open(&node, TopicId::Spectrum, &spectrum_service(&node)?)?;
    if restarted && scenario.clock == shared_types::scenario::Clock::Sim {
        spectra.stats.await_replay();
    }
    let (mut server, solve_l) = RpcServer::<Solve>::open(&node, ServiceId::Inversion)?;
    // The session, or the thread holding it while a stage solves: the loop goes on beating,
    // obeying control and taking spectra (held until the session is back) meanwhile, so a long
    // solve never looks like a hang.
    let mut idle = Some(Session::new(
        sp.wavelengths_nm(),
        sp.stable_samples as usize,
        sp.motion_frames as usize,
        model_config(sp),
        stage3_config(sp),
    ));
    let mut solving: Option<Solving> = None;
    let mut held: Vec<(bool, Observation)> = vec![];
    hk.state = Heartbeat::READY;

    let inputs = [(&control_l, None), (&spectra_l, None), (&solve_l, None)];
    let hb = Duration::from_millis(scenario.run.heartbeat_period_ms);
    let exit = run_loop(&inputs, hb, |wakes| {
        if hk.obey(&[&spectra.stats, &server.stats])? {
            return Ok(Step::Stop);
        }
        let mut last_t_ns = 0;
        for f in hk.take_output_faults() {
            server.tamper.arm(&f);
        }
        let mut pace_error = None;
        spectra.drain(|r| {
            if let Err(e) = hk.pace() {
                pace_error.get_or_insert(e);
            }
            hk.last_latency_ns = r.latency_ns;
            last_t_ns = r.msg.meta.t_ns;
            let (motion, o) = (r.msg.window == Window::Motion as u32, observation(r.msg));
            match idle.as_mut() {
                Some(session) => session.push(motion, o),
                None => held.push((motion, o)),
            }
            Ok(())
        })?;
        if let Some(e) = pace_error {
            return Err(e);
        }
        hk.ack(TopicId::Spectrum, spectra.stats.next_seq, last_t_ns)?;
        if solving.as_ref().is_some_and(|(_, h)| h.is_finished()) {
            if let Some((req, h)) = solving.take() {
                let (mut session, resp) = h
                    .join()
                    .map_err(|_| anyhow::anyhow!("solve stage {} panicked", req.payload.stage))?;
                for (motion, o) in held.drain(..) {
                    session.push(motion, o);
                }
                idle = Some(session);
                let t_ns = req.payload.meta.t_ns;
                server.respond(req, resp, t_ns)?;
            }
        }
        if solving.is_none() {
            if let Some(req) = server.take_request()? {
                let mut session = idle.take().context("the session is away")?;
                let payload = req.payload;
                let worker = std::thread::Builder::new()
                    .name("solve".into())
                    .stack_size(SOLVE_STACK_BYTES)
                    .spawn(move || {
                        let resp = answer(&mut session, &payload);
                        (session, resp)
                    })
                    .context("starting the solve thread")?;
                solving = Some((req, worker));
            }
        }
        if wakes.contains(&Wake::Tick) {
            hk.beat(last_t_ns, &[&spectra.stats, &server.stats])?;
        }
        // While a stage solves, look for its end often (the worker does not wake the loop).
        Ok(match solving {
            Some(_) => Step::WaitAtMost(SOLVE_POLL),
            None => Step::Wait,
        })
    })?;
    if exit == Exit::Terminated {
        tracing::info!("inversion terminated by signal");
    }
    Ok(())
}
