//! The detector's node loop: frames in (pixels read in place from shared memory), matched
//! detections out. Sim-clock: it takes a frame only when the consumers of `detections` have
//! credit for one more message, and acknowledges frames as it processes them.

use std::time::Duration;

use anyhow::{Context, Result};
use glint_physics::camera::PinholeCamera;
use glint_runtime::ports::{FrameInbox, Outbox};
use glint_runtime::{open_node, run_loop, AckReader, Credit, Exit, Housekeeping, Step, Wake};
use shared_types::scenario::{CameraScenario, Clock};
use shared_types::topics::{detections_service, frame_service, DETECTIONS_BUFFER};
use shared_types::{
    deployment, Detection, Detections, DropReason, Heartbeat, Scenario, ServiceId, TopicId,
    MAX_DETECTIONS,
};

use crate::angles::line_of_sight;
use crate::matching::{MatchResult, Matcher, MatcherConfig};
use crate::moments::Blob;
use crate::{Detector, DetectorConfig, Threshold};

/// Detector and matcher settings from the scenario.
pub fn configs(cam: &CameraScenario) -> (DetectorConfig, MatcherConfig) {
    let d = &cam.detector;
    let det = DetectorConfig {
        threshold: Threshold::Sigma {
            k: d.threshold_k_sigma,
        },
        min_area_px: d.min_area_px,
        saturation_dn: cam.saturation_dn.min(u16::MAX as u32) as u16,
        ..Default::default()
    };
    let mat = MatcherConfig {
        exposure_s: cam.exposure_s,
        interval_s: cam.interval_s,
        m00_tol_frac: d.area_tol_frac,
        a_tol_frac: d.semi_axis_tol_frac,
        theta_tol_rad: d.theta_tol_deg.to_radians(),
        ecc_tol: d.ecc_tol,
        round_ecc: d.round_ecc,
        gate_margin_px: d.gate_margin_px,
        max_coast_frames: d.max_coast_frames,
        ..Default::default()
    };
    (det, mat)
}

/// The camera of the scenario.
pub fn camera(cam: &CameraScenario) -> PinholeCamera {
    PinholeCamera {
        width_px: cam.width_px,
        height_px: cam.height_px,
        fov_x_rad: cam.fov_deg.to_radians(),
        fov_y_rad: cam.fov_deg.to_radians(),
    }
}

/// Builds the wire message of one frame from the matcher's result.
/// Eq (9) extrapolates the end point from two centroids: u_t = (1+k) u_c − k u_c' with
/// k = t_ep / (2 (t_ep + t_in)), so its variance is ((1+k)² + k²) times a centroid's.
fn end_point_sigma_factor(exposure_s: f64, interval_s: f64) -> f64 {
    let k = exposure_s / (2.0 * (exposure_s + interval_s));
    ((1.0 + k).powi(2) + k * k).sqrt()
}

pub fn to_message(
    camera: &PinholeCamera,
    blobs: &[Blob],
    m: &MatchResult,
    frame_index: u64,
    exposure_end_ns: u64,
    background_sigma_dn: f64,
    end_point_factor: f64,
) -> Detections {
    let mut out = Detections {
        frame_index,
        exposure_end_ns,
        blobs_found: blobs.len() as u32,
        rejected: m.rejected_previous.len() as u32,
        ..Default::default()
    };
    for (slot, md) in out
        .items
        .iter_mut()
        .zip(m.matched.iter().take(MAX_DETECTIONS))
    {
        let Some(b) = blobs.get(md.blob_index) else {
            continue;
        };
        let los = line_of_sight(camera, md.end_point_px[0], md.end_point_px[1]);
        // Gain 1 e⁻/DN: the sensor's renderer uses it; a real camera would configure it.
        let sigma_px = b.centroid_sigma_px(background_sigma_dn, 1.0) * end_point_factor;
        let sigma_rad = sigma_px * camera.ifov_rad();
        let mut flags = Detection::FLAG_MATCHED;
        if b.touches_border {
            flags |= Detection::FLAG_BORDER;
        }
        if b.saturated_px > 0 {
            flags |= Detection::FLAG_SATURATED;
        }
        *slot = Detection {
            track_id: md.track_id.min(u32::MAX as u64) as u32,
            flags,
            x_px: md.centroid_px[0],
            y_px: md.centroid_px[1],
            end_x_px: md.end_point_px[0],
            end_y_px: md.end_point_px[1],
            area_px: b.area_px as f64,
            a_px: b.a_px,
            b_px: b.b_px,
            theta_rad: b.theta_rad,
            eccentricity: b.eccentricity,
            flux_dn: b.flux_dn,
            azimuth_rad: los.azimuth_rad,
            elevation_rad: los.elevation_rad,
            sigma_rad: if sigma_rad.is_finite() {
                sigma_rad
            } else {
                0.0
            },
        };
        out.n += 1;
    }
    out
}

