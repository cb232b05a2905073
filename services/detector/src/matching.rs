//! Inter-frame matching of blobs (docs/math.md §3.4: feature gates, centroid gate eq 8, end
//! point eq 9).
//!
//! Each blob is described by (m00, a, θ, e) from the configured moment set
//! ([`MatcherConfig::features`], binary by default as in the seed; the weighted set makes m00 the
//! flux in DN). A blob of frame k matches an object of an earlier frame when all gates pass:
//!
//! - `|Δm00| ≤ max(0.2 m00, m00_tol_min)` and `|Δa| ≤ max(0.2 a, a_tol_min_px)` (the floors only
//!   bite on blobs of a few pixels, whose area cannot change by less than one pixel);
//! - `|Δθ| mod 180° ≤ 5°`, **skipped when either e < 0.3**: θ of a near-round blob is noise;
//! - `|Δe| ≤ 0.05`, skipped when both e < 0.3 (`e = sqrt(1 − b²/a²)` has infinite slope at b = a);
//! - centroid distance to the predicted centroid `≤ Δf (t_ep + t_in)(2a/t_ep) + δ_l` (eq 8 for
//!   Δf frames; a = the larger of the two blobs' a), where the prediction is the previous
//!   centroid plus Δf times the last per-frame displacement (zero until an object has been
//!   matched once, which makes the gate exactly eq 8 around the previous centroid).
//!
//! A blob touching the image border is clipped: its area, a and e change, its centroid moves
//! inward by up to a, and its θ gets noisier as it shortens. If either blob touches the border,
//! the m00, a and e gates are skipped, the centroid gate grows by the previous a, and T_θ grows
//! by the ratio of the two a (larger/smaller); θ and the centroid gate still apply.
//!
//! Pairs passing the gates are assigned one-to-one greedily by the smallest normalised distance
//! `Σ (Δ_i / T_i)²` over the applied gates (including the centroid term `(d/l_thr)²`).
//!
//! Object life cycle: an unmatched blob becomes a *candidate*. A candidate matched in the next
//! frame becomes a track with a new persistent id; a candidate not matched in the next frame is
//! a false target and is reported in `rejected_previous` (the seed's rule: a false target appears
//! in one frame only). A track that misses a frame *coasts* on its prediction for up to
//! `max_coast_frames` frames, so a debris whose streak briefly merges with another (crossing
//! streaks: the merged blob fails the area gate of both) keeps its id when the streaks separate.
//!
//! End point (eq 9), the position at the end of the current exposure:
//! `[u_t, v_t] = [u_c, v_c] + t_ep / (2 (t_ep + t_in)) · ([u_c, v_c] − [u_c', v_c']) / Δf`,
//! with the centroids of the configured [`MatcherConfig::centroid`] set (weighted by default:
//! it is the more precise one).

use crate::moments::{Blob, Ellipse, FeatureSet};
use crate::ConfigError;

/// Matching thresholds and timing. Units in the names; defaults are the §3.4 \[ASSUMP\] values.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MatcherConfig {
    /// Exposure t_ep \[s\], > 0. Default 0.02.
    pub exposure_s: f64,
    /// Gap between exposures t_in \[s\], ≥ 0. Default 0.02.
    pub interval_s: f64,
    /// Moment set of the gated features (m00, a, θ, e). Default binary.
    pub features: FeatureSet,
    /// Moment set of the centroids used for the gate, the velocity and the end point.
    /// Default weighted.
    pub centroid: FeatureSet,
    /// T_m as a fraction of the previous m00, ≥ 0. Default 0.2.
    pub m00_tol_frac: f64,
    /// Floor of T_m in m00 units (px or DN), ≥ 0. Default 1.
    pub m00_tol_min: f64,
    /// T_a as a fraction of the previous a, ≥ 0. Default 0.2.
    pub a_tol_frac: f64,
    /// Floor of T_a \[px\], ≥ 0. Default 0.5.
    pub a_tol_min_px: f64,
    /// T_θ \[rad\], in (0, π/2]. Default 5°.
    pub theta_tol_rad: f64,
    /// T_e, > 0. Default 0.05.
    pub ecc_tol: f64,
    /// Blobs with e below this are round: no θ gate (and no e gate if both are round). In
    /// \[0, 1\]. Default 0.3.
    pub round_ecc: f64,
    /// δ_l of eq 8 \[px\], ≥ 0. Default 3.
    pub gate_margin_px: f64,
    /// Frames a track may miss before it is lost, ≥ 0. Default 2.
    pub max_coast_frames: u32,
}

