//! A service survives SIGSTOP + SIGCONT (iceoryx2 raises `Interrupt` on SIGCONT; the loop must
//! not treat it as a stop), keeps heartbeating afterwards, and exits 0 on a `Shutdown` control
//! message. Real process, real shared memory.

mod common;

use std::process::Stdio;
use std::time::{Duration, Instant};

use common::procs::{wait_for_state, KillOnDrop};
use common::*;
use glint_runtime::ports::{Inbox, Outbox};
use glint_runtime::{open_node, remove_shm, shm_entries};
use rustix::process::{kill_process, Pid, Signal};
use shared_types::topics::create_all;
use shared_types::{Command, Control, Heartbeat, ServiceId, TopicId};

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
        let sc = shared_types::Scenario::from_file(&scenario("debris-geo.toml")).unwrap();
        let _services = create_all(&node, &sc).unwrap();
        let (mut hb, _l) = Inbox::<Heartbeat>::open(&node, TopicId::Heartbeat).unwrap();
        let mut control = Outbox::open(&node, TopicId::Control, ServiceId::Orchestrator).unwrap();
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
