//! A service survives SIGSTOP + SIGCONT (iceoryx2 raises `Interrupt` on SIGCONT; the loop must
//! not treat it as a stop), keeps heartbeating afterwards, and exits 0 on a `Shutdown` control
//! message. Real process, real shared memory.

mod common;

use std::process::Stdio;
use std::time::{Duration, Instant};

use common::*;
use glint_runtime::ports::{Inbox, Outbox};
use glint_runtime::{open_node, remove_shm, shm_entries};
use rustix::process::{kill_process, Pid, Signal};
use shared_types::topics::{control_service, create_all, heartbeat_service};
use shared_types::{Command, Control, Heartbeat, ServiceId, TopicId};

struct KillOnDrop(std::process::Child);
impl Drop for KillOnDrop {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// The fields of `PROC_DIR/stat` after the parenthesised command name: state, ppid, …
fn stat_fields(proc_dir: &str) -> Option<Vec<String>> {
    let stat = std::fs::read_to_string(format!("{proc_dir}/stat")).ok()?;
    let (_, rest) = stat.rsplit_once(')')?;
    Some(rest.split_whitespace().map(str::to_string).collect())
}

/// Waits (at most 5 s) until the process state in `/proc/PID/stat` satisfies `ok`.
fn wait_for_state(pid: u32, ok: impl Fn(char) -> bool) {
    let t0 = Instant::now();
    loop {
        let state = stat_fields(&format!("/proc/{pid}"))
            .and_then(|f| f.first().and_then(|s| s.chars().next()));
        if state.is_some_and(&ok) {
            return;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(5),
            "process {pid} state {state:?}"
        );
        std::thread::sleep(Duration::from_millis(2));
    }
}

fn heartbeats_within(hb: &mut Inbox<Heartbeat>, window: Duration) -> usize {
    let t0 = Instant::now();
    let mut n = 0;
    while t0.elapsed() < window {
        hb.drain(|r| {
            n += (r.msg.meta.producer == ServiceId::Sensor as u32) as usize;
            Ok(())
        })
        .unwrap();
        std::thread::sleep(Duration::from_millis(10));
    }
    n
}

#[test]
fn sigstop_sigcont_does_not_end_a_service_and_shutdown_does() {
    let prefix = format!("glt{}s_", std::process::id() % 100_000);
    {
        let node = open_node(&prefix, "test-orchestrator").unwrap();
        let _services = create_all(&node).unwrap();
        let (mut hb, _l) = Inbox::<Heartbeat>::open(
            &node,
            TopicId::Heartbeat,
            &heartbeat_service(&node).unwrap(),
        )
        .unwrap();
        let mut control = Outbox::open(
            &node,
            TopicId::Control,
            &control_service(&node).unwrap(),
            ServiceId::Orchestrator,
        )
        .unwrap();
        let mut sensor = KillOnDrop(
            glint()
                .args(["service", "sensor", "--prefix", &prefix, "--scenario"])
                .arg(scenario("debris-geo.toml"))
                .stderr(Stdio::null())
                .spawn()
                .unwrap(),
        );
        let pid = Pid::from_child(&sensor.0);
        assert!(
            heartbeats_within(&mut hb, Duration::from_millis(600)) > 0,
            "no heartbeat"
        );

        kill_process(pid, Signal::STOP).expect("SIGSTOP");
        wait_for_state(sensor.0.id(), |s| s == 'T');
        let _ = heartbeats_within(&mut hb, Duration::from_millis(50)); // drain what was queued
                                                                       // Stopped, the service sends nothing: SIGSTOP took effect.
        assert_eq!(
            heartbeats_within(&mut hb, Duration::from_millis(500)),
            0,
            "heartbeats while SIGSTOPped"
        );
        kill_process(pid, Signal::CONT).expect("SIGCONT");
        wait_for_state(sensor.0.id(), |s| s != 'T');
        assert!(
            sensor.0.try_wait().unwrap().is_none(),
            "SIGCONT ended the service"
        );
        assert!(
            heartbeats_within(&mut hb, Duration::from_millis(600)) > 0,
            "no heartbeat after SIGCONT"
        );

        let shutdown = Control {
            command: Command::Shutdown as u32,
            target: ServiceId::Sensor as u32,
            ..Default::default()
        };
        control.send(shutdown, 0).unwrap();
        let t0 = Instant::now();
        let status = loop {
            if let Some(s) = sensor.0.try_wait().unwrap() {
                break s;
            }
            assert!(
                t0.elapsed() < Duration::from_secs(5),
                "Shutdown did not stop the service"
            );
            std::thread::sleep(Duration::from_millis(10));
        };
        assert!(status.success(), "{status}");
    }
    remove_shm(&prefix);
    assert!(shm_entries(&prefix).is_empty());
}

#[test]
fn sigterm_stops_a_campaign_instead_of_starting_the_next_deployment() {
    // A 30-seed Monte-Carlo campaign; SIGTERM once the first noisy deployment has started.
    let dir = temp_dir("campaign-sigterm");
    let file = scenario_variant(
        "campaign-efficiency.toml",
        &[("seeds = 50", "seeds = 30")],
        &dir,
    );
    let out = dir.join("out");
    let child = glint()
        .args(["lab", "campaign"])
        .arg(&file)
        .arg("--out")
        .arg(&out)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn glint");
    let mut child = KillOnDrop(child);
    let t0 = Instant::now();
    while !out.join("00/s000").exists() {
        assert!(
            t0.elapsed() < Duration::from_secs(120),
            "no deployment started"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    kill_process(Pid::from_child(&child.0), Signal::TERM).expect("SIGTERM");
    let t1 = Instant::now();
    let status = loop {
        if let Some(s) = child.0.try_wait().expect("wait") {
            break s;
        }
        assert!(
            t1.elapsed() < Duration::from_secs(60),
            "campaign kept running"
        );
        std::thread::sleep(Duration::from_millis(20));
    };
    let mut stderr = String::new();
    use std::io::Read;
    child
        .0
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut stderr)
        .unwrap();
    assert!(!status.success(), "{stderr}");
    assert!(
        stderr.contains("campaign interrupted by a signal"),
        "{stderr}"
    );
    let seeds = std::fs::read_dir(out.join("00"))
        .unwrap()
        .filter(|e| {
            e.as_ref()
                .unwrap()
                .file_name()
                .to_string_lossy()
                .starts_with('s')
        })
        .count();
    // The deployment the signal interrupted, and no other: the campaign stops there.
    assert_eq!(seeds, 1, "{seeds} deployments started after the SIGTERM");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The children of `parent` whose command line is `glint service <name> …`.
fn service_pid(parent: u32, name: &str) -> Option<i32> {
    for entry in std::fs::read_dir("/proc").ok()?.flatten() {
        let Ok(pid) = entry.file_name().to_string_lossy().parse::<i32>() else {
            continue;
        };
        let cmdline = std::fs::read(entry.path().join("cmdline")).unwrap_or_default();
        let args: Vec<&[u8]> = cmdline.split(|&b| b == 0).collect();
        let is_service = args.len() > 2 && args[1] == b"service" && args[2] == name.as_bytes();
        let ppid = stat_fields(&entry.path().to_string_lossy())
            .and_then(|f| f.get(1).and_then(|p| p.parse::<u32>().ok()));
        if is_service && ppid == Some(parent) {
            return Some(pid);
        }
    }
    None
}

/// `glint run FILE --out OUT`, killed if the test ends first.
fn start_run(file: &std::path::Path, out: &std::path::Path) -> KillOnDrop {
    KillOnDrop(
        glint()
            .arg("run")
            .arg(file)
            .arg("--out")
            .arg(out)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("spawn glint"),
    )
}

/// The pid of the run's service `name` once it exists (polled every `poll`, at most 60 s).
fn wait_for_service(run: &KillOnDrop, name: &str, poll: Duration) -> Pid {
    let t0 = Instant::now();
    loop {
        if let Some(pid) = service_pid(run.0.id(), name) {
            return Pid::from_raw(pid).expect("pid");
        }
        assert!(t0.elapsed() < Duration::from_secs(60), "no {name} started");
        std::thread::sleep(poll);
    }
}

/// The run's exit status (at most 120 s).
fn wait_for_exit(run: &mut KillOnDrop) -> std::process::ExitStatus {
    let t0 = Instant::now();
    loop {
        if let Some(s) = run.0.try_wait().expect("wait") {
            return s;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(120),
            "the run did not end"
        );
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// A detector killed (SIGKILL) in the middle of a run: `glint run` exits 1, the report says
/// which service died and how; every topic's `published` is at least what its consumers
/// received (a killed publisher's last heartbeat undercounted it), and the production time
/// and rates cover the frames produced until the failure (they read 0).
#[test]
fn a_killed_service_fails_the_run_with_a_consistent_report() {
    let dir = temp_dir("kill-detector");
    let file = scenario_variant(
        "debris-geo.toml",
        &[("frames = 50", "frames = 20000")],
        &dir,
    );
    let out = dir.join("out");
    let mut run = start_run(&file, &out);
    // Kill it once frames flow: startup takes about 0.1 s and 20000 frames many seconds, so
    // one second in is mid-run (the frame count below checks it).
    let pid = wait_for_service(&run, "detector", Duration::from_millis(20));
    std::thread::sleep(Duration::from_secs(1));
    kill_process(pid, Signal::KILL).expect("SIGKILL");
    let status = wait_for_exit(&mut run);
    assert_eq!(status.code(), Some(1));
    let report = read_json(&out.join("report.json"));
    assert_eq!(report["success"], false);
    let failure = report["failure"].as_str().unwrap_or_default();
    assert!(
        failure.contains("detector") && failure.contains("SIGKILL"),
        "{failure}"
    );
    for (topic, t) in report["topics"].as_object().unwrap() {
        let published = t["published"].as_u64();
        for (name, c) in t["consumers"].as_object().unwrap() {
            if let (Some(p), Some(r)) = (published, c["received"].as_u64()) {
                assert!(p >= r, "{topic}: published {p} < received {r} by {name}");
            }
        }
    }
    let frames = report["topics"]["frame"]["published"].as_u64().unwrap();
    assert!(frames > 0 && frames < 20000, "{frames} frames");
    let timing = &report["timing"];
    let production_s = timing["production_s"].as_f64().unwrap();
    let fps = timing["frames_per_s"].as_f64().unwrap();
    assert!(production_s > 0.3, "{timing}");
    assert!(
        (fps * production_s - frames as f64).abs() <= 1.0,
        "{timing}, {frames} frames"
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
        let mut run = start_run(&scenario("debris-geo.toml"), &out);
        let pid = wait_for_service(&run, "tracker", Duration::from_millis(1));
        kill_process(pid, Signal::KILL).expect("SIGKILL");
        let status = wait_for_exit(&mut run);
        assert_eq!(status.code(), Some(1), "attempt {attempt}");
        let report = read_json(&out.join("report.json"));
        let prefix = report["run"]["prefix"]
            .as_str()
            .expect("prefix")
            .to_string();
        assert_eq!(report["shared_memory"]["leftover"], serde_json::json!([]));
        let left = shm_left(&prefix);
        assert!(left.is_empty(), "attempt {attempt}: {left:?}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}
