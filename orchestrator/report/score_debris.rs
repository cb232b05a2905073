//! Scoring of the debris chain against truth ([002]; math.md §3.9): detection precision and
//! recall, false-target rejection, angle errors before and after the angle filter, EKF position
//! and velocity errors, and NEES. Pure: it reads the messages the orchestrator collected.
//!
//! Association: a detection is a true positive when its end-of-exposure point (eq 9) lies within
//! `gate_px` of a debris' projected position at the end of the exposure; each track is assigned
//! to the debris its detections hit most often.

use std::collections::BTreeMap;

use glint_physics::camera::{angles_from_position, PinholeCamera};
use glint_physics::cw::propagate_lvlhn;
use nalgebra::{Matrix6, Vector3, Vector6};
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

/// Per-frame series of one target, for plots.
#[derive(Debug, Clone, Default)]
pub struct TargetSeries {
    pub t_s: Vec<f64>,
    pub azimuth_meas_deg: Vec<f64>,
    pub azimuth_filt_deg: Vec<f64>,
    pub azimuth_true_deg: Vec<f64>,
    pub elevation_meas_deg: Vec<f64>,
    pub elevation_filt_deg: Vec<f64>,
    pub elevation_true_deg: Vec<f64>,
    /// EKF position error norm and its 3σ bound (3·sqrt(trace of the position covariance)).
    pub pos_err_m: Vec<f64>,
    pub pos_3sigma_m: Vec<f64>,
}

pub struct DebrisScore {
    pub detection: DetectionScore,
    pub targets: Vec<TargetScore>,
    pub series: Vec<TargetSeries>,
}

