//! A deployment split across hosts (`[hosts]`, the bridge over Zenoh), run as a user runs it:
//! two `glint run --host` processes with the same scenario, here on one machine over loopback
//! (each host's part under its own shared-memory prefix, so nothing crosses but through the
//! bridges). The split debris chain gives the single-host run's science, also when either
//! host's bridge is killed or stopped mid-run (restarted, nothing lost); a bridge that may not
//! be restarted, or the orchestrator's host lost, ends every part of the run, with the reason
//! named.

#![cfg(feature = "hosts")]

#[path = "hosts/calls.rs"]
mod calls;
mod common;
#[path = "hosts/matrix.rs"]
mod matrix;
#[path = "hosts/netns.rs"]
mod netns;

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use common::procs::*;
use common::*;
use netns::{tc, Namespaces};
use rustix::process::{kill_process, Signal};

/// A TCP port free on loopback now (the OS's pick).
fn free_port() -> u16 {
    let l = std::net::TcpListener::bind("127.0.0.1:0").expect("a free port");
    l.local_addr().unwrap().port()
}

/// scenarios/debris-split.toml with `frames`, free ports, the laser off, and `extra` before the
/// first table.
fn split(dir: &Path, frames: u32, extra: &str) -> PathBuf {
    let (a, b) = (free_port(), free_port());
    let ports = [
        ("127.0.0.1:7447", format!("127.0.0.1:{a}")),
        ("127.0.0.1:7448", format!("127.0.0.1:{b}")),
    ];
    let frames = format!("frames = {frames}");
    let head = format!("{extra}\n[hosts.board]");
    scenario_variant(
        "debris-split.toml",
        &[
            (ports[0].0, &ports[0].1),
            (ports[1].0, &ports[1].1),
            ("frames = 50", &frames),
            // A round trip across hosts per shot: the laser's own test turns it on.
            ("\nlaser = true", "\nlaser = false"),
            ("[hosts.board]", &head),
        ],
        dir,
    )
}

/// The same scenario on one host: no `[hosts]`, no placement.
fn single(split_file: &Path, dir: &Path) -> PathBuf {
    let text = std::fs::read_to_string(split_file).unwrap();
    let mut out = String::new();
    let mut skipping = false;
    for line in text.lines() {
        if line.starts_with('[') {
            skipping = line.starts_with("[hosts.")
                || line.starts_with("[services.")
                || line.starts_with("[[fault]]");
        }
        if !skipping {
            out += line;
            out += "\n";
        }
    }
    let file = dir.join("single.toml");
    std::fs::write(&file, out).unwrap();
    file
}

/// The ground host's part (`glint run --host ground`), killed if the test ends first.
fn start_ground(file: &Path, out: &Path) -> KillOnDrop {
    start_run(file, out, &["--host", "ground"])
}

