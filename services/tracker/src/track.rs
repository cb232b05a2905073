//! Track management around the §3.6 angle filter and the §3.8 CW EKF (docs/math.md §3.4–3.8).
//!
//! Observations come from the detector's matcher (persistent track ids) with the time of the end
//! of the exposure, the line-of-sight angles (eq 10 at the eq 9 end point) and, when the laser
//! replied, the range. Per track:
//!
//! - **Life cycle** (Stone Soup's initiator/deleter): a track is created *tentative* by its first
//!   observation, becomes *confirmed* at `confirm_hits` (M) observations, and is deleted after
//!   `delete_misses` (N) consecutive frames without one.
//! - **Angle filter**: initialised from the first two angle measurements, then updated with each.
//! - **EKF**: initialised from the first two observations that carry a range, then updated with
//!   (α, β, r), or with (α, β) only when the range is missing.
//! - **Faults**: a numeric failure resets that filter (it re-initialises from the next
//!   observations) and is counted and reported, never a panic; an observation older than the
//!   filter, or a non-positive range, is skipped and reported.

use crate::angle_filter::{
    AngleEstimate, AngleFilter, AngleFilterConfig, AngleMeasurement, FilterError,
};
use crate::ekf::{CwEkf, CwEkfConfig, EkfError, EkfEstimate, RangeFix};
use crate::pointing::{predict_pointing, PointingCommand};
use crate::ConfigError;
use nalgebra::Matrix2;
use std::collections::BTreeMap;

/// Life-cycle and filter settings.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TrackManagerConfig {
    /// M: observations needed to confirm a track, ≥ 1. Default 3.
    pub confirm_hits: u32,
    /// N: consecutive missed frames that delete a track, ≥ 1. Default 3.
    pub delete_misses: u32,
    pub angle_filter: AngleFilterConfig,
    pub ekf: CwEkfConfig,
}

impl Default for TrackManagerConfig {
    /// M = 3, N = 3, default filters.
    fn default() -> Self {
        Self {
            confirm_hits: 3,
            delete_misses: 3,
            angle_filter: AngleFilterConfig::default(),
            ekf: CwEkfConfig::default(),
        }
    }
}

impl TrackManagerConfig {
    pub fn validate(&self) -> Result<(), ConfigError> {
        if self.confirm_hits == 0 {
            return Err(ConfigError::new("confirm_hits", 0, "≥ 1"));
        }
        if self.delete_misses == 0 {
            return Err(ConfigError::new("delete_misses", 0, "≥ 1"));
        }
        self.angle_filter.validate()?;
        self.ekf.validate()
    }
}

/// One detection of a track in a frame.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TrackObservation {
    pub track_id: u64,
    /// Time of the measurement (end of exposure) \[s\].
    pub t_s: f64,
    pub azimuth_rad: f64,
    pub elevation_rad: f64,
    /// Laser range \[m\], if the reply arrived.
    pub range_m: Option<f64>,
    /// Time the range refers to \[s\] when it differs from `t_s` (a shot fired after the angle
    /// measurement with delay-predicted pointing, §3.7); `None` = same time as the angles.
    #[serde(default)]
    pub range_t_s: Option<f64>,
    /// 1σ of these angles \[rad\] when known per detection; `None` = the configured value.
    #[serde(default)]
    pub sigma_rad: Option<f64>,
    /// A separate line of sight for the EKF (e.g. the streak centroid at mid-exposure, whose
    /// errors are white, where the eq-9 end points of consecutive frames share a centroid and
    /// are correlated); `None` = the angles above.
    #[serde(default)]
    pub ekf_angles: Option<EkfAngles>,
}

/// A line-of-sight measurement for the EKF alone.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct EkfAngles {
    pub t_s: f64,
    pub azimuth_rad: f64,
    pub elevation_rad: f64,
    pub sigma_rad: f64,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TrackStatus {
    Tentative,
    Confirmed,
}

/// Which filter a fault concerns.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FilterKind {
    Angle,
    Ekf,
}

/// What was done about a fault.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FaultAction {
    /// The filter was dropped and will re-initialise.
    Reset,
    /// The observation (or its range) was ignored.
    Skipped,
}

/// A filter problem met while processing a frame.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TrackFault {
    pub track_id: u64,
    pub filter: FilterKind,
    pub action: FaultAction,
    pub message: String,
}

