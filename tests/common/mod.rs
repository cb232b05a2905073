//! Helpers for the system tests: run the real `glint` binary, read its report.

#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use glint::matrix::MatrixReport;
use glint::report::inversion::{InversionReport, Stage3Report};
use glint::report::Report;
use serde_json::Value;

pub mod procs;

pub fn glint() -> Command {
    Command::new(env!("CARGO_BIN_EXE_glint"))
}

pub fn scenario(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenarios")
        .join(name)
}

/// A fresh directory for one test's outputs.
/// The Python of the test environment: `python/.venv` (the README's test command, `./test`,
/// makes it, with numpy) or the interpreter `GLINT_PYTHON` names.
pub fn python() -> PathBuf {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let python = std::env::var_os("GLINT_PYTHON")
        .map(PathBuf::from)
        .unwrap_or_else(|| root.join("python/.venv/bin/python"));
    assert!(
        python.is_file(),
        "no Python environment at {}: run `./test` (the README's test command), or \
         `python3 -m venv python/.venv && python/.venv/bin/pip install -e 'python[test]'`",
        python.display()
    );
    python
}

pub fn temp_dir(tag: &str) -> PathBuf {
    let d = std::env::temp_dir()
        .join("glint-tests")
        .join(format!("{}-{tag}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

pub struct RunResult {
    pub output: Output,
    pub dir: PathBuf,
    /// `report.json` read through glint's types.
    pub typed: Report,
}

/// `glint run [scenario] --out dir [--seed N]`, and the parsed report.
pub fn run(scenario: Option<&Path>, dir: &Path, extra: &[&str]) -> RunResult {
    let mut cmd = glint();
    cmd.arg("run");
    if let Some(s) = scenario {
        cmd.arg(s);
    }
    cmd.arg("--out").arg(dir).args(extra);
    let output = cmd.output().expect("spawning glint");
    let text = std::fs::read_to_string(dir.join("report.json")).unwrap_or_else(|e| {
        panic!(
            "no report.json ({e}); stderr:\n{}",
            String::from_utf8_lossy(&output.stderr)
        )
    });
    RunResult {
        output,
        dir: dir.to_path_buf(),
        typed: serde_json::from_str(&text)
            .unwrap_or_else(|e| panic!("report.json does not read as glint's Report: {e}")),
    }
}

/// As [`run`], and the run must have succeeded.
pub fn run_ok(scenario: Option<&Path>, dir: &Path, extra: &[&str]) -> RunResult {
    let r = run(scenario, dir, extra);
    assert!(
        r.output.status.success(),
        "{}",
        String::from_utf8_lossy(&r.output.stderr)
    );
    r
}

/// `glint run` of a `[matrix]` scenario: its output and its `report.json`, read through
/// glint's [`MatrixReport`] (a matrix's report is not a run's [`Report`]).
pub fn run_matrix(scenario: &Path, dir: &Path, extra: &[&str]) -> (Output, MatrixReport) {
    let output = glint()
        .arg("run")
        .arg(scenario)
        .arg("--out")
        .arg(dir)
        .args(extra)
        .output()
        .expect("spawning glint");
    let path = dir.join("report.json");
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| {
        panic!(
            "no report.json ({e}); stderr:\n{}",
            String::from_utf8_lossy(&output.stderr)
        )
    });
    let report = serde_json::from_str(&text).unwrap_or_else(|e| {
        panic!(
            "{} does not read as glint's MatrixReport: {e}",
            path.display()
        )
    });
    (output, report)
}

/// A run's `report.json` at `path`, read through glint's [`Report`] (panics with the path if
/// missing or not a report).
pub fn read_report(path: &Path) -> Report {
    Report::read(path).unwrap_or_else(|e| panic!("{e:#}"))
}

/// The attitude solve's section of a report ([000]); panics without one.
pub fn inversion(report: &Report) -> &InversionReport {
    report
        .results
        .inversion
        .as_ref()
        .expect("no inversion section in the report")
}

/// Stage 3 of the attitude solve (glint's answer); panics without one.
pub fn stage3(report: &Report) -> &Stage3Report {
    inversion(report)
        .stage3
        .as_ref()
        .expect("no stage3 in the report's inversion section")
}

/// The JSON file at `path` (panics with the path if missing or malformed).
/// `glint invert OBS --out DIR [extra…]`, which must succeed; the parsed `DIR/inversion.json`.
pub fn invert_ok(observations: &Path, out_dir: &Path, extra: &[&str]) -> Value {
    let out = glint()
        .arg("invert")
        .arg(observations)
        .arg("--out")
        .arg(out_dir)
        .args(extra)
        .output()
        .unwrap();
    assert_success(&out);
    read_json(&out_dir.join("inversion.json"))
}

/// Asserts that a `glint` command exited 0, showing its stderr when it did not.
pub fn assert_success(out: &std::process::Output) {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

pub fn read_json(path: &Path) -> Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// `glint lab campaign CAMPAIGN --out dir`, which must succeed; returns its `campaign.json`.
pub fn run_campaign_ok(scenario: &Path, dir: &Path) -> Value {
    let out = glint()
        .args(["lab", "campaign"])
        .arg(scenario)
        .arg("--out")
        .arg(dir)
        .output()
        .expect("spawning glint");
    assert_success(&out);
    read_json(&dir.join("campaign.json"))
}

/// `glint lab campaign SCENARIO --rescore --out DIR`: re-scores a Monte-Carlo campaign in
/// `dir`.
pub fn rescore(scenario: &Path, dir: &Path) -> std::process::Output {
    glint()
        .args(["lab", "campaign"])
        .arg(scenario)
        .arg("--rescore")
        .arg("--out")
        .arg(dir)
        .output()
        .expect("spawning glint")
}

/// A shipped scenario with text replacements applied, written into `dir`.
pub fn scenario_variant(name: &str, replacements: &[(&str, &str)], dir: &Path) -> PathBuf {
    let mut text = std::fs::read_to_string(scenario(name)).unwrap();
    for (from, to) in replacements {
        assert!(text.contains(from), "{name} has no `{from}`");
        text = text.replace(from, to);
    }
    let file = dir.join(name);
    std::fs::write(&file, text).unwrap();
    file
}

/// The deterministic part of a report: its `Results` (the run's identity, timings, faults
/// and strangers are beside them).
/// As JSON, so that a score that is not a number (written as null) compares equal to itself.
pub fn deterministic_part(report: &Report) -> Value {
    serde_json::to_value(&report.results).expect("the results as JSON")
}

/// What a prefix left behind, in `/dev/shm` and in iceoryx2's node and service directories.
pub fn shm_left(prefix: &str) -> Vec<String> {
    // An unreadable /dev/shm would make every leftover check pass: fail instead.
    std::fs::read_dir("/dev/shm").expect("/dev/shm cannot be read: no leftover check possible");
    glint_runtime::shm_entries(prefix)
        .iter()
        .map(|p| p.display().to_string())
        .collect()
}

/// What an SVG figure shows: its text labels (trimmed, numbers left out) and how many
/// elements of `tag` it draws.
pub struct Svg {
    pub texts: Vec<String>,
    text: String,
}

impl Svg {
    pub fn read(path: &Path) -> Svg {
        let text =
            std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let mut texts = vec![];
        for chunk in text.split("<text").skip(1) {
            let Some(body) = chunk.split_once('>').map(|(_, b)| b) else {
                continue;
            };
            let label = body.split("</text>").next().unwrap_or_default().trim();
            let numeric = label
                .chars()
                .all(|c| c.is_ascii_digit() || "+-.e−".contains(c));
            if !label.is_empty() && !numeric {
                texts.push(label.to_string());
            }
        }
        Svg { texts, text }
    }

    /// The number of `<tag …>` elements.
    pub fn count(&self, tag: &str) -> usize {
        self.text.matches(&format!("<{tag} ")).count()
    }

    pub fn has_text(&self, label: &str) -> bool {
        self.texts.iter().any(|t| t == label)
    }
}

/// Width and height of a PNG, from its IHDR chunk.
pub fn png_size(path: &Path) -> (u32, u32) {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert_eq!(
        &bytes[..8],
        b"\x89PNG\r\n\x1a\n",
        "{} is not a PNG",
        path.display()
    );
    assert_eq!(&bytes[12..16], b"IHDR");
    let be = |i: usize| u32::from_be_bytes(bytes[i..i + 4].try_into().unwrap());
    (be(16), be(20))
}

/// The `ending` of service `name` in a report (`shutdown`, `sigkill`, …).
pub fn ending<'a>(report: &'a Report, name: &str) -> &'a str {
    report
        .results
        .services
        .iter()
        .find(|s| s.name == name)
        .map(|s| s.ending.as_str())
        .unwrap_or_else(|| panic!("no service {name} in the report"))
}

/// The first CPU this process may run on (`Cpus_allowed_list` in /proc/self/status): what a
/// test pins a service to, on any host or cpuset.
pub fn first_allowed_cpu() -> u32 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap();
    let list = (status.lines())
        .find_map(|l| l.strip_prefix("Cpus_allowed_list:"))
        .expect("Cpus_allowed_list");
    list.trim()
        .split([',', '-'])
        .next()
        .and_then(|c| c.parse().ok())
        .expect("a CPU")
}
