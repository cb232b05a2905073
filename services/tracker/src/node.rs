//! The tracker's node loop: detections in, tracks out. Per frame: angle-filter and EKF updates
//! with the angles at the end of the exposure, then for every confirmed track a laser shot with
//! delay-predicted pointing (§3.7) over request/response to the sensor, and the echo's range
//! applied at its own time. A missed or late echo is counted and the filters go on with angles.

use std::time::Duration;

use anyhow::{Context, Result};
use glint_physics::camera::{position_from_angles, PinholeCamera};
use glint_physics::orbit::MU_EARTH_M3_S2;
use glint_runtime::ports::{Inbox, Outbox};
use glint_runtime::rpc::{CallOutcome, RangeClient};
use glint_runtime::{open_node, run_loop, AckReader, Credit, Exit, Housekeeping, Step, Wake};
use shared_types::scenario::{CameraScenario, Clock};
use shared_types::topics::{detections_service, tracks_service, IpcNode, TRACKS_BUFFER};
use shared_types::{
    deployment, Detections, Heartbeat, RangeRequest, RangeResponse, RangeStatus, Scenario,
    ServiceId, TopicId, TrackEstimate, Tracks, MAX_TRACKS,
};

use crate::angle_filter::AngleFilterConfig;
use crate::ekf::CwEkfConfig;
use crate::track::{EkfAngles, TrackManager, TrackManagerConfig, TrackObservation, TrackStatus};

/// Filter settings from the scenario (noise levels in the filters' own units).
pub fn config(cam: &CameraScenario) -> TrackManagerConfig {
    let t = &cam.tracker;
    let ifov_rad = cam.fov_deg.to_radians() / cam.width_px as f64;
    let sigma_rad = t.angle_sigma_px * ifov_rad;
    let a_m = cam.orbit_semi_major_axis_km * 1e3;
    TrackManagerConfig {
        confirm_hits: t.confirm_hits,
        delete_misses: t.delete_misses,
        angle_filter: AngleFilterConfig {
            accel_noise_var_rad2_s4: t.angle_accel_rad_s2.powi(2),
            measurement_sigma_rad: sigma_rad,
            ..Default::default()
        },
        ekf: CwEkfConfig {
            mean_motion_rad_s: (MU_EARTH_M3_S2 / (a_m * a_m * a_m)).sqrt(),
            accel_noise_m_s_3_2: t.ekf_accel_sigma,
            sigma_azimuth_rad: sigma_rad,
            sigma_elevation_rad: sigma_rad,
            sigma_range_m: cam.laser.range_sigma_m.max(1e-6),
        },
    }
}

/// Everything the tracker does with one frame's detections; returns the wire message.
struct FrameWork<'a> {
    tm: &'a mut TrackManager,
    laser: Option<&'a mut RangeClient>,
    node: &'a IpcNode,
    delay_s: f64,
    timeout: Duration,
    camera: PinholeCamera,
    exposure_s: f64,
    /// σ(end point) / σ(centroid) of eq (9).
    end_point_factor: f64,
    /// Sim clock: a shot the laser did not answer (its sensor restarting or stopped) is fired
    /// again with the same request id until answered; simulated time waits for it.
    sim_clock: bool,
    /// Called while a shot is being retried: the service's heartbeat and control; `false`
    /// once `Shutdown` arrived (the shot is given up).
    keepalive: &'a mut dyn FnMut() -> Result<bool>,
}

/// How long a sim-clock shot is retried before the run is given up on (the orchestrator fails
/// the run long before, when the sensor does not come back).
const LASER_RETRY_LIMIT: Duration = Duration::from_secs(600);

