//! Matching tests on rendered frames (streaks crossing, clipped, appearing late, a one-frame
//! false target) and on hand-made blobs (eq 9, gates, errors).

use super::*;
use crate::segment::BoundingBox;
use crate::synth::{Canvas, Rng};
use crate::{Detector, DetectorConfig};

const T_EP: f64 = 0.02;
const T_FRAME: f64 = 0.04;

/// A target moving uniformly: position at time t \[px\].
#[derive(Clone, Copy)]
struct Mover {
    p0: (f64, f64),
    v_px_s: (f64, f64),
    first_frame: u64,
    last_frame: u64,
}

impl Mover {
    fn at(&self, t: f64) -> (f64, f64) {
        (self.p0.0 + self.v_px_s.0 * t, self.p0.1 + self.v_px_s.1 * t)
    }

    fn visible(&self, k: u64) -> bool {
        (self.first_frame..=self.last_frame).contains(&k)
    }

    /// The true position at the end of exposure k.
    fn end_of_exposure(&self, k: u64) -> (f64, f64) {
        self.at(k as f64 * T_FRAME + T_EP)
    }
}

/// Renders frame k (streaks = motion during the exposure) and detects its blobs.
fn detect_frame(movers: &[Mover], k: u64, w: usize, h: usize, det: &mut Detector) -> Vec<Blob> {
    let mut canvas = Canvas::new(w, h, 100.0);
    canvas.add_noise(2.0, &mut Rng::new(1000 + k));
    let t0 = k as f64 * T_FRAME;
    for m in movers.iter().filter(|m| m.visible(k)) {
        canvas.add_segment(m.at(t0), m.at(t0 + T_EP), 300.0, 0.8);
    }
    det.detect(&canvas.to_u16(), w, h)
        .expect("valid frame")
        .blobs
        .to_vec()
}

/// Runs frames 0..n and returns the per-frame results.
fn run(movers: &[Mover], n: u64, w: usize, h: usize) -> Vec<(Vec<Blob>, MatchResult)> {
    let mut det = Detector::new(DetectorConfig::default()).expect("default config");
    let mut matcher = Matcher::new(MatcherConfig::default()).expect("default config");
    (0..n)
        .map(|k| {
            let blobs = detect_frame(movers, k, w, h, &mut det);
            let result = matcher.update(&blobs, k).expect("increasing frames");
            (blobs, result)
        })
        .collect()
}

fn id_near(result: &MatchResult, p: (f64, f64), tol_px: f64) -> Option<u64> {
    result
        .matched
        .iter()
        .find(|d| (d.end_point_px[0] - p.0).hypot(d.end_point_px[1] - p.1) < tol_px)
        .map(|d| d.track_id)
}

#[test]
fn false_target_is_rejected_and_tracks_keep_ids() {
    let a = Mover {
        p0: (30.0, 40.0),
        v_px_s: (400.0, 150.0),
        first_frame: 0,
        last_frame: 99,
    };
    let b = Mover {
        p0: (170.0, 150.0),
        v_px_s: (-200.0, -350.0),
        first_frame: 0,
        last_frame: 99,
    };
    let false_target = Mover {
        p0: (60.0, 150.0),
        v_px_s: (0.0, 0.0),
        first_frame: 0,
        last_frame: 0,
    };
    let frames = run(&[a, b, false_target], 6, 200, 180);
    let first = &frames[0].1;
    assert_eq!(first.new_candidates.len(), 3);
    assert!(first.matched.is_empty());
    let second = &frames[1].1;
    assert_eq!(second.matched.len(), 2, "{second:?}");
    assert_eq!(second.rejected_previous.len(), 1, "{second:?}");
    let r = second.rejected_previous[0];
    assert_eq!(r.frame_index, 0);
    assert!((r.centroid_px[0] - 60.0).abs() < 0.5 && (r.centroid_px[1] - 150.0).abs() < 0.5);
    let id_a = id_near(second, a.end_of_exposure(1), 1.0).expect("a matched");
    let id_b = id_near(second, b.end_of_exposure(1), 1.0).expect("b matched");
    assert_ne!(id_a, id_b);
    for (k, (_, res)) in frames.iter().enumerate().skip(2) {
        let k = k as u64;
        assert_eq!(res.matched.len(), 2, "frame {k}: {res:?}");
        assert!(res.rejected_previous.is_empty() && res.new_candidates.is_empty());
        // Eq 9 end points land on the true end-of-exposure positions.
        assert_eq!(
            id_near(res, a.end_of_exposure(k), 0.5),
            Some(id_a),
            "frame {k}"
        );
        assert_eq!(
            id_near(res, b.end_of_exposure(k), 0.5),
            Some(id_b),
            "frame {k}"
        );
    }
}

