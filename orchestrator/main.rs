//! `glint`: deploys the characterization chain as separate processes over iceoryx2 shared
//! memory, supervises them, and writes a report. Also the entry point of every service
//! (`glint service <name>`), so one executable ships the whole chain.
//!
//! Exit codes: 0 success, 1 the run failed (a service died, a message was lost, …),
//! 2 bad input (scenario file, arguments).

mod bench;
mod clean;
mod consume;
mod deploy;
mod faults;
mod invert;
#[cfg(feature = "lab")]
mod lab;
mod matrix;
mod membership;
mod observations;
mod plots;
mod png;
mod progress;
mod report;
mod run;
mod run_dir;
mod score_debris;
mod sequence;
mod supervise;
mod tools;

use std::io::IsTerminal;
use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use shared_types::scenario::ScenarioError;
use shared_types::{Scenario, ServiceId};

/// The scenario `glint run` uses without an argument.
const DEFAULT_SCENARIO: &str = include_str!("../scenarios/default.toml");

#[derive(Parser)]
#[command(
    name = "glint",
    version,
    about = "On-board space-object characterization chain over iceoryx2 shared memory"
)]
struct Cli {
    #[command(subcommand)]
    command: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Deploy the chain for a scenario, run it to the end, write the report.
    Run {
        /// Scenario file (TOML); the built-in default when absent.
        scenario: Option<PathBuf>,
        /// Run directory (default: runs/<name>-<UTC timestamp>-<run id>); refused when it
        /// already holds files, unless --force.
        #[arg(long)]
        out: Option<PathBuf>,
        /// Replace the previous run in --out (a glint run directory not in use).
        #[arg(long)]
        force: bool,
        /// Override the scenario's seed.
        #[arg(long)]
        seed: Option<u64>,
        /// Inject a fault, as `SERVICE:KIND@AT[,duration_s=S]`: `detector:kill@20` (once the
        /// detector's input has carried message 20), `tracker:stop@1.5s,duration_s=0.3`
        /// (1.5 s after the start, for 0.3 s). Repeatable; added to the scenario's [[fault]].
        #[arg(long = "fault", value_name = "SERVICE:KIND@AT")]
        faults: Vec<String>,
    },
    /// Remove what crashed deployments left in shared memory (/dev/shm and iceoryx2's node
    /// directory); a deployment still running is left alone.
    Clean {
        /// Only this deployment prefix (`glint_<hex>_`, in report.json under run.prefix).
        #[arg(long)]
        prefix: Option<String>,
    },
    /// Check a scenario file; report every problem with its field and allowed range.
    Validate { scenario: PathBuf },
    /// The three-stage attitude solve on an observation file (format: docs/observations.md).
    Invert {
        observations: PathBuf,
        /// Also print how the three stages got there.
        #[arg(long, short)]
        verbose: bool,
        /// Write `inversion.json` here (default: print only).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Skip the joint multi-band fit.
        #[arg(long)]
        no_joint: bool,
        /// Solver settings (TOML, the fields of `InversionConfig`: `[stage3.start]`,
        /// `[stage3.lm]`, `[stage3.observability]`, `[model]`, …); unset fields keep defaults.
        #[arg(long)]
        config: Option<PathBuf>,
        /// Also fit stage 3 at every band and rank the chosen band against them.
        #[arg(long)]
        band_sweep: bool,
    },
    /// Estimator analysis beside the product: campaigns over a parameter and Monte-Carlo
    /// scoring against the Cramér–Rao bound.
    #[cfg(feature = "lab")]
    Lab {
        #[command(subcommand)]
        lab: LabCmd,
    },
    /// Throughput testing, every figure against a baseline measured in the same run.
    Bench {
        #[command(subcommand)]
        bench: BenchCmd,
    },
    /// The receiving process of `glint bench ipc` (started by it).
    #[command(hide = true)]
    BenchPeer {
        #[arg(long, value_enum)]
        transport: bench::ipc::Transport,
        #[arg(long)]
        count: u64,
        #[arg(long)]
        address: String,
    },
    /// Offline tools: algorithm stages on files, no IPC.
    Tool {
        #[command(subcommand)]
        tool: ToolCmd,
    },
    /// Run one service in this process (the orchestrator spawns these).
    Service {
        /// sensor | detector | tracker | inversion
        name: String,
        /// Shared-memory prefix of the deployment.
        #[arg(long)]
        prefix: String,
        /// The resolved scenario file of the run.
        #[arg(long)]
        scenario: PathBuf,
        /// Started again by supervision after a failure: recover from the producers' replay.
        #[arg(long)]
        restarted: bool,
    },
}

