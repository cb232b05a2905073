//! `glint`: deploys the characterization chain as separate processes over iceoryx2 shared
//! memory, supervises them, and writes a report. Also the entry point of every service
//! (`glint service <name>`), so one executable ships the whole chain. The binary is
//! `orchestrator/main.rs`, a call of [`main`]; this library also gives other tools and the
//! system tests the report's types ([`report::Report`]).
//!
//! Exit codes: 0 success, 1 the run failed (a service died, a message was lost, …),
//! 2 bad input (scenario file, arguments).

mod bench;
mod clean;
mod cli;
mod consume;
mod deploy;
mod faults;
mod invert;
#[cfg(feature = "lab")]
mod lab;
pub mod matrix;
mod membership;
mod observations;
mod plots;
mod png;
mod progress;
pub mod report;
mod run;
mod run_dir;
mod score_debris;
mod sequence;
mod service;
mod supervise;
mod taps;
mod tools;

use std::io::IsTerminal;
use std::path::PathBuf;
use std::process::ExitCode;

use clap::Parser;
use cli::*;
use shared_types::scenario::ScenarioError;
use shared_types::{Scenario, ServiceId};

/// The scenario `glint run` uses without an argument.
const DEFAULT_SCENARIO: &str = include_str!("../scenarios/default.toml");

fn load(path: Option<&PathBuf>) -> Result<(Scenario, String), ScenarioError> {
    match path {
        Some(p) => {
            let sc = Scenario::from_file(p)?;
            // The files a scenario names are read now, not by a service after deployment.
            if let Some(Err(e)) = (sc.earth.as_ref()).map(glint_earth::service_core::sigma_table) {
                return Err(ScenarioError::Invalid {
                    file: p.display().to_string(),
                    errors: vec![shared_types::scenario::FieldError {
                        field: "earth.sigma_table".into(),
                        message: e.to_string(),
                    }],
                });
            }
            Ok((sc, p.display().to_string()))
        }
        None => Ok((
            Scenario::from_toml_str(DEFAULT_SCENARIO, "(built-in default)")?,
            "(built-in default)".to_string(),
        )),
    }
}

/// The scenario (or the default) with `seed` applied; exit code 2 with the error printed.
fn load_with_seed(
    path: Option<&PathBuf>,
    seed: Option<u64>,
) -> Result<(Scenario, String), ExitCode> {
    let (mut sc, file) = load(path).map_err(|e| {
        eprintln!("error: {e}");
        ExitCode::from(2)
    })?;
    if let Some(seed) = seed {
        sc.seed = seed;
    }
    Ok((sc, file))
}

/// Appends the `--fault` arguments to the scenario's faults and validates them with it; an
/// error names the argument.
fn add_faults(sc: &mut Scenario, args: &[String]) -> Result<(), String> {
    let from_file = sc.fault.len();
    for a in args {
        let spec = shared_types::scenario::FaultSpec::parse(a)
            .map_err(|e| format!("--fault `{a}`: {e}"))?;
        // Asked for on the command line: the in-band kinds are wanted, so obeyed.
        sc.faults.enabled |= spec.kind.in_band();
        sc.fault.push(spec);
    }
    sc.validate().map_err(|errors| {
        errors
            .iter()
            .map(|e| {
                // `fault[i].x` of an argument reads as the argument's own field.
                let arg = e
                    .field
                    .strip_prefix("fault[")
                    .and_then(|r| r.split_once("]."))
                    .and_then(|(i, f)| Some((i.parse::<usize>().ok()?, f)))
                    .filter(|(i, _)| *i >= from_file);
                match arg {
                    Some((i, f)) => {
                        format!("--fault `{}`: {f}: {}", args[i - from_file], e.message)
                    }
                    None => e.to_string(),
                }
            })
            .collect::<Vec<_>>()
            .join("; ")
    })
}

/// Prints where the summary is and maps the outcome to the exit code.
fn finish(result: anyhow::Result<(PathBuf, bool)>) -> ExitCode {
    match result {
        Ok((dir, ok)) => {
            println!("{}", dir.join("summary.md").display());
            if ok {
                ExitCode::SUCCESS
            } else {
                eprintln!("run failed: see {}", dir.join("summary.md").display());
                ExitCode::from(1)
            }
        }
        Err(e) => {
            eprintln!("error: {e:#}");
            // A bad --out is the user's to fix, like a bad scenario.
            if e.downcast_ref::<run_dir::OutDirError>().is_some() {
                ExitCode::from(2)
            } else {
                ExitCode::from(1)
            }
        }
    }
}

