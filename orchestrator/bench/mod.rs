//! `glint bench`: throughput testing, every figure measured against a baseline in the same run.
//! `glint bench ipc` compares transports between two processes ([`ipc`]); `glint bench
//! pipeline` the deployed chain with the same work done in one process ([`pipeline`]); `glint
//! bench scaling` that comparison against frame size and number of debris ([`scaling`]).

pub mod ipc;
mod ipc_run;
pub mod pipeline;
pub mod scaling;
pub mod split;

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde_json::{json, Value};

pub use ipc_run::{run_ipc, IpcOptions};

/// The machine the figures came from.
fn host() -> serde_json::Value {
    let cpuinfo = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
    let model = cpuinfo
        .lines()
        .find(|l| l.starts_with("model name"))
        .and_then(|l| l.split(':').nth(1))
        .map(|s| s.trim().to_string());
    let cpus = std::thread::available_parallelism().map_or(0, |n| n.get());
    json!({ "cpus": cpus, "cpu_model": model })
}

/// Writes `doc`'s sections into `DIR/bench.json`, keeping the sections of an earlier bench in
/// the same directory (`glint bench ipc` and `glint bench pipeline` may share one).
fn merge_bench_json(dir: &Path, doc: serde_json::Value) -> Result<()> {
    let path = dir.join("bench.json");
    let mut merged = std::fs::read_to_string(&path)
        .ok()
        .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
        .filter(|v| v.is_object())
        .unwrap_or_else(|| json!({}));
    if let (Some(m), Some(new)) = (merged.as_object_mut(), doc.as_object()) {
        for (k, v) in new {
            m.insert(k.clone(), v.clone());
        }
    }
    std::fs::write(&path, serde_json::to_string_pretty(&merged)? + "\n")
        .with_context(|| format!("writing {}", path.display()))
}

/// One measured point: the deployment (its run directory in `run_dir`) and the in-process
/// baseline of the same scenario.
pub struct Point {
    pub deployed: pipeline::Deployed,
    pub in_process: pipeline::InProcess,
    pub run_dir: PathBuf,
}

/// A deployment with `--record`: its frames/s and what it recorded.
pub struct Recorded {
    pub fps: f64,
    pub written: u64,
    pub not_written: u64,
    pub bytes: u64,
    pub success: bool,
}

/// One of the bench's deployments (`what` names it), run into `run_dir`: its directory,
/// whether it passed, and its report.
fn deploy(
    sc: shared_types::Scenario,
    what: &str,
    run_dir: PathBuf,
    progress: bool,
    record: bool,
) -> Result<(PathBuf, bool, crate::report::Report)> {
    let opts = crate::run::RunOptions {
        scenario: sc,
        scenario_file: format!("glint bench ({what})"),
        out_dir: Some(run_dir),
        replace: true,
        progress,
        record,
        host: None,
    };
    let (dir, ok) = crate::run::run(opts)?;
    let report = crate::report::Report::read(&dir.join("report.json"))?;
    Ok((dir, ok, report))
}

/// Deploys `sc` as processes into `run_dir`, every tapped message recorded to run.mcap.
pub fn measure_recorded(
    sc: shared_types::Scenario,
    run_dir: PathBuf,
    progress: bool,
) -> Result<Recorded> {
    let (dir, ok, report) = deploy(sc, "debris-geo, recorded", run_dir, progress, true)?;
    let rec = report.run.recording.as_ref();
    let bytes = std::fs::metadata(dir.join("run.mcap")).map_or(0, |m| m.len());
    Ok(Recorded {
        fps: report.timing.frames_per_s,
        // The chain's messages (the heartbeats ride along, as many as the run is long).
        written: rec.map_or(0, |r| {
            (r.messages.iter())
                .filter(|(t, _)| *t != shared_types::TopicId::Heartbeat.name())
                .map(|(_, n)| n)
                .sum()
        }),
        not_written: rec.map_or(0, |r| r.not_written.values().sum()),
        bytes,
        success: ok && rec.is_some_and(|r| r.failure.is_none()),
    })
}

/// Pins the bench's services as `--cpu` says (`[services.<name>] cpu`), checked as a scenario's
/// placement is.
fn place(sc: &mut shared_types::Scenario, cpus: &[(String, u32)]) -> Result<(), String> {
    for (name, cpu) in cpus {
        sc.services.entry(name.clone()).or_default().cpu = Some(*cpu);
        let checked = sc.validate().map_err(|errs| {
            let all: Vec<String> = errs.iter().map(|e| e.to_string()).collect();
            all.join("; ")
        });
        checked
            .and_then(|()| {
                crate::run::command::host_has_cpus(sc)
                    .map_err(|(field, message)| format!("{field}: {message}"))
            })
            .map_err(|e| format!("`{name}={cpu}`: {e}"))?;
    }
    Ok(())
}

