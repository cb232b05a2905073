//! How `glint run` fails: a service that dies or hangs, a run past `run.timeout_s`, shared
//! memory a process outside the deployment still holds. Each ends with exit 1, a report that
//! says why, every child stopped and nothing of the deployment left behind. Real processes,
//! real signals, real shared memory; deadlines, not sleeps, decide when to look.

mod common;

use std::time::{Duration, Instant};

use common::procs::*;
use common::*;
use rustix::process::{kill_process, Signal};

/// A long debris run (20000 frames, many seconds) with `run` settings added.
fn long_debris(dir: &std::path::Path, run: &str) -> std::path::PathBuf {
    scenario_variant(
        "debris-geo.toml",
        &[
            ("frames = 50", "frames = 20000"),
            ("seed = 2016\n", &format!("seed = 2016\n\n[run]\n{run}\n")),
        ],
        dir,
    )
}

/// A detector killed (SIGKILL) in the middle of a run that may not restart it: `glint run`
/// exits 1, the report says
/// which service died and how; every topic's `published` is at least what its consumers
/// received (a killed publisher's last heartbeat undercounted it), and the production time
/// and rates cover the frames produced until the failure (they read 0).
#[test]
fn a_killed_service_fails_the_run_with_a_consistent_report() {
    let dir = temp_dir("kill-detector");
    let file = scenario_variant(
        "debris-geo.toml",
        &[
            ("frames = 50", "frames = 20000"),
            (
                "seed = 2016\n",
                "seed = 2016\n\n[supervision]\nrestart = \"never\"\n",
            ),
        ],
        &dir,
    );
    let out = dir.join("out");
    let mut run = start_run(&file, &out, &[]);
    // Kill it once frames flow: startup takes about 0.1 s and 20000 frames many seconds, so
    // one second in is mid-run (the frame count below checks it).
    let pid = wait_for_service(&run, "detector", Duration::from_millis(20));
    std::thread::sleep(Duration::from_secs(1));
    kill_process(pid, Signal::KILL).expect("SIGKILL");
    let status = wait_for_exit(&mut run, Duration::from_secs(120));
    assert_eq!(status.code(), Some(1));
    let report = read_report(&out.join("report.json"));
    assert!(!report.results.success);
    let failure = report.results.failure.as_deref().unwrap_or_default();
    assert!(
        failure.contains("detector") && failure.contains("SIGKILL"),
        "{failure}"
    );
    for (topic, t) in &report.results.topics {
        for (name, c) in &t.consumers {
            if let (Some(p), Some(r)) = (t.published, c.received) {
                assert!(p >= r, "{topic}: published {p} < received {r} by {name}");
            }
        }
    }
    let frames = report.results.topics["frame"].published.unwrap();
    assert!(frames > 0 && frames < 20000, "{frames} frames");
    let timing = &report.timing;
    let production_s = timing.production_s;
    let fps = timing.frames_per_s;
    assert!(production_s > 0.3, "{timing:?}");
    assert!(
        (fps * production_s - frames as f64).abs() <= 1.0,
        "{timing:?}, {frames} frames"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A service killed while the deployment starts leaves nothing of the run in `/dev/shm` or in
/// iceoryx2's node directories, and the report's leftover check covers both (before, the
/// dead node's directory stayed under /tmp/iceoryx2/nodes in 2 of 4 tries, with `leftover: []`).
#[test]
fn a_service_killed_during_startup_leaves_no_node_behind() {
    let dir = temp_dir("kill-at-startup");
    for attempt in 0..4 {
        let out = dir.join(format!("out{attempt}"));
        let mut run = start_run(&scenario("debris-geo.toml"), &out, &[]);
        let pid = wait_for_service(&run, "tracker", Duration::from_millis(1));
        kill_process(pid, Signal::KILL).expect("SIGKILL");
        let status = wait_for_exit(&mut run, Duration::from_secs(120));
        assert_eq!(status.code(), Some(1), "attempt {attempt}");
        let report = read_report(&out.join("report.json"));
        let prefix = &report.run.prefix;
        let leftover = &report.results.shared_memory.leftover;
        assert!(leftover.is_empty(), "attempt {attempt}: {leftover:?}");
        let left = shm_left(prefix);
        assert!(left.is_empty(), "attempt {attempt}: {left:?}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A SIGSTOPped detector still looks alive to waitpid: only the heartbeat deadline catches it.
/// Without restarts the run fails with the deadline named; the stop ladder finds the detector deaf to
/// `Shutdown` and SIGTERM (both wait while it is stopped) and ends it with SIGKILL, while the
/// others stop on `Shutdown`; the accounting shows the frames the detector never took.
#[test]
fn a_hung_service_is_caught_by_the_heartbeat_deadline_and_killed_by_the_ladder() {
    let dir = temp_dir("hang-detector");
    let file = long_debris(
        &dir,
        "heartbeat_period_ms = 50\nheartbeat_deadline_ms = 400\nshutdown_grace_ms = 300\n\n[supervision]\nrestart = \"never\"",
    );
    let out = dir.join("out");
    let mut run = start_run(&file, &out, &[]);
    let pid = wait_for_service(&run, "detector", Duration::from_millis(5));
    wait_for_start(&out);
    let stopped_at = Instant::now();
    kill_process(pid, Signal::STOP).expect("SIGSTOP");
    let status = wait_for_exit(&mut run, Duration::from_secs(60));
    // Detection within the deadline (plus heartbeat period and tick), then two grace periods.
    let took = stopped_at.elapsed();
    assert_eq!(status.code(), Some(1));
    assert!(
        took < Duration::from_secs(5),
        "the run took {took:?} to fail"
    );
    let report = read_report(&out.join("report.json"));
    assert!(!report.results.success);
    let failure = report.results.failure.as_deref().unwrap_or_default();
    assert!(
        failure.contains("service detector sent no heartbeat")
            && failure.contains("run.heartbeat_deadline_ms = 400 ms"),
        "{failure}"
    );
    let services = &report.results.services;
    assert_eq!(ending(&report, "detector"), "sigkill", "{services:?}");
    for name in ["sensor", "tracker"] {
        assert_eq!(ending(&report, name), "shutdown", "{name}: {services:?}");
    }
    assert!(!report.results.accounting.invariant_held);
    let frames = &report.results.topics["frame"];
    assert!(frames.published.unwrap() < 20000, "{frames:?}");
    assert_eq!(
        process_state(pid.as_raw_nonzero().get() as u32),
        None,
        "the detector lives on"
    );
    let leftover = &report.results.shared_memory.leftover;
    assert!(leftover.is_empty(), "{leftover:?}");
    let prefix = &report.run.prefix;
    assert!(shm_left(prefix).is_empty(), "{:?}", shm_left(prefix));
    let _ = std::fs::remove_dir_all(&dir);
}

/// A run still producing at `run.timeout_s` fails with the limit named, stops every service on
/// `Shutdown` and accounts for the frames produced until then.
#[test]
fn a_run_past_its_timeout_fails_and_stops_every_service() {
    let dir = temp_dir("timeout");
    let file = long_debris(&dir, "timeout_s = 1.0");
    let out = dir.join("out");
    let t0 = Instant::now();
    let mut run = start_run(&file, &out, &[]);
    let status = wait_for_exit(&mut run, Duration::from_secs(60));
    assert_eq!(status.code(), Some(1));
    assert!(t0.elapsed() < Duration::from_secs(20), "{:?}", t0.elapsed());
    let report = read_report(&out.join("report.json"));
    let failure = report.results.failure.as_deref().unwrap_or_default();
    assert!(
        failure.contains("run exceeded run.timeout_s = 1 s"),
        "{failure}"
    );
    let services = &report.results.services;
    for name in ["sensor", "detector", "tracker"] {
        assert_eq!(ending(&report, name), "shutdown", "{name}: {services:?}");
    }
    assert!(!report.results.accounting.invariant_held);
    let published = report.results.topics["frame"].published.unwrap();
    assert!(published > 0 && published < 20000, "{published} frames");
    let production_s = report.timing.production_s;
    assert!(production_s > 0.0 && production_s < 1.0, "{production_s}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A process outside the deployment that holds a node under its prefix when the run ends (an
/// observer: a Python client, `glint top`) keeps the prefix's files alive: the run leaves them
/// in place (they are that process's), lists them as leftovers and names the holder, and
/// passes: an observer never decides a run's outcome. Once the holder is gone, `glint clean
/// --prefix` removes everything.
#[test]
fn a_prefix_still_held_at_the_end_is_reported_not_failed_and_glint_clean_removes_it() {
    let dir = temp_dir("held-prefix");
    let out = dir.join("out");
    let mut run = start_run(&scenario("debris-geo.toml"), &out, &[]);
    let pid = wait_for_service(&run, "detector", Duration::from_millis(2));
    let prefix = prefix_of(pid);
    let holder = glint_runtime::open_node(&prefix, "holder").expect("a node under the prefix");
    let status = wait_for_exit(&mut run, Duration::from_secs(120));
    assert_eq!(status.code(), Some(0));
    let report = read_report(&out.join("report.json"));
    let shared_memory = &report.results.shared_memory;
    assert_eq!(shared_memory.held_by, ["holder"]);
    assert!(!shared_memory.leftover.is_empty(), "{shared_memory:?}");
    assert!(report.results.success, "{:?}", report.results.failure);
    assert!(report.results.accounting.invariant_held);
    let summary = std::fs::read_to_string(out.join("summary.md")).unwrap();
    assert!(
        summary.contains("held by node(s) holder outside the deployment")
            && summary.contains(&format!("glint clean --prefix {prefix}")),
        "{summary}"
    );
    // While the holder lives, `glint clean` leaves the prefix alone.
    let text = |o: std::process::Output| {
        assert!(o.status.success(), "{o:?}");
        String::from_utf8_lossy(&o.stdout).into_owned()
    };
    let cleaned = text(
        glint()
            .args(["clean", "--prefix", &prefix])
            .output()
            .unwrap(),
    );
    assert!(
        cleaned.contains("in use by live node(s) holder"),
        "{cleaned}"
    );
    assert!(!shm_left(&prefix).is_empty());
    drop(holder);
    let cleaned = text(
        glint()
            .args(["clean", "--prefix", &prefix])
            .output()
            .unwrap(),
    );
    assert!(cleaned.contains(&format!("{prefix}: ")), "{cleaned}");
    assert!(shm_left(&prefix).is_empty(), "{:?}", shm_left(&prefix));
    // A prefix that is not a deployment's is refused, never matched against everything.
    let out = glint().args(["clean", "--prefix", ""]).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    let _ = std::fs::remove_dir_all(&dir);
}

/// A SIGKILLed orchestrator takes its services with it (parent-death signal, and each service
/// watches its parent), a SIGSTOPped one included (its orphaned process group gets SIGHUP and
/// SIGCONT); `glint clean` then removes everything the deployment left.
#[test]
fn a_killed_orchestrator_leaves_no_service_running_and_glint_clean_leaves_nothing() {
    let dir = temp_dir("kill-orchestrator");
    let file = long_debris(&dir, "timeout_s = 120.0");
    let out = dir.join("out");
    let mut run = start_run(&file, &out, &[]);
    let services: Vec<_> = ["sensor", "detector", "tracker"]
        .map(|name| wait_for_service(&run, name, Duration::from_millis(5)))
        .into();
    let prefix = prefix_of(services[0]);
    wait_for_start(&out);
    kill_process(services[1], Signal::STOP).expect("SIGSTOP the detector");
    wait_for_state(services[1].as_raw_nonzero().get() as u32, |s| s == 'T');
    run.0.kill().expect("SIGKILL the orchestrator");
    run.0.wait().expect("reap");
    let killed = Instant::now();
    for pid in &services {
        let pid = pid.as_raw_nonzero().get() as u32;
        // Gone, or a zombie init has not reaped yet.
        while process_state(pid).is_some_and(|s| s != 'Z') {
            assert!(
                killed.elapsed() < Duration::from_millis(500),
                "service {pid} outlived its orchestrator by 0.5 s: state {:?}",
                process_state(pid)
            );
            std::thread::sleep(Duration::from_millis(5));
        }
    }
    assert!(
        !shm_left(&prefix).is_empty(),
        "a killed orchestrator leaves its services' files"
    );
    let cleaned = glint()
        .args(["clean", "--prefix", &prefix])
        .output()
        .unwrap();
    assert!(cleaned.status.success(), "{cleaned:?}");
    assert!(shm_left(&prefix).is_empty(), "{:?}", shm_left(&prefix));
    let _ = std::fs::remove_dir_all(&dir);
}

/// SIGHUP (a closed terminal) ends a run like SIGTERM: the services stop on `Shutdown`, the
/// report says why, nothing is left.
#[test]
fn sighup_ends_a_run_cleanly() {
    let dir = temp_dir("sighup");
    let file = long_debris(&dir, "timeout_s = 120.0");
    let out = dir.join("out");
    let mut run = start_run(&file, &out, &[]);
    wait_for_start(&out);
    let pid = rustix::process::Pid::from_child(&run.0);
    kill_process(pid, Signal::HUP).expect("SIGHUP");
    let status = wait_for_exit(&mut run, Duration::from_secs(30));
    assert_eq!(status.code(), Some(1));
    let report = read_report(&out.join("report.json"));
    assert_eq!(
        report.results.failure.as_deref(),
        Some("interrupted by a signal")
    );
    let services = &report.results.services;
    for name in ["sensor", "detector", "tracker"] {
        assert_eq!(ending(&report, name), "shutdown", "{name}: {services:?}");
    }
    let prefix = &report.run.prefix;
    assert!(shm_left(prefix).is_empty(), "{:?}", shm_left(prefix));
    let _ = std::fs::remove_dir_all(&dir);
}

/// A stranger that joins a running deployment as one of its services (`glint service detector
/// --prefix <the live prefix>`) is named in the report and fails the run with a clear reason;
/// an observer (any other node) is named too, and does not fail it.
#[test]
fn a_stranger_joining_a_deployment_as_a_service_fails_the_run_and_is_named() {
    let dir = temp_dir("stranger");
    let file = long_debris(&dir, "timeout_s = 60.0");
    let out = dir.join("out");
    let mut run = start_run(&file, &out, &[]);
    let pid = wait_for_service(&run, "detector", Duration::from_millis(5));
    wait_for_start(&out);
    let prefix = prefix_of(pid);
    let observer = glint_runtime::open_node(&prefix, "viewer").expect("a node under the prefix");
    let stranger = KillOnDrop(
        glint()
            .args(["service", "detector", "--prefix", &prefix, "--scenario"])
            .arg(out.join("scenario.toml"))
            .stderr(std::process::Stdio::null())
            .spawn()
            .expect("spawn the stranger"),
    );
    let status = wait_for_exit(&mut run, Duration::from_secs(60));
    assert_eq!(status.code(), Some(1));
    let report = read_report(&out.join("report.json"));
    let failure = report.results.failure.as_deref().unwrap_or_default();
    let stranger_pid = stranger.0.id();
    assert!(
        failure.contains(&format!(
            "a process outside the deployment (pid {stranger_pid}) joined it as node `detector`"
        )),
        "{failure}"
    );
    let strangers = &report.membership.strangers;
    let role = |name: &str| {
        (strangers.iter())
            .find(|s| s.name == name)
            .map(|s| s.role.clone())
    };
    assert_eq!(
        role("detector").as_deref(),
        Some("impostor"),
        "{strangers:?}"
    );
    assert_eq!(role("viewer").as_deref(), Some("observer"), "{strangers:?}");
    drop(stranger);
    drop(observer);
    let cleaned = glint()
        .args(["clean", "--prefix", &prefix])
        .output()
        .unwrap();
    assert!(cleaned.status.success());
    assert!(shm_left(&prefix).is_empty(), "{:?}", shm_left(&prefix));
    let _ = std::fs::remove_dir_all(&dir);
}
