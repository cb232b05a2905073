//! `glint replay`: a recording's sensor streams published into a fresh deployment of the
//! consumers, which reproduce the recorded run's science bit for bit (every topic's digest and
//! the science digest are the recorded report's, recomputed by a different deployment that
//! rendered nothing); a consumer with changed settings shows as the topics that moved;
//! `--inspect` counts what the report counts; a recording's faults and report ride along.

mod common;

use std::path::{Path, PathBuf};

use common::*;
use serde_json::Value;

/// Records `scenario` into `dir/rec`; the recording's path.
fn record(scenario: &Path, dir: &Path) -> (PathBuf, RunResult) {
    let r = run_ok(Some(scenario), &dir.join("rec"), &["--record"]);
    assert!(r.typed.results.success, "{:?}", r.typed.results.failure);
    (r.dir.join("run.mcap"), r)
}

/// `glint replay RECORDING --out DIR EXTRA…`: its output and `replay.json` (if written).
fn replay(recording: &Path, out: &Path, extra: &[&str]) -> (std::process::Output, Option<Value>) {
    let o = glint()
        .arg("replay")
        .arg(recording)
        .arg("--out")
        .arg(out)
        .args(extra)
        .output()
        .expect("glint replay");
    let json = std::fs::read_to_string(out.join("replay.json"))
        .ok()
        .map(|t| serde_json::from_str(&t).expect("replay.json"));
    (o, json)
}

/// Records `scenario`, replays it into every consumer, and holds the replay to the recording.
fn replay_reproduces(scenario: &Path, tag: &str) {
    let dir = temp_dir(tag);
    let (rec, recorded) = record(scenario, &dir);
    let (o, json) = replay(&rec, &dir.join("replay"), &[]);
    assert_success(&o);
    let json = json.expect("replay.json");
    assert_eq!(json["equal"], true, "{json:#}");
    assert_eq!(json["science_equal"], true, "{json:#}");
    // independently of replay.json: the two reports' digests, topic by topic
    let replayed = read_report(&dir.join("replay").join("report.json"));
    assert!(replayed.results.success);
    assert_eq!(
        replayed.results.science.digest_xxh3,
        recorded.typed.results.science.digest_xxh3
    );
    for (name, t) in &recorded.typed.results.topics {
        let r = &replayed.results.topics[name];
        assert!(t.digest_xxh3.is_some(), "{name}");
        assert_eq!(r.digest_xxh3, t.digest_xxh3, "{name}");
        assert_eq!(r.published, t.published, "{name}");
    }
    // the replay rendered nothing: its sensor read the recording
    let log = std::fs::read_to_string(dir.join("replay/logs/sensor.log")).unwrap();
    assert!(log.contains("replaying from the recording"), "{log}");
    let scenario = std::fs::read_to_string(dir.join("replay/scenario.toml")).unwrap();
    assert!(scenario.contains("[replay]"), "{scenario}");
}

#[test]
fn replaying_the_default_run_reproduces_its_debris_and_spectra_science() {
    replay_reproduces(&scenario("default.toml"), "replay-default");
}

#[test]
fn replaying_an_earth_sensor_run_reproduces_its_attitudes() {
    let dir = temp_dir("replay-earth-scenario");
    let table = scenario("earth-sensor-sigma.csv");
    let named = format!("sigma_table = \"{}\"", table.display());
    let file = scenario_variant(
        "earth-sensor-turntable.toml",
        &[
            ("sigma_table = \"earth-sensor-sigma.csv\"", named.as_str()),
            ("width_px = 512", "width_px = 256"),
            ("height_px = 512", "height_px = 256"),
            ("f_px = 130.0", "f_px = 65.0"),
            ("center_px = [255.5, 255.5]", "center_px = [127.5, 127.5]"),
            ("image_circle_px = 255.0", "image_circle_px = 127.0"),
        ],
        &dir,
    );
    replay_reproduces(&file, "replay-earth");
}

#[test]
fn replaying_a_stereo_run_reproduces_its_relative_navigation() {
    replay_reproduces(&scenario("stereo-tumbling.toml"), "replay-stereo");
}

#[test]
fn replaying_a_light_curve_reproduces_its_photometry() {
    replay_reproduces(&scenario("photometry-geo.toml"), "replay-photometry");
}

