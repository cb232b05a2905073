//! Scoring of the debris chain against truth ([002]; math.md §3.9): detection precision and
//! recall, false-target rejection, angle errors before and after the angle filter, EKF position
//! and velocity errors, and NEES. Pure: it reads the messages the orchestrator collected.
//!
//! Association: a detection is a true positive when its end-of-exposure point (eq 9) lies within
//! `gate_px` of a debris' projected position at the end of the exposure; each track is assigned
//! to the debris its detections hit most often.
//!
//! The scores' types and the whole-run entry point are here; the scorer that folds a run's
//! messages as they arrive is [`super::debris_scorer`].

pub use super::debris_scorer::{DebrisScorer, Expect};

use glint_physics::camera::PinholeCamera;
use serde::{Deserialize, Serialize};
use shared_types::{Detections, Tracks, Truth};
use statrs::distribution::{ChiSquared, ContinuousCDF};

/// Detection gate against truth [px].
pub const GATE_PX: f64 = 3.0;

#[derive(Debug, Clone, Serialize, Deserialize, schemars::JsonSchema, PartialEq)]
pub struct DetectionScore {
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    #[schemars(with = "Option<f64>")]
    pub precision: f64,
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    #[schemars(with = "Option<f64>")]
    pub recall: f64,
    pub true_positives: u64,
    pub false_positives: u64,
    pub missed: u64,
    /// Frames scored: every frame after the first (a detection needs a match in the previous
    /// frame, so the first frame reports none by design).
    pub frames_scored: u64,
    pub false_targets: u64,
    pub false_targets_rejected: u64,
}

#[derive(Debug, Clone, Serialize, Deserialize, schemars::JsonSchema, PartialEq)]
pub struct TargetScore {
    /// Debris number as in the scenario (1-based).
    pub id: u32,
    pub track_id: Option<u32>,
    pub frames_tracked: u64,
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    #[schemars(with = "Option<f64>")]
    pub azimuth_err_deg_rms_measured: f64,
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    #[schemars(with = "Option<f64>")]
    pub azimuth_err_deg_rms_filtered: f64,
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    #[schemars(with = "Option<f64>")]
    pub elevation_err_deg_rms_measured: f64,
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    #[schemars(with = "Option<f64>")]
    pub elevation_err_deg_rms_filtered: f64,
    /// "Before filtering": the per-frame direct fix from (α, β, r) [m RMS].
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    #[schemars(with = "Option<f64>")]
    pub pos_err_m_rms_direct: f64,
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    #[schemars(with = "Option<f64>")]
    pub pos_err_m_final: f64,
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    #[schemars(with = "Option<f64>")]
    pub vel_err_mps_final: f64,
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    #[schemars(with = "Option<f64>")]
    pub nees_mean: f64,
    /// NEES at the last frame (for a Monte-Carlo check at a fixed time across seeds).
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    #[schemars(with = "Option<f64>")]
    pub nees_final: f64,
    /// RMS over frames of (measured angle − truth) / (the detection's claimed 1σ), azimuth and
    /// elevation together: ≈ 1 when the detector's uncertainty is honest.
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    #[schemars(with = "Option<f64>")]
    pub angle_err_normalized_rms: f64,
    /// 95 % bounds of the mean NEES of this many 6-dof samples.
    #[serde(deserialize_with = "crate::report::model::pair_or_nan")]
    #[schemars(with = "[Option<f64>; 2]")]
    pub nees_bounds: [f64; 2],
    pub laser_shots: u64,
    pub laser_hits: u64,
}

/// One point of a target's series, for plots.
#[derive(Debug, Clone, Copy)]
pub struct SeriesPoint {
    pub t_s: f64,
    pub azimuth_meas_deg: f64,
    pub azimuth_filt_deg: f64,
    pub azimuth_true_deg: f64,
    pub elevation_meas_deg: f64,
    pub elevation_filt_deg: f64,
    pub elevation_true_deg: f64,
    /// EKF position error norm and its 3σ bound (3·sqrt(trace of the position covariance))
    /// [m], once the EKF is valid.
    pub pos_err_m: Option<(f64, f64)>,
}

