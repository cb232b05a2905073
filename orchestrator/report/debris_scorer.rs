//! The debris chain scored as its messages arrive ([`DebrisScorer`]), in memory that does
//! not grow with the run; [`super::score_debris::score`] runs it over a whole run at once.

use std::collections::BTreeMap;

use glint_physics::camera::{angles_from_position, PinholeCamera};
use glint_physics::cw::propagate_lvlhn;
use nalgebra::{Matrix6, Vector3, Vector6};
use shared_types::{Detections, Tracks, Truth};

use super::score_debris::{
    nees_bounds, wrap_rad, DebrisScore, DetectionScore, SeriesPoint, TargetScore, TargetSeries,
    GATE_PX,
};

/// A root mean square in constant memory (the squares summed in the order taken).
#[derive(Debug, Clone, Copy, Default)]
struct Rms {
    sum_sq: f64,
    n: usize,
}

impl Rms {
    fn push(&mut self, x: f64) {
        self.sum_sq += x * x;
        self.n += 1;
    }
    fn value(&self) -> f64 {
        if self.n == 0 {
            return f64::NAN;
        }
        (self.sum_sq / self.n as f64).sqrt()
    }
}

/// What a track scored against one debris, frame by frame; the debris' score is its pair
/// with the track that followed it most often, known only when the run has ended.
#[derive(Default)]
struct PairScore {
    frames_tracked: u64,
    az_m: Rms,
    az_f: Rms,
    el_m: Rms,
    el_f: Rms,
    direct: Rms,
    normalized: Rms,
    nees_sum: f64,
    nees_n: usize,
    nees_last: Option<f64>,
    shots: u64,
    hits: u64,
    last: Option<(Vector6<f64>, Vector6<f64>)>,
    series: TargetSeries,
}

/// One frame's messages, joined by frame index.
#[derive(Default)]
struct Parts {
    truth: Option<Truth>,
    detections: Option<Detections>,
    tracks: Option<Tracks>,
}

/// Which of a frame's [`Parts`] a run delivers.
#[derive(Debug, Clone, Copy)]
pub struct Expect {
    pub truth: bool,
    pub detections: bool,
    pub tracks: bool,
}

/// The debris chain scored as its messages arrive, in memory that does not grow with the
/// run: a frame's truth, detections and tracks are joined by frame index, scored in frame
/// order as soon as each is in (or can no longer come: its topic has moved past it), then
/// forgotten. [`DebrisScorer::score`] gives what [`score`] gives on the whole run.
pub struct DebrisScorer {
    camera: PinholeCamera,
    n_rad_s: f64,
    expect: Expect,
    /// The frame whose truth and detections are kept for the annotated picture.
    picture: Option<u64>,
    pub picture_truth: Option<Truth>,
    pub picture_detections: Option<Detections>,
    pending: BTreeMap<u64, Parts>,
    /// Per part, the newest frame index taken.
    newest: [Option<u64>; 3],
    n_debris: Option<usize>,
    first_frame: Option<u64>,
    tp: u64,
    fp: u64,
    missed: u64,
    frames_scored: u64,
    votes: BTreeMap<u32, BTreeMap<usize, u64>>,
    false_total: u64,
    false_rejected: u64,
    /// The false targets of a frame no detection of its own lay on: the next frame's may.
    open_false: Option<(u64, Vec<[f64; 2]>)>,
    pairs: BTreeMap<(u32, usize), PairScore>,
    /// Every estimate that carried a laser shot, whatever debris it followed.
    pub laser_shots: u64,
}

impl DebrisScorer {
    pub fn new(camera: PinholeCamera, n_rad_s: f64, expect: Expect, picture: Option<u64>) -> Self {
        DebrisScorer {
            camera,
            n_rad_s,
            expect,
            picture,
            picture_truth: None,
            picture_detections: None,
            pending: BTreeMap::new(),
            newest: [None; 3],
            n_debris: None,
            first_frame: None,
            tp: 0,
            fp: 0,
            missed: 0,
            frames_scored: 0,
            votes: BTreeMap::new(),
            false_total: 0,
            false_rejected: 0,
            open_false: None,
            pairs: BTreeMap::new(),
            laser_shots: 0,
        }
    }

