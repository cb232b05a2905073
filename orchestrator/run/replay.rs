//! `glint replay run.mcap`: the recording's sensor streams published into a fresh deployment
//! of the consumers named (the sensor replays them, `[replay]`), and the replay's results held
//! against the recording's report topic by topic. `--inspect` prints what a recording holds.
//!
//! In sim-clock mode a replay reproduces the recorded run's science bit for bit: every topic
//! the replay carries has the digest the recorded run's report gives it. A consumer built
//! differently (a changed detector) shows as the topics whose digests moved.

use std::collections::BTreeMap;
use std::io::IsTerminal;
use std::path::Path;
use std::process::ExitCode;

use anyhow::{Context, Result};
use glint_sensor::recording::Recording;
use serde::{Deserialize, Serialize};
use shared_types::scenario::ReplayScenario;
use shared_types::{deployment, Scenario, ServiceId};

use crate::cli::ReplayArgs;
use crate::report::Report;
use crate::run::{self, command};

/// One topic of a replay against the recording (`replay.json`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TopicComparison {
    pub recorded_digest_xxh3: Option<String>,
    pub replayed_digest_xxh3: Option<String>,
    pub recorded_published: Option<u64>,
    pub replayed_published: Option<u64>,
    pub equal: bool,
}

/// `DIR/replay.json`: the replay's results against the recording's.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ReplayReport {
    pub recording: String,
    pub services: Vec<String>,
    /// Every topic the replay carried equals the recorded run's (`None`: the recording holds
    /// no report to compare with).
    pub equal: Option<bool>,
    /// A replay of every consumer: its science digest (every topic and the solve's answers)
    /// equals the recorded run's.
    pub science_equal: Option<bool>,
    pub topics: BTreeMap<String, TopicComparison>,
}

/// `glint replay`.
pub(crate) fn command(args: ReplayArgs) -> ExitCode {
    glint_runtime::init_tracing("orchestrator");
    let recording = match Recording::open(&args.recording) {
        Ok(r) => r,
        Err(e) => {
            eprintln!("error: {e:#}");
            return ExitCode::from(2);
        }
    };
    if args.inspect {
        print!("{}", inspect(&recording));
        return ExitCode::SUCCESS;
    }
    let sc = match scenario(&recording, &args) {
        Ok(sc) => sc,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    let services: Vec<String> = (deployment::services(&sc).into_iter())
        .filter(|s| *s != ServiceId::Sensor)
        .map(|s| s.name().to_string())
        .collect();
    let recorded = recorded_report(&recording);
    let file = format!("replay of {}", args.recording.display());
    drop(recording);
    let opts = run::RunOptions {
        scenario: sc,
        scenario_file: file,
        out_dir: args.out,
        replace: args.force,
        progress: std::io::stderr().is_terminal(),
        record: false,
        host: None,
    };
    let result = run::run(opts);
    let Ok((dir, ok)) = &result else {
        return command::finish(result);
    };
    let compared = Report::read(&dir.join("report.json")).and_then(|replayed| {
        let r = compare(&args.recording, services, recorded.as_ref(), &replayed);
        std::fs::write(
            dir.join("replay.json"),
            serde_json::to_string_pretty(&r)? + "\n",
        )
        .context("writing replay.json")?;
        Ok(r)
    });
    match compared {
        Ok(r) => {
            eprint!("{}", verdict(&r));
            let code = command::finish(Ok((dir.clone(), *ok)));
            if *ok && r.equal == Some(false) {
                return ExitCode::from(1);
            }
            code
        }
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(1)
        }
    }
}

/// Camera frames the recording holds.
fn recorded_frames(recording: &Recording) -> u64 {
    (recording.channels())
        .find(|c| c.topic == shared_types::TopicId::Frame.name())
        .map_or(0, |c| c.messages)
}

/// The recording's report, if it has one; one that does not parse (another glint's) is said,
/// and nothing is compared.
fn recorded_report(recording: &Recording) -> Option<Report> {
    let text = recording.report_json.as_deref()?;
    match serde_json::from_str(text) {
        Ok(r) => Some(r),
        Err(e) => {
            eprintln!(
                "warning: {}: its report.json does not read as this glint's report ({e}); the \
                 replay is not compared with it",
                recording.path().display()
            );
            None
        }
    }
}