/// Points a series keeps at least before it is thinned (every point of a run this short).
const SERIES_POINTS: usize = 4096;

/// Per-frame series of one target, for plots: every frame's point up to `2 · SERIES_POINTS`,
/// then every other one, then every fourth…, so a long run's plot spans the whole run in
/// bounded memory.
#[derive(Debug, Clone, Default)]
pub struct TargetSeries {
    pub points: Vec<SeriesPoint>,
    offered: u64,
    stride: u64,
}

impl TargetSeries {
    pub(super) fn push(&mut self, p: SeriesPoint) {
        let stride = self.stride.max(1);
        if self.offered % stride == 0 {
            self.points.push(p);
            if self.points.len() >= 2 * SERIES_POINTS {
                crate::plots::thin_by_half(&mut self.points);
                self.stride = stride * 2;
            }
        }
        self.offered += 1;
    }
}

pub struct DebrisScore {
    pub detection: DetectionScore,
    pub targets: Vec<TargetScore>,
    pub series: Vec<TargetSeries>,
}

/// 95 % interval of the mean of `n` χ²(k) samples (exact χ²(n·k) quantiles, divided by n).
pub fn nees_bounds(n: usize, k: usize) -> [f64; 2] {
    chi2_mean_bounds(n * k, n)
}

/// 95 % interval of the mean of n NEES values whose sum is χ²(`total_dof`): the exact 2.5 % and
/// 97.5 % quantiles of χ²(`total_dof`) (statrs), divided by n.
pub fn chi2_mean_bounds(total_dof: usize, n: usize) -> [f64; 2] {
    if n == 0 || total_dof == 0 {
        return [f64::NAN, f64::NAN];
    }
    let Ok(chi2) = ChiSquared::new(total_dof as f64) else {
        return [f64::NAN, f64::NAN];
    };
    [0.025, 0.975].map(|p| chi2.inverse_cdf(p) / n as f64)
}

