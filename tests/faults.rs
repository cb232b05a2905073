//! Fault injection against real deployments: `--fault` and `[[fault]]` entries signal real
//! service processes; supervision notices the failure (the process's exit, or its missed
//! heartbeat deadline), restarts the service, and the producers replay what the new
//! incarnation needs. In sim-clock mode the science after any one kill or stop is identical
//! to the fault-free run's, and the report's `faults[]` says when each fault was injected,
//! noticed and recovered from, and that nothing was lost.

mod common;
#[path = "faults/realtime.rs"]
mod realtime;

use std::collections::BTreeMap;

use common::*;
use glint::report::{FaultReport, Report};

fn fault(report: &Report) -> &FaultReport {
    let faults = &report.faults;
    assert_eq!(faults.len(), 1, "{faults:?}");
    &faults[0]
}

/// A time of the fault's record [s], which must be there.
fn secs(v: Option<f64>, what: &str, f: &FaultReport) -> f64 {
    v.unwrap_or_else(|| panic!("{what} missing in {f:?}"))
}

/// What two runs of the same scenario and seed must share whatever faults they survived: the
/// science digest, the science sections, and every topic's content and counts (not the
/// duplicates a replay brings).
fn science(report: &Report) -> impl PartialEq + std::fmt::Debug + '_ {
    let r = &report.results;
    let topics: BTreeMap<&str, _> = r
        .topics
        .iter()
        .map(|(name, t)| {
            let consumers: BTreeMap<&str, _> = t
                .consumers
                .iter()
                .map(|(c, v)| (c.as_str(), (v.received, v.dropped)))
                .collect();
            (name.as_str(), (&t.digest_xxh3, t.published, consumers))
        })
        .collect();
    (
        &r.science,
        &r.detection,
        &r.tracking,
        &r.inversion,
        r.laser.shots,
        topics,
    )
}

/// A fault that supervision noticed and recovered from by one restart, within the targets:
/// noticed < 0.5 s after injection, recovered < 2 s after the fault ended, nothing lost.
fn assert_recovered(f: &FaultReport, detected_by: &str) {
    assert_eq!(f.detected_by.as_deref(), Some(detected_by), "{f:?}");
    assert_eq!(f.restarts, 1, "{f:?}");
    assert_eq!(f.lost, Some(0), "{f:?}");
    assert!(f.invariant_held, "{f:?}");
    let ended = secs(f.ended_s, "ended_s", f);
    let recovered = secs(f.recovered_s, "recovered_s", f) - ended;
    assert!(
        (0.0..2.0).contains(&recovered),
        "recovered {recovered} s after: {f:?}"
    );
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
    let f = fault(&r.typed);
    assert_eq!(f.service, "detector");
    assert_eq!(f.kind, "stop");
    let (injected, ended, recovered) = (
        secs(f.injected_s, "injected_s", f),
        secs(f.ended_s, "ended_s", f),
        secs(f.recovered_s, "recovered_s", f),
    );
    assert!(ended - injected >= 0.4 && ended - injected < 0.5, "{f:?}");
    assert!(recovered >= ended && recovered - ended < 0.5, "{f:?}");
    // Shorter than the 5 s deadline: tolerated, not detected.
    assert!(f.detected_s.is_none(), "{f:?}");
    assert_eq!(f.lost, Some(0));
    assert!(f.invariant_held);
    // The stopped detector held the sensor back by credit: production lasted the stop.
    let production_s = r.typed.timing.production_s;
    assert!(production_s >= 0.4, "production {production_s} s");
    assert_eq!(science(&r.typed), science(&clean.typed));
    let _ = std::fs::remove_dir_all(&dir);
}