/// Deploys `sc` (a `[replay]`: the frames from a recording) as processes into `run_dir`; its
/// frames/s.
pub fn measure_replayed(
    sc: shared_types::Scenario,
    run_dir: PathBuf,
    progress: bool,
) -> Result<f64> {
    let (dir, ok, report) = deploy(sc, "from a recording", run_dir, progress, false)?;
    if !ok {
        anyhow::bail!(
            "the deployment fed from the recording failed: {} (see {})",
            report.results.failure.as_deref().unwrap_or("unknown"),
            dir.join("summary.md").display()
        );
    }
    Ok(report.timing.frames_per_s)
}

/// Deploys `sc` as processes into `run_dir`, then does the same work in this process.
pub fn measure(sc: shared_types::Scenario, run_dir: PathBuf, progress: bool) -> Result<Point> {
    let frames = sc.camera.as_ref().map_or(0, |c| c.frames);
    let opts = crate::run::RunOptions {
        scenario: sc.clone(),
        scenario_file: "glint bench (debris-geo)".into(),
        out_dir: Some(run_dir),
        replace: true,
        progress,
        record: false,
        host: None,
    };
    let (dir, ok) = crate::run::run(opts)?;
    let report_path = dir.join("report.json");
    let report: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(&report_path)
            .with_context(|| format!("reading {}", report_path.display()))?,
    )?;
    if !ok {
        anyhow::bail!(
            "the deployment failed: {} (see {})",
            report["failure"].as_str().unwrap_or("unknown"),
            dir.join("summary.md").display()
        );
    }
    let deployed = pipeline::read_report(&report);
    let bar = if progress {
        crate::progress::bar(frames)
    } else {
        indicatif::ProgressBar::hidden()
    };
    bar.set_message("in one process");
    let in_process = pipeline::in_process(&sc, &bar)?;
    bar.finish_and_clear();
    Ok(Point {
        deployed,
        in_process,
        run_dir: dir,
    })
}

/// Deploys the pipeline, runs the in-process baseline, writes `bench.json` and
/// `pipeline.csv`, prints the table.
pub fn run_pipeline(
    o: &pipeline::PipelineOptions,
    sc: shared_types::Scenario,
    record: bool,
    replayed: Option<shared_types::Scenario>,
    split: bool,
) -> Result<()> {
    let split_sc = split.then(|| sc.clone());
    std::fs::create_dir_all(&o.out).with_context(|| format!("creating {}", o.out.display()))?;
    let progress = std::io::IsTerminal::is_terminal(&std::io::stderr());
    let recorded_sc = record.then(|| sc.clone());
    let placement: serde_json::Map<String, Value> = (sc.services.iter())
        .filter_map(|(name, p)| Some((name.clone(), json!(p.cpu?))))
        .collect();
    let Point {
        deployed,
        in_process: ip,
        run_dir: dir,
    } = measure(sc, o.out.join("run"), progress)?;
    pipeline::print(o, &deployed, &ip);
    if !placement.is_empty() {
        let pins: Vec<String> = (placement.iter())
            .map(|(name, cpu)| format!("{name} on CPU {cpu}"))
            .collect();
        println!("(placement: {})", pins.join(", "));
    }
    pipeline::plot_time(&o.out, &deployed)?;
    let mut section = pipeline::json(o, &deployed, &ip);
    section["scenario"]["cpu"] = Value::Object(placement);
    if let Some(sc) = replayed {
        let fps = measure_replayed(sc, o.out.join("run-from-recording"), progress)?;
        println!(
            "from the recording: {fps:.1} frames/s (the chain alone, no rendering), rendered: \
             {:.1} frames/s: {:.2}×",
            deployed.fps,
            fps / deployed.fps
        );
        section["from_recording"] = json!({
            "frames_per_s": fps,
            "frames_per_s_rendered": deployed.fps,
            "ratio": fps / deployed.fps,
        });
    }
    if let Some(sc) = split_sc {
        let s = split::measure(&sc, &o.out, progress)?;
        section["split"] = split::report(&s, &deployed);
    }
    if let Some(sc) = recorded_sc {
        let r = measure_recorded(sc, o.out.join("run-recorded"), progress)?;
        let cost = 1.0 - r.fps / deployed.fps;
        println!(
            "recording: {:.1} frames/s with every message recorded, {:.1} without: {:.1} % \
             slower; {} messages written ({:.0} MiB), {} not written",
            r.fps,
            deployed.fps,
            100.0 * cost,
            r.written,
            r.bytes as f64 / (1u64 << 20) as f64,
            r.not_written,
        );
        section["recording"] = json!({
            "frames_per_s": r.fps,
            "frames_per_s_unrecorded": deployed.fps,
            "cost": cost,
            "messages_written": r.written,
            "messages_not_written": r.not_written,
            "bytes": r.bytes,
            "success": r.success,
        });
    }
    merge_bench_json(
        &o.out,
        json!({ "glint_version": env!("CARGO_PKG_VERSION"), "host": host(), "pipeline": section }),
    )?;
    let mut csv = csv::Writer::from_path(o.out.join("pipeline.csv"))?;
    csv.write_record(["where", "stage", "p50_us", "p99_us", "cpu_s"])?;
    for (name, p50, p99) in &deployed.stages {
        csv.write_record(["deployment", name, &format!("{p50}"), &format!("{p99}"), ""])?;
    }
    for (name, c) in &deployed.cpu_s {
        csv.write_record([
            "deployment",
            &format!("process:{name}"),
            "",
            "",
            &format!("{c}"),
        ])?;
    }
    for (name, ns) in &ip.stages {
        let (_, p50, p99) = pipeline::stats_us(ns);
        csv.write_record(["in_process", name, &format!("{p50}"), &format!("{p99}"), ""])?;
    }
    csv.flush()?;
    println!(
        "\n{} (the deployment: {})",
        o.out.join("bench.json").display(),
        dir.display()
    );
    Ok(())
}