#[test]
fn crossing_streaks_keep_their_ids_through_the_merge() {
    // Both streaks are centred on (100, 100) during frame 3: a "+" shaped merged blob.
    let h = Mover {
        p0: (35.0, 100.0),
        v_px_s: (500.0, 0.0),
        first_frame: 0,
        last_frame: 99,
    };
    let v = Mover {
        p0: (100.0, 35.0),
        v_px_s: (0.0, 500.0),
        first_frame: 0,
        last_frame: 99,
    };
    let frames = run(&[h, v], 7, 200, 200);
    let ids_before = (
        id_near(&frames[2].1, h.end_of_exposure(2), 1.0).expect("h before"),
        id_near(&frames[2].1, v.end_of_exposure(2), 1.0).expect("v before"),
    );
    let (blobs3, merged) = &frames[3];
    assert_eq!(blobs3.len(), 1, "the streaks merge into one component");
    assert!(merged.matched.is_empty(), "{merged:?}");
    let mut coasting = merged.coasting.clone();
    coasting.sort_unstable();
    assert_eq!(coasting, vec![ids_before.0, ids_before.1]);
    let after = &frames[4].1;
    assert_eq!(after.matched.len(), 2, "{after:?}");
    assert_eq!(
        id_near(after, h.end_of_exposure(4), 1.0),
        Some(ids_before.0)
    );
    assert_eq!(
        id_near(after, v.end_of_exposure(4), 1.0),
        Some(ids_before.1)
    );
    assert!(after.matched.iter().all(|d| d.frames_since_previous == 2));
    assert_eq!(
        after.rejected_previous.len(),
        1,
        "the merged blob is a false target"
    );
    for (k, (_, res)) in frames.iter().enumerate().skip(5) {
        let k = k as u64;
        assert_eq!(id_near(res, h.end_of_exposure(k), 1.0), Some(ids_before.0));
        assert_eq!(id_near(res, v.end_of_exposure(k), 1.0), Some(ids_before.1));
        assert!(res.lost_tracks.is_empty() && res.rejected_previous.is_empty());
    }
}

#[test]
fn clipped_streak_at_the_border_stays_matched() {
    // Moves right at 20 px/frame; frame 3 spans x = 160..170 on a 165-px-wide frame.
    let m = Mover {
        p0: (100.0, 60.0),
        v_px_s: (500.0, 0.0),
        first_frame: 0,
        last_frame: 99,
    };
    let frames = run(&[m], 5, 165, 120);
    let id = id_near(&frames[1].1, m.end_of_exposure(1), 1.0).expect("matched");
    let (blobs3, res3) = &frames[3];
    assert_eq!(blobs3.len(), 1);
    assert!(blobs3[0].touches_border);
    let full = frames[2].0[0].area_px;
    assert!(
        blobs3[0].area_px < full * 3 / 4,
        "clipped: {} vs {full}",
        blobs3[0].area_px
    );
    assert_eq!(res3.matched.len(), 1, "{res3:?}");
    assert_eq!(res3.matched[0].track_id, id);
    // Frame 4 is outside: the track coasts, then is lost after max_coast_frames.
    assert_eq!(frames[4].1.coasting, vec![id]);
}

