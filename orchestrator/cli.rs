//! The `glint` command line: every command, its arguments and their parsers (clap derive).
//! `lib.rs` dispatches them, one function per command.

use std::path::PathBuf;

use clap::{Parser, Subcommand};

use crate::bench;

#[derive(Parser)]
#[command(
    name = "glint",
    version,
    about = "On-board space-object characterization chain over iceoryx2 shared memory"
)]
pub(crate) struct Cli {
    #[command(subcommand)]
    pub command: Cmd,
}

#[derive(Subcommand)]
pub(crate) enum Cmd {
    /// Deploy the chain for a scenario, run it to the end, write the report.
    Run(RunArgs),
    /// Publish a recording's sensor streams into a fresh deployment of its consumers and hold
    /// their results against the recording's (docs/recording.md); `--inspect`: what it holds.
    Replay(ReplayArgs),
    /// A live view of a running deployment: per service its state, pid, restarts, rates,
    /// latency, drops, CPU and memory, from its heartbeats and /proc.
    Top {
        /// The deployment's prefix (`glint_<hex>_`); default: the one running.
        prefix: Option<String>,
        /// Print one snapshot (after watching 1.5 s) and exit.
        #[arg(long)]
        once: bool,
        /// With --once: the snapshot as JSON.
        #[arg(long, requires = "once")]
        json: bool,
    },
    /// Remove what crashed deployments left in shared memory (/dev/shm and iceoryx2's node
    /// directory); a deployment still running is left alone.
    Clean {
        /// Only this deployment prefix (`glint_<hex>_`, in report.json under run.prefix).
        #[arg(long)]
        prefix: Option<String>,
        /// List what ended deployments left (one path a line), removing nothing.
        #[arg(long, conflicts_with = "prefix")]
        list: bool,
    },
    /// Check a scenario file; report every problem with its field and allowed range.
    Validate { scenario: PathBuf },
    /// About `report.json`: `--schema` prints its JSON Schema (docs/report.schema.json).
    Report {
        /// Print the JSON Schema of report.json.
        #[arg(long)]
        schema: bool,
    },
    /// The three-stage attitude solve on an observation file (format: docs/observations.md).
    Invert(InvertArgs),
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
    BenchPeer(PeerArgs),
    /// Offline tools: algorithm stages on files, no IPC.
    Tool {
        #[command(subcommand)]
        tool: ToolCmd,
    },
    /// Run one service in this process (the orchestrator spawns these).
    Service(ServiceArgs),
}

#[cfg(feature = "lab")]
#[derive(Subcommand)]
pub(crate) enum LabCmd {
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
    /// [001] how often the identification names the right geometry: light curves of every
    /// shape in SHAPES.toml about random axes, with noise, identified; a confusion table.
    Identify {
        #[arg(long)]
        shapes: PathBuf,
        /// Random spin axes per shape.
        #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u16).range(1..=1000))]
        axes: u16,
        /// Magnitude noise σ [mag].
        #[arg(long, default_value_t = 0.05)]
        noise: f64,
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Where identify.json and confusion.md go (default: runs/identify-<UTC timestamp>).
        #[arg(long)]
        out: Option<PathBuf>,
    },
}