impl Default for MatcherConfig {
    fn default() -> Self {
        Self {
            exposure_s: 0.02,
            interval_s: 0.02,
            features: FeatureSet::Binary,
            centroid: FeatureSet::Weighted,
            m00_tol_frac: 0.2,
            m00_tol_min: 1.0,
            a_tol_frac: 0.2,
            a_tol_min_px: 0.5,
            theta_tol_rad: 5f64.to_radians(),
            ecc_tol: 0.05,
            round_ecc: 0.3,
            gate_margin_px: 3.0,
            max_coast_frames: 2,
        }
    }
}

impl MatcherConfig {
    /// Checks every field against its documented range.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let checks: [(&'static str, f64, bool, &'static str); 10] = [
            ("exposure_s", self.exposure_s, self.exposure_s > 0.0, "> 0"),
            ("interval_s", self.interval_s, self.interval_s >= 0.0, "≥ 0"),
            (
                "m00_tol_frac",
                self.m00_tol_frac,
                self.m00_tol_frac >= 0.0,
                "≥ 0",
            ),
            (
                "m00_tol_min",
                self.m00_tol_min,
                self.m00_tol_min >= 0.0,
                "≥ 0",
            ),
            ("a_tol_frac", self.a_tol_frac, self.a_tol_frac >= 0.0, "≥ 0"),
            (
                "a_tol_min_px",
                self.a_tol_min_px,
                self.a_tol_min_px >= 0.0,
                "≥ 0",
            ),
            (
                "theta_tol_rad",
                self.theta_tol_rad,
                self.theta_tol_rad > 0.0 && self.theta_tol_rad <= std::f64::consts::FRAC_PI_2,
                "(0, π/2]",
            ),
            ("ecc_tol", self.ecc_tol, self.ecc_tol > 0.0, "> 0"),
            (
                "round_ecc",
                self.round_ecc,
                (0.0..=1.0).contains(&self.round_ecc),
                "[0, 1]",
            ),
            (
                "gate_margin_px",
                self.gate_margin_px,
                self.gate_margin_px >= 0.0,
                "≥ 0",
            ),
        ];
        for (field, value, ok, allowed) in checks {
            if !ok || !value.is_finite() {
                return Err(ConfigError::new(field, value, allowed));
            }
        }
        Ok(())
    }

    /// Frame period `t_ep + t_in` \[s\].
    pub fn frame_period_s(&self) -> f64 {
        self.exposure_s + self.interval_s
    }
}

/// A blob assigned to a track in the current frame.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MatchedDetection {
    /// Persistent track id (assigned when a candidate is first matched).
    pub track_id: u64,
    /// Index into the `blobs` slice given to [`Matcher::update`].
    pub blob_index: usize,
    /// Centroid \[x, y\] \[px\] (configured centroid set).
    pub centroid_px: [f64; 2],
    /// Eq 9: position at the end of the current exposure \[x, y\] \[px\].
    pub end_point_px: [f64; 2],
    /// Centroid displacement per frame \[x, y\] \[px/frame\].
    pub velocity_px_per_frame: [f64; 2],
    /// Frames since the track's previous detection (1 unless it coasted).
    pub frames_since_previous: u64,
    /// Detections of this track including this one (≥ 2).
    pub hits: u32,
    /// This match turned a candidate into a track.
    pub new_track: bool,
    /// Normalised feature distance of the assignment.
    pub feature_distance: f64,
}