#[test]
fn late_target_gets_a_new_id() {
    let a = Mover {
        p0: (20.0, 20.0),
        v_px_s: (300.0, 300.0),
        first_frame: 0,
        last_frame: 99,
    };
    let late = Mover {
        p0: (170.0, 40.0),
        v_px_s: (-250.0, 400.0),
        first_frame: 3,
        last_frame: 99,
    };
    let frames = run(&[a, late], 7, 200, 200);
    let id_a = id_near(&frames[1].1, a.end_of_exposure(1), 1.0).expect("a");
    assert_eq!(frames[3].1.new_candidates.len(), 1);
    let res4 = &frames[4].1;
    let id_late = id_near(res4, late.end_of_exposure(4), 1.0).expect("late matched");
    assert_ne!(id_late, id_a);
    assert!(res4
        .matched
        .iter()
        .any(|d| d.track_id == id_late && d.new_track && d.hits == 2));
    assert_eq!(id_near(&frames[6].1, a.end_of_exposure(6), 1.0), Some(id_a));
    assert_eq!(
        id_near(&frames[6].1, late.end_of_exposure(6), 1.0),
        Some(id_late)
    );
}

/// A hand-made blob (binary and weighted features equal).
fn blob(x: f64, y: f64, area: u32, a: f64, b: f64, theta_deg: f64) -> Blob {
    let e = (1.0 - (b / a).powi(2)).max(0.0).sqrt();
    let ellipse = Ellipse {
        m00: f64::from(area),
        x_px: x,
        y_px: y,
        a_px: a,
        b_px: b,
        theta_rad: theta_deg.to_radians(),
        eccentricity: e,
    };
    Blob {
        area_px: area,
        x_px: x,
        y_px: y,
        a_px: a,
        b_px: b,
        theta_rad: ellipse.theta_rad,
        eccentricity: e,
        weighted: ellipse,
        flux_dn: f64::from(area),
        peak_dn: 1000,
        bbox: BoundingBox {
            x_min_px: 0,
            y_min_px: 0,
            x_max_px: 0,
            y_max_px: 0,
        },
        touches_border: false,
        saturated_px: 0,
    }
}

#[test]
fn end_point_follows_eq_9() {
    let mut m = Matcher::new(MatcherConfig::default()).expect("config");
    m.update(&[blob(10.0, 20.0, 30, 4.0, 1.0, 36.87)], 7)
        .expect("ok");
    let r = m
        .update(&[blob(14.0, 23.0, 30, 4.0, 1.0, 36.87)], 8)
        .expect("ok");
    let d = r.matched[0];
    // t_ep/(2(t_ep + t_in)) = 1/4 of the frame displacement (4, 3).
    assert_eq!(d.end_point_px, [15.0, 23.75]);
    assert_eq!(d.velocity_px_per_frame, [4.0, 3.0]);
    assert_eq!((d.track_id, d.hits, d.new_track), (1, 2, true));
    // A frame skipped: the displacement is per frame and the gate scales with Δf.
    let r = m
        .update(&[blob(22.0, 29.0, 30, 4.0, 1.0, 36.87)], 10)
        .expect("ok");
    assert_eq!(r.matched[0].velocity_px_per_frame, [4.0, 3.0]);
    assert_eq!(r.matched[0].frames_since_previous, 2);
    assert_eq!((r.matched[0].track_id, r.matched[0].new_track), (1, false));
}

