//! `glint run`: create the services, spawn the children, wait for readiness, start, supervise,
//! account for every message, stop with the ladder, remove the shared memory, write the report.

pub mod clean;
pub mod command;
pub mod consume;
pub mod deploy;
pub mod faults;
pub mod hosts;
pub mod keeper;
pub mod latency;
pub mod links;
pub mod live;
pub mod matrix;
pub mod membership;
pub mod memory;
pub mod record;
pub mod remote;
pub mod replay;
pub mod run_dir;
pub mod sequence;
pub mod supervise;
pub mod taps;

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use glint_runtime::{open_node, remove_shm, run_loop, shm_entries};
use shared_types::{Scenario, TopicId};

use crate::report::{self, RunFacts};
use crate::run::consume::Consumer;
use crate::run::live::{Live, Spawner};

/// Orchestrator tick: supervision and progress cadence.
const TICK: Duration = Duration::from_millis(20);

pub struct RunOptions {
    pub scenario: Scenario,
    pub scenario_file: String,
    pub out_dir: Option<PathBuf>,
    /// Replace a previous run in `out_dir` (`--force`; see [`crate::run::run_dir`]).
    pub replace: bool,
    pub progress: bool,
    /// `--record`: every tapped topic to `DIR/run.mcap` ([`record`]).
    pub record: bool,
    /// `--host`: this host's part of a deployment split across hosts (`None`: not split, or
    /// the orchestrator's host).
    pub host: Option<String>,
}

/// Runs a deployment to the end. Returns the run directory and whether the run succeeded.
/// Set once a deployment of this process was stopped by SIGINT/SIGTERM: campaigns stop there
/// instead of starting the next deployment.
static INTERRUPTED: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// An error if a deployment of this process was interrupted by a signal.
pub fn bail_if_interrupted(what: &str) -> Result<()> {
    if INTERRUPTED.load(std::sync::atomic::Ordering::SeqCst) {
        anyhow::bail!("{what} interrupted by a signal");
    }
    Ok(())
}

pub fn run(opts: RunOptions) -> Result<(PathBuf, bool)> {
    let scenario = &opts.scenario;
    // A host of a split deployment other than the orchestrator's runs its part only.
    if let Some(host) = (opts.host.as_deref()).filter(|h| Some(*h) != scenario.orchestrator_host())
    {
        return hosts::run_host(&opts, host);
    }
    let prefix = run_prefix();
    let id = prefix.trim_start_matches("glint_").trim_end_matches('_');
    // Held (locked) until the report is written: no other run can use this directory.
    let dir =
        crate::run::run_dir::prepare(opts.out_dir.as_deref(), &scenario.name, id, opts.replace)?;
    let out_dir = dir.path.clone();
    let resolved = out_dir.join("scenario.toml");
    std::fs::write(&resolved, scenario.to_toml())
        .with_context(|| format!("writing {}", resolved.display()))?;
    let exe = std::env::current_exe().context("locating the glint executable")?;

    let wall0 = Instant::now();
    let cpu0_s = crate::run::deploy::cpu_seconds("self");
    let result = deploy_and_run(scenario, &prefix, &exe, &resolved, &out_dir, &opts);
    // Everything iceoryx2 is dropped inside deploy_and_run; now nothing of the prefix may remain.
    let (removed, held_by) = remove_shm(&prefix);
    let leftover: Vec<String> = shm_entries(&prefix)
        .iter()
        .map(|p| p.display().to_string())
        .collect();
    let mut facts = result?;
    facts.shm_removed = removed;
    facts.shm_leftover = leftover;
    // Files still held by a live node outside the deployment (a Python client, `glint top`, a
    // recorder attached past the end) are that observer's: left in place and reported, never
    // the run's failure. `glint clean --prefix` removes them once it has gone.
    facts.shm_held_by = held_by;
    facts.wall_s = wall0.elapsed().as_secs_f64();
    // This process may have worked before the run (a bench's earlier points): count the run's.
    facts.orchestrator_cpu_s =
        (facts.orchestrator_cpu_s.zip(cpu0_s)).map(|(c, c0)| (c - c0).max(0.0));
    facts.prefix = prefix;
    facts.scenario_file = opts.scenario_file.clone();
    let recorder = facts.recorder.take();
    let mut report = report::write(&out_dir, scenario, &facts)?;
    if let Some(r) = recorder {
        let json = serde_json::to_string_pretty(&report)? + "\n";
        if let Some(failure) = r.close(&json, &report.faults) {
            // The report said the recording was whole: it says now why it is not.
            eprintln!("error: {failure}");
            if let Some(rec) = report.run.recording.as_mut() {
                rec.failure = Some(failure);
            }
            report.results.success = false;
            report::rewrite(&out_dir, &report)?;
        }
    }
    // A soak also holds its own verdict: every fault recovered, memory flat.
    let ok = report.results.success && report.soak.as_ref().is_none_or(|s| s.passed);
    drop(dir);
    Ok((out_dir, ok))
}