    pub fn take_truth(&mut self, t: &Truth) {
        if t.kind != Truth::KIND_FRAME {
            return;
        }
        self.pending.entry(t.frame_index).or_default().truth = Some(*t);
        self.arrived(0, t.frame_index);
    }

    pub fn take_detections(&mut self, d: &Detections) {
        self.pending.entry(d.frame_index).or_default().detections = Some(*d);
        self.arrived(1, d.frame_index);
    }

    pub fn take_tracks(&mut self, t: &Tracks) {
        self.laser_shots += (t.items[..(t.n as usize).min(t.items.len())].iter())
            .filter(|e| e.range_status != u32::MAX)
            .count() as u64;
        self.pending.entry(t.frame_index).or_default().tracks = Some(*t);
        self.arrived(2, t.frame_index);
    }

    fn arrived(&mut self, part: usize, frame: u64) {
        self.newest[part] = Some(self.newest[part].map_or(frame, |n| n.max(frame)));
        while let Some((&k, parts)) = self.pending.first_key_value() {
            // A part is in, or its topic has moved past this frame (in order: it never comes).
            let settled = |has: bool, expected: bool, p: usize| {
                has || !expected || self.newest[p].is_some_and(|n| n > k)
            };
            let ready = settled(parts.truth.is_some(), self.expect.truth, 0)
                && settled(parts.detections.is_some(), self.expect.detections, 1)
                && settled(parts.tracks.is_some(), self.expect.tracks, 2);
            if !ready {
                break;
            }
            let parts = self.pending.pop_first().map(|(_, p)| p).unwrap_or_default();
            self.frame(k, parts);
        }
    }

    /// Scores what is still pending: the run has ended.
    pub fn finish(&mut self) {
        while let Some((k, parts)) = self.pending.pop_first() {
            self.frame(k, parts);
        }
        if let Some((_, open)) = self.open_false.take() {
            self.false_rejected += open.len() as u64;
        }
    }

    fn project(&self, t: &Truth, i: usize) -> Option<(f64, f64)> {
        let s = t.debris_state_lvlh[i];
        self.camera.project(Vector3::new(s[0], s[1], s[2]))
    }

    /// Scores frame `k`.
    fn frame(&mut self, k: u64, parts: Parts) {
        if Some(k) == self.picture {
            self.picture_truth = parts.truth;
            self.picture_detections = parts.detections;
        }
        // The previous frame's false targets no detection of their own lay on: this frame's
        // detections may (when it is the next one), or none ever will.
        if let Some((f, open)) = self.open_false.take() {
            let still_open = match (&parts.detections, k == f + 1) {
                (Some(d), true) => open
                    .into_iter()
                    .filter(|ft| !lies_on(d, *ft))
                    .collect::<Vec<_>>(),
                _ => open,
            };
            self.false_rejected += still_open.len() as u64;
        }
        let Some(t) = parts.truth else {
            return;
        };
        let n_debris = *self.n_debris.get_or_insert(t.n_debris as usize);
        let first_frame = *self.first_frame.get_or_insert(k);
        if let Some(d) = &parts.detections {
            self.detections(&t, d, n_debris, first_frame);
        }
        let falses = &t.false_targets_px[..t.n_false as usize];
        self.false_total += falses.len() as u64;
        let open: Vec<[f64; 2]> = (falses.iter().copied())
            .filter(|ft| parts.detections.as_ref().is_none_or(|d| !lies_on(d, *ft)))
            .collect();
        if !open.is_empty() {
            self.open_false = Some((k, open));
        }
        if let Some(tr) = &parts.tracks {
            self.tracks(&t, parts.detections.as_ref(), tr, n_debris);
        }
    }