impl FrameWork<'_> {
    fn process(&mut self, d: &Detections) -> Result<Tracks> {
        let t_s = d.exposure_end_ns as f64 * 1e-9;
        // From integer nanoseconds, so that it is the same f64 as any other path to that instant.
        let half_ns = (0.5 * self.exposure_s * 1e9).round() as u64;
        let mid_exposure_s = d.exposure_end_ns.saturating_sub(half_ns) as f64 * 1e-9;
        let items = &d.items[..(d.n as usize).min(d.items.len())];
        let observations: Vec<TrackObservation> = items
            .iter()
            .map(|det| TrackObservation {
                track_id: det.track_id as u64,
                t_s,
                azimuth_rad: det.azimuth_rad,
                elevation_rad: det.elevation_rad,
                range_m: None,
                range_t_s: None,
                sigma_rad: (det.sigma_rad > 0.0).then_some(det.sigma_rad),
                ekf_angles: (det.sigma_rad > 0.0).then(|| {
                    let (az, el) = self.camera.angles_from_pixel(det.x_px, det.y_px);
                    EkfAngles {
                        t_s: mid_exposure_s,
                        azimuth_rad: az,
                        elevation_rad: el,
                        sigma_rad: det.sigma_rad / self.end_point_factor,
                    }
                }),
            })
            .collect();
        let outcome = self.tm.process_frame(&observations);
        for f in &outcome.faults {
            tracing::warn!(
                track = f.track_id,
                "{:?} {:?}: {}",
                f.filter,
                f.action,
                f.message
            );
        }
        let mut msg = Tracks {
            frame_index: d.frame_index,
            ..Default::default()
        };
        let ids: Vec<u64> = self.tm.tracks().map(|t| t.track_id).collect();
        for id in ids.into_iter().take(MAX_TRACKS) {
            let observed = items.iter().find(|det| det.track_id as u64 == id);
            let mut est = TrackEstimate {
                track_id: id.min(u32::MAX as u64) as u32,
                state_t_ns: d.exposure_end_ns,
                direct_position_m: [f64::NAN; 3],
                ..Default::default()
            };
            let confirmed = self
                .tm
                .track(id)
                .is_some_and(|t| t.status == TrackStatus::Confirmed);
            est.status = match (observed.is_some(), confirmed) {
                (false, _) => 2,
                (true, true) => 1,
                (true, false) => 0,
            };
            if let Some(det) = observed {
                est.azimuth_meas_rad = det.azimuth_rad;
                est.elevation_meas_rad = det.elevation_rad;
            }
            // Laser: confirmed tracks seen this frame, pointing predicted over the delay.
            if let (Some(client), true, true) =
                (self.laser.as_deref_mut(), observed.is_some(), confirmed)
            {
                if let Some(cmd) = self.tm.pointing(id, self.delay_s) {
                    est.pointing_azimuth_rad = cmd.azimuth_rad;
                    est.pointing_elevation_rad = cmd.elevation_rad;
                    let req = RangeRequest {
                        azimuth_rad: cmd.azimuth_rad,
                        elevation_rad: cmd.elevation_rad,
                        track_id: est.track_id,
                        ..Default::default()
                    };
                    let outcome = fire(
                        client,
                        self.node,
                        req,
                        d.exposure_end_ns,
                        self.timeout,
                        self.sim_clock,
                        &mut *self.keepalive,
                    )?;
                    match outcome {
                        CallOutcome::Answered(resp) => {
                            est.range_status = resp.status;
                            if resp.status == RangeStatus::Hit as u32 {
                                est.range_meas_m = resp.range_m;
                                let echo_s = resp.meta.t_ns as f64 * 1e-9;
                                est.state_t_ns = resp.meta.t_ns;
                                for f in self.tm.apply_range(id, echo_s, resp.range_m) {
                                    tracing::warn!(track = id, "range: {}", f.message);
                                }
                                let p = position_from_angles(
                                    cmd.azimuth_rad,
                                    cmd.elevation_rad,
                                    resp.range_m,
                                );
                                est.direct_position_m = [p.x, p.y, p.z];
                            }
                        }
                        CallOutcome::TimedOut
                        | CallOutcome::Disconnected
                        | CallOutcome::Malformed => {
                            msg.range_timeouts += 1;
                        }
                    }
                }
            }
            if let Some(track) = self.tm.track(id) {
                if let Some(f) = &track.angle_filter {
                    let x = f.state();
                    // The filtered angles at the end of this exposure.
                    let (xp, _) = f
                        .predicted(t_s.max(f.t_s()))
                        .unwrap_or((*x, *f.covariance()));
                    est.azimuth_filt_rad = xp[0];
                    est.elevation_filt_rad = xp[2];
                    est.angles_valid = 1;
                }
                if let Some(ekf) = &track.ekf {
                    est.ekf_valid = 1;
                    est.state_lvlh.copy_from_slice(ekf.state().as_slice());
                    let p = ekf.covariance();
                    for r in 0..6 {
                        for c in 0..6 {
                            est.covariance[6 * r + c] = p[(r, c)];
                        }
                    }
                    est.state_t_ns = (ekf.t_s() * 1e9).round() as u64;
                }
            }
            msg.items[msg.n as usize] = est;
            msg.n += 1;
        }
        Ok(msg)
    }
}

/// One laser shot. In sim-clock mode an unanswered shot (timed out, or its server gone) is
/// fired again with the same request id, heartbeating in between, until it is answered.
fn fire(
    client: &mut RangeClient,
    node: &IpcNode,
    req: RangeRequest,
    t_ns: u64,
    timeout: Duration,
    sim_clock: bool,
    keepalive: &mut dyn FnMut() -> Result<bool>,
) -> Result<CallOutcome<RangeResponse>> {
    let id = client.new_id();
    let t0 = std::time::Instant::now();
    let mut retries = 0u32;
    loop {
        let wait = if sim_clock {
            timeout.min(Duration::from_millis(100))
        } else {
            timeout
        };
        let outcome = client.call_with_id(node, req, id, t_ns, wait)?;
        if matches!(outcome, CallOutcome::Answered(_)) || !sim_clock {
            if retries > 0 {
                tracing::info!(request = id, retries, "laser shot answered after retries");
            }
            return Ok(outcome);
        }
        if t0.elapsed() > LASER_RETRY_LIMIT {
            anyhow::bail!("the laser did not answer request {id} for {LASER_RETRY_LIMIT:?}");
        }
        if retries == 0 {
            tracing::warn!(request = id, ?outcome, "laser shot unanswered; retrying");
        }
        retries += 1;
        if !keepalive()? {
            return Ok(outcome);
        }
        if !glint_runtime::waitloop::pause(node, Duration::from_millis(20)) {
            anyhow::bail!("terminated while waiting for the laser");
        }
    }
}