/// A detector with a lower threshold, fed the recorded frames: the detections and the tracks
/// differ from the recording's, the frames and spectra do not; the exit code says so.
#[test]
fn a_replay_into_a_changed_detector_shows_the_difference() {
    let dir = temp_dir("replay-changed");
    let (rec, _) = record(&scenario("debris-geo.toml"), &dir);
    let changed = scenario_variant(
        "debris-geo.toml",
        &[(
            "[camera.laser]",
            "[camera.detector]\nthreshold_k_sigma = 3.0\n\n[camera.laser]",
        )],
        &dir,
    );
    let changed = changed.display().to_string();
    let (o, json) = replay(&rec, &dir.join("replay"), &["--scenario", &changed]);
    assert_eq!(o.status.code(), Some(1), "{o:?}");
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(
        stderr.contains("differs from the recording on detections"),
        "{stderr}"
    );
    let json = json.expect("replay.json");
    assert_eq!(json["equal"], false);
    for (topic, equal) in [
        ("frame", true),
        ("truth", true),
        ("detections", false),
        ("tracks", false),
    ] {
        assert_eq!(json["topics"][topic]["equal"], equal, "{topic}: {json:#}");
    }
    // the run itself passed: every frame reached the changed detector
    let replayed = read_report(&dir.join("replay").join("report.json"));
    assert!(replayed.results.success);
}

/// `--service detector`: the detector alone, fed the recording; its detections equal the
/// recorded ones, and no tracker was deployed.
#[test]
fn the_detector_alone_replays_to_the_recorded_detections() {
    let dir = temp_dir("replay-detector");
    let (rec, recorded) = record(&scenario("debris-geo.toml"), &dir);
    let (o, json) = replay(&rec, &dir.join("replay"), &["--service", "detector"]);
    assert_success(&o);
    let json = json.expect("replay.json");
    assert_eq!(json["equal"], true, "{json:#}");
    assert_eq!(json["services"], serde_json::json!(["detector"]));
    assert!(json["topics"].get("tracks").is_none(), "{json:#}");
    let replayed = read_report(&dir.join("replay").join("report.json"));
    let names: Vec<&str> = replayed
        .results
        .services
        .iter()
        .map(|s| s.name.as_str())
        .collect();
    assert_eq!(names, ["sensor", "detector"]);
    assert_eq!(
        replayed.results.topics["detections"].digest_xxh3,
        recorded.typed.results.topics["detections"].digest_xxh3
    );
    // paced at 4 × the recorded time: the same detections, and the 50 frames' 1.96 s of
    // simulated time take at least 0.49 s
    let (o, json) = replay(
        &rec,
        &dir.join("paced"),
        &["--service", "detector", "--speed", "4"],
    );
    assert_success(&o);
    assert_eq!(json.expect("replay.json")["equal"], true);
    let paced = read_report(&dir.join("paced").join("report.json"));
    assert!(
        paced.timing.production_s >= 0.49 * 0.99,
        "{}",
        paced.timing.production_s
    );

    // a consumer whose input no one would publish is refused, naming what is missing
    let (o, _) = replay(&rec, &dir.join("bad"), &["--service", "tracker"]);
    assert_eq!(o.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(
        stderr.contains("tracker takes detections from detector: name detector too"),
        "{stderr}"
    );
}

/// `--inspect` prints the scenario and every channel with the count the report gives it.
#[test]
fn inspect_lists_every_topic_with_the_reports_count() {
    let dir = temp_dir("replay-inspect");
    let (rec, recorded) = record(&scenario("photometry-geo.toml"), &dir);
    let o = glint()
        .arg("replay")
        .arg("--inspect")
        .arg(&rec)
        .output()
        .unwrap();
    assert_success(&o);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("scenario: photometry-geo (seed"), "{text}");
    assert!(text.contains("report: success"), "{text}");
    for (name, t) in &recorded.typed.results.topics {
        if !t.consumers.contains_key("orchestrator") {
            continue;
        }
        let line = (text.lines())
            .find(|l| l.split_whitespace().next() == Some(name.as_str()))
            .unwrap_or_else(|| panic!("no line for {name}: {text}"));
        let count: u64 = line.split_whitespace().nth(1).unwrap().parse().unwrap();
        assert_eq!(Some(count), t.published, "{name}");
    }
    // not a recording: exit 2, the file named
    let o = glint()
        .arg("replay")
        .arg("--inspect")
        .arg(scenario("photometry-geo.toml"))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("not a readable MCAP file"));
}