/// An object of the previous frame that matched nothing: a false target.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RejectedObject {
    /// Frame in which it was seen.
    pub frame_index: u64,
    pub centroid_px: [f64; 2],
    pub m00: f64,
}

/// A track that missed more than `max_coast_frames` frames.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LostTrack {
    pub track_id: u64,
    pub last_frame_index: u64,
    pub centroid_px: [f64; 2],
    pub hits: u32,
}

/// The outcome of one [`Matcher::update`].
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MatchResult {
    pub frame_index: u64,
    pub matched: Vec<MatchedDetection>,
    /// Candidates of the previous frame without a match (false targets).
    pub rejected_previous: Vec<RejectedObject>,
    /// Indices of blobs that matched nothing; they are candidates for the next frame.
    pub new_candidates: Vec<usize>,
    /// Tracks not detected in this frame but kept on their prediction.
    pub coasting: Vec<u64>,
    pub lost_tracks: Vec<LostTrack>,
    /// Indices of blobs with non-finite features (ignored).
    pub invalid_blobs: Vec<usize>,
}

/// Matching failure.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum MatchError {
    #[error("frame index {got} does not follow the previous frame {previous}")]
    NonIncreasingFrame { previous: u64, got: u64 },
}

/// What the matcher remembers of an object.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Object {
    track_id: Option<u64>,
    features: Ellipse,
    centroid: [f64; 2],
    velocity: Option<[f64; 2]>,
    touches_border: bool,
    last_frame: u64,
    hits: u32,
}

/// Frame-to-frame matcher with persistent track ids.
#[derive(Debug, Clone)]
pub struct Matcher {
    config: MatcherConfig,
    objects: Vec<Object>,
    last_frame: Option<u64>,
    next_track_id: u64,
    pairs: Vec<(f64, usize, usize)>,
}

mod gates;

/// What a matcher remembers between frames: its objects, the last frame, the next track id
/// (its settings come from the scenario).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MatcherState {
    objects: Vec<Object>,
    last_frame: Option<u64>,
    next_track_id: u64,
}

impl Matcher {
    /// What it remembers between frames.
    pub fn state(&self) -> MatcherState {
        MatcherState {
            objects: self.objects.clone(),
            last_frame: self.last_frame,
            next_track_id: self.next_track_id,
        }
    }

    /// Remembers `state` instead (a restored checkpoint): the next frame matches as it would
    /// have after the frames `state` was taken from.
    pub fn restore(&mut self, state: MatcherState) {
        self.objects = state.objects;
        self.last_frame = state.last_frame;
        self.next_track_id = state.next_track_id;
    }

    /// A matcher for validated settings; track ids start at 1.
    pub fn new(config: MatcherConfig) -> Result<Self, ConfigError> {
        config.validate()?;
        Ok(Self {
            config,
            objects: Vec::new(),
            last_frame: None,
            next_track_id: 1,
            pairs: Vec::new(),
        })
    }

    pub fn config(&self) -> &MatcherConfig {
        &self.config
    }

    /// Forgets every object (track ids keep increasing).
    pub fn reset(&mut self) {
        self.objects.clear();
        self.last_frame = None;
    }

    /// Number of live tracks (matched at least once and not lost).
    pub fn track_count(&self) -> usize {
        self.objects.iter().filter(|o| o.track_id.is_some()).count()
    }