#[derive(Subcommand)]
pub(crate) enum BenchCmd {
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
        /// Also deploy the same chain with `--record` (every frame to run.mcap) and give its
        /// frames/s against the unrecorded deployment's of the same bench.
        #[arg(long)]
        record: bool,
        /// The chain of a recording (`glint run --record`'s run.mcap: its camera, detector
        /// and tracker), deployed rendered and then fed the recorded frames (memory-mapped, no
        /// rendering): the chain's own frames/s against the rendered deployment's.
        #[arg(long, conflicts_with_all = ["frames", "size", "targets"])]
        source: Option<PathBuf>,
        /// Pin a service to a CPU, SERVICE=CPU (repeatable; `[services.<name>] cpu` of a
        /// scenario): e.g. `--cpu sensor=0 --cpu detector=1`.
        #[arg(long, value_parser = parse_placement)]
        cpu: Vec<(String, u32)>,
        /// Also deploy the chain split across two hosts on this machine (sensor | detector +
        /// tracker, a bridge each side over loopback; needs `--laser off` and the `hosts`
        /// feature): its frames/s, latencies and bytes on the wire beside the local
        /// deployment's, and one TCP stream's frames/s, the link's limit.
        #[arg(long, conflicts_with = "source")]
        split: bool,
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
pub(crate) enum BenchClock {
    Sim,
    Realtime,
}

#[derive(Clone, Copy, clap::ValueEnum)]
pub(crate) enum OnOff {
    On,
    Off,
}

/// `WIDTHxHEIGHT`, each side 16–4096 px.
pub(crate) fn parse_placement(s: &str) -> Result<(String, u32), String> {
    let (name, cpu) =
        (s.split_once('=')).ok_or_else(|| format!("`{s}`: give SERVICE=CPU, e.g. detector=1"))?;
    let cpu =
        (cpu.parse::<u32>()).map_err(|_| format!("`{s}`: the CPU `{cpu}` is not a number"))?;
    Ok((name.to_string(), cpu))
}

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
pub(crate) fn parse_within(s: &str, lo: f64, hi: f64, unit: &str) -> Result<f64, String> {
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
pub(crate) fn parse_positive(s: &str) -> Result<f64, String> {
    parse_within(s, 1.0, 1e5, "")
}

/// A lens's field half-angle in degrees, 10 to 180.
pub(crate) fn parse_field(s: &str) -> Result<f64, String> {
    parse_within(s, 10.0, 180.0, "°")
}

/// An altitude in km, 100 to 100000.
pub(crate) fn parse_altitude(s: &str) -> Result<f64, String> {
    parse_within(s, 100.0, 1e5, " km")
}

/// `X,Y` in pixels, each finite and within ±1e6.
pub(crate) fn parse_point(s: &str) -> Result<(f64, f64), String> {
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
pub(crate) enum ToolCmd {
    /// Every message topic's payload type and every wire type's layout, as JSON (what a
    /// client decodes glint's messages with: docs/recording.md).
    Layouts,
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
        /// Fisheye focal length [px/rad] (r = f θ, the ideal lens), 1 to 100000.
        #[arg(long = "f-px", value_parser = parse_positive, required_unless_present = "lens")]
        f_px: Option<f64>,
        /// Principal point X,Y [px], 0-based, the first pixel's centre at (0, 0).
        #[arg(long, value_parser = parse_point, required_unless_present = "lens")]
        center: Option<(f64, f64)>,
        /// The lens's calibration instead of --f-px and --center: LENS.toml with OpenCV's
        /// fisheye fx, fy, cx, cy and D = [k1, k2, k3, k4] (Kannala–Brandt), optionally
        /// field_deg and image_circle_px (docs/earth-sensor.md).
        #[arg(long, conflicts_with_all = ["f_px", "center"])]
        lens: Option<PathBuf>,
        /// Orbit altitude [km], 100 to 100000 (the limb's angular radius).
        #[arg(long = "altitude-km", default_value_t = 950.0, value_parser = parse_altitude)]
        altitude_km: f64,
        /// The lens's field: the largest angle from the optical axis it images [deg], 10 to
        /// 180 (90: a 180° fisheye). Edges at the field's boundary are never limb points.
        #[arg(long = "field-deg", default_value_t = 90.0, value_parser = parse_field)]
        field_deg: f64,
        /// The image circle's radius [px] when the lens vignettes inside its field.
        #[arg(long = "image-circle-px", value_parser = parse_positive)]
        image_circle_px: Option<f64>,
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
        #[arg(long = "f-px", value_parser = parse_positive, required_unless_present_any = ["scenario", "lens"])]
        f_px: Option<f64>,
        #[arg(long, value_parser = parse_point, required_unless_present_any = ["scenario", "lens"])]
        center: Option<(f64, f64)>,
        /// The lens's calibration (LENS.toml, as for `glint tool earth`).
        #[arg(long, conflicts_with_all = ["f_px", "center", "scenario"])]
        lens: Option<PathBuf>,
        #[arg(long = "altitude-km", default_value_t = 950.0, value_parser = parse_altitude)]
        altitude_km: f64,
        #[arg(long = "field-deg", default_value_t = 90.0, value_parser = parse_field)]
        field_deg: f64,
        #[arg(long = "image-circle-px", value_parser = parse_positive)]
        image_circle_px: Option<f64>,
        /// The table file to write.
        #[arg(long)]
        out: PathBuf,
    },
    /// The [004] relative-navigation filter on a file of stereo measurements (`t_s, feature,
    /// x_l, y_l, x_r, y_r`) and its rig (RIG.toml); writes DIR/relnav.csv, prints a JSON
    /// summary. docs/relnav.md fixes both formats.
    Relnav {
        meas: PathBuf,
        #[arg(long)]
        rig: PathBuf,
        /// Directory for relnav.csv.
        #[arg(long, default_value = ".")]
        out: PathBuf,
    },
    /// The [001] chain on a light curve (`t_s, mag, sigma_mag, sun_x.., obs_x.., range_m`) and
    /// the user's shapes (SHAPES.toml naming OBJ files): geometry, spin and size by the database,
    /// then the attitude by the UKF; writes DIR/identification.json and DIR/attitude.csv,
    /// prints the identification. docs/photometry.md fixes the formats.
    Photometry {
        lc: PathBuf,
        #[arg(long)]
        shapes: PathBuf,
        /// Directory for identification.json and attitude.csv.
        #[arg(long, default_value = ".")]
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

#[derive(clap::Args)]
pub(crate) struct ReplayArgs {
    /// A recording (`glint run --record`'s DIR/run.mcap).
    pub recording: PathBuf,
    /// Print the topics, their counts and time spans, and the scenario; deploy nothing.
    #[arg(long)]
    pub inspect: bool,
    /// Consumers to deploy (repeatable; default: every one the scenario deploys).
    #[arg(long = "service")]
    pub services: Vec<String>,
    /// Publish at this multiple of the recorded simulated time (0.01 to 1000).
    #[arg(long, conflicts_with = "as_fast_as_possible")]
    pub speed: Option<f64>,
    /// Publish as fast as the consumers take it (the default).
    #[arg(long)]
    pub as_fast_as_possible: bool,
    /// The consumers' settings from this scenario instead of the recording's (its streams
    /// must be the recording's).
    #[arg(long)]
    pub scenario: Option<PathBuf>,
    /// Run directory (default: runs/<name>-<UTC timestamp>-<run id>).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Replace the previous run in --out.
    #[arg(long)]
    pub force: bool,
}

#[derive(clap::Args)]
pub(crate) struct RunArgs {
    /// Scenario file (TOML); the built-in default when absent.
    pub scenario: Option<PathBuf>,
    /// Run directory (default: runs/<name>-<UTC timestamp>-<run id>); refused when it
    /// already holds files, unless --force.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Replace the previous run in --out (a glint run directory not in use).
    #[arg(long)]
    pub force: bool,
    /// Record every data topic the orchestrator taps to DIR/run.mcap (docs/recording.md).
    #[arg(long)]
    pub record: bool,
    /// Override the scenario's seed.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Inject a fault, as `SERVICE:KIND@AT[,duration_s=S]`: `detector:kill@20` (once the
    /// detector's input has carried message 20), `tracker:stop@1.5s,duration_s=0.3`
    /// (1.5 s after the start, for 0.3 s). Repeatable; added to the scenario's [[fault]].
    #[arg(long = "fault", value_name = "SERVICE:KIND@AT")]
    pub faults: Vec<String>,
    /// Keep the chain running this long (`90s`, `10m`, `2h`; a number is seconds), a fault
    /// every 10 s (the scenario's `[soak]` sets the schedule), and report every fault's
    /// recovery and each process's memory over time.
    #[arg(long, value_name = "DURATION", value_parser = parse_duration_s)]
    pub soak: Option<f64>,
    /// In a deployment split across hosts (`[hosts]`): run this host's part. The host marked
    /// `orchestrator` (the default) runs the orchestrator of record and writes the report;
    /// every other host runs its services and its bridge until the orchestrator ends the run.
    #[arg(long)]
    pub host: Option<String>,
}

/// `90`, `90s`, `10m`, `1.5h` → seconds.
fn parse_duration_s(text: &str) -> Result<f64, String> {
    let t = text.trim();
    let (number, unit_s) = match t.char_indices().last() {
        Some((i, 's')) => (&t[..i], 1.0),
        Some((i, 'm')) => (&t[..i], 60.0),
        Some((i, 'h')) => (&t[..i], 3600.0),
        _ => (t, 1.0),
    };
    match number.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v * unit_s),
        _ => Err(format!(
            "`{text}`: expected a duration such as 90s, 10m or 2h"
        )),
    }
}

#[derive(clap::Args)]
pub(crate) struct InvertArgs {
    pub observations: PathBuf,
    /// Also print how the three stages got there.
    #[arg(long, short)]
    pub verbose: bool,
    /// Write `inversion.json` here (default: print only).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Skip the joint multi-band fit.
    #[arg(long)]
    pub no_joint: bool,
    /// Solver settings (TOML, the fields of `InversionConfig`: `[stage3.start]`,
    /// `[stage3.lm]`, `[stage3.observability]`, `[model]`, …); unset fields keep defaults.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Also fit stage 3 at every band and rank the chosen band against them.
    #[arg(long)]
    pub band_sweep: bool,
}

#[derive(clap::Args)]
pub(crate) struct PeerArgs {
    #[arg(long, value_enum)]
    pub transport: bench::ipc::Transport,
    #[arg(long)]
    pub count: u64,
    #[arg(long)]
    pub address: String,
}

#[derive(clap::Args)]
pub(crate) struct ServiceArgs {
    /// sensor | detector | tracker | inversion
    pub name: String,
    /// Shared-memory prefix of the deployment.
    #[arg(long)]
    pub prefix: String,
    /// The resolved scenario file of the run.
    #[arg(long)]
    pub scenario: PathBuf,
    /// Started again by supervision after a failure: recover from the producers' replay.
    #[arg(long)]
    pub restarted: bool,
    /// The host it runs on, in a deployment split across hosts (`[hosts]`).
    #[arg(long)]
    pub host: Option<String>,
}
