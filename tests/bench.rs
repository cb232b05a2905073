//! `glint bench ipc`: real processes over real iceoryx2 shared memory, a Unix socket and TCP.
//! Timings are figures, not asserted; what is asserted is that every round trip came back with
//! the checksum of the bytes sent (the command fails otherwise), that every (transport, size)
//! is in bench.json with ordered percentiles, and that the files a user reads are there.

mod common;

use std::path::Path;

use common::{first_allowed_cpu, glint, read_json, read_report, temp_dir, Svg};

/// `glint bench ARGS --out DIR`, which must succeed; its stdout.
fn glint_bench(args: &[&str], dir: &Path) -> String {
    let out = glint()
        .arg("bench")
        .args(args)
        .arg("--out")
        .arg(dir)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    stdout
}

#[test]
fn bench_ipc_measures_every_transport_and_size() {
    let dir = temp_dir("bench-ipc");
    let stdout = glint_bench(
        &["ipc", "--scale", "0.01", "--size", "8", "--size", "2097152"],
        &dir,
    );
    // One clear answer first: the zero-copy ratios, then the table.
    assert!(stdout.starts_with("2 MiB hop: iceoryx2 "), "{stdout}");
    let bench = read_json(&dir.join("bench.json"));
    let rows = bench["ipc"]["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 4 * 2, "{rows:?}");
    for t in ["iceoryx2", "iceoryx2-spin", "uds", "tcp"] {
        for size in [8, 2 << 20] {
            let r = rows
                .iter()
                .find(|r| r["transport"] == t && r["payload_bytes"] == size)
                .unwrap_or_else(|| panic!("no row for {t} {size}"));
            // 50 round trips at this scale (the minimum is 20).
            let expected = if size == 8 { 50 } else { 20 };
            assert_eq!(r["samples"], expected, "{r}");
            let p = |k: &str| r[k].as_f64().unwrap();
            assert!(p("p50_us") > 0.0, "{r}");
            assert!(
                p("p50_us") <= p("p90_us") && p("p90_us") <= p("p99_us"),
                "{r}"
            );
            assert!(
                p("p99_us") <= p("p999_us") && p("p999_us") <= p("max_us"),
                "{r}"
            );
            assert!(p("msgs_per_s") > 0.0, "{r}");
        }
    }
    assert!(
        bench["ipc"]["ratios"]["uds_over_iceoryx2_2mib"]
            .as_f64()
            .unwrap()
            > 0.0
    );
    assert!(bench["host"]["cpus"].as_u64().unwrap() >= 1);
    let csv = std::fs::read_to_string(dir.join("ipc.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 8, "{csv}");
    for f in [
        "ipc-latency.svg",
        "ipc-hist-iceoryx2-2MiB.svg",
        "ipc-hist-uds-2MiB.svg",
    ] {
        assert!(dir.join(f).exists(), "{f} missing");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bench_ipc_rejects_a_bad_scale() {
    let out = glint()
        .args(["bench", "ipc", "--scale", "0"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("--scale 0 is out of range: allowed 0.001 to 100"),
        "{err}"
    );
}

/// `glint bench pipeline` on a small scene: the real deployment (processes, shared memory, the
/// laser loop) and the in-process run of the same frames. The CPU time /proc gives a
/// single-threaded process cannot exceed the run's wall time; every frame has a latency for
/// every stage; nothing is dropped in sim-clock mode; the speedup is the ratio of the two rates.
#[test]
fn bench_pipeline_deploys_and_compares_with_one_process() {
    let dir = temp_dir("bench-pipeline");
    let cpu = format!("detector={}", first_allowed_cpu());
    let stdout = glint_bench(
        &[
            "pipeline",
            "--frames",
            "30",
            "--size",
            "256x256",
            "--targets",
            "2",
            "--cpu",
            &cpu,
        ],
        &dir,
    );
    assert!(stdout.starts_with("pipeline: "), "{stdout}");
    let placement = format!("(placement: detector on CPU {})", first_allowed_cpu());
    assert!(stdout.contains(&placement), "{stdout}");
    let bench = read_json(&dir.join("bench.json"));
    let p = &bench["pipeline"];
    assert_eq!(p["frames"], 30, "{p}");
    assert_eq!(p["dropped"], 0, "{p}");
    assert_eq!(p["success"], true, "{p}");
    assert_eq!(p["in_process"]["frames"], 30, "{p}");
    // a fair baseline: as many frame buffers as the deployment circulates (256² frames: a
    // 16-frame history and one loan), and the detector's check of every frame
    assert_eq!(p["in_process"]["pool_frames"], 17, "{p}");
    assert_eq!(p["scenario"]["cpu"]["detector"], first_allowed_cpu(), "{p}");
    assert!(
        p["in_process"]["stages"]["verify"]["mean_us"]
            .as_f64()
            .unwrap()
            > 0.0,
        "{p}"
    );
    let f = |v: &serde_json::Value| v.as_f64().unwrap();
    assert!(
        f(&p["floor"]["pass_hot_us"]) > 0.0 && f(&p["floor"]["pass_cold_us"]) > 0.0,
        "{p}"
    );
    assert!(f(&p["fps"]) > 0.0 && f(&p["in_process_fps"]) > 0.0, "{p}");
    let ratio = f(&p["fps"]) / f(&p["in_process_fps"]);
    assert!((f(&p["speedup"]) - ratio).abs() < 1e-9 * ratio, "{p}");
    let report = read_report(&dir.join("run").join("report.json"));
    let wall_s = report.timing.wall_s;
    for stage in ["sensor", "detector", "tracker", "orchestrator"] {
        let s = &p["stages"][stage];
        // /proc counts CPU time in clock ticks (10 ms): a short stage may read 0 on a fast host.
        let cpu = f(&s["cpu_s"]);
        assert!(
            (0.0..=wall_s + 0.05).contains(&cpu),
            "{stage}: {s}, wall {wall_s} s"
        );
        assert!(f(&s["p50_us"]) <= f(&s["p99_us"]), "{stage}: {s}");
    }
    for stage in ["detect", "track", "end_to_end"] {
        let l = report.timing.stage_latency_us.get(stage);
        assert_eq!(
            l.and_then(|l| l.as_ref()).map(|l| l.count),
            Some(30),
            "{stage}: {l:?}"
        );
    }
    // Where each process's time went: awake or asleep from before Start to after the last
    // result, so the three cover the production and fit in the run; busy's parts fit in busy;
    // and the kernel's CPU count (/proc, independent of the timers) fits in the awake time
    // (plus the start-up before the timers run).
    let production_s = report.timing.production_s;
    assert_eq!(
        p["time_s"],
        serde_json::to_value(&report.timing.time_s).unwrap()
    );
    for name in ["sensor", "detector", "tracker"] {
        let t = &p["time_s"][name];
        let busy = f(&t["busy_s"]);
        let total = busy + f(&t["credit_wait_s"]) + f(&t["idle_s"]);
        assert!(
            total >= production_s - 1e-3 && total <= wall_s,
            "{name}: {t}, production {production_s} s, wall {wall_s} s"
        );
        let parts = f(&t["checksum_s"]) + f(&t["publish_s"]) + f(&t["rpc_wait_s"]);
        assert!(
            parts <= busy + 1e-9 && f(&t["work_s"]) >= 0.0,
            "{name}: {t}"
        );
        assert!(
            f(&p["stages"][name]["cpu_s"]) <= busy + 0.1,
            "{name}: {t} against {}",
            p["stages"][name]
        );
        assert!(f(&t["publish_s"]) > 0.0, "{name}: {t}");
    }
    let t = &p["time_s"];
    // The sensor hashes every frame, the detector verifies it; only the tracker waits for the
    // laser.
    assert!(
        f(&t["sensor"]["checksum_s"]) > 0.0 && f(&t["detector"]["checksum_s"]) > 0.0,
        "{t}"
    );
    assert_eq!(f(&t["tracker"]["checksum_s"]), 0.0, "{t}");
    assert!(
        f(&t["tracker"]["rpc_wait_s"]) > 0.0 && f(&t["sensor"]["rpc_wait_s"]) == 0.0,
        "{t}"
    );
    assert!(
        stdout.contains("where the time goes (the deployment, ms per frame)"),
        "{stdout}"
    );
    // The run's summary gives each service's busy share, from the same timers.
    let summary = std::fs::read_to_string(dir.join("run").join("summary.md")).unwrap();
    for name in ["sensor", "detector", "tracker"] {
        let t = &p["time_s"][name];
        let busy = f(&t["busy_s"]);
        let working = busy - f(&t["rpc_wait_s"]);
        let share = 100.0 * working / (busy + f(&t["credit_wait_s"]) + f(&t["idle_s"]));
        let row = (summary.lines())
            .find(|l| l.starts_with(&format!("| {name} |")))
            .unwrap_or_else(|| panic!("{name} row: {summary}"));
        let shown: f64 = (row.rsplit('|').nth(1))
            .and_then(|c| c.trim().strip_suffix(" %"))
            .and_then(|c| c.parse().ok())
            .unwrap_or_else(|| panic!("busy column of {row}"));
        assert!((shown - share).abs() <= 0.51, "{row}: {share}");
    }
    let svg = Svg::read(&dir.join("pipeline-time.svg"));
    for text in [
        "sensor",
        "detector",
        "tracker",
        "work",
        "laser wait",
        "credit wait",
        "idle",
    ] {
        assert!(svg.has_text(text), "{text}: {:?}", svg.texts);
    }
    assert!(dir.join("pipeline.csv").is_file());
    let _ = std::fs::remove_dir_all(&dir);
}

/// `glint bench pipeline --record`: the same chain deployed again with every tapped message
/// recorded; its rate beside the unrecorded one's of the same bench, and the recording whole
/// (the frames, their truth, detections and tracks: four messages a frame, none missing);
/// then `--source` feeds that recording to the chain.
#[test]
fn bench_pipeline_record_gives_the_recording_cost_and_misses_nothing() {
    let dir = temp_dir("bench-pipeline-record");
    let stdout = glint_bench(
        &[
            "pipeline",
            "--frames",
            "30",
            "--size",
            "256x256",
            "--targets",
            "2",
            "--record",
        ],
        &dir,
    );
    assert!(stdout.contains("recording: "), "{stdout}");
    let bench = read_json(&dir.join("bench.json"));
    let r = &bench["pipeline"]["recording"];
    assert_eq!(r["success"], true, "{r}");
    assert_eq!(r["messages_written"], 4 * 30, "{r}");
    assert_eq!(r["messages_not_written"], 0, "{r}");
    let f = |v: &serde_json::Value| v.as_f64().unwrap();
    assert!(f(&r["frames_per_s"]) > 0.0, "{r}");
    let cost = 1.0 - f(&r["frames_per_s"]) / f(&r["frames_per_s_unrecorded"]);
    assert!((f(&r["cost"]) - cost).abs() < 1e-9, "{r}");
    // 30 frames of 256² u16 at least
    assert!(r["bytes"].as_u64().unwrap() > 30 * 256 * 256 * 2, "{r}");
    let recording = dir.join("run-recorded").join("run.mcap");
    assert!(recording.is_file());

    // `--source`: the chain fed that recording's frames, against the chain rendering them
    let from = temp_dir("bench-pipeline-source");
    let stdout = glint_bench(
        &["pipeline", "--source", recording.to_str().unwrap()],
        &from,
    );
    assert!(stdout.contains("from the recording: "), "{stdout}");
    let s = &read_json(&from.join("bench.json"))["pipeline"]["from_recording"];
    assert!(f(&s["frames_per_s"]) > 0.0, "{s}");
    assert!((f(&s["ratio"]) - f(&s["frames_per_s"]) / f(&s["frames_per_s_rendered"])).abs() < 1e-9);
    // the recorded frames themselves, every one of them: the frame and detection digests of the
    // deployment fed from the recording are the rendered deployment's of the same scenario
    let fed = read_report(&from.join("run-from-recording").join("report.json"));
    let rendered = read_report(&from.join("run").join("report.json"));
    assert_eq!(fed.results.topics["frame"].published, Some(30));
    for topic in ["frame", "detections", "tracks"] {
        let (a, b) = (&fed.results.topics[topic], &rendered.results.topics[topic]);
        assert!(a.digest_xxh3.is_some(), "{topic}");
        assert_eq!(a.digest_xxh3, b.digest_xxh3, "{topic}");
    }
    let _ = std::fs::remove_dir_all(&from);
}

#[test]
fn bench_pipeline_rejects_a_bad_size_or_target_count() {
    for args in [
        ["--size", "10x10"],
        ["--size", "1024"],
        ["--targets", "17"],
        ["--cpu", "detector"],
        ["--cpu", "laser=0"],
        ["--cpu", "detector=1023"],
    ] {
        let out = glint()
            .args(["bench", "pipeline"])
            .args(args)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains(args[1]), "{args:?}: {stderr}");
    }
}

/// `glint bench scaling` on two sizes and two debris counts: four real deployments, each with
/// its in-process baseline. The frames per point follow 1/pixels within their bounds, nothing
/// is dropped, and the printed exponents are the least-squares slopes of the CSV's columns,
/// recomputed here.
#[test]
fn bench_scaling_sweeps_size_and_targets() {
    let dir = temp_dir("bench-scaling");
    let stdout = glint_bench(
        &[
            "scaling",
            "--frames",
            "2",
            "--laser",
            "off",
            "--size",
            "128x128",
            "--size",
            "256x256",
            "--targets",
            "1",
            "--targets",
            "3",
        ],
        &dir,
    );
    assert!(
        stdout.starts_with("scaling: detector cost ∝ pixels^"),
        "{stdout}"
    );
    let bench = read_json(&dir.join("bench.json"));
    let points = bench["scaling"]["points"].as_array().unwrap();
    let shape: Vec<(String, u64, u64, u64)> = (points.iter())
        .map(|p| {
            let u = |k: &str| p[k].as_u64().unwrap();
            (
                p["sweep"].as_str().unwrap().into(),
                u("width_px"),
                u("targets"),
                u("frames"),
            )
        })
        .collect();
    // 2 frames at 1024² ⇒ 2·64 = 128 at 128² and 2·16 = 32 at 256², capped at 4 × 2 = 8.
    let expected = [
        ("size", 128, 4, 8),
        ("size", 256, 4, 8),
        ("targets", 1024, 1, 2),
        ("targets", 1024, 3, 2),
    ];
    assert_eq!(shape.len(), expected.len(), "{shape:?}");
    for (got, want) in shape.iter().zip(expected) {
        assert_eq!((got.0.as_str(), got.1, got.2, got.3), want, "{shape:?}");
    }
    for p in points {
        assert_eq!(p["dropped"], 0, "{p}");
        assert!(p["fps"].as_f64().unwrap() > 0.0, "{p}");
    }
    let csv = std::fs::read_to_string(dir.join("scaling.csv")).unwrap();
    let rows: Vec<Vec<&str>> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect())
        .collect();
    assert_eq!(rows.len(), 4, "{csv}");
    let slope = |sweep: &str, x: &dyn Fn(&[&str]) -> f64, col: usize| {
        let pts: Vec<(f64, f64)> = (rows.iter().filter(|r| r[0] == sweep))
            .map(|r| (x(r).ln(), r[col].parse::<f64>().unwrap().ln()))
            .collect();
        let (a, b) = (pts[0], pts[1]);
        (b.1 - a.1) / (b.0 - a.0)
    };
    let px = |r: &[&str]| r[1].parse::<f64>().unwrap() * r[2].parse::<f64>().unwrap();
    let k = |r: &[&str]| r[3].parse::<f64>().unwrap();
    let e = &bench["scaling"]["exponents"];
    // The CSV rounds to 1 ns: compare to that precision.
    let close = |a: f64, b: &serde_json::Value| (a - b.as_f64().unwrap()).abs() < 0.05;
    assert!(close(slope("size", &px, 10), &e["detect_vs_pixels"]), "{e}");
    assert!(close(slope("size", &px, 8), &e["render_vs_pixels"]), "{e}");
    assert!(
        close(slope("targets", &k, 11), &e["track_vs_targets"]),
        "{e}"
    );
    for f in [
        "scaling-fps-vs-size.svg",
        "scaling-cost-vs-size.svg",
        "scaling-fps-vs-targets.svg",
        "scaling-cost-vs-targets.svg",
    ] {
        assert!(dir.join(f).exists(), "{f} missing");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// `--split`: the chain also deployed across two `glint run --host` processes on this machine;
/// every frame crossed the bridge (counted on the wire), none lost or refused, the science the
/// local deployment's; beside it, one TCP stream's frames/s. Figures are printed, not asserted.
#[cfg(feature = "hosts")]
#[test]
fn bench_pipeline_split_carries_every_frame_across_the_bridge() {
    let dir = temp_dir("bench-pipeline-split");
    let args = ["pipeline", "--frames", "30", "--size", "256x256"];
    let stdout = glint_bench(&[&args[..], &["--laser", "off", "--split"]].concat(), &dir);
    assert!(stdout.contains("split across two hosts"), "{stdout}");
    let s = &read_json(&dir.join("bench.json"))["pipeline"]["split"];
    assert_eq!(s["frames_on_wire"], 30, "{s}");
    // header, 256² u16 pixels and the 32-byte envelope, per frame
    let header = std::mem::size_of::<shared_types::FrameHeader>() as u64;
    assert_eq!(
        s["frame_bytes_on_wire"],
        30 * (header + 2 * 256 * 256 + 32),
        "{s}"
    );
    assert_eq!(
        (&s["link_lost"], &s["refused"], &s["dropped"]),
        (&0.into(), &0.into(), &0.into())
    );
    assert_eq!(s["science_equal"], true, "{s}");
    let f = |v: &serde_json::Value| v.as_f64().unwrap();
    assert!(
        f(&s["frames_per_s"]) > 0.0 && f(&s["tcp_frames_per_s"]) > 0.0,
        "{s}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
