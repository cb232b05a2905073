//! The sensor's node loop: open ports, wait for `Start`, then produce frames, spectra and truth —
//! in sim-clock mode as fast as the consumers' acknowledgements allow (lockstep, nothing
//! dropped), in realtime mode paced by the wall clock — while answering laser-range requests.

use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use glint_runtime::ports::{FrameOutbox, Outbox};
use glint_runtime::rpc::RangeServer;
use glint_runtime::{open_node, run_loop, AckReader, Credit, Exit, Housekeeping, Step};
use shared_types::scenario::Clock;
use shared_types::topics::{
    frame_service, spectrum_service, truth_service, FRAME_BUFFER, SPECTRUM_BUFFER, TRUTH_BUFFER,
};
use shared_types::{
    deployment, Command, Heartbeat, RangeResponse, RangeStatus, Scenario, ServiceId, TopicId,
};

use crate::debris_scene::DebrisScene;
use crate::laser::{respond, LaserConfig, RangeOutcome};
use crate::render::noise::{inverse_normal_cdf, Xoshiro256pp};
use crate::spectra_scene::SpectraScene;

/// Messages produced per wake-up before the loop checks control and acks again.
const BATCH: usize = 8;
const LASER_STREAM: u64 = 1 << 56;

/// `restarted`: a new incarnation after a crash; it produces everything again from the start
/// (rendering is stateless), and its consumers skip what they already have as duplicates.
pub fn run(prefix: &str, scenario: &Scenario, restarted: bool) -> Result<()> {
    if restarted {
        tracing::info!("restarted: producing again from the start");
    }
    let node = open_node(prefix, "sensor")?;
    let (mut hk, control_listener) = Housekeeping::open(&node, ServiceId::Sensor)?;
    hk.faults_enabled = scenario.faults.enabled;
    hk.heartbeat_period = Duration::from_millis(scenario.run.heartbeat_period_ms);
    let (mut acks, ack_listener) = AckReader::open(&node)?;
    let (mut range, range_listener) = RangeServer::open(&node, ServiceId::Sensor)?;
    let mut truth_out = Outbox::open(
        &node,
        TopicId::Truth,
        &truth_service(&node)?,
        ServiceId::Sensor,
    )?;

    let debris = match &scenario.camera {
        Some(cam) => {
            Some(DebrisScene::new(cam, scenario.seed).map_err(|e| anyhow::anyhow!("{e}"))?)
        }
        None => None,
    };
    let mut frames = match &scenario.camera {
        Some(cam) => Some(FrameOutbox::open(
            &node,
            &frame_service(&node)?,
            cam.pixels(),
        )?),
        None => None,
    };
    let spectra = match &scenario.spectra {
        Some(sp) => Some(SpectraScene::new(sp, scenario.seed).context("spectra scene")?),
        None => None,
    };
    let mut spectrum_out = match &scenario.spectra {
        Some(_) => Some(Outbox::open(
            &node,
            TopicId::Spectrum,
            &spectrum_service(&node)?,
            ServiceId::Sensor,
        )?),
        None => None,
    };
    let laser = scenario.camera.as_ref().map(|c| LaserConfig {
        beam_full_width_rad: c.laser.beam_deg.to_radians(),
        range_sigma_m: c.laser.range_sigma_m,
        delay_s: c.laser.delay_s,
    });

    let n_frames = deployment::expected_messages(scenario, TopicId::Frame);
    let n_spectra = deployment::expected_messages(scenario, TopicId::Spectrum);
    let mut frame_credit = Credit::new(
        FRAME_BUFFER,
        deployment::consumers(scenario, TopicId::Frame),
    );
    let mut spectrum_credit = Credit::new(
        SPECTRUM_BUFFER,
        deployment::consumers(scenario, TopicId::Spectrum),
    );
    let mut truth_credit = Credit::new(
        TRUTH_BUFFER,
        deployment::consumers(scenario, TopicId::Truth),
    );
    let realtime = scenario.clock == Clock::Realtime;
    let frame_period = scenario
        .camera
        .as_ref()
        .map(|c| Duration::from_nanos(c.frame_period_ns()))
        .unwrap_or_default();

    let mut started: Option<Instant> = None;
    let mut paused = false;
    let hb_period = Duration::from_millis(scenario.run.heartbeat_period_ms);
    hk.state = Heartbeat::READY;
    tracing::info!(n_frames, n_spectra, ?scenario.clock, "sensor ready");

    let inputs = [
        (&control_listener, None),
        (&ack_listener, None),
        (&range_listener, None),
    ];
    let exit = run_loop(&inputs, hb_period, |wakes| {
        for cmd in hk.poll_control()? {
            match cmd {
                Command::Start if started.is_none() => {
                    started = Some(Instant::now());
                    hk.state = Heartbeat::RUNNING;
                }
                Command::Pause => paused = true,
                Command::Resume => paused = false,
                Command::Replay => {
                    for r in hk.take_replays() {
                        tracing::info!(
                            consumer = r.consumer.name(),
                            topic = r.topic.name(),
                            from = r.from_seq,
                            "replay"
                        );
                        match r.topic {
                            TopicId::Frame => {
                                frame_credit.reset(r.consumer, r.from_seq);
                                if let Some(f) = frames.as_mut() {
                                    f.rewind(r.from_seq);
                                }
                            }
                            TopicId::Spectrum => {
                                spectrum_credit.reset(r.consumer, r.from_seq);
                                if let Some(s) = spectrum_out.as_mut() {
                                    s.rewind(r.from_seq);
                                }
                            }
                            _ => {}
                        }
                    }
                }
                Command::Shutdown => {
                    hk.state = Heartbeat::STOPPING;
                    let f = frames.as_ref().map(|f| &f.stats);
                    let s = spectrum_out.as_ref().map(|s| &s.stats);
                    let stats: Vec<_> = [f, s, Some(&truth_out.stats), Some(&range.stats)]
                        .into_iter()
                        .flatten()
                        .collect();
                    hk.beat(0, &stats)?;
                    return Ok(Step::Stop);
                }
                _ => {}
            }
        }
        // In-band drops and corruptions hit the sensor's main output: frames, or spectra.
        for f in hk.take_output_faults() {
            match (frames.as_mut(), spectrum_out.as_mut()) {
                (Some(out), _) => out.tamper.arm(&f),
                (None, Some(out)) => out.tamper.arm(&f),
                (None, None) => {}
            }
        }
        acks.poll(&mut [
            (TopicId::Frame, &mut frame_credit),
            (TopicId::Spectrum, &mut spectrum_credit),
            (TopicId::Truth, &mut truth_credit),
        ])?;
        range.serve(|req| answer_range(&debris, &laser, scenario.seed, req))?;

        let mut next_wake: Option<Duration> = None;
        let mut produced = 0;
        if let (Some(t0), false) = (started, paused) {
            for _ in 0..BATCH {
                // Next message of each stream, by simulated time. In sim-clock mode the sensor
                // emits strictly in simulated-time order (frames before spectra on a tie), so the
                // interleaving — and with it every sequence number — is deterministic.
                let next_frame = match (frames.as_ref(), debris.as_ref()) {
                    (Some(out), Some(scene)) if out.next_seq() < n_frames => {
                        let k = out.next_seq();
                        Some((k, (scene.exposure_end_s(k) * 1e9).round() as u64))
                    }
                    _ => None,
                };
                let next_spectrum = match (spectrum_out.as_ref(), spectra.as_ref()) {
                    (Some(out), Some(scene)) if out.next_seq() < n_spectra => {
                        let k = out.next_seq();
                        Some((k, scene.t_ns(k)))
                    }
                    _ => None,
                };
                let truth_ok = truth_credit.allows(truth_out.stats.published);
                let frame_first = match (next_frame, next_spectrum) {
                    (Some((_, tf)), Some((_, ts))) => tf <= ts,
                    (Some(_), None) => true,
                    _ => false,
                };
                let mut progressed = false;
                if let (Some((k, t_ns)), Some(out), Some(scene)) =
                    (next_frame, frames.as_mut(), debris.as_ref())
                {
                    let due = if realtime {
                        let at = frame_period * k as u32;
                        let now = t0.elapsed();
                        if now < at {
                            next_wake =
                                Some(next_wake.map_or(at - now, |w: Duration| w.min(at - now)));
                        }
                        now >= at
                    } else {
                        // A replay (a restarted consumer) carries no truth: it was sent once.
                        frame_first && frame_credit.allows(k) && (truth_ok || out.replaying())
                    };
                    if due {
                        hk.pace()?;
                        let replay = out.replaying();
                        out.publish(t_ns, |h, px| {
                            h.frame_index = k;
                            h.exposure_start_ns = (scene.exposure_start_s(k) * 1e9).round() as u64;
                            h.exposure_ns = scene_exposure_ns(scenario).max(1);
                            h.interval_ns = scenario
                                .camera
                                .as_ref()
                                .map_or(0, |c| (c.interval_s * 1e9).round() as u64);
                            h.width_px = scene.camera.width_px;
                            h.height_px = scene.camera.height_px;
                            scene.render(k, px);
                        })?;
                        if !replay {
                            truth_out.send(scene.truth(k), t_ns)?;
                        }
                        progressed = true;
                    }
                }
                if let (Some((k, _)), Some(out), Some(scene)) =
                    (next_spectrum, spectrum_out.as_mut(), spectra.as_ref())
                {
                    let replay = out.replaying();
                    let due = realtime
                        || (!frame_first
                            && spectrum_credit.allows(k)
                            && (replay || truth_credit.allows(truth_out.stats.published)));
                    if due {
                        hk.pace()?;
                        let (sp, truth, t_ns) = scene.sample(k).context("spectrum sample")?;
                        out.send(sp, t_ns)?;
                        if !replay {
                            truth_out.send(truth, t_ns)?;
                        }
                        progressed = true;
                    }
                }
                if !progressed {
                    break;
                }
                produced += 1;
            }
            let frames_done = frames.as_ref().is_none_or(|f| f.next_seq() >= n_frames);
            let spectra_done = spectrum_out
                .as_ref()
                .is_none_or(|s| s.next_seq() >= n_spectra);
            if frames_done && spectra_done && hk.state == Heartbeat::RUNNING {
                hk.state = Heartbeat::FINISHED;
                tracing::info!("sensor finished producing");
            }
        }
        if wakes.contains(&glint_runtime::Wake::Tick) || hk.state == Heartbeat::FINISHED {
            let f = frames.as_ref().map(|f| &f.stats);
            let s = spectrum_out.as_ref().map(|s| &s.stats);
            let stats: Vec<_> = [f, s, Some(&truth_out.stats), Some(&range.stats)]
                .into_iter()
                .flatten()
                .collect();
            let t_ns = 0;
            if wakes.contains(&glint_runtime::Wake::Tick) {
                hk.beat(t_ns, &stats)?;
            }
        }
        // A full batch means there may be more to produce right away; otherwise wait for acks
        // (sim) or the next frame time (realtime), never spin.
        Ok(match next_wake {
            _ if produced == BATCH => Step::WaitAtMost(Duration::ZERO),
            Some(d) if realtime => Step::WaitAtMost(d),
            _ => Step::Wait,
        })
    })?;
    if exit == Exit::Terminated {
        tracing::info!("sensor terminated by signal");
    }
    Ok(())
}