pub(super) fn wrap_rad(a: f64) -> f64 {
    (a + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI
}

/// Scores a whole run at once. `truths` are frame truths (kind 0) in any order.
///
/// `n_rad_s` is the observer's mean motion, used to carry a frame's truth to the time of an EKF
/// state (the laser echo).
pub fn score(
    camera: &PinholeCamera,
    n_rad_s: f64,
    truths: &[Truth],
    detections: &[Detections],
    tracks: &[Tracks],
) -> DebrisScore {
    let expect = Expect {
        truth: true,
        detections: true,
        tracks: true,
    };
    let mut s = DebrisScorer::new(*camera, n_rad_s, expect, None);
    truths.iter().for_each(|t| s.take_truth(t));
    detections.iter().for_each(|d| s.take_detections(d));
    tracks.iter().for_each(|t| s.take_tracks(t));
    s.finish();
    s.score()
}

#[cfg(test)]
mod tests {
    use super::*;
    use glint_physics::camera::angles_from_position;
    use nalgebra::Vector3;
    use shared_types::{Detection, TrackEstimate};

    fn camera() -> PinholeCamera {
        PinholeCamera::zhai2016()
    }

    fn truth(frame: u64, pos: [f64; 3], false_px: Option<[f64; 2]>) -> Truth {
        let mut t = Truth {
            frame_index: frame,
            n_debris: 1,
            ..Default::default()
        };
        t.debris_state_lvlh[0] = [pos[0], pos[1], pos[2], 1.0, 0.0, 0.0];
        if let Some(f) = false_px {
            t.n_false = 1;
            t.false_targets_px[0] = f;
        }
        t
    }

    fn detections(frame: u64, px: &[(f64, f64)]) -> Detections {
        let mut d = Detections {
            frame_index: frame,
            n: px.len() as u32,
            ..Default::default()
        };
        for (slot, (x, y)) in d.items.iter_mut().zip(px) {
            *slot = Detection {
                track_id: 7,
                end_x_px: *x,
                end_y_px: *y,
                x_px: *x,
                y_px: *y,
                ..Default::default()
            };
        }
        d
    }

    #[test]
    fn precision_recall_and_false_targets() {
        let cam = camera();
        let pos = [10_000.0, 100.0, 200.0];
        let (x, y) = cam.project(Vector3::from(pos)).unwrap();
        let truths = [
            truth(0, pos, Some([100.0, 100.0])),
            truth(1, pos, None),
            truth(2, pos, None),
        ];
        // Frame 1: a hit and a spurious detection; frame 2: the debris is missed.
        let dets = [
            detections(0, &[]),
            detections(1, &[(x + 1.0, y), (500.0, 500.0)]),
            detections(2, &[]),
        ];
        let s = score(&cam, 7.29e-5, &truths, &dets, &[]);
        assert_eq!(s.detection.true_positives, 1);
        assert_eq!(s.detection.false_positives, 1);
        assert_eq!(s.detection.missed, 1);
        assert_eq!(s.detection.precision, 0.5);
        assert_eq!(s.detection.recall, 0.5);
        assert_eq!(
            (
                s.detection.false_targets,
                s.detection.false_targets_rejected
            ),
            (1, 1)
        );
    }

    #[test]
    fn a_perfect_track_scores_zero_error_and_finite_nees() {
        let cam = camera();
        let pos = [10_000.0, 100.0, 200.0];
        let (x, y) = cam.project(Vector3::from(pos)).unwrap();
        let truths = [truth(0, pos, None), truth(1, pos, None)];
        let dets = [detections(0, &[]), detections(1, &[(x, y)])];
        let (az, el) = angles_from_position(Vector3::from(pos));
        let mut tr = Tracks {
            frame_index: 1,
            n: 1,
            ..Default::default()
        };
        let mut cov = [0.0; 36];
        for k in 0..6 {
            cov[k * 7] = 1.0;
        }
        tr.items[0] = TrackEstimate {
            track_id: 7,
            azimuth_meas_rad: az,
            elevation_meas_rad: el,
            azimuth_filt_rad: az,
            elevation_filt_rad: el,
            angles_valid: 1,
            state_lvlh: [pos[0] + 1.0, pos[1], pos[2], 1.0, 0.0, 0.0],
            covariance: cov,
            ekf_valid: 1,
            state_t_ns: truths[1].meta.t_ns,
            ..Default::default()
        };
        let s = score(&cam, 7.29e-5, &truths, &dets, &[tr]);
        let t = &s.targets[0];
        assert_eq!(t.track_id, Some(7));
        assert!(t.azimuth_err_deg_rms_filtered.abs() < 1e-12);
        assert!((t.pos_err_m_final - 1.0).abs() < 1e-9);
        assert!((t.nees_mean - 1.0).abs() < 1e-9);
    }

    #[test]
    fn nees_bounds_match_chi_square_quantiles() {
        // χ²(6) 95 % interval: [1.2373442457912, 14.449375335448] (bisection on the closed-form
        // CDF 1 − e^{−x/2}(1 + x/2 + x²/8)).
        let [lo, hi] = nees_bounds(1, 6);
        assert!(
            (lo - 1.237_344_245_791).abs() < 1e-9 && (hi - 14.449_375_335_448).abs() < 1e-9,
            "{lo} {hi}"
        );
        // Mean of 50 samples: χ²(300)/50, quantiles 253.912322602 and 349.874468830 (bisection
        // on the regularised incomplete gamma series).
        let [lo, hi] = nees_bounds(50, 6);
        assert!(
            (lo - 253.912_322_602 / 50.0).abs() < 1e-9
                && (hi - 349.874_468_830 / 50.0).abs() < 1e-9,
            "{lo} {hi}"
        );
    }
}