fn rms(v: &[f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt()
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

fn wrap_rad(a: f64) -> f64 {
    (a + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI
}

/// Scores a run. `truths` are frame truths (kind 0) in any order.
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
    let truth_by_frame: BTreeMap<u64, &Truth> = truths
        .iter()
        .filter(|t| t.kind == Truth::KIND_FRAME)
        .map(|t| (t.frame_index, t))
        .collect();
    let n_debris = truth_by_frame
        .values()
        .next()
        .map_or(0, |t| t.n_debris as usize);
    let project = |t: &Truth, i: usize| {
        let s = t.debris_state_lvlh[i];
        camera.project(Vector3::new(s[0], s[1], s[2]))
    };

    // Detection precision / recall and track → debris votes.
    let (mut tp, mut fp, mut missed, mut frames_scored) = (0u64, 0u64, 0u64, 0u64);
    let mut votes: BTreeMap<u32, BTreeMap<usize, u64>> = BTreeMap::new();
    let first_frame = truth_by_frame.keys().next().copied().unwrap_or(0);
    for d in detections {
        let Some(t) = truth_by_frame.get(&d.frame_index) else {
            continue;
        };
        if d.frame_index == first_frame {
            continue;
        }
        frames_scored += 1;
        let mut taken = vec![false; n_debris];
        for det in &d.items[..d.n as usize] {
            let best = (0..n_debris)
                .filter(|&i| !taken[i])
                .filter_map(|i| {
                    project(t, i).map(|(x, y)| (i, (x - det.end_x_px).hypot(y - det.end_y_px)))
                })
                .filter(|(_, dist)| *dist <= GATE_PX)
                .min_by(|a, b| a.1.total_cmp(&b.1));
            match best {
                Some((i, _)) => {
                    taken[i] = true;
                    tp += 1;
                    *votes.entry(det.track_id).or_default().entry(i).or_default() += 1;
                }
                None => fp += 1,
            }
        }
        let visible = (0..n_debris)
            .filter(|&i| project(t, i).is_some_and(|(x, y)| camera.contains(x, y)))
            .count();
        missed += visible.saturating_sub(taken.iter().filter(|x| **x).count()) as u64;
    }

    // False targets: rejected when no detection of their frame or the next lies on them.
    let (mut false_total, mut false_rejected) = (0u64, 0u64);
    for t in truth_by_frame.values() {
        for ft in &t.false_targets_px[..t.n_false as usize] {
            false_total += 1;
            let reported = detections
                .iter()
                .filter(|d| d.frame_index == t.frame_index || d.frame_index == t.frame_index + 1)
                .flat_map(|d| d.items[..d.n as usize].iter())
                .any(|det| (det.x_px - ft[0]).hypot(det.y_px - ft[1]) <= GATE_PX);
            false_rejected += (!reported) as u64;
        }
    }

    let track_to_debris: BTreeMap<u32, usize> = votes
        .iter()
        .filter_map(|(tid, v)| v.iter().max_by_key(|(_, c)| **c).map(|(i, _)| (*tid, *i)))
        .collect();

    let sigma_of: BTreeMap<(u64, u32), f64> = detections
        .iter()
        .flat_map(|d| {
            d.items[..d.n as usize]
                .iter()
                .map(move |det| ((d.frame_index, det.track_id), det.sigma_rad))
        })
        .collect();
    let mut targets = vec![];
    let mut series = vec![];
    for i in 0..n_debris {
        // The track that follows debris i for the most frames.
        let track_id = track_to_debris
            .iter()
            .filter(|(_, d)| **d == i)
            .max_by_key(|(tid, _)| votes[*tid][&i])
            .map(|(tid, _)| *tid);
        let mut s = TargetSeries::default();
        let (mut az_m, mut az_f, mut el_m, mut el_f, mut direct) =
            (vec![], vec![], vec![], vec![], vec![]);
        let mut nees = vec![];
        let mut normalized = vec![];
        let (mut shots, mut hits, mut frames_tracked) = (0u64, 0u64, 0u64);
        let mut last: Option<(Vector6<f64>, Vector6<f64>)> = None;
        for tr in tracks {
            let Some(t) = truth_by_frame.get(&tr.frame_index) else {
                continue;
            };
            let Some(est) = tr.items[..tr.n as usize]
                .iter()
                .find(|e| Some(e.track_id) == track_id)
            else {
                continue;
            };
            frames_tracked += 1;
            let x_true = Vector6::from_column_slice(&t.debris_state_lvlh[i]);
            let (az_t, el_t) = angles_from_position(x_true.fixed_rows::<3>(0).into_owned());
            // Truth at the time of the state estimate (the echo when a range was applied).
            let dt_s = (est.state_t_ns as f64 - t.meta.t_ns as f64) * 1e-9;
            let x_true_state = if dt_s.abs() > 0.0 {
                propagate_lvlhn(x_true, n_rad_s, dt_s)
            } else {
                x_true
            };
            let deg = f64::to_degrees;
            if let Some(sigma) = sigma_of
                .get(&(tr.frame_index, est.track_id))
                .filter(|s| **s > 0.0)
            {
                normalized.push(wrap_rad(est.azimuth_meas_rad - az_t) / sigma);
                normalized.push((est.elevation_meas_rad - el_t) / sigma);
            }
            az_m.push(deg(wrap_rad(est.azimuth_meas_rad - az_t)));
            el_m.push(deg(est.elevation_meas_rad - el_t));
            if est.angles_valid == 1 {
                az_f.push(deg(wrap_rad(est.azimuth_filt_rad - az_t)));
                el_f.push(deg(est.elevation_filt_rad - el_t));
            }
            s.t_s.push(t.meta.t_ns as f64 * 1e-9);
            s.azimuth_meas_deg.push(deg(est.azimuth_meas_rad));
            s.azimuth_filt_deg.push(if est.angles_valid == 1 {
                deg(est.azimuth_filt_rad)
            } else {
                f64::NAN
            });
            s.azimuth_true_deg.push(deg(az_t));
            s.elevation_meas_deg.push(deg(est.elevation_meas_rad));
            s.elevation_filt_deg.push(if est.angles_valid == 1 {
                deg(est.elevation_filt_rad)
            } else {
                f64::NAN
            });
            s.elevation_true_deg.push(deg(el_t));
            if est.range_status != u32::MAX {
                shots += 1;
                hits += (est.range_status == shared_types::RangeStatus::Hit as u32) as u64;
            }
            if est.direct_position_m.iter().all(|v| v.is_finite())
                && est.range_status == shared_types::RangeStatus::Hit as u32
            {
                direct.push(
                    (Vector3::from_column_slice(&est.direct_position_m)
                        - x_true_state.fixed_rows::<3>(0))
                    .norm(),
                );
            }
            if est.ekf_valid == 1 {
                let x = Vector6::from_column_slice(&est.state_lvlh);
                let p = Matrix6::from_row_slice(&est.covariance);
                let e = x - x_true_state;
                if let Some(pinv) = p.try_inverse() {
                    nees.push((e.transpose() * pinv * e)[(0, 0)]);
                }
                s.pos_err_m.push(e.fixed_rows::<3>(0).norm());
                s.pos_3sigma_m
                    .push(3.0 * (p[(0, 0)] + p[(1, 1)] + p[(2, 2)]).max(0.0).sqrt());
                last = Some((x, x_true_state));
            }
        }
        let (pos_final, vel_final) = last.map_or((f64::NAN, f64::NAN), |(x, xt)| {
            let e = x - xt;
            (e.fixed_rows::<3>(0).norm(), e.fixed_rows::<3>(3).norm())
        });
        targets.push(TargetScore {
            id: i as u32 + 1,
            track_id,
            frames_tracked,
            azimuth_err_deg_rms_measured: rms(&az_m),
            azimuth_err_deg_rms_filtered: rms(&az_f),
            elevation_err_deg_rms_measured: rms(&el_m),
            elevation_err_deg_rms_filtered: rms(&el_f),
            pos_err_m_rms_direct: rms(&direct),
            pos_err_m_final: pos_final,
            vel_err_mps_final: vel_final,
            nees_mean: if nees.is_empty() {
                f64::NAN
            } else {
                nees.iter().sum::<f64>() / nees.len() as f64
            },
            nees_final: nees.last().copied().unwrap_or(f64::NAN),
            angle_err_normalized_rms: rms(&normalized),
            nees_bounds: nees_bounds(nees.len(), 6),
            laser_shots: shots,
            laser_hits: hits,
        });
        series.push(s);
    }
    let ratio = |a: u64, b: u64| {
        if b == 0 {
            f64::NAN
        } else {
            a as f64 / b as f64
        }
    };
    DebrisScore {
        detection: DetectionScore {
            precision: ratio(tp, tp + fp),
            recall: ratio(tp, tp + missed),
            true_positives: tp,
            false_positives: fp,
            missed,
            frames_scored,
            false_targets: false_total,
            false_targets_rejected: false_rejected,
        },
        targets,
        series,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
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