/// The scenario a replay deploys: the recording's (or `--scenario`'s: the consumers' settings
/// changed), its streams from the recording, the consumers named.
fn scenario(recording: &Recording, args: &ReplayArgs) -> Result<Scenario, String> {
    let path = recording.path();
    let mut sc = match &args.scenario {
        Some(file) => command::load(Some(file)).map_err(|e| e.to_string())?.0,
        None => {
            let toml = recording.scenario_toml.as_deref().ok_or_else(|| {
                format!(
                    "{}: holds no scenario (not a recording of `glint run --record`)",
                    path.display()
                )
            })?;
            Scenario::from_toml_str(toml, &format!("{} (its scenario)", path.display()))
                .map_err(|e| e.to_string())?
        }
    };
    // A replay runs on the sim clock, paced by `--speed` alone: the streams come from the
    // recording, and every consumer takes every message.
    sc.clock = shared_types::scenario::Clock::Sim;
    // The recording holds what the recorded run's faults did; a replay injects none (a
    // `--scenario`'s faults it does).
    if args.scenario.is_none() {
        sc.fault.clear();
        sc.matrix = None;
    }
    // A soak's camera ran until its time was up, with faults on a schedule: the replay is the
    // frames it recorded, without them.
    if sc.soak.take().is_some() {
        sc.fault.clear();
        if let Some(cam) = &mut sc.camera {
            cam.frames = recorded_frames(recording);
        }
    }
    // Paced, the replay takes the recorded span over the speed: its time limit grows by that.
    if let Some(x) = args.speed.filter(|x| *x > 0.0) {
        let span_s = (recording.channels())
            .filter(|c| {
                shared_types::TopicId::from_name(&c.topic).is_some_and(|t| t.spec().truth.is_some())
            })
            .map(|c| (c.sim_span_ns.1 - c.sim_span_ns.0) as f64 * 1e-9)
            .fold(0.0, f64::max);
        sc.run.timeout_s = (sc.run.timeout_s + span_s / x).min(86_400.0);
    }
    let absolute = std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf());
    sc.replay = Some(ReplayScenario {
        recording: absolute.display().to_string(),
        services: args.services.clone(),
        speed: args.speed.unwrap_or(0.0),
    });
    sc.validate().map_err(|errors| {
        let all: Vec<String> = errors.iter().map(|e| e.to_string()).collect();
        format!("{}: {}", path.display(), all.join("; "))
    })?;
    complete(recording, &sc).map_err(|e| format!("{e:#}"))?;
    Ok(sc)
}

/// Every message the scenario's sensor streams carry, and its truth, is in the recording: a
/// replay needs every one (a recorded run whose sensor dropped or lost messages, or a
/// `--scenario` asking for more, is refused before anything is deployed).
pub fn complete(recording: &Recording, sc: &Scenario) -> Result<()> {
    for t in deployment::outputs(sc, ServiceId::Sensor) {
        let Some(kind) = t.spec().truth else {
            continue;
        };
        let want = deployment::expected_messages(sc, t);
        recording
            .first(t, want)
            .context("a replay needs every message its scenario makes")?;
        let truths = recording.truths(kind)?.len() as u64;
        if truths < want {
            anyhow::bail!(
                "{}: holds {truths} truths of topic {} for its {want} messages",
                recording.path().display(),
                t.name()
            );
        }
    }
    Ok(())
}

/// `glint bench pipeline --source run.mcap`: the recording's [002] chain (its camera, detector
/// and tracker; every other stream left out), rendered, and the same fed from the recording.
pub fn bench_scenarios(path: &Path) -> Result<(Scenario, Scenario)> {
    let recording = Recording::open(path)?;
    let toml = (recording.scenario_toml.as_deref())
        .with_context(|| format!("{}: holds no scenario", path.display()))?;
    let mut sc = Scenario::from_toml_str(toml, &format!("{} (its scenario)", path.display()))
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let frames = recorded_frames(&recording);
    let Some(cam) = sc.camera.as_mut() else {
        anyhow::bail!(
            "{}: its scenario has no [camera]: no frames to feed",
            path.display()
        );
    };
    cam.frames = frames;
    (sc.spectra, sc.earth, sc.stereo, sc.photometry) = (None, None, None, None);
    (sc.soak, sc.matrix) = (None, None);
    sc.fault.clear();
    let mut replayed = sc.clone();
    let absolute = std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf());
    replayed.replay = Some(ReplayScenario {
        recording: absolute.display().to_string(),
        services: vec![],
        speed: 0.0,
    });
    replayed
        .validate()
        .map_err(|e| anyhow::anyhow!("{}: {e:?}", path.display()))?;
    Ok((sc, replayed))
}