    /// Detection precision and recall, and the track → debris votes.
    fn detections(&mut self, t: &Truth, d: &Detections, n_debris: usize, first_frame: u64) {
        if d.frame_index == first_frame {
            return;
        }
        self.frames_scored += 1;
        let mut taken = vec![false; n_debris];
        for det in &d.items[..d.n as usize] {
            let best = (0..n_debris)
                .filter(|&i| !taken[i])
                .filter_map(|i| {
                    self.project(t, i)
                        .map(|(x, y)| (i, (x - det.end_x_px).hypot(y - det.end_y_px)))
                })
                .filter(|(_, dist)| *dist <= GATE_PX)
                .min_by(|a, b| a.1.total_cmp(&b.1));
            match best {
                Some((i, _)) => {
                    taken[i] = true;
                    self.tp += 1;
                    *(self.votes.entry(det.track_id).or_default())
                        .entry(i)
                        .or_default() += 1;
                }
                None => self.fp += 1,
            }
        }
        let visible = (0..n_debris)
            .filter(|&i| {
                self.project(t, i)
                    .is_some_and(|(x, y)| self.camera.contains(x, y))
            })
            .count();
        self.missed += visible.saturating_sub(taken.iter().filter(|x| **x).count()) as u64;
    }

    /// Every track's estimate of this frame against every debris.
    fn tracks(&mut self, t: &Truth, d: Option<&Detections>, tr: &Tracks, n_debris: usize) {
        let deg = f64::to_degrees;
        let mut seen: Vec<u32> = vec![];
        for est in &tr.items[..tr.n as usize] {
            // A track's first estimate in the frame is its estimate.
            if seen.contains(&est.track_id) {
                continue;
            }
            seen.push(est.track_id);
            // The detection's claimed 1σ (the last of this track's detections in the frame).
            let sigma = d.and_then(|d| {
                (d.items[..d.n as usize].iter())
                    .rev()
                    .find(|det| det.track_id == est.track_id)
                    .map(|det| det.sigma_rad)
            });
            let x = Vector6::from_column_slice(&est.state_lvlh);
            let p = Matrix6::from_row_slice(&est.covariance);
            let pinv = (est.ekf_valid == 1).then(|| p.try_inverse()).flatten();
            let dt_s = (est.state_t_ns as f64 - t.meta.t_ns as f64) * 1e-9;
            for i in 0..n_debris {
                let x_true = Vector6::from_column_slice(&t.debris_state_lvlh[i]);
                let (az_t, el_t) = angles_from_position(x_true.fixed_rows::<3>(0).into_owned());
                // Truth at the time of the state estimate (the echo when a range was applied).
                let x_true_state = if dt_s.abs() > 0.0 {
                    propagate_lvlhn(x_true, self.n_rad_s, dt_s)
                } else {
                    x_true
                };
                let voted = self
                    .votes
                    .get(&est.track_id)
                    .is_some_and(|v| v.contains_key(&i));
                let pair = self.pairs.entry((est.track_id, i)).or_default();
                pair.frames_tracked += 1;
                if let Some(sigma) = sigma.filter(|s| *s > 0.0) {
                    pair.normalized
                        .push(wrap_rad(est.azimuth_meas_rad - az_t) / sigma);
                    pair.normalized
                        .push((est.elevation_meas_rad - el_t) / sigma);
                }
                pair.az_m.push(deg(wrap_rad(est.azimuth_meas_rad - az_t)));
                pair.el_m.push(deg(est.elevation_meas_rad - el_t));
                if est.angles_valid == 1 {
                    pair.az_f.push(deg(wrap_rad(est.azimuth_filt_rad - az_t)));
                    pair.el_f.push(deg(est.elevation_filt_rad - el_t));
                }
                if est.range_status != u32::MAX {
                    pair.shots += 1;
                    pair.hits += (est.range_status == shared_types::RangeStatus::Hit as u32) as u64;
                }
                if est.direct_position_m.iter().all(|v| v.is_finite())
                    && est.range_status == shared_types::RangeStatus::Hit as u32
                {
                    pair.direct.push(
                        (Vector3::from_column_slice(&est.direct_position_m)
                            - x_true_state.fixed_rows::<3>(0))
                        .norm(),
                    );
                }
                let mut pos_err_m = None;
                if est.ekf_valid == 1 {
                    let e = x - x_true_state;
                    if let Some(pinv) = &pinv {
                        let nees = (e.transpose() * pinv * e)[(0, 0)];
                        pair.nees_sum += nees;
                        pair.nees_n += 1;
                        pair.nees_last = Some(nees);
                    }
                    pos_err_m = Some((
                        e.fixed_rows::<3>(0).norm(),
                        3.0 * (p[(0, 0)] + p[(1, 1)] + p[(2, 2)]).max(0.0).sqrt(),
                    ));
                    pair.last = Some((x, x_true_state));
                }
                // Plots follow a track's debris: the pairs it has been seen on.
                if voted {
                    let filt = |v: f64| {
                        if est.angles_valid == 1 {
                            deg(v)
                        } else {
                            f64::NAN
                        }
                    };
                    pair.series.push(SeriesPoint {
                        t_s: t.meta.t_ns as f64 * 1e-9,
                        azimuth_meas_deg: deg(est.azimuth_meas_rad),
                        azimuth_filt_deg: filt(est.azimuth_filt_rad),
                        azimuth_true_deg: deg(az_t),
                        elevation_meas_deg: deg(est.elevation_meas_rad),
                        elevation_filt_deg: filt(est.elevation_filt_rad),
                        elevation_true_deg: deg(el_t),
                        pos_err_m,
                    });
                }
            }
        }
    }

