//! The fault matrix across hosts: each host runs `glint run` on the same `[matrix]` scenario;
//! the orchestrator's host runs the baseline and every case and judges each end to end, the
//! other host runs its part of each and judges the faults it fired on its own bridge.

use super::*;
use glint::matrix::HostMatrixReport;

/// scenarios/faults-split.toml: the split chain's matrix over both hosts' bridges: killed, stopped (the link cut), and
/// slowed to a 20 Mbit/s link for 10 messages. Six cases, each detected (a delay: it ended) and
/// recovered from on the host that fired it, nothing lost and the science equal to the
/// baseline's in the orchestrator's report; each fault took effect (a kill restarted the
/// bridge, a stop cut the link, the slowed frames crossed no faster than 20 Mbit/s).
#[test]
fn a_matrix_across_hosts_faults_each_hosts_bridge_and_loses_nothing() {
    let dir = temp_dir("hosts-matrix");
    // scenarios/faults-split.toml on free ports
    let (a, b) = (free_port(), free_port());
    let (a, b) = (format!("127.0.0.1:{a}"), format!("127.0.0.1:{b}"));
    let file = scenario_variant(
        "faults-split.toml",
        &[("127.0.0.1:7447", &a), ("127.0.0.1:7448", &b)],
        &dir,
    );
    let mut ground = start_ground(&file, &dir.join("ground"));
    let mut board = start_run(&file, &dir.join("board"), &[]);
    let status = wait_for_exit(&mut board, Duration::from_secs(240));
    let log = std::fs::read_to_string(stderr_path(&dir.join("board"))).unwrap_or_default();
    let summary = std::fs::read_to_string(dir.join("board/summary.md")).unwrap_or_default();
    assert!(status.success(), "{log}\n{summary}");
    let ground_status = wait_for_exit(&mut ground, Duration::from_secs(60));
    let ground_summary = std::fs::read_to_string(dir.join("ground/summary.md")).unwrap();
    assert!(ground_status.success(), "{ground_summary}");

    // The orchestrator's report: every case, end to end.
    let report: glint::matrix::MatrixReport =
        serde_json::from_str(&std::fs::read_to_string(dir.join("board/report.json")).unwrap())
            .unwrap();
    let names: Vec<&str> = report.cases.iter().map(|c| c.case.as_str()).collect();
    assert_eq!(
        names,
        [
            "bridge-board-kill",
            "bridge-board-stop",
            "bridge-board-delay",
            "bridge-ground-kill",
            "bridge-ground-stop",
            "bridge-ground-delay",
        ]
    );
    assert!(report.success, "{summary}");
    for c in &report.cases {
        assert!(c.passed && c.science_equal == Some(true), "{c:?}");
    }
    // Board's own faults, with their timelines here: a kill noticed by the exit and
    // restarted, a stop noticed as ground cut off, a delay that ended.
    let fault = |faults: &[glint::matrix::CaseFault], case: &str| {
        (faults.iter().find(|f| f.case == case))
            .unwrap_or_else(|| panic!("{case} in {faults:?}"))
            .fault
            .clone()
    };
    let kill = fault(&report.faults, "bridge-board-kill");
    assert_eq!(
        (kill.detected_by.as_deref(), kill.restarts),
        (Some("exit"), 1)
    );
    let stop = fault(&report.faults, "bridge-board-stop");
    assert_eq!(stop.detected_by.as_deref(), Some("host cut off"));
    assert_eq!(stop.lost, Some(0));
    assert!(fault(&report.faults, "bridge-board-delay")
        .ended_s
        .is_some());

    // Ground's report: its part of every case, and the faults it fired judged there.
    let ground_report: HostMatrixReport =
        serde_json::from_str(&std::fs::read_to_string(dir.join("ground/report.json")).unwrap())
            .unwrap();
    assert!(ground_report.success, "{ground_summary}");
    let ground_names: Vec<&str> = (ground_report.cases.iter())
        .map(|c| c.case.as_str())
        .collect();
    assert_eq!(ground_names, names);
    let kill = fault(&ground_report.faults, "bridge-ground-kill");
    assert_eq!(
        (kill.detected_by.as_deref(), kill.restarts),
        (Some("exit"), 1)
    );
    let stop = fault(&ground_report.faults, "bridge-ground-stop");
    assert_eq!(stop.detected_by.as_deref(), Some("heartbeat silent"));
    assert!(stop.recovered_s.is_some());
    assert_eq!(ground_report.faults.len(), 3, "{ground_summary}");

    // The slow link took effect: board's frames (1 Mbit each; unslowed, the bridge carries
    // them many times faster) crossed at no more than 20 Mbit/s and near it, the link busy;
    // ground held its 10 small detections and tracks for their bits (a few ms in all).
    for (part, case) in [
        ("board", "bridge-board-delay"),
        ("ground", "bridge-ground-delay"),
    ] {
        let log_file = dir.join(part).join(case).join("logs/bridge.log");
        let log = std::fs::read_to_string(&log_file).unwrap();
        let line = (log.lines())
            .find(|l| l.contains("slow link over"))
            .unwrap_or_else(|| panic!("{part}'s bridge log:\n{log}"));
        assert!(line.contains("10 messages slowed"), "{line}");
        let rate: f64 = (line.split(" at ").nth(1))
            .and_then(|r| r.split(" Mbit/s").next())
            .and_then(|r| r.parse().ok())
            .unwrap_or_else(|| panic!("{line}"));
        if part == "board" {
            assert!((10.0..=20.0 * 1.05).contains(&rate), "{line}");
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A matrix whose other host never joins (never started, or out of step) stops at the first
/// case it missed, naming the host, instead of running every case against no one: the
/// orchestrator's host waits its startup limit and the host silence limit, then fails.
#[test]
fn a_matrix_whose_other_host_never_joins_stops_naming_it() {
    let dir = temp_dir("hosts-matrix-alone");
    let (a, b) = (free_port(), free_port());
    let (a, b) = (format!("127.0.0.1:{a}"), format!("127.0.0.1:{b}"));
    let limits = "seed = 2016\n[run]\nstartup_timeout_ms = 1000\nheartbeat_deadline_ms = 500\n\
                  [supervision]\nbackoff_ms = 100\nbackoff_max_ms = 500\n";
    let file = scenario_variant(
        "faults-split.toml",
        &[
            ("127.0.0.1:7447", &a),
            ("127.0.0.1:7448", &b),
            ("seed = 2016\n", limits),
        ],
        &dir,
    );
    let t0 = Instant::now();
    let mut board = start_run(&file, &dir.join("board"), &[]);
    let status = wait_for_exit(&mut board, Duration::from_secs(60));
    let waited = t0.elapsed();
    let summary = std::fs::read_to_string(dir.join("board/summary.md")).unwrap_or_default();
    assert_eq!(status.code(), Some(1), "{summary}");
    assert!(
        summary.contains("The matrix stopped at the baseline: host ground never joined it"),
        "{summary}"
    );
    let report: glint::matrix::MatrixReport =
        serde_json::from_str(&std::fs::read_to_string(dir.join("board/report.json")).unwrap())
            .unwrap();
    assert!(!report.success && report.cases.is_empty(), "{report:?}");
    // it waited for ground: the startup limit and the host silence limit (0.5 + 0.5 + 1 s)
    assert!(waited >= Duration::from_secs(3), "{waited:?}");
    let _ = std::fs::remove_dir_all(&dir);
}
