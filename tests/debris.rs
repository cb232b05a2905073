//! The [002] debris scenario across sensor, detector and tracker processes, scored against
//! truth by the orchestrator; and the offline detect tool on rendered and broken files.

mod common;

use common::*;

#[test]
fn debris_scenario_meets_its_targets_across_processes() {
    let dir = temp_dir("debris");
    let r = run_ok(Some(&scenario("debris-geo.toml")), &dir, &[]);
    let rep = &r.typed.results;
    let names: Vec<&str> = rep.services.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(names, ["sensor", "detector", "tracker"]);
    for t in ["frame", "detections", "tracks", "truth"] {
        assert_eq!(rep.topics[t].published, Some(50), "{t}");
    }
    let d = rep.detection.as_ref().expect("a detection score");
    assert_eq!(d.precision, 1.0, "{d:?}");
    assert_eq!(d.recall, 1.0, "{d:?}");
    assert_eq!(d.false_targets, 2);
    assert_eq!(d.false_targets_rejected, 2);
    let targets = &rep.tracking.as_ref().expect("a tracking score").targets;
    assert_eq!(targets.len(), 4, "all four debris");
    for t in targets {
        assert!(t.track_id.is_some(), "{t:?}");
        assert!(t.frames_tracked >= 48, "{t:?}");
        assert!(t.azimuth_err_deg_rms_filtered <= 1e-3, "{t:?}");
        assert!(t.elevation_err_deg_rms_filtered <= 1e-3, "{t:?}");
        assert!(t.pos_err_m_final <= 0.5, "{t:?}");
        assert!(t.vel_err_mps_final <= 0.5, "{t:?}");
        // The filter's consistency (NEES against χ²) is asserted over 50 seeds in tests/nees.rs.
        assert!(
            t.laser_hits as f64 >= 0.9 * t.laser_shots as f64 && t.laser_shots >= 40,
            "{t:?}"
        );
    }
    // Every measurement reaches its filter: none is skipped (the mid-exposure angles and the
    // laser ranges reach the EKF along different float paths to the same instant) or reset.
    let log = std::fs::read_to_string(dir.join("logs/tracker.log")).expect("tracker log");
    let faults: Vec<&str> = log
        .lines()
        .filter(|l| l.contains("Skipped") || l.contains("Reset"))
        .collect();
    assert!(faults.is_empty(), "filter faults: {faults:#?}");
    // The figures show every track: one dot per measured frame and a line per filter.
    let angles = Svg::read(&dir.join("debris-angles.svg"));
    let ekf = Svg::read(&dir.join("debris-ekf.svg"));
    for k in 1..=4 {
        assert!(
            angles.has_text(&format!("#{k} measured")),
            "{:?}",
            angles.texts
        );
        assert!(
            angles.has_text(&format!("#{k} filtered")),
            "{:?}",
            angles.texts
        );
        assert!(ekf.has_text(&format!("#{k} 3σ")), "{:?}", ekf.texts);
    }
    assert_eq!(angles.count("circle"), 4 * 50, "a dot per track and frame");
    // The EKF starts at a track's second fix: a dot per tracked frame after the first.
    let ekf_frames: u64 = targets.iter().map(|t| t.frames_tracked - 1).sum();
    assert_eq!(
        ekf.count("circle") as u64,
        ekf_frames,
        "a dot per EKF estimate"
    );
    let frame = Svg::read(&dir.join("frame-annotated.svg"));
    assert_eq!(frame.count("circle"), 4, "the four detections of frame 1");
    for k in 1..=4 {
        assert!(frame.has_text(&format!("track {k}")), "{:?}", frame.texts);
    }
    // The 1024² frame, 2× max-pooled.
    assert_eq!(png_size(&dir.join("frame-0001.png")), (512, 512));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn offline_detect_finds_the_rendered_debris_and_rejects_bad_files() {
    let dir = temp_dir("tool-detect");
    let frame = dir.join("f0.pgm");
    let out = glint()
        .args(["tool", "render"])
        .arg(scenario("debris-geo.toml"))
        .args(["--frame", "0", "--out"])
        .arg(&frame)
        .output()
        .unwrap();
    assert_success(&out);
    let out = glint()
        .args(["tool", "detect"])
        .arg(&frame)
        .output()
        .unwrap();
    assert_success(&out);
    let j: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    // Frame 0 of debris-geo: 4 debris streaks and 2 false targets.
    let dets = j["detections"].as_array().unwrap();
    assert_eq!(dets.len(), 6, "{j}");
    for d in dets {
        for k in ["x", "y", "area", "a", "b", "theta_rad", "eccentricity"] {
            assert!(d[k].is_number(), "{k} in {d}");
        }
        assert!(d["a"].as_f64() >= d["b"].as_f64());
    }
    // Broken inputs: exit 2 with a message naming the problem, never a panic.
    let cases: [(&str, &[u8], &str); 3] = [
        ("magic.pgm", b"P2\n2 2\n65535\n1 2 3 4\n", "magic"),
        ("short.pgm", b"P5\n4 4\n65535\n\x00\x01", "short"),
        ("maxval.pgm", b"P5\n2 2\n0\n\x00\x00\x00\x00", "maxval"),
    ];
    for (name, bytes, word) in cases {
        let p = dir.join(name);
        std::fs::write(&p, bytes).unwrap();
        let out = glint().args(["tool", "detect"]).arg(&p).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr).to_lowercase();
        assert_eq!(out.status.code(), Some(2), "{name}: {err}");
        assert!(err.contains(name) && err.contains(word), "{name}: {err}");
        assert!(!err.contains("panicked"));
    }
    let _ = std::fs::remove_dir_all(&dir);
}
