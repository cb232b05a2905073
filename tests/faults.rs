//! Fault injection against real deployments: `--fault` and `[[fault]]` entries signal real
//! service processes; the report's `faults[]` says when each fault was injected, noticed and
//! recovered from, and what it cost. Restarts are not built yet: a fault supervision notices
//! ends the run (exit 1), one it does not (a stop shorter than the heartbeat deadline) must
//! leave the science exactly as the fault-free run's.

mod common;

use common::*;
use serde_json::Value;

fn fault(report: &Value) -> &Value {
    let faults = report["faults"].as_array().expect("faults[]");
    assert_eq!(faults.len(), 1, "{faults:?}");
    &faults[0]
}

fn secs(v: &Value, key: &str) -> f64 {
    v[key]
        .as_f64()
        .unwrap_or_else(|| panic!("{key} missing in {v}"))
}

/// The report without faults, run identity, timing, pids: what two runs of the same scenario
/// and seed must share.
fn science(report: &Value) -> Value {
    let mut r = deterministic_part(report);
    r.as_object_mut().unwrap().remove("faults");
    r
}

#[test]
fn a_stop_shorter_than_the_heartbeat_deadline_holds_the_chain_and_changes_nothing() {
    let dir = temp_dir("fault-stop");
    let clean = run_ok(Some(&scenario("debris-geo.toml")), &dir.join("clean"), &[]);
    let r = run_ok(
        Some(&scenario("debris-geo.toml")),
        &dir.join("stopped"),
        &["--fault", "detector:stop@10,duration_s=0.4"],
    );
    let f = fault(&r.report);
    assert_eq!(f["service"], "detector");
    assert_eq!(f["kind"], "stop");
    let (injected, ended, recovered) = (
        secs(f, "injected_s"),
        secs(f, "ended_s"),
        secs(f, "recovered_s"),
    );
    assert!(ended - injected >= 0.4 && ended - injected < 0.5, "{f}");
    assert!(recovered >= ended && recovered - ended < 0.5, "{f}");
    // Shorter than the 5 s deadline: tolerated, not detected.
    assert!(f["detected_s"].is_null(), "{f}");
    assert_eq!(f["lost"], 0);
    assert_eq!(f["invariant_held"], true);
    // The stopped detector held the sensor back by credit: production lasted the stop.
    let production_s = r.report["timing"]["production_s"].as_f64().unwrap();
    assert!(production_s >= 0.4, "production {production_s} s");
    assert_eq!(science(&r.report), science(&clean.report));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_killed_detector_is_detected_by_its_exit_and_the_report_counts_what_it_lost() {
    let dir = temp_dir("fault-kill");
    let out = dir.join("out");
    let r = run(
        Some(&scenario("debris-geo.toml")),
        &out,
        &["--fault", "detector:kill@10"],
    );
    assert_eq!(r.output.status.code(), Some(1));
    assert_eq!(r.report["success"], false);
    let failure = r.report["failure"].as_str().unwrap();
    assert!(
        failure.contains("service detector exited unexpectedly")
            && failure.contains("(injected fault: detector:kill@10)"),
        "{failure}"
    );
    let f = fault(&r.report);
    assert_eq!(f["detected_by"], "exit");
    let latency = secs(f, "detected_s") - secs(f, "injected_s");
    assert!((0.0..0.5).contains(&latency), "detected {latency} s after");
    assert!(f["recovered_s"].is_null(), "no restarts yet: {f}");
    // Lost: frames published to the detector that it never took.
    let frames = &r.report["topics"]["frame"];
    let taken = frames["consumers"]["detector"]["received"]
        .as_u64()
        .unwrap_or(0);
    let lost = f["lost"].as_u64().unwrap();
    assert_eq!(
        lost,
        frames["published"].as_u64().unwrap() - taken,
        "{frames}"
    );
    assert!(lost > 0, "{frames}");
    assert_eq!(f["invariant_held"], false);
    // The timeline shows the service rows and the kill; the summary's table, the fault.
    let svg = Svg::read(&out.join("faults.svg"));
    for name in ["sensor", "detector", "tracker"] {
        assert!(svg.has_text(name), "{:?}", svg.texts);
    }
    let summary = std::fs::read_to_string(out.join("summary.md")).unwrap();
    assert!(summary.contains("| detector | kill@10 |"), "{summary}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_stop_past_the_heartbeat_deadline_is_detected_by_it() {
    let dir = temp_dir("fault-long-stop");
    let file = scenario_variant(
        "debris-geo.toml",
        &[(
            "seed = 2016\n",
            "seed = 2016\n\n[run]\nheartbeat_period_ms = 50\nheartbeat_deadline_ms = 300\nshutdown_grace_ms = 300\n\n[[fault]]\nservice = \"tracker\"\nkind = \"stop\"\nat_seq = 5\nduration_s = 30.0\n",
        )],
        &dir,
    );
    let r = run(Some(&file), &dir.join("out"), &[]);
    assert_eq!(r.output.status.code(), Some(1));
    let f = fault(&r.report);
    assert_eq!(f["detected_by"], "heartbeat deadline", "{f}");
    let latency = secs(f, "detected_s") - secs(f, "injected_s");
    // The deadline (less the heartbeat period before the stop), plus the target's 0.1 s and a
    // supervision tick's margin.
    assert!((0.25..0.5).contains(&latency), "detected {latency} s after");
    // Continued at the end so that it could obey Shutdown, not killed.
    assert_eq!(ending(&r.report, "tracker"), "shutdown", "{}", r.report);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_bad_fault_is_bad_input_naming_the_argument_or_the_field() {
    let dir = temp_dir("fault-bad");
    for (arg, says) in [
        ("detector:explode@3", "--fault `detector:explode@3`: unknown kind `explode`; allowed: kill, stop"),
        ("inversion:kill@3", "--fault `inversion:kill@3`: service: `inversion` is not a service this scenario deploys; allowed: sensor, detector, tracker"),
        ("detector:stop@3", "--fault `detector:stop@3`: duration_s: a stop needs its duration"),
        ("detector:kill@3,duration_s=1", "--fault `detector:kill@3,duration_s=1`: duration_s: a kill has no duration"),
        ("detector:stop@-1s,duration_s=1", "at_s: -1 is out of range; allowed 0..=86400"),
    ] {
        let out = glint()
            .args(["run"])
            .arg(scenario("debris-geo.toml"))
            .arg("--out")
            .arg(dir.join("never"))
            .args(["--fault", arg])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{arg}: {err}");
        assert!(err.contains(says), "{arg}: {err}");
    }
    let file = scenario_variant(
        "debris-geo.toml",
        &[(
            "seed = 2016\n",
            "seed = 2016\n\n[[fault]]\nservice = \"detector\"\nkind = \"kill\"\n",
        )],
        &dir,
    );
    let out = glint().arg("validate").arg(&file).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        err.contains("field `fault[0].at_seq`: give exactly one of at_seq and at_s"),
        "{err}"
    );
    assert!(!dir.join("never").exists());
    let _ = std::fs::remove_dir_all(&dir);
}
