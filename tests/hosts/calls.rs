//! Calls across hosts: the tracker's laser shots and the orchestrator's solve calls, made on
//! one host and answered on another through the bridges, give the single-host science.

use super::*;

/// The laser across hosts: the tracker on ground fires at the sensor on board, its calls
/// carried by the bridges (ground's serves them, board's asks the sensor). Ground's bridge is
/// killed at frame 150, calls in flight with it: the tracker asks again under the same ids,
/// the restarted bridge carries them, and the science — the EKF fed by every range — equals
/// the single-host run's.
#[test]
fn the_laser_across_hosts_gives_the_single_host_science_even_with_a_bridge_killed() {
    let dir = temp_dir("hosts-laser");
    let kill =
        "[[fault]]\nservice = \"bridge\"\nhost = \"ground\"\nkind = \"kill\"\nat_seq = 150\n";
    let frames = 300;
    let file = split(&dir, frames, kill);
    small_frames(&file);
    let text = std::fs::read_to_string(&file).unwrap();
    assert!(text.contains("\nlaser = false"));
    std::fs::write(&file, text.replace("\nlaser = false", "\nlaser = true")).unwrap();
    let mut ground = start_ground(&file, &dir.join("ground"));
    let mut board = start_run(&file, &dir.join("board"), &[]);
    let (report, alone) = ended_whole(&mut board, &mut ground, &file, &dir, frames);
    // Ranged across hosts: as many shots as on one host (debris in view, about two a frame in
    // 256² frames), every one served
    // by the sensor on board (a shot asked again is served again, and counted once).
    let (split_laser, alone_laser) = (&report.results.laser, &alone.results.laser);
    assert!(alone_laser.shots >= frames as u64, "{alone_laser:?}");
    assert_eq!(split_laser.shots, alone_laser.shots, "{split_laser:?}");
    assert_eq!(split_laser.served, alone_laser.served, "{split_laser:?}");
    let summary = std::fs::read_to_string(dir.join("board/summary.md")).unwrap();
    assert!(!summary.contains("No laser ranges"), "{summary}");
    // Board's bridge, per hop: it took every request off the wire (a shot asked again is
    // taken again) and put an answer back for each but those it could not answer.
    let [taken, answered, lost, _] = range_hop(&summary);
    assert!(taken >= alone_laser.shots && taken == answered + lost);
    // The kill took effect: ground's part restarted its bridge, and the calls went on through
    // the new incarnation (ground's per-hop counters are its).
    let ground_summary = std::fs::read_to_string(dir.join("ground/summary.md")).unwrap();
    let row = (ground_summary.lines())
        .find(|l| l.starts_with("| bridge:kill@150,host=ground |"))
        .unwrap_or_else(|| panic!("ground's fault row in\n{ground_summary}"));
    assert!(row.trim_end().ends_with("| 1 |"), "one restart: {row}");
    let [taken, answered, ..] = range_hop(&ground_summary);
    assert!(taken > 0 && answered > 0, "the new bridge carried calls");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The attitude solve across hosts: the [000] Y-spin scene with the sensor on `board` (the
/// orchestrator's host) and the inversion on `ground`. The spectra cross one way; the
/// orchestrator's three solve calls cross to the inversion and back through the bridges. The
/// answer — every stage, the rate and its covariance — equals the single-host run's.
#[test]
fn the_attitude_solve_across_hosts_gives_the_single_host_answer() {
    let dir = temp_dir("hosts-solve");
    let hosts = format!(
        "[hosts.board]\nendpoint = \"tcp/127.0.0.1:{}\"\norchestrator = true\n\
         [hosts.ground]\nendpoint = \"tcp/127.0.0.1:{}\"\n\
         [services.inversion]\nhost = \"ground\"\n\n[spectra]",
        free_port(),
        free_port()
    );
    let file = scenario_variant("geo-hover-yspin.toml", &[("[spectra]", &hosts)], &dir);
    let mut ground = start_ground(&file, &dir.join("ground"));
    let mut board = start_run(&file, &dir.join("board"), &[]);
    let status = wait_for_exit(&mut board, Duration::from_secs(120));
    let log = std::fs::read_to_string(stderr_path(&dir.join("board"))).unwrap_or_default();
    assert!(status.success(), "{log}");
    assert!(wait_for_exit(&mut ground, Duration::from_secs(30)).success());
    let split_r = read_report(&dir.join("board/report.json"));
    let alone = run_ok(
        Some(&scenario("geo-hover-yspin.toml")),
        &dir.join("single"),
        &[],
    )
    .typed;
    assert!(split_r.results.accounting.invariant_held);
    assert_eq!(
        split_r.results.topics["spectrum"].consumers["inversion"].received,
        Some(1440)
    );
    let (s3, s3_alone) = (stage3(&split_r), stage3(&alone));
    assert_eq!(s3.status, "ok", "{s3:?}");
    assert_eq!(
        serde_json::to_value(inversion(&split_r)).unwrap(),
        serde_json::to_value(inversion(&alone)).unwrap(),
        "the solve across hosts answers as on one host"
    );
    assert_eq!(s3.truth_deg_per_frame, s3_alone.truth_deg_per_frame);
    assert_eq!(
        split_r.results.science.digest_xxh3,
        alone.results.science.digest_xxh3
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A summary's per-hop row of the `range` call: taken, passed on, lost, refused.
fn range_hop(summary: &str) -> [u64; 4] {
    let row = (summary.lines())
        .find(|l| l.starts_with("| range |"))
        .unwrap_or_else(|| panic!("a range row per hop in\n{summary}"));
    let n: Vec<u64> = (row.split('|').skip(2).take(4))
        .map(|c| c.trim().parse().unwrap())
        .collect();
    [n[0], n[1], n[2], n[3]]
}
