//! Fault injection in realtime mode: nothing is replayed, what a fault cost is counted as
//! dropped, and the run ends on the run's clock.

use std::path::PathBuf;

use super::*;

/// The debris chain in realtime at 25 frames/s with a 1 s restart backoff, run with `fault`
/// (a kill): the run's directory and its result.
fn killed_in_realtime(name: &str, fault: &str) -> (PathBuf, RunResult) {
    let dir = temp_dir(name);
    let file = scenario_variant(
        "debris-geo.toml",
        &[(
            "seed = 2016\n",
            "seed = 2016\nclock = \"realtime\"\n\n[supervision]\nbackoff_ms = 1000\n",
        )],
        &dir,
    );
    let r = run_ok(Some(&file), &dir.join("kill"), &["--fault", fault]);
    (dir, r)
}

/// Realtime mode: a detector slowed past the frame rate drops frames (its buffer overflows),
/// counts them, and the run ends when the sensor is done — the detections it did not make are
/// not waited for — with `received + dropped == published` for every consumer.
#[test]
fn in_realtime_a_slowed_consumer_drops_counted_frames_and_the_run_still_ends() {
    let dir = temp_dir("fault-realtime");
    let file = scenario_variant(
        "debris-geo.toml",
        &[("seed = 2016\n", "seed = 2016\nclock = \"realtime\"\n")],
        &dir,
    );
    let r = run_ok(
        Some(&file),
        &dir.join("out"),
        &["--fault", "detector:delay@5,delay_ms=200,duration_s=1.5"],
    );
    let topics = &r.typed.results.topics;
    let frames = &topics["frame"];
    assert_eq!(frames.published, Some(50));
    let det = &frames.consumers["detector"];
    let (received, dropped) = (det.received.unwrap(), det.dropped.unwrap());
    assert_eq!(received + dropped, 50, "{det:?}");
    assert!(
        dropped > 0,
        "a 200 ms delay for 1.5 s at 25 frames/s overflows the 16-frame buffer: {det:?}"
    );
    assert_eq!(
        (det.dropped_by_reason.as_ref()).and_then(|by| by.get("overflow").copied()),
        Some(dropped),
        "{det:?}"
    );
    // The fault's cost is the frames the detector never processed.
    assert_eq!(fault(&r.typed).lost, Some(dropped), "{:?}", r.typed.faults);
    // One detections message per frame the detector took; the tracker took them all.
    let detections = &topics["detections"];
    assert_eq!(detections.expected, received, "{detections:?}");
    assert_eq!(detections.consumers["tracker"].received, Some(received));
    assert!(r.typed.results.accounting.invariant_held);
    let _ = std::fs::remove_dir_all(&dir);
}

/// Realtime mode: nothing is replayed to a restarted detector. It is held down 1 s (its restart
/// backoff) while frames keep coming at 25 frames/s, more than its queue keeps; the new
/// incarnation continues its accounting where the last one left it and resumes at the newest
/// frames. Its fault's `lost` is exactly the frames it never processed, counted as dropped;
/// its detections continue at the next seq, one per frame it processed, so none takes the seq
/// of one already sent (before, the new incarnation's first detections were skipped by the
/// tracker as duplicates of the old one's).
#[test]
fn in_realtime_a_restarted_consumer_resumes_at_the_newest_frame_and_counts_what_it_missed() {
    let (dir, r) = killed_in_realtime("fault-realtime-kill", "detector:kill@10");
    let f = fault(&r.typed);
    assert_eq!(f.detected_by.as_deref(), Some("exit"), "{f:?}");
    assert_eq!(
        (f.restarts, f.replayed),
        (1, Some(0)),
        "nothing replayed: {f:?}"
    );
    let topics = &r.typed.results.topics;
    let det = &topics["frame"].consumers["detector"];
    let (processed, dropped) = (det.received.unwrap(), det.dropped.unwrap());
    assert_eq!(processed + dropped, 50, "{det:?}");
    assert!(
        dropped > 0,
        "1 s down at 25 frames/s overflows a 16-frame queue: {det:?}"
    );
    assert_eq!(
        f.lost,
        Some(dropped),
        "lost is what it never processed: {f:?}"
    );
    let detections = &topics["detections"];
    assert_eq!(detections.published, Some(processed), "{detections:?}");
    for (name, c) in &detections.consumers {
        assert_eq!(c.received, Some(processed), "{name}: {c:?}");
        assert_eq!(
            c.duplicates.unwrap_or(0),
            0,
            "{name}: no seq taken twice: {c:?}"
        );
    }
    assert!(r.typed.results.accounting.invariant_held);
    let _ = std::fs::remove_dir_all(&dir);
}

/// Realtime mode: a restarted sensor does not make the run again from its first frame. Held down
/// 1 s (its restart backoff) at 25 frames/s, it continues at the frame the run's clock has come
/// to: the ~25 frames that came due while it was down were never made — its fault's `lost`,
/// one gap at every consumer, its truth skipping as many — and no frame is sent twice (before,
/// the new incarnation rendered frames 0… again at the run's pace, which every consumer skipped
/// as duplicates, and the run took the outage's length longer).
#[test]
fn in_realtime_a_restarted_sensor_continues_at_the_frame_due_and_counts_what_it_never_made() {
    let (dir, r) = killed_in_realtime("fault-realtime-sensor", "sensor:kill@10");
    let f = fault(&r.typed);
    assert_eq!(
        (f.detected_by.as_deref(), f.restarts),
        (Some("exit"), 1),
        "{f:?}"
    );
    let lost = f.lost.expect("a sensor fault says what it never made");
    assert!(
        (10..=40).contains(&lost),
        "about 1 s of frames at 25 frames/s came due while it was down: {f:?}"
    );
    let topics = &r.typed.results.topics;
    for topic in ["frame", "truth"] {
        let t = &topics[topic];
        assert_eq!(t.published, Some(50), "{topic}: {t:?}");
        for (name, c) in &t.consumers {
            let (received, dropped) = (c.received.unwrap(), c.dropped.unwrap());
            assert_eq!(received + dropped, 50, "{topic} at {name}: {c:?}");
            assert_eq!(
                c.duplicates.unwrap_or(0),
                0,
                "{topic} at {name}: nothing sent twice"
            );
            // The truth may miss one more: a frame sent just before the kill, its truth not.
            assert!(
                (lost..=lost + 1).contains(&dropped),
                "{topic} at {name}: the gap is what it never made: {c:?}, lost {lost}"
            );
        }
    }
    assert!(r.typed.results.accounting.invariant_held);
    let _ = std::fs::remove_dir_all(&dir);
}