/// `glint bench ipc|pipeline|scaling`.
pub(crate) fn command(bench: crate::cli::BenchCmd) -> std::process::ExitCode {
    use crate::cli::{BenchClock, BenchCmd, OnOff};
    use std::path::PathBuf;
    use std::process::ExitCode;
    match bench {
        BenchCmd::Pipeline {
            out,
            frames,
            size,
            targets,
            clock,
            laser,
            record,
            source,
            cpu,
            split,
        } => {
            glint_runtime::init_tracing("orchestrator");
            if split && !cfg!(feature = "hosts") {
                eprintln!("error: --split: {}", crate::run::hosts::WITHOUT_HOSTS);
                return ExitCode::from(2);
            }
            let opts = crate::bench::pipeline::PipelineOptions {
                out: out.unwrap_or_else(|| {
                    PathBuf::from("runs")
                        .join(format!("bench-pipeline-{}", crate::run::utc_stamp()))
                }),
                frames,
                width_px: size.0,
                height_px: size.1,
                targets: targets as usize,
                clock: match clock {
                    BenchClock::Sim => shared_types::scenario::Clock::Sim,
                    BenchClock::Realtime => shared_types::scenario::Clock::Realtime,
                },
                laser: matches!(laser, OnOff::On),
            };
            let (sc, replayed) = match &source {
                Some(path) => match crate::run::replay::bench_scenarios(path) {
                    Ok((sc, replayed)) => (sc, Some(replayed)),
                    Err(e) => {
                        eprintln!("error: {e:#}");
                        return ExitCode::from(2);
                    }
                },
                None => match crate::bench::pipeline::scenario(&opts) {
                    Ok(sc) => (sc, None),
                    Err(e) => {
                        eprintln!("error: the bench's scenario: {e}");
                        return ExitCode::from(2);
                    }
                },
            };
            let (mut sc, mut replayed) = (sc, replayed);
            for s in std::iter::once(&mut sc).chain(replayed.as_mut()) {
                if let Err(e) = place(s, &cpu) {
                    eprintln!("error: --cpu {e}");
                    return ExitCode::from(2);
                }
            }
            match crate::bench::run_pipeline(&opts, sc, record, replayed, split) {
                Ok(()) => ExitCode::SUCCESS,
                Err(e) => {
                    eprintln!("error: {e:#}");
                    ExitCode::from(1)
                }
            }
        }
        BenchCmd::Scaling {
            out,
            frames,
            sizes,
            targets,
            laser,
        } => {
            glint_runtime::init_tracing("orchestrator");
            let sides = [256, 512, 1024, 2048, 4096];
            let opts = crate::bench::scaling::ScalingOptions {
                out: out.unwrap_or_else(|| {
                    PathBuf::from("runs").join(format!("bench-scaling-{}", crate::run::utc_stamp()))
                }),
                frames,
                sizes: if sizes.is_empty() {
                    sides.iter().map(|&s| (s, s)).collect()
                } else {
                    sizes
                },
                targets: if targets.is_empty() {
                    vec![1, 2, 4, 8, 16]
                } else {
                    targets.into_iter().map(|k| k as usize).collect()
                },
                laser: matches!(laser, OnOff::On),
            };
            match crate::bench::scaling::run(&opts) {
                Ok(()) => ExitCode::SUCCESS,
                Err(e) => {
                    eprintln!("error: {e:#}");
                    ExitCode::from(1)
                }
            }
        }
        BenchCmd::Ipc {
            out,
            transports,
            sizes,
            scale,
        } => {
            if !(scale.is_finite() && (0.001..=100.0).contains(&scale)) {
                eprintln!("error: --scale {scale} is out of range: allowed 0.001 to 100");
                return ExitCode::from(2);
            }
            glint_runtime::lifeline::handle_hangup();
            let opts = crate::bench::IpcOptions {
                out: out.unwrap_or_else(|| {
                    PathBuf::from("runs").join(format!("bench-ipc-{}", crate::run::utc_stamp()))
                }),
                transports: match transports.is_empty() {
                    true => crate::bench::ipc::Transport::ALL.to_vec(),
                    false => transports,
                },
                sizes: match sizes.is_empty() {
                    true => crate::bench::ipc::SIZES.to_vec(),
                    false => sizes.into_iter().map(|s| s as usize).collect(),
                },
                scale,
            };
            match crate::bench::run_ipc(&opts) {
                Ok(()) => ExitCode::SUCCESS,
                Err(e) => {
                    eprintln!("error: {e:#}");
                    ExitCode::from(1)
                }
            }
        }
    }
}