#[cfg(feature = "lab")]
#[derive(Subcommand)]
enum LabCmd {
    /// Run a campaign scenario (a `[campaign]` section): one deployment per value (and per
    /// seed), the table beside the paper, the Monte-Carlo scoring.
    Campaign {
        scenario: PathBuf,
        /// Campaign directory (default: runs/<name>-<UTC timestamp>).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Override the scenario's seed.
        #[arg(long)]
        seed: Option<u64>,
        /// Re-score a Monte-Carlo campaign already in `--out` from its deployments' reports,
        /// without deploying again (after a change to the scoring).
        #[arg(long, requires = "out")]
        rescore: bool,
    },
}

#[derive(Subcommand)]
enum BenchCmd {
    /// One-way latency and message rate between two processes over iceoryx2 (woken by an
    /// event, and spinning), a Unix socket and TCP, for payloads of 8 B to 4 MiB.
    Ipc {
        /// Where bench.json, ipc.csv and the plots go (default: runs/bench-ipc-<UTC timestamp>).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Only these transports (repeatable; default: all).
        #[arg(long = "transport", value_enum)]
        transports: Vec<bench::ipc::Transport>,
        /// Only these payload sizes in bytes (repeatable; default: 8, 4 KiB, 64 KiB, 1, 2, 4 MiB).
        #[arg(long = "size", value_parser = clap::value_parser!(u64).range(1..=(64 << 20)))]
        sizes: Vec<u64>,
        /// Round trips measured, as a multiple of the default (5000 up to 64 KiB, 1500 up to
        /// 1 MiB, 800 above).
        #[arg(long, default_value_t = 1.0)]
        scale: f64,
    },
    /// The [002] chain (sensor → detector → tracker, laser loop) deployed as processes, against
    /// the same work done in one process: frames/s, CPU per process, latency per stage.
    Pipeline {
        /// Where bench.json, pipeline.csv and the deployment's run directory go (default:
        /// runs/bench-pipeline-<UTC timestamp>).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Frames to produce.
        #[arg(long, default_value_t = 2000, value_parser = clap::value_parser!(u64).range(1..=10_000_000))]
        frames: u64,
        /// Frame size, WIDTHxHEIGHT in pixels (each 16 to 4096).
        #[arg(long, default_value = "1024x1024", value_parser = parse_size)]
        size: (u32, u32),
        /// Debris in the scene (1 to 16): [002]'s Table 4, repeated along-track beyond four.
        #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u64).range(1..=16))]
        targets: u64,
        /// Sim: lockstep, nothing dropped; realtime: frames paced at the scenario's rate.
        #[arg(long, value_enum, default_value = "sim")]
        clock: BenchClock,
        /// Fire the laser at confirmed tracks.
        #[arg(long, value_enum, default_value = "on")]
        laser: OnOff,
    },
    /// The pipeline bench swept over frame size (at 4 debris) and number of debris (at
    /// 1024²): frames/s and each core's time per frame, and the exponent of their growth.
    Scaling {
        /// Where bench.json, scaling.csv, the plots and the deployments go (default:
        /// runs/bench-scaling-<UTC timestamp>).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Frames of a 1024² point; other sizes get frames ∝ 1/pixels (20 to 4× this).
        #[arg(long, default_value_t = 500, value_parser = clap::value_parser!(u64).range(1..=1_000_000))]
        frames: u64,
        /// Frame sizes of the size sweep, WIDTHxHEIGHT (repeatable; default: 256² to 4096²).
        #[arg(long = "size", value_parser = parse_size)]
        sizes: Vec<(u32, u32)>,
        /// Debris counts of the targets sweep (repeatable, 1 to 16; default: 1, 2, 4, 8, 16).
        #[arg(long = "targets", value_parser = clap::value_parser!(u64).range(1..=16))]
        targets: Vec<u64>,
        /// Fire the laser at confirmed tracks.
        #[arg(long, value_enum, default_value = "on")]
        laser: OnOff,
    },
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum BenchClock {
    Sim,
    Realtime,
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum OnOff {
    On,
    Off,
}

/// `WIDTHxHEIGHT`, each side 16–4096 px.
fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("`{s}`: expected WIDTHxHEIGHT, e.g. 1024x1024"))?;
    let side = |v: &str| -> Result<u32, String> {
        let n: u32 = v
            .trim()
            .parse()
            .map_err(|_| format!("`{v}` is not a whole number"))?;
        if (16..=4096).contains(&n) {
            Ok(n)
        } else {
            Err(format!("{n} px is out of range: allowed 16 to 4096"))
        }
    };
    Ok((side(w)?, side(h)?))
}

/// A number within [lo, hi], `unit` after it in the error ("" for none).
fn parse_within(s: &str, lo: f64, hi: f64, unit: &str) -> Result<f64, String> {
    let v: f64 = s
        .trim()
        .parse()
        .map_err(|_| format!("`{s}` is not a number"))?;
    if v.is_finite() && (lo..=hi).contains(&v) {
        Ok(v)
    } else {
        Err(format!("{v}{unit} is out of range: allowed {lo} to {hi}"))
    }
}

/// A focal length in px/rad, 1 to 100000.
fn parse_positive(s: &str) -> Result<f64, String> {
    parse_within(s, 1.0, 1e5, "")
}