/// Each service of the full chain (frames and spectra), SIGKILLed mid-run, is restarted;
/// its producers replay, its consumers skip what they already have, and the results are those
/// of the fault-free run, digest for digest.
#[test]
fn a_killed_service_is_restarted_and_the_science_is_that_of_the_fault_free_run() {
    let dir = temp_dir("fault-kill");
    let clean = run_ok(Some(&scenario("default.toml")), &dir.join("clean"), &[]);
    // (fault, the topic replayed after the restart, the service that replays it)
    for (spec, replayed, producer) in [
        ("detector:kill@10", "frame", "sensor"),
        ("tracker:kill@20", "detections", "detector"),
        ("inversion:kill@40", "spectrum", "sensor"),
        ("sensor:kill@15", "frame", "sensor"),
    ] {
        let service = spec.split(':').next().unwrap();
        let out = dir.join(service);
        let r = run_ok(Some(&scenario("default.toml")), &out, &["--fault", spec]);
        let f = fault(&r.typed);
        assert_eq!(f.service, service);
        assert_recovered(f, "exit");
        let latency = secs(f.detected_s, "detected_s", f) - secs(f.injected_s, "injected_s", f);
        assert!(
            (0.0..0.5).contains(&latency),
            "{spec}: detected {latency} s after"
        );
        assert_eq!(science(&r.typed), science(&clean.typed), "{spec}");
        let restarted = (r.typed.results.services.iter())
            .find(|s| s.name == service)
            .unwrap();
        assert_eq!(restarted.restarts, 1, "{spec}");
        // The replay happened: it reached someone who already had those messages (counted,
        // not received), or, when a consumer's queue kept only the newest of the burst (safe
        // overflow drops the copies it already holds), the producer logged the rewind.
        let topic = &r.typed.results.topics[replayed];
        let duplicates: u64 = (topic.consumers.values())
            .map(|c| c.duplicates.unwrap())
            .sum();
        let read_log = |name: &str| {
            std::fs::read_to_string(out.join("logs").join(format!("{name}.log"))).unwrap()
        };
        let rewind = format!("replay consumer=\"{service}\" topic=\"{replayed}\"");
        assert!(
            duplicates > 0 || (producer != service && read_log(producer).contains(&rewind)),
            "{spec}: {topic:?}"
        );
        let log = read_log(service);
        assert!(log.contains("--- restart 1 ---"), "{spec}: {log}");
    }
    // The summary's table and the timeline show the fault and its recovery.
    let out = dir.join("sensor");
    let summary = std::fs::read_to_string(out.join("summary.md")).unwrap();
    assert!(summary.contains("| sensor | kill@15 |"), "{summary}");
    let svg = Svg::read(&out.join("faults.svg"));
    for name in ["sensor", "detector", "tracker", "inversion"] {
        assert!(svg.has_text(name), "{:?}", svg.texts);
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A stop past the heartbeat deadline: only the deadline notices it; supervision kills the
/// stopped process and restarts it, and the science is unchanged.
#[test]
fn a_stop_past_the_heartbeat_deadline_is_detected_by_it_and_restarted() {
    let dir = temp_dir("fault-long-stop");
    let run_section =
        "[run]\nheartbeat_period_ms = 50\nheartbeat_deadline_ms = 300\nshutdown_grace_ms = 300\n";
    let clean_file = scenario_variant(
        "debris-geo.toml",
        &[("seed = 2016\n", &format!("seed = 2016\n\n{run_section}"))],
        &dir,
    );
    let clean = run_ok(Some(&clean_file), &dir.join("clean"), &[]);
    let file = scenario_variant(
        "debris-geo.toml",
        &[(
            "seed = 2016\n",
            &format!("seed = 2016\n\n{run_section}\n[[fault]]\nservice = \"tracker\"\nkind = \"stop\"\nat_seq = 5\nduration_s = 30.0\n"),
        )],
        &dir,
    );
    let r = run_ok(Some(&file), &dir.join("out"), &[]);
    let f = fault(&r.typed);
    assert_recovered(f, "heartbeat deadline");
    let detected = secs(f.detected_s, "detected_s", f);
    let latency = detected - secs(f.injected_s, "injected_s", f);
    // The deadline runs from the last heartbeat heard, up to one period before the stop and
    // another period earlier when a loaded machine delays that heartbeat (so ≥ 300 − 2·50 ms);
    // at most the deadline plus the target's 0.1 s and a supervision tick's margin.
    assert!((0.2..0.5).contains(&latency), "detected {latency} s after");
    // The stop ended when supervision killed it, long before its 30 s.
    assert_eq!(secs(f.ended_s, "ended_s", f), detected, "{f:?}");
    assert_eq!(science(&r.typed), science(&clean.typed));
    assert_eq!(
        ending(&r.typed, "tracker"),
        "shutdown",
        "{:?}",
        r.typed.results.services
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// `restart = "never"` (here for the detector only) and an exhausted budget fail the run with
/// the rule named; the kill is still detected and what it cost counted.
#[test]
fn without_restarts_a_killed_service_fails_the_run_naming_the_rule() {
    let dir = temp_dir("fault-never");
    let file = scenario_variant(
        "debris-geo.toml",
        &[(
            "seed = 2016\n",
            "seed = 2016\n\n[supervision.services.detector]\nrestart = \"never\"\n",
        )],
        &dir,
    );
    let out = dir.join("out");
    let r = run(Some(&file), &out, &["--fault", "detector:kill@10"]);
    assert_eq!(r.output.status.code(), Some(1));
    let failure = r.typed.results.failure.as_deref().unwrap();
    assert!(
        failure.contains("service detector exited unexpectedly")
            && failure.contains("(injected fault: detector:kill@10)")
            && failure.contains("not restarted: supervision.restart = \"never\""),
        "{failure}"
    );
    let f = fault(&r.typed);
    assert_eq!(f.detected_by.as_deref(), Some("exit"));
    assert!(f.recovered_s.is_none(), "{f:?}");
    assert_eq!(f.restarts, 0);
    // Lost: frames published to the detector that it never took.
    let frames = &r.typed.results.topics["frame"];
    let taken = (frames.consumers.get("detector"))
        .and_then(|c| c.received)
        .unwrap_or(0);
    let lost = f.lost.unwrap();
    assert_eq!(lost, frames.published.unwrap() - taken, "{frames:?}");
    assert!(lost > 0, "{frames:?}");
    assert!(!f.invariant_held);
    // Two kills against a budget of one restart.
    let file = scenario_variant(
        "debris-geo.toml",
        &[(
            "seed = 2016\n",
            "seed = 2016\n\n[supervision]\nmax_restarts = 1\n",
        )],
        &dir,
    );
    let r = run(
        Some(&file),
        &dir.join("budget"),
        &["--fault", "tracker:kill@10", "--fault", "tracker:kill@30"],
    );
    assert_eq!(r.output.status.code(), Some(1));
    let failure = r.typed.results.failure.as_deref().unwrap();
    assert!(
        failure.contains("supervision.max_restarts = 1"),
        "{failure}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_bad_fault_is_bad_input_naming_the_argument_or_the_field() {
    let dir = temp_dir("fault-bad");
    for (arg, says) in [
        ("detector:explode@3", "--fault `detector:explode@3`: unknown kind `explode`; allowed: kill, stop, panic, delay, drop, corrupt"),
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

/// `scenarios/faults-matrix.toml`: the baseline, then every service × every kind (kill, stop,
/// panic, delay, drop, corrupt). Every case detected, recovered and accounted for (the time
/// targets are figures, not asserted), the matrix in summary.md, and the campaign's report
/// listing every case's fault with its case name.
#[test]
fn the_fault_matrix_passes_every_invariant() {
    let dir = temp_dir("fault-matrix");
    let out = dir.join("matrix");
    let (output, matrix) = run_matrix(&scenario("faults-matrix.toml"), &out, &[]);
    let summary = std::fs::read_to_string(out.join("summary.md")).unwrap();
    assert!(output.status.success(), "{summary}");
    assert!(matrix.success);
    let cases = &matrix.cases;
    assert_eq!(cases.len(), 30, "5 services × 6 kinds: {cases:?}");
    for c in cases {
        assert!(c.passed, "{c:?}");
    }
    let faults = &matrix.faults;
    assert_eq!(faults.len(), 30);
    for case_fault in faults {
        let f = &case_fault.fault;
        assert_eq!(case_fault.case, format!("{}-{}", f.service, f.kind));
        match f.kind.as_str() {
            "drop" | "corrupt" => {
                assert!(f.science_equal.is_none(), "{case_fault:?}");
                assert!(f.injected.unwrap() > 0, "{case_fault:?}");
                assert_eq!(f.injected, f.counted, "{case_fault:?}");
            }
            "delay" => assert_eq!(f.science_equal, Some(true), "{case_fault:?}"),
            _ => {
                assert_eq!(f.science_equal, Some(true), "{case_fault:?}");
                assert_eq!(f.restarts, 1, "{case_fault:?}");
                assert_eq!(f.lost, Some(0), "{case_fault:?}");
            }
        }
    }
    assert!(summary.contains("fault matrix: PASS"), "{summary}");
    // The grid: a row per service, a ✓ per kind (timing, "late", is this machine's figure).
    for service in ["sensor", "detector", "tracker", "inversion", "earth"] {
        let row = summary
            .lines()
            .find(|l| l.starts_with(&format!("| {service} |")))
            .unwrap_or_else(|| panic!("no row for {service}: {summary}"));
        assert_eq!(row.matches('✓').count(), 6, "{row}");
    }
    // Each case keeps its own run directory; the baseline's science is what they were held to.
    let base = read_report(&out.join("baseline").join("report.json"));
    let kill = read_report(&out.join("tracker-kill").join("report.json"));
    assert_eq!(base.results.science, kill.results.science);
    assert!(base.faults.is_empty(), "{:?}", base.faults);
    let _ = std::fs::remove_dir_all(&dir);
}

/// In-band faults are obeyed only where the scenario enables them; `--fault` enables them.
#[test]
fn in_band_faults_need_faults_enabled_in_the_scenario() {
    let dir = temp_dir("fault-enabled");
    let file = scenario_variant(
        "debris-geo.toml",
        &[(
            "seed = 2016\n",
            "seed = 2016\n\n[[fault]]\nservice = \"detector\"\nkind = \"panic\"\nat_seq = 5\n",
        )],
        &dir,
    );
    let out = glint().arg("validate").arg(&file).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("fault[0].kind") && err.contains("faults.enabled = true"),
        "{err}"
    );
    // On the command line the wish is explicit: obeyed; a corrupted detections message is
    // rejected by the tracker and the orchestrator and counted.
    let r = run_ok(
        Some(&scenario("debris-geo.toml")),
        &dir.join("corrupt"),
        &["--fault", "detector:corrupt@10,how=count,count=3"],
    );
    let f = fault(&r.typed);
    assert_eq!((f.injected, f.counted), (Some(3), Some(3)), "{f:?}");
    for c in ["tracker", "orchestrator"] {
        let by = &r.typed.results.topics["detections"].consumers[c].dropped_by_reason;
        let reason = |k: &str| by.as_ref().and_then(|by| by.get(k).copied());
        assert_eq!(reason("malformed"), Some(3), "{c}: {by:?}");
        assert_eq!(reason("overflow"), Some(0), "{c}: {by:?}");
    }
    assert!(r.typed.results.accounting.invariant_held);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A restarted service takes up its last checkpoint and is fed again only the inputs after
/// it: the detector, the tracker (whose input the detector replays from a log trimmed to the
/// tracker's checkpoints) and the sensor, each killed late in the run. The science is the
/// fault-free run's; the negative control (checkpoints too rare to be taken) replays from the
/// first input and restores nothing.
#[test]
fn a_restart_resumes_from_its_checkpoint_and_replays_only_what_came_after() {
    let dir = temp_dir("fault-checkpoint");
    let every = |n: &str, ms: &str| {
        let sub = dir.join(format!("every-{n}"));
        std::fs::create_dir_all(&sub).unwrap();
        let table = format!(
            "[supervision]\ncheckpoint_every_inputs = {n}\ncheckpoint_every_ms = {ms}\n\n[camera]\n"
        );
        scenario_variant("debris-geo.toml", &[("[camera]\n", table.as_str())], &sub)
    };
    let (often, never) = (every("8", "600000"), every("1000000", "600000"));
    let clean = run_ok(Some(&often), &dir.join("clean"), &[]);
    for spec in ["detector:kill@40", "tracker:kill@40", "sensor:kill@40"] {
        let service = spec.split(':').next().unwrap();
        let replayed = |file: &std::path::Path, name: &str| {
            let out = dir.join(format!("{service}-{name}"));
            let r = run_ok(Some(file), &out, &["--fault", spec]);
            assert_eq!(science(&r.typed), science(&clean.typed), "{spec} {name}");
            let f = fault(&r.typed);
            assert_recovered(f, "exit");
            let log =
                std::fs::read_to_string(out.join("logs").join(format!("{service}.log"))).unwrap();
            (
                f.replayed.expect("a restart says what it replayed"),
                log.contains("restored its checkpoint"),
            )
        };
        let (with, restored) = replayed(&often, "often");
        let (without, restored_without) = replayed(&never, "never");
        assert!(restored && !restored_without, "{spec}");
        assert!(
            with < without && without >= 20,
            "{spec}: replayed {with} with checkpoints every 8 inputs, {without} without"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A delay counted in inputs that outlasts the inputs (1000 from frame 10 of 50; in the fault
/// matrix an order can land late, since sim-clock producers run ahead of it by up to their
/// credit window, further on a faster host): it is over when the inputs are, so the verdict
/// does not depend on how far ahead the producers were.
#[test]
fn a_delay_counted_past_the_last_input_ends_with_the_run() {
    let dir = temp_dir("fault-delay-past-end");
    let r = run_ok(
        Some(&scenario("debris-geo.toml")),
        &dir.join("out"),
        &["--fault", "detector:delay@10,count=1000,delay_ms=5"],
    );
    assert!(r.typed.results.success, "{:?}", r.typed.results.failure);
    let f = fault(&r.typed);
    assert!(f.injected_s.is_some(), "{f:?}");
    assert_eq!(f.not_reached, None, "{f:?}");
    let (ended, recovered) = (f.ended_s.unwrap(), f.recovered_s.unwrap());
    assert!(recovered >= ended, "{f:?}");
    // it took effect: the detector says how many inputs it slowed before the inputs ended
    let log = std::fs::read_to_string(r.dir.join("logs/detector.log")).unwrap();
    let line = (log.lines())
        .find(|l| l.contains("delay over (the run's inputs ended first)"))
        .unwrap_or_else(|| panic!("{log}"));
    let slowed: u64 = (line.split("slowed=").nth(1))
        .and_then(|v| v.split_whitespace().next())
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("{line}"));
    assert!((1..=40).contains(&slowed), "{line}");
    let _ = std::fs::remove_dir_all(&dir);
}