/// `glint` with the process's arguments.
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    match cli.command {
        Cmd::Clean { prefix } => {
            if let Some(p) = prefix
                .as_deref()
                .filter(|p| !glint_runtime::is_deployment_prefix(p))
            {
                eprintln!("error: --prefix {p:?}: a deployment prefix is glint_<hex digits>_ (report.json, run.prefix)");
                return ExitCode::from(2);
            }
            for line in clean::clean(prefix.as_deref()) {
                println!("{line}");
            }
            ExitCode::SUCCESS
        }
        Cmd::Report { schema } => {
            if !schema {
                eprintln!("error: `glint report` needs --schema");
                return ExitCode::from(2);
            }
            let text = serde_json::to_string_pretty(&report::Report::schema()).unwrap_or_default();
            println!("{text}");
            ExitCode::SUCCESS
        }
        Cmd::Validate { scenario } => match load(Some(&scenario)) {
            Ok((s, _)) => {
                let yes = |b: bool| if b { "yes" } else { "no" };
                println!(
                    "{}: ok ({}: camera {}, spectra {}, earth {})",
                    scenario.display(),
                    s.name,
                    yes(s.camera.is_some()),
                    yes(s.spectra.is_some()),
                    yes(s.earth.is_some())
                );
                ExitCode::SUCCESS
            }
            Err(e) => {
                eprintln!("error: {e}");
                ExitCode::from(2)
            }
        },
        Cmd::Run {
            scenario,
            out,
            force,
            seed,
            faults,
        } => {
            glint_runtime::init_tracing("orchestrator");
            let (mut sc, file) = match load_with_seed(scenario.as_ref(), seed) {
                Ok(x) => x,
                Err(code) => return code,
            };
            if let Err(e) = add_faults(&mut sc, &faults) {
                eprintln!("error: {e}");
                return ExitCode::from(2);
            }
            if sc.campaign.is_some() {
                eprintln!(
                    "error: {file}: a [campaign] scenario runs with `glint lab campaign {file}`"
                );
                return ExitCode::from(2);
            }
            let opts = run::RunOptions {
                scenario: sc,
                scenario_file: file,
                out_dir: out,
                replace: force,
                progress: std::io::stderr().is_terminal(),
            };
            if opts.scenario.matrix.is_some() {
                return finish(matrix::run_matrix(opts));
            }
            let result = run::run(opts);
            if let Ok((dir, _)) = &result {
                let report = report::Report::read(&dir.join("report.json")).ok();
                if let Some(text) = report.as_ref().and_then(report::earth::console) {
                    eprint!("{text}");
                }
            }
            finish(result)
        }
        #[cfg(feature = "lab")]
        Cmd::Lab {
            lab:
                LabCmd::Campaign {
                    scenario,
                    out,
                    seed,
                    rescore,
                },
        } => {
            glint_runtime::init_tracing("orchestrator");
            let (sc, file) = match load_with_seed(Some(&scenario), seed) {
                Ok(x) => x,
                Err(code) => return code,
            };
            let Some(campaign) = &sc.campaign else {
                eprintln!("error: {file}: no [campaign] section (run it with `glint run {file}`)");
                return ExitCode::from(2);
            };
            if rescore && campaign.seeds <= 1 {
                eprintln!("error: {file}: --rescore needs a [campaign] with seeds > 1");
                return ExitCode::from(2);
            }
            let progress = std::io::stderr().is_terminal();
            finish(lab::run(&sc, &file, out, progress, rescore))
        }
        Cmd::Invert {
            observations,
            out,
            no_joint,
            config,
            band_sweep,
            verbose,
        } => match invert::invert(
            &observations,
            &invert::InvertOptions {
                joint: !no_joint,
                config: config.as_deref(),
                band_sweep,
                verbose,
            },
        ) {
            Ok((json, text)) => {
                print!("{text}");
                if let Some(dir) = out {
                    let written = std::fs::create_dir_all(&dir).and_then(|_| {
                        std::fs::write(
                            dir.join("inversion.json"),
                            serde_json::to_string_pretty(&json).unwrap_or_default() + "\n",
                        )
                    });
                    if let Err(e) = written {
                        eprintln!("error: {}: {e}", dir.display());
                        return ExitCode::from(1);
                    }
                }
                ExitCode::SUCCESS
            }
            Err(e) => {
                eprintln!("error: {e:#}");
                ExitCode::from(2)
            }
        },
        Cmd::Bench {
            bench:
                BenchCmd::Pipeline {
                    out,
                    frames,
                    size,
                    targets,
                    clock,
                    laser,
                },
        } => {
            glint_runtime::init_tracing("orchestrator");
            let opts = bench::pipeline::PipelineOptions {
                out: out.unwrap_or_else(|| {
                    PathBuf::from("runs").join(format!("bench-pipeline-{}", run::utc_stamp()))
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
            let sc = match bench::pipeline::scenario(&opts) {
                Ok(sc) => sc,
                Err(e) => {
                    eprintln!("error: the bench's scenario: {e}");
                    return ExitCode::from(2);
                }
            };
            match bench::run_pipeline(&opts, sc) {
                Ok(()) => ExitCode::SUCCESS,
                Err(e) => {
                    eprintln!("error: {e:#}");
                    ExitCode::from(1)
                }
            }
        }
        Cmd::Bench {
            bench:
                BenchCmd::Scaling {
                    out,
                    frames,
                    sizes,
                    targets,
                    laser,
                },
        } => {
            glint_runtime::init_tracing("orchestrator");
            let sides = [256, 512, 1024, 2048, 4096];
            let opts = bench::scaling::ScalingOptions {
                out: out.unwrap_or_else(|| {
                    PathBuf::from("runs").join(format!("bench-scaling-{}", run::utc_stamp()))
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
            match bench::scaling::run(&opts) {
                Ok(()) => ExitCode::SUCCESS,
                Err(e) => {
                    eprintln!("error: {e:#}");
                    ExitCode::from(1)
                }
            }
        }
        Cmd::Bench {
            bench:
                BenchCmd::Ipc {
                    out,
                    transports,
                    sizes,
                    scale,
                },
        } => {
            if !(scale.is_finite() && (0.001..=100.0).contains(&scale)) {
                eprintln!("error: --scale {scale} is out of range: allowed 0.001 to 100");
                return ExitCode::from(2);
            }
            glint_runtime::lifeline::handle_hangup();
            let opts = bench::IpcOptions {
                out: out.unwrap_or_else(|| {
                    PathBuf::from("runs").join(format!("bench-ipc-{}", run::utc_stamp()))
                }),
                transports: match transports.is_empty() {
                    true => bench::ipc::Transport::ALL.to_vec(),
                    false => transports,
                },
                sizes: match sizes.is_empty() {
                    true => bench::ipc::SIZES.to_vec(),
                    false => sizes.into_iter().map(|s| s as usize).collect(),
                },
                scale,
            };
            match bench::run_ipc(&opts) {
                Ok(()) => ExitCode::SUCCESS,
                Err(e) => {
                    eprintln!("error: {e:#}");
                    ExitCode::from(1)
                }
            }
        }
        Cmd::BenchPeer {
            transport,
            count,
            address,
        } => {
            glint_runtime::lifeline::watch_parent();
            let args = bench::ipc::PeerArgs {
                transport,
                count,
                address,
            };
            match bench::ipc::peer(args) {
                Ok(()) => ExitCode::SUCCESS,
                Err(e) => {
                    eprintln!("error: bench receiver: {e:#}");
                    ExitCode::from(1)
                }
            }
        }
        Cmd::Tool { tool } => {
            let result = match tool {
                ToolCmd::Detect { frame, threshold } => {
                    tools::detect(&frame, threshold).map(|json| println!("{json}"))
                }
                ToolCmd::Earth {
                    frame,
                    f_px,
                    center,
                    altitude_km,
                    sigma_table,
                } => {
                    let tool = tools::EarthTool {
                        f_px,
                        center_px: center,
                        altitude_km,
                    };
                    tools::earth(&frame, &tool, sigma_table.as_deref()).map(|j| println!("{j}"))
                }
                ToolCmd::EarthCalibrate {
                    frames,
                    scenario,
                    images,
                    f_px,
                    center,
                    altitude_km,
                    out,
                } => match (scenario, f_px, center) {
                    (Some(file), _, _) => match Scenario::from_file(&file) {
                        Ok(sc) => tools::earth_calibrate_scenario(&sc, images, &out)
                            .map(|j| println!("{j}")),
                        Err(e) => Err(anyhow::anyhow!("{e}")),
                    },
                    (None, Some(f_px), Some(center)) => {
                        let tool = tools::EarthTool {
                            f_px,
                            center_px: center,
                            altitude_km,
                        };
                        tools::earth_calibrate(&frames, &tool, &out).map(|j| println!("{j}"))
                    }
                    _ => Err(anyhow::anyhow!(
                        "give calibration frames with --f-px and --center, or --scenario"
                    )),
                },
                ToolCmd::Tfit { samples } => tools::tfit(&samples).map(|json| println!("{json}")),
                ToolCmd::Render {
                    scenario,
                    frame,
                    out,
                    seed,
                    earth,
                } => match Scenario::from_file(&scenario) {
                    Ok(mut sc) => {
                        if let Some(s) = seed {
                            sc.seed = s;
                        }
                        tools::render(&sc, frame, &out, earth)
                    }
                    Err(e) => Err(anyhow::anyhow!("{e}")),
                },
            };
            match result {
                Ok(()) => ExitCode::SUCCESS,
                Err(e) => {
                    eprintln!("error: {e:#}");
                    ExitCode::from(2)
                }
            }
        }
        Cmd::Service {
            name,
            prefix,
            scenario,
            restarted,
        } => {
            glint_runtime::init_tracing(&name);
            // A service ends with the process that started it (see glint_runtime::lifeline).
            glint_runtime::lifeline::watch_parent();
            let sc = match Scenario::from_file(&scenario) {
                Ok(s) => s,
                Err(e) => {
                    eprintln!("error: {e}");
                    return ExitCode::from(2);
                }
            };
            let args = glint_runtime::ServiceArgs {
                prefix: &prefix,
                scenario: &sc,
                restarted,
            };
            let Some(id) = ServiceId::from_name(&name) else {
                eprintln!(
                    "error: unknown service '{name}' (available: {})",
                    ServiceId::names()
                );
                return ExitCode::from(2);
            };
            let result = service::run(id, args);
            match result {
                Ok(()) => ExitCode::SUCCESS,
                Err(e) => {
                    tracing::error!("{e:#}");
                    eprintln!("error: {e:#}");
                    ExitCode::from(1)
                }
            }
        }
    }
}