#[test]
fn gates_reject_each_feature_and_round_blobs_skip_theta() {
    let base = blob(50.0, 50.0, 40, 5.0, 1.5, 20.0);
    // (current blob, should match, what is tested); base e = 0.954, eq 8 gate 4·5 + 3 = 23 px.
    let cases = [
        (
            blob(51.0, 50.0, 60, 5.0, 1.5, 20.0),
            false,
            "area off by 50 %",
        ),
        (blob(51.0, 50.0, 40, 7.0, 2.1, 20.0), false, "a off by 40 %"),
        (blob(51.0, 50.0, 40, 5.0, 1.5, 30.0), false, "θ off by 10°"),
        (blob(51.0, 50.0, 40, 5.0, 1.5, 23.0), true, "θ off by 3°"),
        (
            blob(51.0, 50.0, 40, 5.0, 2.5, 20.0),
            false,
            "e off by 0.088",
        ),
        (
            blob(70.0, 50.0, 40, 5.0, 1.5, 20.0),
            true,
            "centroid 20 px < 23 px",
        ),
        (
            blob(74.0, 50.0, 40, 5.0, 1.5, 20.0),
            false,
            "centroid 24 px > 23 px",
        ),
    ];
    for (cur, want, what) in cases {
        let mut m = Matcher::new(MatcherConfig::default()).expect("config");
        m.update(&[base], 0).expect("ok");
        let r = m.update(&[cur], 1).expect("ok");
        assert_eq!(r.matched.len() == 1, want, "{what}: {r:?}");
    }
    // Round blobs: θ is noise and not gated.
    let mut m = Matcher::new(MatcherConfig::default()).expect("config");
    m.update(&[blob(10.0, 10.0, 9, 1.5, 1.47, -60.0)], 0)
        .expect("ok");
    let r = m
        .update(&[blob(11.0, 10.0, 9, 1.5, 1.44, 40.0)], 1)
        .expect("ok");
    assert_eq!(r.matched.len(), 1, "{r:?}");
    // θ wraps at ±90°: 89° and −89° are 2° apart.
    let mut m = Matcher::new(MatcherConfig::default()).expect("config");
    m.update(&[blob(10.0, 10.0, 30, 5.0, 1.0, 89.0)], 0)
        .expect("ok");
    let r = m
        .update(&[blob(10.0, 12.0, 30, 5.0, 1.0, -89.0)], 1)
        .expect("ok");
    assert_eq!(r.matched.len(), 1, "{r:?}");
}

#[test]
fn greedy_assignment_prefers_the_closer_features() {
    let mut m = Matcher::new(MatcherConfig::default()).expect("config");
    m.update(&[blob(50.0, 50.0, 40, 5.0, 1.5, 20.0)], 0)
        .expect("ok");
    let r = m
        .update(
            &[
                blob(53.0, 50.0, 44, 5.3, 1.6, 22.0),
                blob(51.0, 50.0, 40, 5.0, 1.5, 20.0),
            ],
            1,
        )
        .expect("ok");
    assert_eq!(r.matched.len(), 1);
    assert_eq!(r.matched[0].blob_index, 1);
    assert_eq!(r.new_candidates, vec![0]);
}

#[test]
fn tracks_are_lost_after_max_coast_and_errors_are_reported() {
    let mut m = Matcher::new(MatcherConfig::default()).expect("config");
    let b = blob(50.0, 50.0, 40, 5.0, 1.5, 20.0);
    m.update(&[b], 0).expect("ok");
    m.update(&[b], 1).expect("ok");
    assert_eq!(m.track_count(), 1);
    assert_eq!(m.update(&[], 2).expect("ok").coasting, vec![1]);
    assert_eq!(m.update(&[], 3).expect("ok").coasting, vec![1]);
    let r = m.update(&[], 4).expect("ok");
    assert_eq!(r.lost_tracks.len(), 1);
    assert_eq!(r.lost_tracks[0].last_frame_index, 1);
    assert_eq!(m.track_count(), 0);
    assert_eq!(
        m.update(&[], 4),
        Err(MatchError::NonIncreasingFrame {
            previous: 4,
            got: 4
        })
    );
    let mut bad = b;
    bad.a_px = f64::NAN;
    let r = m.update(&[bad, b], 5).expect("ok");
    assert_eq!((r.invalid_blobs, r.new_candidates), (vec![0], vec![1]));
    let json = serde_json::to_string(&MatcherConfig::default()).expect("serialises");
    assert!(json.contains("\"gate_margin_px\":3.0"));
    let bad_cfg = MatcherConfig {
        exposure_s: 0.0,
        ..MatcherConfig::default()
    };
    assert_eq!(
        Matcher::new(bad_cfg).map(|_| ()).map_err(|e| e.field),
        Err("exposure_s")
    );
}