/// What one frame changed.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FrameOutcome {
    pub created: Vec<u64>,
    pub confirmed: Vec<u64>,
    pub updated: Vec<u64>,
    pub missed: Vec<u64>,
    pub deleted: Vec<u64>,
    pub faults: Vec<TrackFault>,
}

/// One track and its filters.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Track {
    pub track_id: u64,
    pub status: TrackStatus,
    pub hits: u32,
    pub consecutive_misses: u32,
    /// Time of the last observation \[s\].
    pub last_t_s: f64,
    /// Filter resets after numeric failures.
    pub resets: u32,
    pub angle_filter: Option<AngleFilter>,
    pub ekf: Option<CwEkf>,
    pending_angles: Option<AngleMeasurement>,
    /// A first fix awaiting its second, with the covariance of its (α, β).
    pending_fix: Option<(RangeFix, Matrix2<f64>)>,
}

/// A track's state for the JSON report.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TrackReport {
    pub track_id: u64,
    pub status: TrackStatus,
    pub hits: u32,
    pub consecutive_misses: u32,
    pub last_t_s: f64,
    pub resets: u32,
    pub angles: Option<AngleEstimate>,
    pub relative_state: Option<EkfEstimate>,
}

impl Track {
    fn new(track_id: u64, t_s: f64) -> Self {
        Self {
            track_id,
            status: TrackStatus::Tentative,
            hits: 0,
            consecutive_misses: 0,
            last_t_s: t_s,
            resets: 0,
            angle_filter: None,
            ekf: None,
            pending_angles: None,
            pending_fix: None,
        }
    }

    pub fn report(&self) -> TrackReport {
        TrackReport {
            track_id: self.track_id,
            status: self.status,
            hits: self.hits,
            consecutive_misses: self.consecutive_misses,
            last_t_s: self.last_t_s,
            resets: self.resets,
            angles: self.angle_filter.as_ref().map(AngleFilter::estimate),
            relative_state: self.ekf.as_ref().map(CwEkf::estimate),
        }
    }

    fn fault(&self, filter: FilterKind, action: FaultAction, message: String) -> TrackFault {
        TrackFault {
            track_id: self.track_id,
            filter,
            action,
            message,
        }
    }

    fn observe_angles(
        &mut self,
        cfg: &AngleFilterConfig,
        z: AngleMeasurement,
        sigma_rad: Option<f64>,
    ) -> Option<TrackFault> {
        let Some(filter) = self.angle_filter.as_mut() else {
            match self.pending_angles.take() {
                Some(first) if z.t_s > first.t_s => match AngleFilter::initialize(*cfg, &first, &z)
                {
                    Ok(f) => self.angle_filter = Some(f),
                    Err(e) => {
                        self.pending_angles = Some(z);
                        return Some(self.fault(
                            FilterKind::Angle,
                            FaultAction::Skipped,
                            e.to_string(),
                        ));
                    }
                },
                _ => self.pending_angles = Some(z),
            }
            return None;
        };
        match filter.update_with_sigma(&z, sigma_rad) {
            Ok(_) => None,
            Err(e @ FilterError::TimeReversed { .. }) => {
                Some(self.fault(FilterKind::Angle, FaultAction::Skipped, e.to_string()))
            }
            Err(e) => {
                self.angle_filter = None;
                self.pending_angles = Some(z);
                self.resets += 1;
                Some(self.fault(FilterKind::Angle, FaultAction::Reset, e.to_string()))
            }
        }
    }