/// Each topic the replay carried, against the recording's report.
fn compare(
    path: &Path,
    services: Vec<String>,
    recorded: Option<&Report>,
    replayed: &Report,
) -> ReplayReport {
    let mut topics = BTreeMap::new();
    for (name, t) in &replayed.results.topics {
        let Some(rec) = recorded else { break };
        let r = rec.results.topics.get(name);
        let recorded_digest = r.and_then(|r| r.digest_xxh3.clone());
        topics.insert(
            name.clone(),
            TopicComparison {
                equal: recorded_digest.is_some() && recorded_digest == t.digest_xxh3,
                recorded_digest_xxh3: recorded_digest,
                replayed_digest_xxh3: t.digest_xxh3.clone(),
                recorded_published: r.and_then(|r| r.published),
                replayed_published: t.published,
            },
        );
    }
    fn every_consumer(r: &Report) -> Vec<&str> {
        let mut names: Vec<&str> = r.results.services.iter().map(|s| s.name.as_str()).collect();
        names.sort_unstable();
        names
    }
    let science_equal = recorded
        .filter(|rec| every_consumer(rec) == every_consumer(replayed))
        .map(|rec| rec.results.science.digest_xxh3 == replayed.results.science.digest_xxh3);
    ReplayReport {
        recording: path.display().to_string(),
        services,
        equal: recorded.map(|_| topics.values().all(|t| t.equal) && science_equal != Some(false)),
        science_equal,
        topics,
    }
}

/// The comparison in a few lines, the answer first.
fn verdict(r: &ReplayReport) -> String {
    let differ: Vec<&str> = (r.topics.iter())
        .filter(|(_, t)| !t.equal)
        .map(|(n, _)| n.as_str())
        .collect();
    match r.equal {
        None => format!("replay: {} holds no report to compare with\n", r.recording),
        Some(true) => format!(
            "replay: every topic equal to the recording{} ({} topics: {}; services {})\n",
            if r.science_equal == Some(true) {
                ", the science digest too"
            } else {
                ""
            },
            r.topics.len(),
            r.topics.keys().cloned().collect::<Vec<_>>().join(", "),
            r.services.join(", ")
        ),
        Some(false) => format!(
            "replay: differs from the recording on {}{} (digests in replay.json)\n",
            differ.join(", "),
            if r.science_equal == Some(false) {
                " and the science digest"
            } else {
                ""
            },
        ),
    }
}

/// `--inspect`: the scenario, then every channel: messages, bytes, simulated time span.
fn inspect(recording: &Recording) -> String {
    let mut out = format!("{}\n", recording.path().display());
    match recording
        .scenario_toml
        .as_deref()
        .map(toml::from_str::<Scenario>)
    {
        Some(Ok(sc)) => {
            let services: Vec<&str> = (deployment::services(&sc).iter())
                .map(|s| s.name())
                .collect();
            out += &format!(
                "scenario: {} (seed {}, clock {:?}; deploys {})\n",
                sc.name,
                sc.seed,
                sc.clock,
                services.join(", ")
            );
        }
        Some(Err(e)) => out += &format!("scenario: unreadable ({e})\n"),
        None => out += "scenario: none\n",
    }
    let report: Option<Result<Report, String>> = (recording.report_json.as_deref())
        .map(|text| serde_json::from_str(text).map_err(|e| e.to_string()));
    out += &match &report {
        Some(Err(e)) => format!("report: unreadable by this glint ({e})\n"),
        Some(Ok(r)) => format!(
            "report: {} ({} faults); science digest {}\n",
            if r.results.success {
                "success"
            } else {
                "failed"
            },
            r.faults.len(),
            r.results.science.digest_xxh3
        ),
        None => "report: none (the run did not finish writing it)\n".to_string(),
    };
    out += &format!(
        "{:<20} {:>9} {:>12} {:>24}  {}\n",
        "topic", "messages", "MiB", "sim time [s]", "schema"
    );
    for c in recording.channels() {
        out += &format!(
            "{:<20} {:>9} {:>12.1} {:>24}  {}\n",
            c.topic,
            c.messages,
            c.bytes as f64 / (1 << 20) as f64,
            format!(
                "{:.3} – {:.3}",
                c.sim_span_ns.0 as f64 * 1e-9,
                c.sim_span_ns.1 as f64 * 1e-9
            ),
            c.schema
        );
    }
    out
}
