//! `glint top`, used as a person uses it: against a live deployment (a realtime debris run, a
//! few seconds long), its `--once --json` snapshot names every service with its pid, state and
//! rates, and its screen in a pseudo-terminal (`script`) shows every service and quits on `q`.
//! The run it watched passes, with `glint-top` reported as an observer.

mod common;

use std::io::{BufRead, BufReader, Write};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::Duration;

use common::*;
use serde_json::Value;

/// Starts a realtime debris run (`frames` at 25 frames/s) and waits for its prefix.
fn start_run(dir: &Path, frames: u32) -> (Child, String, mpsc::Receiver<String>) {
    let file = scenario_variant(
        "debris-geo.toml",
        &[
            ("frames = 50", &format!("frames = {frames}")),
            ("[camera]", "clock = \"realtime\"\n\n[camera]"),
        ],
        dir,
    );
    let mut child = glint()
        .arg("run")
        .arg(&file)
        .arg("--out")
        .arg(dir.join("run"))
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("glint run");
    let stderr = child.stderr.take().unwrap();
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            let _ = tx.send(line);
        }
    });
    let prefix = loop {
        let line = rx
            .recv_timeout(Duration::from_secs(60))
            .expect("the run's `deployed` line");
        if let Some(rest) = line
            .split("prefix=\"")
            .nth(1)
            .filter(|_| line.contains("deployed"))
        {
            break rest.split('"').next().unwrap().to_string();
        }
        if let Some(rest) = line
            .split("prefix=")
            .nth(1)
            .filter(|_| line.contains("deployed"))
        {
            break rest
                .split_whitespace()
                .next()
                .unwrap()
                .trim_matches('"')
                .to_string();
        }
    };
    (child, prefix, rx)
}

#[test]
fn top_shows_every_service_of_a_live_deployment() {
    let dir = temp_dir("top");
    let (mut run, prefix, _log) = start_run(&dir, 250);
    // let the services come up and run
    std::thread::sleep(Duration::from_millis(1500));

    // one snapshot, as a script takes it
    let o = glint()
        .args(["top", "--once", "--json", &prefix])
        .output()
        .unwrap();
    assert_success(&o);
    let snap: Value = serde_json::from_slice(&o.stdout).expect("JSON");
    assert_eq!(snap["prefix"], prefix.as_str());
    let services = snap["services"].as_array().unwrap();
    let names: Vec<&str> = services
        .iter()
        .map(|s| s["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["sensor", "detector", "tracker"], "{snap:#}");
    for s in services {
        assert!(s["pid"].as_u64().unwrap() > 0, "{s}");
        assert_eq!(s["state"], "running", "{s}");
        assert!(s["rss_mib"].as_f64().unwrap() > 1.0, "{s}");
        assert!(s["cpu_percent"].as_f64().is_some(), "{s}");
    }
    // 25 frames/s in realtime: the detector takes them at about that rate
    let detector = &services[1];
    let rate = detector["inputs_per_s"].as_f64().unwrap();
    assert!(rate > 5.0 && rate < 100.0, "{detector}");
    assert!(
        detector["latency_p50_us"].as_f64().unwrap() > 0.0,
        "{detector}"
    );
    // its pids are the processes the run spawned
    let pid = detector["pid"].as_u64().unwrap();
    let cmdline = std::fs::read_to_string(format!("/proc/{pid}/cmdline")).unwrap();
    assert!(
        cmdline.contains("detector") && cmdline.contains(&prefix),
        "{cmdline}"
    );

    // the screen, in a pseudo-terminal: every service shown; `q` quits
    let mut top = Command::new("script")
        .args(["-qfec"])
        .arg(format!(
            "stty rows 30 cols 150; {} top {prefix}",
            env!("CARGO_BIN_EXE_glint")
        ))
        .arg("/dev/null")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("script (util-linux) for a pseudo-terminal");
    std::thread::sleep(Duration::from_millis(1500));
    top.stdin.as_mut().unwrap().write_all(b"q").unwrap();
    let (tx, rx) = mpsc::channel();
    let waiter = std::thread::spawn(move || {
        let out = top.wait_with_output().unwrap();
        let _ = tx.send(());
        out
    });
    rx.recv_timeout(Duration::from_secs(10))
        .expect("glint top quits on q");
    let out = waiter.join().unwrap();
    assert!(out.status.success(), "{out:?}");
    // The bytes are ratatui's diff redraws (a name can be written in pieces around letters
    // already on screen), so read the screen a terminal would show, not the raw stream: the
    // alternate screen as it stood just before `q` left it.
    const LEAVE_ALTERNATE: &[u8] = b"\x1b[?1049l";
    let shown = (out.stdout.windows(LEAVE_ALTERNATE.len()))
        .rposition(|w| w == LEAVE_ALTERNATE)
        .map_or(&out.stdout[..], |end| &out.stdout[..end]);
    let size = |n| std::num::NonZeroU16::new(n).unwrap();
    let mut term = vt100::Parser::new(size(30), size(150), 0);
    term.process(shown);
    let screen = term.screen().contents();
    for name in [
        "glint top",
        prefix.as_str(),
        "sensor",
        "detector",
        "tracker",
        "running",
    ] {
        assert!(
            screen.contains(name),
            "no `{name}` on the screen:\n{screen}"
        );
    }

    // the run ends well, with glint-top seen as an observer
    assert!(run.wait().unwrap().success());
    let report = read_report(&dir.join("run").join("report.json"));
    assert!(report.results.success);
    let observers: Vec<&str> = (report.membership.strangers.iter())
        .filter(|s| s.role == "observer")
        .map(|s| s.name.as_str())
        .collect();
    assert!(observers.contains(&"glint-top"), "{:?}", report.membership);
}

/// Nothing running under a prefix: exit 2 and a sentence.
#[test]
fn top_without_a_deployment_says_so() {
    let o = glint()
        .args(["top", "--once", "glint_0badc0de_"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(
        stderr.contains("no deployment is running under glint_0badc0de_"),
        "{stderr}"
    );
    let o = glint().args(["top", "--once", "nope"]).output().unwrap();
    assert_eq!(o.status.code(), Some(2));
}