    fn observe_ekf(
        &mut self,
        cfg: &CwEkfConfig,
        obs: &TrackObservation,
        faults: &mut Vec<TrackFault>,
    ) {
        let (angles, angles_sigma) = match obs.ekf_angles {
            Some(a) => (
                AngleMeasurement {
                    t_s: a.t_s,
                    azimuth_rad: a.azimuth_rad,
                    elevation_rad: a.elevation_rad,
                },
                Some(a.sigma_rad),
            ),
            None => (
                AngleMeasurement {
                    t_s: obs.t_s,
                    azimuth_rad: obs.azimuth_rad,
                    elevation_rad: obs.elevation_rad,
                },
                obs.sigma_rad,
            ),
        };
        let range_t_s = obs.range_t_s.unwrap_or(obs.t_s);
        let range = match obs.range_m {
            Some(r) if r.is_finite() && r > 0.0 && range_t_s >= obs.t_s - crate::SAME_INSTANT_S => {
                Some(r)
            }
            Some(r) => {
                // A bad range: report it and carry on with the angles.
                let msg = format!(
                    "range {r} m at {range_t_s} s is not a positive finite number after the angles"
                );
                faults.push(self.fault(FilterKind::Ekf, FaultAction::Skipped, msg));
                None
            }
            None => None,
        };
        match range {
            Some(r)
                if (range_t_s - obs.t_s).abs() <= crate::SAME_INSTANT_S && self.ekf.is_some() =>
            {
                let fix = RangeFix {
                    t_s: obs.t_s,
                    azimuth_rad: obs.azimuth_rad,
                    elevation_rad: obs.elevation_rad,
                    range_m: r,
                };
                let result = self.ekf.as_mut().map(|e| e.update(&fix).map(|_| ()));
                self.settle(result, faults);
            }
            _ => {
                if self.ekf.is_some() {
                    let result = self.ekf.as_mut().map(|e| {
                        e.update_angles_with_sigma(&angles, angles_sigma)
                            .map(|_| ())
                    });
                    self.settle(result, faults);
                }
                if let Some(r) = range {
                    self.observe_range(cfg, range_t_s, r, obs, faults);
                }
            }
        }
    }

    /// Applies a range measured at `t_s` (after this track's latest angles): initialises the EKF
    /// from two fixes, or updates it with the range row alone.
    fn observe_range(
        &mut self,
        cfg: &CwEkfConfig,
        t_s: f64,
        range_m: f64,
        obs: &TrackObservation,
        faults: &mut Vec<TrackFault>,
    ) {
        if let Some(ekf) = self.ekf.as_mut() {
            let result = ekf.update_range(t_s, range_m).map(|_| ());
            self.settle(Some(result), faults);
            return;
        }
        // Initialisation needs fixes (α, β, r) at one time: the range's, with the angles the
        // angle filter predicts for that time and their covariance (the measured ones and
        // σ_α, σ_β when the times agree).
        let (az, el, angles_cov) = if t_s > obs.t_s {
            match self
                .angle_filter
                .as_ref()
                .and_then(|f| f.predicted(t_s).ok())
            {
                Some((x, p)) => (
                    x[0],
                    x[2],
                    Matrix2::new(p[(0, 0)], p[(0, 2)], p[(2, 0)], p[(2, 2)]),
                ),
                None => return,
            }
        } else {
            let r = cfg.measurement_covariance();
            (
                obs.azimuth_rad,
                obs.elevation_rad,
                r.fixed_view::<2, 2>(0, 0).into_owned(),
            )
        };
        let fix = RangeFix {
            t_s,
            azimuth_rad: az,
            elevation_rad: el,
            range_m,
        };
        match self.pending_fix.take() {
            Some((first, first_cov)) if fix.t_s > first.t_s => {
                match CwEkf::initialize_with_angle_covariances(
                    *cfg,
                    &first,
                    &fix,
                    [first_cov, angles_cov],
                ) {
                    Ok(f) => self.ekf = Some(f),
                    Err(e) => {
                        self.pending_fix = Some((fix, angles_cov));
                        faults.push(self.fault(
                            FilterKind::Ekf,
                            FaultAction::Skipped,
                            e.to_string(),
                        ));
                    }
                }
            }
            _ => self.pending_fix = Some((fix, angles_cov)),
        }
    }

    /// Records the outcome of an EKF update: a time-order problem skips the measurement, any
    /// numeric failure resets the filter (it re-initialises from later fixes).
    fn settle(&mut self, result: Option<Result<(), EkfError>>, faults: &mut Vec<TrackFault>) {
        match result {
            None | Some(Ok(())) => {}
            Some(Err(e @ EkfError::TimeReversed { .. })) => {
                faults.push(self.fault(FilterKind::Ekf, FaultAction::Skipped, e.to_string()));
            }
            Some(Err(e)) => {
                self.ekf = None;
                self.resets += 1;
                faults.push(self.fault(FilterKind::Ekf, FaultAction::Reset, e.to_string()));
            }
        }
    }
}

/// Owns every track; fed once per frame.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackManager {
    config: TrackManagerConfig,
    tracks: BTreeMap<u64, Track>,
}

impl TrackManager {
    pub fn new(config: TrackManagerConfig) -> Result<Self, ConfigError> {
        config.validate()?;
        Ok(Self {
            config,
            tracks: BTreeMap::new(),
        })
    }

    pub fn config(&self) -> &TrackManagerConfig {
        &self.config
    }