pub fn run(prefix: &str, scenario: &Scenario, restarted: bool) -> Result<()> {
    let cam = scenario
        .camera
        .as_ref()
        .context("the detector needs a [camera] section")?;
    let node = open_node(prefix, "detector")?;
    let (mut hk, control_l) = Housekeeping::open(&node, ServiceId::Detector)?;
    hk.faults_enabled = scenario.faults.enabled;
    hk.heartbeat_period = Duration::from_millis(scenario.run.heartbeat_period_ms);
    let (mut frames, frame_l) = FrameInbox::open(&node, &frame_service(&node)?)?;
    // Integrity of the pixels is checked on receipt (one xxh3 pass, ~0.1 ms per 1024² frame).
    frames.verify_checksum = true;
    let realtime = scenario.clock == Clock::Realtime;
    if restarted && !realtime {
        frames.stats.await_replay();
    }
    let mut out = Outbox::open(
        &node,
        TopicId::Detections,
        &detections_service(&node)?,
        ServiceId::Detector,
    )?;
    // Detections are not re-made from frames on demand: a restarted tracker is sent them again.
    out.keep_log();
    let (mut acks, ack_l) = AckReader::open(&node)?;
    let mut credit = Credit::new(
        DETECTIONS_BUFFER,
        deployment::consumers(scenario, TopicId::Detections),
    );
    let (det_cfg, match_cfg) = configs(cam);
    let mut detector = Detector::new(det_cfg).map_err(|e| anyhow::anyhow!("{e}"))?;
    let mut matcher = Matcher::new(match_cfg).map_err(|e| anyhow::anyhow!("{e}"))?;
    let camera = camera(cam);
    let (w, h) = (cam.width_px as usize, cam.height_px as usize);
    let end_factor = end_point_sigma_factor(cam.exposure_s, cam.interval_s);
    hk.state = Heartbeat::READY;
    let mut send_error: Option<anyhow::Error> = None;

    let inputs = [(&control_l, None), (&frame_l, None), (&ack_l, None)];
    let hb = Duration::from_millis(scenario.run.heartbeat_period_ms);
    let exit = run_loop(&inputs, hb, |wakes| {
        if hk.obey(&[&frames.stats, &out.stats])? {
            return Ok(Step::Stop);
        }
        acks.poll(&mut [(TopicId::Detections, &mut credit)])?;
        for f in hk.take_output_faults() {
            out.tamper.arm(&f);
        }
        for r in hk.take_replays() {
            if r.topic == TopicId::Detections {
                tracing::info!(consumer = r.consumer.name(), from = r.from_seq, "replay");
                credit.reset(r.consumer, r.from_seq);
                out.rewind(r.from_seq);
            }
        }
        if out.replaying() {
            out.resend(credit.available(out.next_seq()))?;
            if out.replaying() {
                // New frames wait until the restarted consumer has caught up.
                return Ok(Step::Wait);
            }
        }
        let limit = credit.input_limit(out.stats.published, realtime);
        let mut last_t_ns = 0;
        frames.drain_up_to(limit, |header, pixels, latency_ns| {
            if let Err(e) = hk.pace() {
                send_error.get_or_insert(e);
            }
            hk.last_latency_ns = latency_ns;
            let found = detector
                .detect(pixels, w, h)
                .map_err(|_| DropReason::Malformed)?;
            let result = matcher
                .update(found.blobs, header.frame_index)
                .map_err(|_| DropReason::Stale)?;
            let msg = to_message(
                &camera,
                found.blobs,
                &result,
                header.frame_index,
                header.meta.t_ns,
                found.background.sigma_dn,
                end_factor,
            );
            last_t_ns = header.meta.t_ns;
            if let Err(e) = out.send(msg, header.meta.t_ns) {
                send_error.get_or_insert(e);
            }
            Ok(())
        })?;
        if let Some(e) = send_error.take() {
            return Err(e);
        }
        hk.ack(TopicId::Frame, frames.stats.next_seq, last_t_ns)?;
        if wakes.contains(&Wake::Tick) {
            hk.beat(last_t_ns, &[&frames.stats, &out.stats])?;
        }
        Ok(Step::Wait)
    })?;
    if exit == Exit::Terminated {
        tracing::info!("detector terminated by signal");
    }
    Ok(())
}