    /// The score of everything taken so far (of the whole run after [`DebrisScorer::finish`]).
    pub fn score(&self) -> DebrisScore {
        let votes = &self.votes;
        let track_to_debris: BTreeMap<u32, usize> = votes
            .iter()
            .filter_map(|(tid, v)| v.iter().max_by_key(|(_, c)| **c).map(|(i, _)| (*tid, *i)))
            .collect();
        let empty = PairScore::default();
        let mut targets = vec![];
        let mut series = vec![];
        for i in 0..self.n_debris.unwrap_or(0) {
            // The track that follows debris i for the most frames.
            let track_id = track_to_debris
                .iter()
                .filter(|(_, d)| **d == i)
                .max_by_key(|(tid, _)| votes[*tid][&i])
                .map(|(tid, _)| *tid);
            let pair = track_id
                .and_then(|tid| self.pairs.get(&(tid, i)))
                .unwrap_or(&empty);
            let (pos_final, vel_final) = pair.last.map_or((f64::NAN, f64::NAN), |(x, xt)| {
                let e = x - xt;
                (e.fixed_rows::<3>(0).norm(), e.fixed_rows::<3>(3).norm())
            });
            targets.push(TargetScore {
                id: i as u32 + 1,
                track_id,
                frames_tracked: pair.frames_tracked,
                azimuth_err_deg_rms_measured: pair.az_m.value(),
                azimuth_err_deg_rms_filtered: pair.az_f.value(),
                elevation_err_deg_rms_measured: pair.el_m.value(),
                elevation_err_deg_rms_filtered: pair.el_f.value(),
                pos_err_m_rms_direct: pair.direct.value(),
                pos_err_m_final: pos_final,
                vel_err_mps_final: vel_final,
                nees_mean: if pair.nees_n == 0 {
                    f64::NAN
                } else {
                    pair.nees_sum / pair.nees_n as f64
                },
                nees_final: pair.nees_last.unwrap_or(f64::NAN),
                angle_err_normalized_rms: pair.normalized.value(),
                nees_bounds: nees_bounds(pair.nees_n, 6),
                laser_shots: pair.shots,
                laser_hits: pair.hits,
            });
            series.push(pair.series.clone());
        }
        let ratio = |a: u64, b: u64| {
            if b == 0 {
                f64::NAN
            } else {
                a as f64 / b as f64
            }
        };
        let (tp, fp, missed) = (self.tp, self.fp, self.missed);
        DebrisScore {
            detection: DetectionScore {
                precision: ratio(tp, tp + fp),
                recall: ratio(tp, tp + missed),
                true_positives: tp,
                false_positives: fp,
                missed,
                frames_scored: self.frames_scored,
                false_targets: self.false_total,
                false_targets_rejected: self.false_rejected,
            },
            targets,
            series,
        }
    }
}

/// Whether a detection of `d` lies on the false target at `ft` [px].
fn lies_on(d: &Detections, ft: [f64; 2]) -> bool {
    (d.items[..d.n as usize].iter())
        .any(|det| (det.x_px - ft[0]).hypot(det.y_px - ft[1]) <= GATE_PX)
}