    /// Every track and its filters: what the manager carries from frame to frame.
    pub fn state(&self) -> BTreeMap<u64, Track> {
        self.tracks.clone()
    }

    /// Carries `tracks` instead (a restored checkpoint).
    pub fn restore(&mut self, tracks: BTreeMap<u64, Track>) {
        self.tracks = tracks;
    }

    pub fn track(&self, track_id: u64) -> Option<&Track> {
        self.tracks.get(&track_id)
    }

    /// Tracks in id order.
    pub fn tracks(&self) -> impl Iterator<Item = &Track> {
        self.tracks.values()
    }

    /// Report rows of every track, in id order.
    pub fn reports(&self) -> Vec<TrackReport> {
        self.tracks.values().map(Track::report).collect()
    }

    /// Eq 16 pointing for a track from its angle filter, `delay_s` after its last estimate.
    pub fn pointing(&self, track_id: u64, delay_s: f64) -> Option<PointingCommand> {
        let filter = self.tracks.get(&track_id)?.angle_filter.as_ref()?;
        Some(predict_pointing(&filter.estimate(), delay_s))
    }

    /// Applies a laser range of `track_id` measured at `t_s` (after its latest angles, e.g. the
    /// echo of a shot fired with [`TrackManager::pointing`]). Unknown tracks are ignored.
    pub fn apply_range(&mut self, track_id: u64, t_s: f64, range_m: f64) -> Vec<TrackFault> {
        let cfg = self.config.ekf;
        let mut faults = vec![];
        if let Some(track) = self.tracks.get_mut(&track_id) {
            if !(range_m.is_finite() && range_m > 0.0 && t_s >= track.last_t_s) {
                let msg = format!("range {range_m} m at {t_s} s rejected");
                faults.push(track.fault(FilterKind::Ekf, FaultAction::Skipped, msg));
                return faults;
            }
            // The track's latest filtered angles stand for the angles of this range when the
            // two times coincide; otherwise they are predicted to `t_s`.
            let Some(filter) = track.angle_filter.as_ref() else {
                return faults;
            };
            let x = filter.state();
            let obs = TrackObservation {
                track_id,
                t_s: track.last_t_s,
                azimuth_rad: x[0],
                elevation_rad: x[2],
                range_m: Some(range_m),
                range_t_s: Some(t_s),
                sigma_rad: None,
                ekf_angles: None,
            };
            track.observe_range(&cfg, t_s, range_m, &obs, &mut faults);
        }
        faults
    }

    /// Applies one frame's observations; every track without one records a miss.
    pub fn process_frame(&mut self, observations: &[TrackObservation]) -> FrameOutcome {
        let mut out = FrameOutcome::default();
        let cfg = self.config;
        for obs in observations {
            if !(obs.t_s.is_finite()
                && obs.azimuth_rad.is_finite()
                && obs.elevation_rad.is_finite())
            {
                out.faults.push(TrackFault {
                    track_id: obs.track_id,
                    filter: FilterKind::Angle,
                    action: FaultAction::Skipped,
                    message: "non-finite time or angle".into(),
                });
                continue;
            }
            let track = self.tracks.entry(obs.track_id).or_insert_with(|| {
                out.created.push(obs.track_id);
                Track::new(obs.track_id, obs.t_s)
            });
            let z = AngleMeasurement {
                t_s: obs.t_s,
                azimuth_rad: obs.azimuth_rad,
                elevation_rad: obs.elevation_rad,
            };
            out.faults
                .extend(track.observe_angles(&cfg.angle_filter, z, obs.sigma_rad));
            track.observe_ekf(&cfg.ekf, obs, &mut out.faults);
            if !out.updated.contains(&obs.track_id) {
                track.hits = track.hits.saturating_add(1);
                out.updated.push(obs.track_id);
            }
            track.consecutive_misses = 0;
            track.last_t_s = track.last_t_s.max(obs.t_s);
            if track.status == TrackStatus::Tentative && track.hits >= cfg.confirm_hits {
                track.status = TrackStatus::Confirmed;
                out.confirmed.push(obs.track_id);
            }
        }
        for (id, track) in &mut self.tracks {
            if !out.updated.contains(id) {
                track.consecutive_misses += 1;
                out.missed.push(*id);
                if track.consecutive_misses >= cfg.delete_misses {
                    out.deleted.push(*id);
                }
            }
        }
        for id in &out.deleted {
            self.tracks.remove(id);
        }
        out
    }
}

#[cfg(test)]
mod tests;