/// An altitude in km, 100 to 100000.
fn parse_altitude(s: &str) -> Result<f64, String> {
    parse_within(s, 100.0, 1e5, " km")
}

/// `X,Y` in pixels, each finite and within ±1e6.
fn parse_point(s: &str) -> Result<(f64, f64), String> {
    let (x, y) = s
        .split_once(',')
        .ok_or_else(|| format!("`{s}`: expected X,Y, e.g. 255.5,255.5"))?;
    let one = |v: &str| -> Result<f64, String> {
        let n: f64 = v
            .trim()
            .parse()
            .map_err(|_| format!("`{v}` is not a number"))?;
        if n.is_finite() && n.abs() <= 1e6 {
            Ok(n)
        } else {
            Err(format!("{n} is out of range: allowed −1000000 to 1000000"))
        }
    };
    Ok((one(x)?, one(y)?))
}

#[derive(Subcommand)]
enum ToolCmd {
    /// Detect objects in a 16-bit binary PGM (P5); prints JSON.
    Detect {
        frame: PathBuf,
        /// Absolute threshold [DN] instead of background + 5σ.
        #[arg(long)]
        threshold: Option<u16>,
    },
    /// The t location-scale maximum-likelihood fit of a sample file (one number per line, `#`
    /// comments); prints JSON {n, mu, sigma, nu, nll, iterations}.
    Tfit { samples: PathBuf },
    /// The [003] attitude angle β of one fisheye Earth image (16- or 8-bit PGM) by the
    /// cross-product method, its lookup version and the Hough baseline; prints JSON.
    Earth {
        frame: PathBuf,
        /// Fisheye focal length [px/rad] (r = f θ), 1 to 100000.
        #[arg(long = "f-px", value_parser = parse_positive)]
        f_px: f64,
        /// Principal point X,Y [px], 0-based, the first pixel's centre at (0, 0).
        #[arg(long, value_parser = parse_point)]
        center: (f64, f64),
        /// Orbit altitude [km], 100 to 100000 (the limb's angular radius).
        #[arg(long = "altitude-km", default_value_t = 950.0, value_parser = parse_altitude)]
        altitude_km: f64,
        /// The lookup version's σ(μ) table (`glint tool earth-calibrate`); without it, the
        /// frame's own fitted σ.
        #[arg(long = "sigma-table")]
        sigma_table: Option<PathBuf>,
    },
    /// The [003] lookup version's σ(μ) table from calibration frames (fisheye Earth images at
    /// known angles, 16- or 8-bit PGM), or from a scenario's own `[earth]` sensor at 0°–60°:
    /// one t fit per frame; writes CSV `mu_deg,sigma_deg`.
    EarthCalibrate {
        /// Calibration frames.
        #[arg(required_unless_present = "scenario")]
        frames: Vec<PathBuf>,
        /// Calibrate a scenario's `[earth]` sensor on frames it renders (instead of files).
        #[arg(long, conflicts_with_all = ["frames", "f_px", "center"])]
        scenario: Option<PathBuf>,
        /// Frames per angle with `--scenario`.
        #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u32).range(1..=100))]
        images: u32,
        #[arg(long = "f-px", value_parser = parse_positive, required_unless_present = "scenario")]
        f_px: Option<f64>,
        #[arg(long, value_parser = parse_point, required_unless_present = "scenario")]
        center: Option<(f64, f64)>,
        #[arg(long = "altitude-km", default_value_t = 950.0, value_parser = parse_altitude)]
        altitude_km: f64,
        /// The table file to write.
        #[arg(long)]
        out: PathBuf,
    },
    /// Render one camera frame of a scenario into a 16-bit PGM.
    Render {
        scenario: PathBuf,
        #[arg(long, default_value_t = 0)]
        frame: u64,
        #[arg(long)]
        out: PathBuf,
        #[arg(long)]
        seed: Option<u64>,
        /// Render the `[earth]` sensor's frame instead of the camera's.
        #[arg(long)]
        earth: bool,
    },
}

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

fn main() -> ExitCode {
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
            finish(run::run(opts))
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
            use glint_runtime::run_service;
            let result = match ServiceId::from_name(&name) {
                Some(ServiceId::Sensor) => run_service::<glint_sensor::node::SensorNode>(args),
                Some(ServiceId::Detector) => {
                    run_service::<glint_detector::node::DetectorNode>(args)
                }
                Some(ServiceId::Tracker) => run_service::<glint_tracker::node::TrackerNode>(args),
                Some(ServiceId::Inversion) => {
                    run_service::<glint_inversion::node::InversionNode>(args)
                }
                Some(ServiceId::Earth) => run_service::<glint_earth::node::EarthNode>(args),
                _ => {
                    eprintln!(
                        "error: unknown service '{name}' (available: sensor, detector, tracker, inversion, earth)"
                    );
                    return ExitCode::from(2);
                }
            };
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