fn deploy_and_run(
    scenario: &Scenario,
    prefix: &str,
    exe: &Path,
    resolved: &Path,
    out_dir: &Path,
    opts: &RunOptions,
) -> Result<RunFacts> {
    let progress = opts.progress;
    // The table of services and topics holds to its rules (a replay source for every data
    // input of a restartable service, …) before anything is deployed from it.
    shared_types::table::check().map_err(|e| anyhow::anyhow!("the table of services: {e}"))?;
    let node = open_node(prefix, "orchestrator")?;
    let _services = shared_types::topics::create_all(&node, scenario)?;
    let snapshots = report::snapshots(scenario);
    let (mut consumer, listeners) =
        Consumer::open(&node, scenario, &snapshots, report::folds(scenario))?;
    if opts.record {
        let path = out_dir.join("run.mcap");
        consumer
            .taps
            .record_into(crate::run::record::Recorder::create(&path, scenario)?);
    }
    let sequencer = crate::run::sequence::Sequencer::open(&node, scenario)?;
    let mut inputs: Vec<_> = listeners.iter().map(|l| (l, None)).collect();
    // Solve answers wake the loop (the sequencer polls its call in flight).
    let solve_reply = match &sequencer {
        Some(_) => Some(
            shared_types::topics::event_service(&node, TopicId::Solve, true)?
                .listener_builder()
                .create()
                .map_err(|e| anyhow::anyhow!("solve reply listener: {e:?}"))?,
        ),
        None => None,
    };
    if let Some(l) = &solve_reply {
        inputs.push((l, None));
    }
    let spawner = Spawner {
        exe,
        prefix,
        scenario_file: resolved,
        log_dir: out_dir.join("logs"),
        host: opts.host.as_deref(),
    };
    let mut live = Live::spawn(scenario, &node, spawner, consumer, sequencer, progress)?;
    // A signal is seen by one wait loop of the process: a deployment run beside the one that
    // saw it (a campaign's) stops on the flag that one set.
    let mut interrupted = false;
    let exit = run_loop(&inputs, TICK, |wakes| {
        if INTERRUPTED.load(std::sync::atomic::Ordering::SeqCst) {
            interrupted = true;
            return Ok(glint_runtime::Step::Stop);
        }
        live.step(wakes)
    })?;
    let exit = if interrupted {
        glint_runtime::Exit::Terminated
    } else {
        exit
    };
    live.stop(exit)?;
    let facts = live.facts();
    drop(inputs);
    drop(listeners);
    drop(solve_reply);
    drop(node);
    Ok(facts)
}

/// A prefix unique to this deployment, short enough for iceoryx2's file names: 32 bits from
/// the OS's random source (mixed with the time and pid), so another deployment's — or a
/// guesser's — prefix does not collide with it.
pub(crate) fn run_prefix() -> String {
    use std::io::Read;
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos())
        .unwrap_or(0);
    let mut random = [0u8; 16];
    let _ = std::fs::File::open("/dev/urandom").and_then(|mut f| f.read_exact(&mut random));
    let h = xxhash_rust::xxh3::xxh3_64(
        &[
            nanos.to_le_bytes().as_slice(),
            &std::process::id().to_le_bytes(),
            &random,
        ]
        .concat(),
    );
    format!("glint_{:08x}_", h as u32)
}

/// `YYYYmmdd-HHMMSS` in UTC.
pub fn utc_stamp() -> String {
    jiff::Timestamp::now().strftime("%Y%m%d-%H%M%S").to_string()
}
