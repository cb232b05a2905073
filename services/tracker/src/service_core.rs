//! The tracker service's core: one frame's detections in, that frame's tracks out (the wire
//! message). Per frame: angle-filter and EKF updates with the angles at the end of the
//! exposure, then for every confirmed track a laser shot with delay-predicted pointing (§3.7)
//! through a [`Laser`], and the echo's range applied at its own time. A missed or late echo is
//! counted and the filters go on with angles. No IPC: the node's laser is a request/response
//! client, a test's can be the sensor's laser model called in-process.

use anyhow::Result;
use glint_physics::camera::{position_from_angles, PinholeCamera};
use glint_physics::orbit::MU_EARTH_M3_S2;
use shared_types::scenario::CameraScenario;
use shared_types::{
    Detections, RangeRequest, RangeResponse, RangeStatus, TrackEstimate, Tracks, MAX_TRACKS,
};

use crate::angle_filter::AngleFilterConfig;
use crate::ekf::CwEkfConfig;
use crate::track::{EkfAngles, TrackManager, TrackManagerConfig, TrackObservation, TrackStatus};
use crate::ConfigError;

/// The range finder the tracker points: `Ok(None)` when a shot went unanswered (timed out,
/// server gone, malformed answer).
pub trait Laser {
    fn fire(&mut self, req: RangeRequest, t_ns: u64) -> Result<Option<RangeResponse>>;
}

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

/// The track manager of one camera, and what a frame's message needs besides.
pub struct TrackerCore {
    tm: TrackManager,
    camera: PinholeCamera,
    exposure_s: f64,
    /// Laser delay the pointing is predicted over [s].
    delay_s: f64,
    /// Whether confirmed tracks are ranged.
    laser: bool,
    /// σ(end point) / σ(centroid) of eq (9).
    end_point_factor: f64,
}

impl TrackerCore {
    /// Every track and its filters: what the tracker carries from frame to frame.
    pub fn state(&self) -> std::collections::BTreeMap<u64, crate::track::Track> {
        self.tm.state()
    }

    /// Carries `tracks` instead (a restored checkpoint).
    pub fn restore(&mut self, tracks: std::collections::BTreeMap<u64, crate::track::Track>) {
        self.tm.restore(tracks);
    }

    pub fn new(cam: &CameraScenario) -> Result<Self, ConfigError> {
        let k = cam.exposure_s / (2.0 * (cam.exposure_s + cam.interval_s));
        Ok(TrackerCore {
            tm: TrackManager::new(config(cam))?,
            camera: PinholeCamera {
                width_px: cam.width_px,
                height_px: cam.height_px,
                fov_x_rad: cam.fov_deg.to_radians(),
                fov_y_rad: cam.fov_deg.to_radians(),
            },
            exposure_s: cam.exposure_s,
            delay_s: cam.laser.delay_s,
            laser: cam.tracker.laser,
            end_point_factor: ((1.0 + k).powi(2) + k * k).sqrt(),
        })
    }

    /// Whether the tracker ranges its confirmed tracks (the scenario's `tracker.laser`).
    pub fn uses_laser(&self) -> bool {
        self.laser
    }

    /// Updates the tracks with one frame's detections and ranges the confirmed ones.
    pub fn process(&mut self, d: &Detections, laser: &mut dyn Laser) -> Result<Tracks> {
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
            if let (true, true, true) = (self.laser, observed.is_some(), confirmed) {
                if let Some(cmd) = self.tm.pointing(id, self.delay_s) {
                    est.pointing_azimuth_rad = cmd.azimuth_rad;
                    est.pointing_elevation_rad = cmd.elevation_rad;
                    let req = RangeRequest {
                        azimuth_rad: cmd.azimuth_rad,
                        elevation_rad: cmd.elevation_rad,
                        track_id: est.track_id,
                        ..Default::default()
                    };
                    match laser.fire(req, d.exposure_end_ns)? {
                        Some(resp) => {
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
                        None => msg.range_timeouts += 1,
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