/// A run with a fault: the fault is a message on the `faults` channel and the report an
/// attachment; the replay of what the faulted run recorded still reproduces its science.
#[test]
fn a_faulted_run_records_its_fault_and_report_and_replays_equal() {
    let dir = temp_dir("replay-fault");
    let r = run_ok(
        Some(&scenario("debris-geo.toml")),
        &dir.join("rec"),
        &["--record", "--fault", "detector:kill@20"],
    );
    assert!(r.typed.results.success, "{:?}", r.typed.results.failure);
    assert_eq!(r.typed.faults.len(), 1);
    assert!(
        r.typed.faults[0].recovered_s.is_some(),
        "the kill took effect and was recovered"
    );
    let rec = r.dir.join("run.mcap");
    let bytes = std::fs::read(&rec).unwrap();
    let mut faults = vec![];
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        if m.channel.topic == "faults" {
            assert_eq!(m.channel.message_encoding, "json");
            faults.push(serde_json::from_slice::<Value>(&m.data).unwrap());
        }
    }
    assert_eq!(faults.len(), 1);
    assert_eq!(faults[0]["kind"], "kill");
    assert_eq!(faults[0]["service"], "detector");
    let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
    let index = (summary.attachment_indexes.iter())
        .find(|a| a.name == "report.json")
        .expect("the report attached");
    let attached = mcap::read::attachment(&bytes, index).unwrap();
    let attached: Value = serde_json::from_slice(&attached.data).unwrap();
    let written = read_json(&r.dir.join("report.json"));
    assert_eq!(attached, written);

    // the recorded frames (each once, though the restarted detector was sent some again)
    // replayed without the fault: the same science
    let (o, json) = replay(&rec, &dir.join("replay"), &[]);
    assert_success(&o);
    assert_eq!(json.expect("replay.json")["equal"], true);
}

/// What a replay cannot reproduce is refused before anything is deployed, naming the message:
/// a recording whose sensor dropped a frame (a fault); a scenario file whose `[replay]` names
/// no recording. A scenario file's `[replay]` is relative to the file, and a `--scenario` with
/// fewer frames than were recorded replays those (the run passes; its results differ).
#[test]
fn what_a_replay_cannot_reproduce_is_refused_and_a_scenario_file_may_replay() {
    let dir = temp_dir("replay-refused");
    let r = run_ok(
        Some(&scenario("debris-geo.toml")),
        &dir.join("gap"),
        &["--record", "--fault", "sensor:drop@10"],
    );
    assert!(r.typed.results.success, "{:?}", r.typed.results.failure);
    let dropped: u64 = (r.typed.results.topics["frame"].consumers.values())
        .map(|c| c.dropped.unwrap_or(0))
        .sum();
    assert!(dropped > 0, "the sensor's drop took effect");
    let (o, json) = replay(&r.dir.join("run.mcap"), &dir.join("gap-replay"), &[]);
    assert_eq!(o.status.code(), Some(2), "{o:?}");
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(stderr.contains("of topic frame is missing"), "{stderr}");
    assert!(json.is_none());

    // a scenario file with `[replay]`, its recording relative to the file
    let (_, recorded) = record(&scenario("debris-geo.toml"), &dir);
    let text = std::fs::read_to_string(scenario("debris-geo.toml")).unwrap();
    let file = dir.join("from-recording.toml");
    std::fs::write(
        &file,
        format!("{text}\n[replay]\nrecording = \"rec/run.mcap\"\n"),
    )
    .unwrap();
    let replayed = run_ok(Some(&file), &dir.join("from-file"), &[]);
    assert!(replayed.typed.results.success);
    assert_eq!(
        replayed.typed.results.science.digest_xxh3,
        recorded.typed.results.science.digest_xxh3
    );
    std::fs::write(
        &file,
        format!("{text}\n[replay]\nrecording = \"none.mcap\"\n"),
    )
    .unwrap();
    let o = glint()
        .arg("run")
        .arg(&file)
        .arg("--out")
        .arg(dir.join("none"))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2), "{o:?}");
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(
        stderr.contains("replay.recording") && stderr.contains("none.mcap"),
        "{stderr}"
    );

    // fewer frames than recorded: those frames, every one accounted for
    let shorter = scenario_variant("debris-geo.toml", &[("frames = 50", "frames = 30")], &dir);
    let shorter = shorter.display().to_string();
    let (o, json) = replay(
        &recorded.dir.join("run.mcap"),
        &dir.join("short"),
        &["--scenario", &shorter],
    );
    assert_eq!(o.status.code(), Some(1), "{o:?}");
    assert_eq!(
        json.expect("replay.json")["topics"]["frame"]["equal"],
        false
    );
    let short = read_report(&dir.join("short").join("report.json"));
    assert!(short.results.success, "{:?}", short.results.failure);
    assert_eq!(short.results.topics["frame"].published, Some(30));
}
