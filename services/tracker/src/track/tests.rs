//! Track-manager tests: life cycle, filter initialisation, angles-only frames, pointing, faults.

use super::*;
use crate::ekf::{measurement, GEO_MEAN_MOTION_RAD_S};
use crate::pointing::{beam_hits, SEED_BEAM_WIDTH_RAD, SEED_LASER_DELAY_S};
use glint_physics::cw::propagate_lvlhn;
use glint_physics::rng::SeededRng as Rng;
use nalgebra::Vector6;

const DT: f64 = 0.04;

fn truth(x0: [f64; 6], t: f64) -> Vector6<f64> {
    propagate_lvlhn(Vector6::from(x0), GEO_MEAN_MOTION_RAD_S, t)
}

fn observe(id: u64, x: &Vector6<f64>, t: f64, with_range: bool, rng: &mut Rng) -> TrackObservation {
    let h = measurement(x);
    TrackObservation {
        track_id: id,
        t_s: t,
        azimuth_rad: h[0] + 1.7e-4 * rng.gaussian(),
        elevation_rad: h[1] + 1.7e-4 * rng.gaussian(),
        range_m: with_range.then(|| h[2] + 0.1 / 3.0 * rng.gaussian()),
        range_t_s: None,
        sigma_rad: None,
        ekf_angles: None,
    }
}

/// One pass of 50 frames with the range of a shot echoing t_r = 0.03 s after each exposure's
/// angles (§3.7): the filter's state at the end, its time, and its NEES there.
fn delayed_laser_pass(seed: u64) -> (Vector6<f64>, f64, f64) {
    let mut tm = TrackManager::new(TrackManagerConfig::default()).expect("valid");
    let mut rng = Rng::new(seed);
    for k in 0..50u32 {
        let t = f64::from(k) * DT;
        let x = truth(DEBRIS[0], t);
        let h = measurement(&x);
        let t_echo = t + SEED_LASER_DELAY_S;
        let r_echo = measurement(&truth(DEBRIS[0], t_echo))[2] + 0.1 / 3.0 * rng.gaussian();
        let obs = TrackObservation {
            track_id: 1,
            t_s: t,
            azimuth_rad: h[0] + 1.7e-4 * rng.gaussian(),
            elevation_rad: h[1] + 1.7e-4 * rng.gaussian(),
            range_m: Some(r_echo),
            range_t_s: Some(t_echo),
            sigma_rad: None,
            ekf_angles: None,
        };
        let out = tm.process_frame(&[obs]);
        assert!(out.faults.is_empty(), "{:?}", out.faults);
        if let Some(ekf) = tm.track(1).and_then(|t| t.ekf.as_ref()) {
            assert!(
                (ekf.t_s() - t_echo).abs() < 1e-12,
                "the filter ends at the echo time"
            );
        }
    }
    let ekf = tm
        .track(1)
        .and_then(|t| t.ekf.as_ref())
        .expect("initialised");
    let nees = ekf
        .nees(&truth(DEBRIS[0], ekf.t_s()))
        .expect("positive definite");
    (ekf.state().into_owned(), ekf.t_s(), nees)
}

#[test]
fn delayed_laser_range_is_applied_at_its_own_time() {
    // The filter must use the angles and the delayed range each at its own time, and converge
    // to the truth.
    let (state, t_s, _) = delayed_laser_pass(7);
    let e = state - truth(DEBRIS[0], t_s);
    assert!(
        e.fixed_rows::<3>(0).norm() < 3.0,
        "position error {}",
        e.fixed_rows::<3>(0).norm()
    );
    assert!(
        e.fixed_rows::<3>(3).norm() < 5.0,
        "velocity error {}",
        e.fixed_rows::<3>(3).norm()
    );
}

#[test]
fn the_filter_with_delayed_ranges_is_consistent_over_200_seeds() {
    // A consistent filter's final NEES is χ²(6): the mean over 200 independent passes lies in
    // the 95 % band of χ²(1200)/200 = [5.527, 6.492]. A range applied at the wrong time biases
    // the state by the range rate × 0.03 s; angles predicted to the range's time but given the
    // measurement's σ in P₀ left the mean at 6.74 (over 2000 seeds).
    const SEEDS: u64 = 200;
    let mean = (1..=SEEDS).map(|s| delayed_laser_pass(s).2).sum::<f64>() / SEEDS as f64;
    assert!(
        (5.527..=6.492).contains(&mean),
        "mean final NEES {mean:.3} over {SEEDS} seeds"
    );
}

const DEBRIS: [[f64; 6]; 2] = [
    [10000.0, 600.0, 700.0, -60.0, -10.0, -100.0],
    [9000.0, 600.0, -500.0, -100.0, -600.0, 400.0],
];

#[test]
fn life_cycle_confirms_and_deletes() {
    let mut tm = TrackManager::new(TrackManagerConfig::default()).expect("valid");
    let mut rng = Rng::new(1);
    let mut outcomes = Vec::new();
    for k in 0..6u32 {
        let t = f64::from(k) * DT;
        let mut obs = vec![observe(1, &truth(DEBRIS[0], t), t, true, &mut rng)];
        if k < 2 {
            obs.push(observe(2, &truth(DEBRIS[1], t), t, true, &mut rng));
        }
        outcomes.push(tm.process_frame(&obs));
    }
    assert_eq!(outcomes[0].created, vec![1, 2]);
    assert!(outcomes[1].confirmed.is_empty());
    assert_eq!(outcomes[2].confirmed, vec![1], "M = 3 hits");
    assert_eq!(outcomes[2].missed, vec![2]);
    assert!(outcomes[3].deleted.is_empty());
    assert_eq!(outcomes[4].deleted, vec![2], "N = 3 consecutive misses");
    assert!(tm.track(2).is_none());
    let t1 = tm.track(1).expect("alive");
    assert_eq!(
        (t1.status, t1.hits, t1.consecutive_misses),
        (TrackStatus::Confirmed, 6, 0)
    );
    assert!(outcomes.iter().all(|o| o.faults.is_empty()));
}