pub fn run(prefix: &str, scenario: &Scenario, restarted: bool) -> Result<()> {
    let cam = scenario
        .camera
        .as_ref()
        .context("the tracker needs a [camera] section")?;
    let node = open_node(prefix, "tracker")?;
    let (mut hk, control_l) = Housekeeping::open(&node, ServiceId::Tracker)?;
    hk.faults_enabled = scenario.faults.enabled;
    hk.heartbeat_period = Duration::from_millis(scenario.run.heartbeat_period_ms);
    let (mut dets, dets_l) =
        Inbox::<Detections>::open(&node, TopicId::Detections, &detections_service(&node)?)?;
    let realtime = scenario.clock == Clock::Realtime;
    if restarted && !realtime {
        dets.stats.await_replay();
    }
    let mut out = Outbox::open(
        &node,
        TopicId::Tracks,
        &tracks_service(&node)?,
        ServiceId::Tracker,
    )?;
    let (mut acks, ack_l) = AckReader::open(&node)?;
    let mut credit = Credit::new(
        TRACKS_BUFFER,
        deployment::consumers(scenario, TopicId::Tracks),
    );
    let mut client = if cam.tracker.laser {
        Some(RangeClient::open(&node, ServiceId::Tracker)?)
    } else {
        None
    };
    let mut tm = TrackManager::new(config(cam)).map_err(|e| anyhow::anyhow!("{e}"))?;
    let timeout = Duration::from_millis(cam.tracker.range_timeout_ms);
    let camera = PinholeCamera {
        width_px: cam.width_px,
        height_px: cam.height_px,
        fov_x_rad: cam.fov_deg.to_radians(),
        fov_y_rad: cam.fov_deg.to_radians(),
    };
    let k = cam.exposure_s / (2.0 * (cam.exposure_s + cam.interval_s));
    let end_point_factor = ((1.0 + k).powi(2) + k * k).sqrt();
    hk.state = Heartbeat::READY;

    let inputs = [(&control_l, None), (&dets_l, None), (&ack_l, None)];
    let hb = Duration::from_millis(scenario.run.heartbeat_period_ms);
    let exit = run_loop(&inputs, hb, |wakes| {
        if hk.obey(&[&dets.stats, &out.stats])? {
            return Ok(Step::Stop);
        }
        acks.poll(&mut [(TopicId::Tracks, &mut credit)])?;
        for f in hk.take_output_faults() {
            out.tamper.arm(&f);
        }
        let limit = credit.input_limit(out.stats.published, realtime);
        let mut pending: Vec<Detections> = vec![];
        dets.drain_up_to(limit, |r| {
            hk.last_latency_ns = r.latency_ns;
            pending.push(*r.msg);
            Ok(())
        })?;
        let mut last_t_ns = 0;
        for d in &pending {
            hk.pace()?;
            let msg = {
                let (hk, stats) = (&mut hk, [&dets.stats, &out.stats]);
                let mut keepalive = || {
                    if hk.poll_control()?.contains(&shared_types::Command::Start) {
                        hk.state = Heartbeat::RUNNING;
                    }
                    hk.beat(d.exposure_end_ns, &stats)?;
                    Ok(!hk.shutdown_requested)
                };
                let mut work = FrameWork {
                    tm: &mut tm,
                    laser: client.as_mut(),
                    node: &node,
                    delay_s: cam.laser.delay_s,
                    timeout,
                    camera,
                    exposure_s: cam.exposure_s,
                    end_point_factor,
                    sim_clock: !realtime,
                    keepalive: &mut keepalive,
                };
                work.process(d)?
            };
            out.send(msg, d.exposure_end_ns)?;
            last_t_ns = d.exposure_end_ns;
        }
        hk.ack(TopicId::Detections, dets.stats.next_seq, last_t_ns)?;
        if wakes.contains(&Wake::Tick) {
            hk.beat(last_t_ns, &[&dets.stats, &out.stats])?;
        }
        Ok(Step::Wait)
    })?;
    if exit == Exit::Terminated {
        tracing::info!("tracker terminated by signal");
    }
    Ok(())
}
