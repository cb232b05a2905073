//! Soaks: a long run with faults on a schedule, end to end, and its bad input.

mod common;

use common::*;

/// A short soak, end to end: the camera runs until the soak's time is up (its `frames` is
/// ignored), faults fire on the schedule (a kill of the sensor, then of the detector), the
/// orchestrator ends the stream and accounts for every frame sent, and the report gives the
/// soak's verdict and each process's memory over time. The stream ended where it was ordered
/// to: the frames published are the soak's count, past the scenario's 50.
#[test]
fn a_short_soak_fires_its_schedule_ends_its_stream_and_reports_memory() {
    let dir = temp_dir("soak");
    let file = scenario_variant(
        "debris-geo.toml",
        &[(
            "seed = 2016\n",
            "seed = 2016\n\n[soak]\nduration_s = 7\nfault_every_s = 2\nkinds = [\"kill\"]\n",
        )],
        &dir,
    );
    let r = run_ok(Some(&file), &dir.join("out"), &[]);
    let soak = r.typed.soak.as_ref().expect("a soak's report");
    assert!(soak.passed, "{soak:?}");
    assert_eq!(
        (soak.faults, soak.detected, soak.recovered),
        (2, 2, 2),
        "{soak:?}"
    );
    assert_eq!(soak.lost, 0);
    let kinds: Vec<(&str, &str)> = (r.typed.faults.iter())
        .map(|f| (f.service.as_str(), f.kind.as_str()))
        .collect();
    assert_eq!(kinds, [("sensor", "kill"), ("detector", "kill")]);
    assert!(
        r.typed.faults.iter().all(|f| f.restarts == 1),
        "{:?}",
        r.typed.faults
    );
    let frames = soak.frames.expect("the stream was ended");
    assert!(soak.ended_s.unwrap() >= 7.0, "{soak:?}");
    assert!(
        frames > 50,
        "the scenario's frames = 50 was ignored: {frames}"
    );
    assert_eq!(r.typed.results.topics["frame"].published, Some(frames));
    assert!(r.typed.results.accounting.invariant_held);
    for p in ["sensor", "detector", "tracker", "orchestrator"] {
        let m = &r.typed.timing.memory[p];
        let last_mb = *m.rss_mb.last().unwrap();
        assert!(m.t_s.len() >= 5 && last_mb > 1.0, "{p}: {m:?}");
        assert!(m.growth_pct.is_finite() && m.warm_mb > 1.0, "{p}: {m:?}");
    }
    assert!(dir.join("out").join("memory.svg").exists());
    let summary = std::fs::read_to_string(dir.join("out").join("summary.md")).unwrap();
    assert!(summary.contains("## Soak — PASS"), "{summary}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A soak's bad input is refused naming the file and the field, exit 2.
#[test]
fn a_bad_soak_is_bad_input_naming_the_file_and_field() {
    let dir = temp_dir("soak-bad");
    for (file, arg, says) in [
        ("debris-geo.toml", "0.5s", "soak.duration_s"),
        ("geo-hover-yspin.toml", "10s", "needs a [camera]"),
        ("debris-geo.toml", "ten", "expected a duration such as 90s"),
    ] {
        let out = glint()
            .arg("run")
            .arg(scenario(file))
            .args(["--out"])
            .arg(dir.join("never"))
            .args(["--soak", arg])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{arg}: {err}");
        assert!(err.contains(says), "{arg}: {err}");
        if arg != "ten" {
            assert!(err.contains(file), "{arg}: {err}");
        }
    }
    assert!(!dir.join("never").exists());
    let _ = std::fs::remove_dir_all(&dir);
}