#[test]
fn filters_initialise_and_track_debris_4() {
    let mut tm = TrackManager::new(TrackManagerConfig::default()).expect("valid");
    let mut rng = Rng::new(9);
    let first = observe(7, &truth(DEBRIS[0], 0.0), 0.0, true, &mut rng);
    tm.process_frame(&[first]);
    let track = tm.track(7).expect("created");
    assert!(track.angle_filter.is_none() && track.ekf.is_none());
    // Frame 1 has no range: the angle filter starts, the EKF waits for a second range.
    tm.process_frame(&[observe(7, &truth(DEBRIS[0], DT), DT, false, &mut rng)]);
    let track = tm.track(7).expect("alive");
    assert!(track.angle_filter.is_some() && track.ekf.is_none());
    let t = 2.0 * DT;
    tm.process_frame(&[observe(7, &truth(DEBRIS[0], t), t, true, &mut rng)]);
    assert!(tm.track(7).and_then(|t| t.ekf.as_ref()).is_some());
    // 25 frames (1 s), every fourth without a range reply.
    let mut hits = 0;
    for k in 3..25u32 {
        let t = f64::from(k) * DT;
        let x = truth(DEBRIS[0], t);
        let out = tm.process_frame(&[observe(7, &x, t, k % 4 != 0, &mut rng)]);
        assert!(out.faults.is_empty(), "{out:?}");
        // Laser pointing for t + t_r from the filtered angles (eq 16) against the truth then.
        let cmd = tm.pointing(7, SEED_LASER_DELAY_S).expect("angle filter");
        let h = measurement(&truth(DEBRIS[0], t + SEED_LASER_DELAY_S));
        if beam_hits(&cmd, h[0], h[1], SEED_BEAM_WIDTH_RAD) {
            hits += 1;
        }
    }
    assert_eq!(hits, 22, "every laser shot lands within the beam");
    let report = tm.reports()[0];
    let x = truth(DEBRIS[0], 24.0 * DT);
    let est = report.relative_state.expect("EKF running");
    let pos_err = (0..3)
        .map(|i| (est.position_m[i] - x[i]).powi(2))
        .sum::<f64>()
        .sqrt();
    let vel_err = (0..3)
        .map(|i| (est.velocity_m_s[i] - x[i + 3]).powi(2))
        .sum::<f64>()
        .sqrt();
    assert!(
        pos_err < 5.0 && vel_err < 10.0,
        "{pos_err} m, {vel_err} m/s"
    );
    let angles = report.angles.expect("angle filter running");
    let h = measurement(&x);
    assert!((angles.azimuth_rad - h[0]).abs() < 2e-4 && (angles.elevation_rad - h[1]).abs() < 2e-4);
    let json = serde_json::to_string(&tm.reports()).expect("serialises");
    assert!(json.contains("\"status\":\"confirmed\"") && json.contains("relative_state"));
}

#[test]
fn faults_are_reported_not_fatal() {
    let mut tm = TrackManager::new(TrackManagerConfig::default()).expect("valid");
    let mut rng = Rng::new(3);
    for k in 0..3u32 {
        let t = f64::from(k) * DT;
        tm.process_frame(&[observe(1, &truth(DEBRIS[0], t), t, true, &mut rng)]);
    }
    // An observation older than the filters: skipped by both.
    let stale = observe(1, &truth(DEBRIS[0], 0.0), 0.0, true, &mut rng);
    let out = tm.process_frame(&[stale]);
    assert_eq!(out.faults.len(), 2, "{out:?}");
    assert!(out.faults.iter().all(|f| f.action == FaultAction::Skipped));
    // A negative range: reported, the angles still update the EKF.
    let t = 4.0 * DT;
    let mut bad = observe(1, &truth(DEBRIS[0], t), t, true, &mut rng);
    bad.range_m = Some(-5.0);
    let out = tm.process_frame(&[bad]);
    assert_eq!(out.faults.len(), 1);
    assert_eq!(out.faults[0].filter, FilterKind::Ekf);
    assert_eq!(
        tm.track(1).and_then(|t| t.ekf.as_ref()).map(|e| e.t_s()),
        Some(t)
    );
    // Non-finite angles: skipped without creating a track.
    let mut nan = observe(5, &truth(DEBRIS[0], t), 5.0, true, &mut rng);
    nan.azimuth_rad = f64::NAN;
    let out = tm.process_frame(&[nan]);
    assert!(out.created.is_empty() && out.faults.len() == 1);
    assert!(tm.track(5).is_none());
    assert!(TrackManager::new(TrackManagerConfig {
        confirm_hits: 0,
        ..TrackManagerConfig::default()
    })
    .is_err());
    let cfg: TrackManagerConfig = serde_json::from_str(r#"{"delete_misses": 5}"#).expect("parses");
    assert_eq!((cfg.confirm_hits, cfg.delete_misses), (3, 5));
}