    /// Matches the blobs of frame `frame_index` against the remembered objects.
    pub fn update(&mut self, blobs: &[Blob], frame_index: u64) -> Result<MatchResult, MatchError> {
        if let Some(previous) = self.last_frame {
            if frame_index <= previous {
                return Err(MatchError::NonIncreasingFrame {
                    previous,
                    got: frame_index,
                });
            }
        }
        self.last_frame = Some(frame_index);
        let mut result = MatchResult {
            frame_index,
            ..MatchResult::default()
        };
        let cfg = self.config;
        let valid: Vec<bool> = blobs.iter().map(gates::is_finite).collect();
        self.pairs.clear();
        for (i, obj) in self.objects.iter().enumerate() {
            for (j, blob) in blobs.iter().enumerate() {
                if valid[j] {
                    if let Some(cost) = gates::gate(&cfg, obj, blob, frame_index) {
                        self.pairs.push((cost, i, j));
                    }
                }
            }
        }
        self.pairs
            .sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
        let mut obj_used = vec![false; self.objects.len()];
        let mut blob_used = vec![false; blobs.len()];
        let mut next = Vec::with_capacity(self.objects.len() + blobs.len());
        let pairs = std::mem::take(&mut self.pairs);
        for &(cost, i, j) in &pairs {
            if obj_used[i] || blob_used[j] {
                continue;
            }
            obj_used[i] = true;
            blob_used[j] = true;
            let (detection, object) = self.assign(i, j, &blobs[j], cost, frame_index);
            result.matched.push(detection);
            next.push(object);
        }
        self.pairs = pairs;
        result.matched.sort_by_key(|d| d.blob_index);
        for (obj, _) in self
            .objects
            .iter()
            .zip(&obj_used)
            .filter(|(_, used)| !**used)
        {
            match obj.track_id {
                None => result.rejected_previous.push(RejectedObject {
                    frame_index: obj.last_frame,
                    centroid_px: obj.centroid,
                    m00: obj.features.m00,
                }),
                Some(track_id)
                    if frame_index - obj.last_frame <= u64::from(cfg.max_coast_frames) =>
                {
                    result.coasting.push(track_id);
                    next.push(*obj);
                }
                Some(track_id) => result.lost_tracks.push(LostTrack {
                    track_id,
                    last_frame_index: obj.last_frame,
                    centroid_px: obj.centroid,
                    hits: obj.hits,
                }),
            }
        }
        for (j, blob) in blobs.iter().enumerate() {
            if !valid[j] {
                result.invalid_blobs.push(j);
            } else if !blob_used[j] {
                result.new_candidates.push(j);
                next.push(Object {
                    track_id: None,
                    features: blob.ellipse(cfg.features),
                    centroid: gates::centroid(&cfg, blob),
                    velocity: None,
                    touches_border: blob.touches_border,
                    last_frame: frame_index,
                    hits: 1,
                });
            }
        }
        self.objects = next;
        Ok(result)
    }

    /// Builds the detection and the updated object for the pair (object i, blob j).
    fn assign(
        &mut self,
        i: usize,
        j: usize,
        blob: &Blob,
        cost: f64,
        frame_index: u64,
    ) -> (MatchedDetection, Object) {
        let cfg = &self.config;
        let obj = self.objects[i];
        let frames = frame_index - obj.last_frame;
        let c = gates::centroid(cfg, blob);
        let df = frames as f64;
        let v = [(c[0] - obj.centroid[0]) / df, (c[1] - obj.centroid[1]) / df];
        // Eq 9: the streak end is half an exposure of motion beyond the centroid.
        let k = cfg.exposure_s / (2.0 * cfg.frame_period_s());
        let end = [c[0] + k * v[0], c[1] + k * v[1]];
        let new_track = obj.track_id.is_none();
        let track_id = obj.track_id.unwrap_or_else(|| {
            let id = self.next_track_id;
            self.next_track_id += 1;
            id
        });
        let hits = obj.hits.saturating_add(1);
        let detection = MatchedDetection {
            track_id,
            blob_index: j,
            centroid_px: c,
            end_point_px: end,
            velocity_px_per_frame: v,
            frames_since_previous: frames,
            hits,
            new_track,
            feature_distance: cost,
        };
        let object = Object {
            track_id: Some(track_id),
            features: blob.ellipse(cfg.features),
            centroid: c,
            velocity: Some(v),
            touches_border: blob.touches_border,
            last_frame: frame_index,
            hits,
        };
        (detection, object)
    }
}

#[cfg(test)]
mod tests;