fn scene_exposure_ns(scenario: &Scenario) -> u64 {
    scenario
        .camera
        .as_ref()
        .map_or(0, |c| (c.exposure_s * 1e9).round() as u64)
}

/// The laser: fire at the request's time, echo after the delay, deterministic noise per request.
fn answer_range(
    debris: &Option<DebrisScene>,
    laser: &Option<LaserConfig>,
    seed: u64,
    req: &shared_types::RangeRequest,
) -> (RangeResponse, u64) {
    let mut resp = RangeResponse {
        request_id: req.request_id,
        track_id: req.track_id,
        status: RangeStatus::Miss as u32,
        ..Default::default()
    };
    let (Some(scene), Some(cfg)) = (debris, laser) else {
        return (resp, req.meta.t_ns);
    };
    let t_fire_s = req.meta.t_ns as f64 * 1e-9;
    let echo_ns = req.meta.t_ns + (cfg.delay_s * 1e9).round() as u64;
    let targets = scene.laser_targets(t_fire_s + cfg.delay_s);
    let mut rng = Xoshiro256pp::new(seed, LASER_STREAM + req.request_id);
    let noise = inverse_normal_cdf(rng.next_open01());
    if let RangeOutcome::Hit { range_m, .. } =
        respond(cfg, req.azimuth_rad, req.elevation_rad, &targets, noise)
    {
        resp.status = RangeStatus::Hit as u32;
        resp.range_m = range_m;
    }
    (resp, echo_ns)
}