/// The split chain gives the single-host run's science digest and every topic's digest; every
/// message is accounted for across the hosts (the detector and tracker on `ground` report
/// through the bridge); what crossed is counted per hop on both sides.
#[test]
fn the_split_debris_chain_gives_the_single_host_science() {
    let dir = temp_dir("hosts-split");
    let file = split(&dir, 20, "");
    // The orchestrator's host first, the other a second later: the run starts only once both
    // bridges take each other's topics (nothing sent before would arrive).
    let mut board_run = start_run(&file, &dir.join("board"), &[]);
    std::thread::sleep(Duration::from_secs(1));
    let mut ground = start_ground(&file, &dir.join("ground"));
    let board_status = wait_for_exit(&mut board_run, Duration::from_secs(60));
    let board_log = std::fs::read_to_string(stderr_path(&dir.join("board"))).unwrap_or_default();
    assert!(board_status.success(), "{board_log}");
    let board = read_report(&dir.join("board/report.json"));
    let status = wait_for_exit(&mut ground, Duration::from_secs(30));
    let ground_summary = std::fs::read_to_string(dir.join("ground/summary.md")).unwrap();
    assert!(status.success(), "{ground_summary}");
    let alone = run_ok(Some(&single(&file, &dir)), &dir.join("single"), &[]);

    let (split_r, single_r) = (&board.results, &alone.typed.results);
    assert_eq!(split_r.science.digest_xxh3, single_r.science.digest_xxh3);
    for (topic, t) in &single_r.topics {
        assert_eq!(split_r.topics[topic].digest_xxh3, t.digest_xxh3, "{topic}");
    }
    // The remote consumers' counters arrived across the bridge: every frame taken on ground.
    let frame = &split_r.topics["frame"];
    assert_eq!(frame.consumers["detector"].received, Some(20));
    assert_eq!(
        split_r.topics["tracks"].consumers["orchestrator"].received,
        Some(20)
    );
    assert!(split_r.accounting.invariant_held);
    for name in ["sensor", "detector", "tracker", "bridge"] {
        assert_eq!(ending(&board, name), "shutdown", "{name}");
    }
    // Per hop: ground's bridge took 20 frames off the wire and passed 20 on; it put 20
    // detections and 20 tracks on the wire. None lost, none refused.
    for row in [
        "| frame | 20 | 20 | 0 | 0 |",
        "| detections | 20 | 20 | 0 | 0 |",
        "| tracks | 20 | 20 | 0 | 0 |",
    ] {
        assert!(ground_summary.contains(row), "{row} in\n{ground_summary}");
    }
    // With the laser off the summary says the run is angles only and shows
    // no range columns or EKF picture (they would hold only NaN).
    let board_summary = std::fs::read_to_string(dir.join("board/summary.md")).unwrap();
    assert!(
        board_summary.contains("No laser ranges in this run") && !board_summary.contains("NaN"),
        "{board_summary}"
    );
    assert!(!dir.join("board/debris-ekf.svg").exists());
    for part in ["board", "ground", "single"] {
        let log = std::fs::read_to_string(stderr_path(&dir.join(part))).unwrap_or_default();
        assert!(!log.contains("panicked"), "{part}: {log}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Waits until `ground`'s `glint service <name>` is up; its pid.
fn ground_service(ground: &KillOnDrop, name: &str) -> u32 {
    let pid = wait_for_service(ground, name, Duration::from_millis(5));
    pid.as_raw_nonzero().get() as u32
}

/// `file` with frames of 256² instead of 1024² (runs of thousands of frames in a debug build).
fn small_frames(file: &Path) {
    let text = std::fs::read_to_string(file).unwrap();
    let text = (text.replace("width_px = 1024", "width_px = 256"))
        .replace("height_px = 1024", "height_px = 256");
    std::fs::write(file, text).unwrap();
}

/// The split chain of 3000 frames of 256² with `extra` (faults) in a sim-clock run, both hosts
/// started, ended whole (every frame at the detector, the science equal to one host's): the
/// orchestrator's report, and the one fault it lists.
fn bridge_faults_run(
    dir: &Path,
    extra: &str,
) -> (glint::report::Report, glint::report::FaultReport) {
    let frames = 3000;
    let file = split(dir, frames, extra);
    small_frames(&file);
    let mut ground = start_ground(&file, &dir.join("ground"));
    let mut board = start_run(&file, &dir.join("board"), &[]);
    let (report, _) = ended_whole(&mut board, &mut ground, &file, dir, frames);
    let [f] = report.faults.as_slice() else {
        panic!("one fault on board: {:?}", report.faults);
    };
    let f = f.clone();
    (report, f)
}

/// Ground's summary row of the fault it fired on its bridge, stopped at frame 1600 for 2 s:
/// detected by, recovered (a time), restarts.
fn ground_stop_row(dir: &Path) -> (String, f64, u32) {
    let summary = std::fs::read_to_string(dir.join("ground/summary.md")).unwrap();
    let row = (summary.lines())
        .find(|l| l.starts_with("| bridge:stop@1600,duration_s=2,host=ground |"))
        .unwrap_or_else(|| panic!("ground's fault row in\n{summary}"));
    // | fault | injected | detected (by) | recovered | restarts |
    let cells: Vec<&str> = row.split('|').map(str::trim).collect();
    let by = cells[3]
        .rsplit('(')
        .next()
        .unwrap_or("")
        .trim_end_matches(')');
    let recovered = cells[4]
        .parse::<f64>()
        .unwrap_or_else(|_| panic!("recovered: {row}"));
    (by.to_string(), recovered, cells[5].parse().unwrap())
}

/// A fault that stops ground's bridge at frame 1600 for 2 s.
const GROUND_STOP: &str = "[[fault]]\nservice = \"bridge\"\nhost = \"ground\"\nkind = \"stop\"\n\
    at_seq = 1600\nduration_s = 2.0\n";

/// Each host's bridge fails mid-run, by faults the scenario names: the orchestrator's host's
/// bridge is SIGKILLed at frame 800 (noticed by its exit), ground's is SIGSTOPped at frame 1600
/// for 2 s (noticed silent after three heartbeat periods, killed at the 1 s deadline). Each
/// host's supervision restarts its own bridge, the other bridge puts again what was in flight,
/// and nothing is lost: every frame reaches the detector, the science equals the single-host
/// run's.
#[test]
fn bridges_killed_or_stopped_on_either_host_are_restarted_and_nothing_is_lost() {
    let dir = temp_dir("hosts-bridge-faults");
    let kill = "[run]\nheartbeat_deadline_ms = 1000\n\
        [[fault]]\nservice = \"bridge\"\nkind = \"kill\"\nat_seq = 800\n";
    let (report, f) = bridge_faults_run(&dir, &format!("{kill}{GROUND_STOP}"));
    // board's bridge: killed, noticed by its exit, restarted, caught up
    assert_eq!((f.service.as_str(), f.kind.as_str()), ("bridge", "kill"));
    assert_eq!(f.detected_by.as_deref(), Some("exit"));
    assert_eq!(f.restarts, 1);
    assert!(f.recovered_s.is_some(), "{f:?}");
    assert_eq!(ending(&report, "bridge"), "shutdown");
    // ground's bridge: stopped, noticed silent (three heartbeat periods), killed at the 1 s
    // deadline and restarted by ground's part
    let (by, _, restarts) = ground_stop_row(&dir);
    assert_eq!((by.as_str(), restarts), ("heartbeat silent", 1));
    // the orchestrator saw ground cut off for about the 1 s it took to notice the stop
    let ground_host = (report.run.hosts.iter())
        .find(|h| h.name == "ground")
        .unwrap();
    let long = (ground_host.outages.iter())
        .any(|o| o.recovered_s.is_some_and(|r| r - o.last_heard_s >= 1.0));
    assert!(long, "{ground_host:?}");
    // each bridge put again what was in flight when the other came back
    for part in ["board", "ground"] {
        let log = std::fs::read_to_string(dir.join(part).join("logs/bridge.log")).unwrap();
        assert!(log.contains("put again"), "{part}'s bridge log:\n{log}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A bridge stopped (SIGSTOP) for 2 s, shorter than the heartbeat deadline: the link is cut,
/// as by a partition, on any machine (no network namespaces needed). Board's bridge at frame
/// 800: the orchestrator finds ground cut off; ground's at frame 1600: ground's part finds its
/// bridge silent. Neither is restarted; each is heard again once resumed; nothing is lost and
/// the science equals the single-host run's.
#[test]
fn a_bridge_stopped_for_two_seconds_cuts_the_link_and_nothing_is_lost() {
    let dir = temp_dir("hosts-bridge-stop");
    let stop = "[[fault]]\nservice = \"bridge\"\nkind = \"stop\"\nat_seq = 800\nduration_s = 2.0\n";
    let (_, f) = bridge_faults_run(&dir, &format!("{stop}{GROUND_STOP}"));
    assert_eq!(f.detected_by.as_deref(), Some("host cut off"), "{f:?}");
    let (injected, detected) = (f.injected_s.unwrap(), f.detected_s.unwrap());
    // three heartbeat periods of silence (0.3 s), not supervision's 5 s deadline
    assert!(detected - injected < 1.0, "{f:?}");
    assert!(f.recovered_s.is_some_and(|r| r >= injected + 2.0), "{f:?}");
    assert_eq!(f.restarts, 0);
    let (by, _, restarts) = ground_stop_row(&dir);
    assert_eq!((by.as_str(), restarts), ("heartbeat silent", 0));
    let _ = std::fs::remove_dir_all(&dir);
}

/// A slow link, injected: each host's bridge waits 20 ms before each of 50 data messages it
/// puts on the wire (`delay` faults on the bridge, board's at frame 800, ground's at frame
/// 1600). Each delay took effect (over no sooner than 50 × 20 ms after it began: a lower bound
/// on any host), the chain caught up, nothing was lost, the science equals one host's.
#[test]
fn a_slow_link_injected_on_either_host_loses_nothing() {
    let dir = temp_dir("hosts-bridge-delay");
    let delay = |host: &str, at: u32| {
        format!(
            "[[fault]]\nservice = \"bridge\"\n{host}kind = \"delay\"\nat_seq = {at}\n\
             delay_ms = 20\ncount = 50\n"
        )
    };
    let faults = format!(
        "[faults]\nenabled = true\n{}{}",
        delay("", 800),
        delay("host = \"ground\"\n", 1600)
    );
    let (_, f) = bridge_faults_run(&dir, &faults);
    let (injected, ended) = (f.injected_s.unwrap(), f.ended_s.expect("the delay ended"));
    assert!(ended - injected >= 1.0, "{f:?}");
    assert!(f.recovered_s.is_some(), "{f:?}");
    let summary = std::fs::read_to_string(dir.join("ground/summary.md")).unwrap();
    let row = (summary.lines())
        .find(|l| l.starts_with("| bridge:delay@1600,host=ground |"))
        .unwrap_or_else(|| panic!("ground's fault row in\n{summary}"));
    let cells: Vec<f64> = (row.split('|').map(str::trim))
        .filter_map(|c| c.parse().ok())
        .collect();
    // injected, recovered (after the delay ended), restarts
    let [injected, recovered, restarts] = cells.as_slice() else {
        panic!("{row}");
    };
    assert!(recovered - injected >= 1.0 && *restarts == 0.0, "{row}");
    for part in ["board", "ground"] {
        let log = std::fs::read_to_string(dir.join(part).join("logs/bridge.log")).unwrap();
        assert!(
            log.contains("50 messages slowed"),
            "{part}'s bridge log:\n{log}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Ground's bridge SIGKILLed mid-run where its supervision may not restart it: ground's part
/// ends, naming why; the orchestrator of record, hearing nothing more from the services
/// there, fails the run naming the host once that host could have brought a bridge back
/// (the heartbeat deadline, the backoff, the startup limit); no process of either host remains.
#[test]
fn a_bridge_not_restarted_fails_the_run_naming_the_host_and_nothing_remains() {
    let dir = temp_dir("hosts-bridge-kill");
    let run = "clock = \"realtime\"\n[run]\ntimeout_s = 120.0\nheartbeat_deadline_ms = 1000\n\
               startup_timeout_ms = 2000\n[supervision.services.bridge]\nrestart = \"never\"\n";
    let file = split(&dir, 2000, run);
    let mut ground = start_ground(&file, &dir.join("ground"));
    let mut board = start_run(&file, &dir.join("board"), &[]);
    wait_for_start(&dir.join("board"));
    let bridge = ground_service(&ground, "bridge");
    let detector = ground_service(&ground, "detector");
    std::thread::sleep(Duration::from_millis(500));
    let pid = rustix::process::Pid::from_raw(bridge as i32).unwrap();
    kill_process(pid, Signal::KILL).expect("SIGKILL ground's bridge");
    let killed = Instant::now();
    let status = wait_for_exit(&mut board, Duration::from_secs(30));
    assert_eq!(status.code(), Some(1));
    let report = read_report(&dir.join("board/report.json"));
    let failure = report.results.failure.clone().unwrap_or_default();
    assert!(
        failure.contains("on host ground") && failure.contains("across the bridge"),
        "{failure}"
    );
    // failed at the silence limit (1 s + 2 s backoff at most + 2 s), not at the run's timeout
    assert!(
        killed.elapsed() < Duration::from_secs(20),
        "{:?}",
        killed.elapsed()
    );
    let status = wait_for_exit(&mut ground, Duration::from_secs(30));
    assert!(!status.success());
    let summary = std::fs::read_to_string(dir.join("ground/summary.md")).unwrap();
    assert!(
        summary.contains("the bridge failed and is not restarted"),
        "{summary}"
    );
    assert_eq!(process_state(detector).filter(|s| *s != 'Z'), None);
    let _ = std::fs::remove_dir_all(&dir);
}

/// The orchestrator of record SIGKILLed: its host's processes go with it (parent-death
/// signal), the ground bridge sees the board's bridge gone and the ground part stops its
/// services and ends, naming why; `glint clean` removes what the killed orchestrator left.
#[test]
fn a_killed_orchestrator_ends_the_other_hosts_part() {
    let dir = temp_dir("hosts-orchestrator-kill");
    // ground waits the silence limit for board's bridge: 1 s + 2 s backoff at most + 2 s
    let run = "clock = \"realtime\"\n[run]\ntimeout_s = 120.0\nheartbeat_deadline_ms = 1000\n\
               startup_timeout_ms = 2000\n";
    let file = split(&dir, 2000, run);
    let mut ground = start_ground(&file, &dir.join("ground"));
    let mut board = start_run(&file, &dir.join("board"), &[]);
    wait_for_start(&dir.join("board"));
    let sensor = wait_for_service(&board, "sensor", Duration::from_millis(5));
    let prefix = prefix_of(sensor);
    let detector = ground_service(&ground, "detector");
    board.0.kill().expect("SIGKILL the orchestrator");
    board.0.wait().expect("reap");
    let status = wait_for_exit(&mut ground, Duration::from_secs(30));
    assert!(!status.success());
    let summary = std::fs::read_to_string(dir.join("ground/summary.md")).unwrap();
    assert!(
        summary.contains("lost the orchestrator's host `board`"),
        "{summary}"
    );
    assert_eq!(process_state(detector).filter(|s| *s != 'Z'), None);
    let cleaned = glint()
        .args(["clean", "--prefix", &prefix])
        .output()
        .unwrap();
    assert!(cleaned.status.success(), "{cleaned:?}");
    assert!(shm_left(&prefix).is_empty(), "{:?}", shm_left(&prefix));
    let _ = std::fs::remove_dir_all(&dir);
}

/// The link between the hosts cut for 2 s in the middle of a sim-clock run (two network
/// namespaces, a veth pair, `ip link set down`): the orchestrator notices the other host cut
/// off within 0.5 s, hears it again once the link is back, and nothing is lost: every frame is
/// accounted for and the science equals the single-host run's. The outage is in the report.
#[test]
fn a_two_second_partition_is_noticed_and_nothing_is_lost() {
    partition(1, Duration::from_secs(2));
}

/// A cut of 12 s, longer than Zenoh's default lease (10 s): the lease is the host silence
/// limit (27 s here), so the session and the run outlast it, and nothing is lost. Ignored by
/// default (it takes 15 s): `cargo test --features hosts --test hosts -- --ignored`.
#[test]
#[ignore]
fn a_partition_longer_than_zenohs_default_lease_loses_nothing() {
    partition(3, Duration::from_secs(12));
}

fn partition(k: u32, cut: Duration) {
    let Some(ns) = Namespaces::new(k) else {
        eprintln!("SKIPPED: this machine cannot make network namespaces (root and iproute2)");
        return;
    };
    let dir = temp_dir(&format!("hosts-partition-{}", cut.as_secs()));
    let frames = 4000;
    let file = ns.scenario(&dir, frames);
    let mut ground = ns.run(1, &file, &dir.join("ground"), "ground");
    let mut board = ns.run(0, &file, &dir.join("board"), "board");
    wait_for_start(&dir.join("board"));
    std::thread::sleep(Duration::from_millis(300));
    let cut_ms = ns.link(false);
    std::thread::sleep(cut);
    let back_ms = ns.link(true);
    let (report, _) = ended_whole(&mut board, &mut ground, &file, &dir, frames);
    let ground_host = (report.run.hosts.iter())
        .find(|h| h.name == "ground")
        .unwrap();
    let [outage] = ground_host.outages.as_slice() else {
        panic!("one outage: {:?}", ground_host.outages);
    };
    let noticed_ms = outage.detected_unix_ms as i64 - cut_ms as i64;
    let heard_ms = outage.recovered_unix_ms.expect("heard again") as i64 - back_ms as i64;
    eprintln!(
        "partition of {:?}: noticed {noticed_ms} ms after the cut, heard again {heard_ms} ms \
         after the link came back",
        cut
    );
    assert!(
        (0..500).contains(&noticed_ms),
        "noticed {noticed_ms} ms after the cut"
    );
    assert!(
        (0..1000).contains(&heard_ms),
        "heard again {heard_ms} ms after the link came back"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A slow link (`tc` token bucket on the veth, 100 Mbit/s both ways): the split chain runs at
/// what the link carries, and still loses nothing and gives the single-host science.
#[test]
fn a_slow_link_slows_the_chain_and_loses_nothing() {
    let Some(ns) = Namespaces::new(2) else {
        eprintln!("SKIPPED: this machine cannot make network namespaces (root and iproute2)");
        return;
    };
    let dir = temp_dir("hosts-slow-link");
    let frames = 200;
    let file = ns.scenario(&dir, frames);
    const RATE_BIT_S: f64 = 100e6;
    for (i, veth) in [(0, ns.veth.clone()), (1, ns.veth.replacen("gla", "glb", 1))] {
        let tbf = [
            "-n",
            &ns.names[i],
            "qdisc",
            "add",
            "dev",
            &veth,
            "root",
            "tbf",
        ];
        let rate = ["rate", "100mbit", "burst", "32kb", "latency", "400ms"];
        assert!(tc(&[&tbf[..], &rate[..]].concat()), "tc tbf on {veth}");
    }
    let mut ground = ns.run(1, &file, &dir.join("ground"), "ground");
    let mut board = ns.run(0, &file, &dir.join("board"), "board");
    let (report, alone) = ended_whole(&mut board, &mut ground, &file, &dir, frames);
    // the limit took effect: the frames crossed no faster than the link carries them
    let frame_bits =
        8.0 * (std::mem::size_of::<shared_types::FrameHeader>() + 2 * 256 * 256) as f64;
    let fps = report.timing.frames_per_s;
    assert!(
        fps * frame_bits < 1.1 * RATE_BIT_S,
        "{fps} frames/s over 100 Mbit/s"
    );
    eprintln!(
        "slow link (100 Mbit/s): {fps:.1} frames/s ({:.0} Mbit/s of frames); one host: {:.1} frames/s",
        fps * frame_bits / 1e6,
        alone.timing.frames_per_s
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Both parts of a split run ended well, every frame reached the detector on `ground`, every
/// message is accounted for, and the science equals the same scenario's on one host: the
/// board's report and the single-host run's report.
fn ended_whole(
    board: &mut KillOnDrop,
    ground: &mut KillOnDrop,
    file: &Path,
    dir: &Path,
    frames: u32,
) -> (glint::report::Report, glint::report::Report) {
    let status = wait_for_exit(board, Duration::from_secs(120));
    let log = std::fs::read_to_string(stderr_path(&dir.join("board"))).unwrap_or_default();
    assert!(status.success(), "{log}");
    assert!(wait_for_exit(ground, Duration::from_secs(30)).success());
    let report = read_report(&dir.join("board/report.json"));
    let r = &report.results;
    assert!(r.accounting.invariant_held);
    assert_eq!(
        r.topics["frame"].consumers["detector"].received,
        Some(frames as u64)
    );
    let alone = run_ok(Some(&single(file, dir)), &dir.join("single"), &[]).typed;
    assert_eq!(r.science.digest_xxh3, alone.results.science.digest_xxh3);
    (report, alone)
}
