//! `glint run`: create the services, spawn the children, wait for readiness, start, supervise,
//! account for every message, stop with the ladder, remove the shared memory, write the report.

pub mod clean;
pub mod command;
pub mod consume;
pub mod deploy;
pub mod faults;
pub mod matrix;
pub mod membership;
pub mod run_dir;
pub mod sequence;
pub mod supervise;
pub mod taps;

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use glint_runtime::{open_node, remove_shm, run_loop, shm_entries, Step, Wake};
use shared_types::scenario::Clock;
use shared_types::{deployment, Command, Control, Heartbeat, Replay, Scenario, ServiceId, TopicId};

use crate::report::{self, Outcome, RunFacts};
use crate::run::consume::Consumer;
use crate::run::deploy::{stop_ladder, Ending, ServiceProcess};
use crate::run::faults::{Act, Injector};
use crate::run::membership::Membership;
use crate::run::supervise::{Action, Noticed, Observation, Supervisor};

/// Orchestrator tick: supervision and progress cadence.
const TICK: Duration = Duration::from_millis(20);
/// How often the live nodes under the prefix are checked against the deployment.
const MEMBERSHIP_SCAN: Duration = Duration::from_millis(250);

pub struct RunOptions {
    pub scenario: Scenario,
    pub scenario_file: String,
    pub out_dir: Option<PathBuf>,
    /// Replace a previous run in `out_dir` (`--force`; see [`crate::run::run_dir`]).
    pub replace: bool,
    pub progress: bool,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    Starting,
    Running,
    Done,
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
    let result = deploy_and_run(scenario, &prefix, &exe, &resolved, &out_dir, opts.progress);
    // Everything iceoryx2 is dropped inside deploy_and_run; now nothing of the prefix may remain.
    let (removed, held_by) = remove_shm(&prefix);
    let leftover: Vec<String> = shm_entries(&prefix)
        .iter()
        .map(|p| p.display().to_string())
        .collect();
    let mut facts = result?;
    facts.shm_removed = removed;
    facts.shm_leftover = leftover;
    if !held_by.is_empty() && facts.failure.is_none() {
        facts.failure = Some(format!(
            "the deployment's shared memory is still held by node(s) {} outside it; their files \
             under prefix {prefix} are left in place (`glint clean --prefix {prefix}` removes \
             them once those processes end)",
            held_by.join(", ")
        ));
    }
    facts.shm_held_by = held_by;
    facts.wall_s = wall0.elapsed().as_secs_f64();
    // This process may have worked before the run (a bench's earlier points): count the run's.
    facts.orchestrator_cpu_s =
        (facts.orchestrator_cpu_s.zip(cpu0_s)).map(|(c, c0)| (c - c0).max(0.0));
    facts.prefix = prefix;
    facts.scenario_file = opts.scenario_file.clone();
    let ok = report::write(&out_dir, scenario, &facts)?.results.success;
    drop(dir);
    Ok((out_dir, ok))
}

fn deploy_and_run(
    scenario: &Scenario,
    prefix: &str,
    exe: &Path,
    resolved: &Path,
    out_dir: &Path,
    progress: bool,
) -> Result<RunFacts> {
    let node = open_node(prefix, "orchestrator")?;
    let _services = shared_types::topics::create_all(&node, scenario)?;
    let snapshots = report::snapshots(scenario);
    let (mut consumer, listeners) = Consumer::open(&node, scenario, &snapshots)?;
    let mut sequencer = crate::run::sequence::Sequencer::open(&node, scenario)?;

    let log_dir = out_dir.join("logs");
    let mut children: Vec<ServiceProcess> = vec![];
    for id in deployment::services(scenario) {
        children.push(ServiceProcess::spawn(
            exe, id, prefix, resolved, &log_dir, 0,
        )?);
    }
    tracing::info!(prefix, services = children.len(), "deployed");

    let bar = progress.then(|| crate::progress::bar(consumer.progress().1));
    let limits = &scenario.run;
    let t_start = Instant::now();
    let mut t_running: Option<Instant> = None;
    let mut t_done: Option<Instant> = None;
    let mut phase = Phase::Starting;
    let mut failure: Option<String> = None;

    let mut inputs: Vec<_> = listeners.iter().map(|l| (l, None)).collect();
    // Solve answers wake the loop (the sequencer polls its call in flight).
    let solve_reply = match &sequencer {
        Some(_) => Some(
            shared_types::topics::event_service(&node, shared_types::TopicId::Solve, true)?
                .listener_builder()
                .create()
                .map_err(|e| anyhow::anyhow!("solve reply listener: {e:?}"))?,
        ),
        None => None,
    };
    if let Some(l) = &solve_reply {
        inputs.push((l, None));
    }
    let hb_deadline = Duration::from_millis(limits.heartbeat_deadline_ms);
    let mut injector = Injector::new(scenario);
    let ids: Vec<ServiceId> = children.iter().map(|c| c.id).collect();
    let mut supervisor = Supervisor::new(
        &scenario.supervision,
        &ids,
        hb_deadline,
        Duration::from_millis(limits.startup_timeout_ms),
    );
    let hb_period = Duration::from_millis(limits.heartbeat_period_ms);
    let mut acks_refreshed = Instant::now();
    let sim_clock = scenario.clock == Clock::Sim;
    let mut membership = Membership::default();
    let mut scanned = Instant::now();
    let since_start = |t: Instant, t0: Option<Instant>| {
        t0.map_or(0.0, |t0| t.saturating_duration_since(t0).as_secs_f64())
    };
    let exit = run_loop(&inputs, TICK, |wakes| {
        consumer.poll()?;
        if phase == Phase::Running {
            let now_s = since_start(Instant::now(), t_running);
            let due = injector.step(now_s, |t| consumer.carried(t));
            for a in due {
                tracing::info!(service = a.service.name(), act = ?a.act, "fault injected");
                match a.act {
                    Act::Signal(sig) => {
                        if let Some(c) = children.iter().find(|c| c.id == a.service) {
                            c.signal(sig);
                        }
                    }
                    Act::Order(f) => consumer.order_fault(a.service, f)?,
                }
            }
            // Drops and corruptions are noticed where they are counted.
            for (i, output, kind) in injector.awaiting_count() {
                // The solve answers' one client is the sequencer.
                let counted = match (output, &sequencer) {
                    (Some(TopicId::Solve), Some(seq)) => seq.counted(kind),
                    (Some(topic), _) => consumer.counted(topic, kind),
                    (None, _) => false,
                };
                if counted {
                    injector.counted(i, since_start(Instant::now(), t_running));
                }
            }
            for (id, seen) in &consumer.seen {
                injector.heard_from(*id, since_start(seen.at, t_running));
            }
        }
        if let Some(b) = &bar {
            b.set_position(consumer.progress().0);
        }
        if phase == Phase::Starting {
            let ready = children.iter().all(|c| {
                consumer
                    .seen
                    .get(&c.id)
                    .is_some_and(|s| s.heartbeat.state >= Heartbeat::READY)
            });
            if ready {
                consumer.command(Command::Start, Control::ALL)?;
                t_running = Some(Instant::now());
                supervisor.started(Instant::now());
                phase = Phase::Running;
                tracing::info!(
                    startup_ms = t_start.elapsed().as_millis() as u64,
                    "all services ready; started"
                );
            } else if t_start.elapsed() > Duration::from_millis(limits.startup_timeout_ms) {
                failure = Some(format!(
                    "services not ready within run.startup_timeout_ms = {} ms",
                    limits.startup_timeout_ms
                ));
                return Ok(Step::Stop);
            }
        }
        if phase == Phase::Running {
            if let Some(seq) = sequencer.as_mut() {
                seq.step(&consumer, supervisor.is_up(ServiceId::Inversion))?;
                if let Some(f) = &seq.failure {
                    failure = Some(f.clone());
                    return Ok(Step::Stop);
                }
            }
        }
        let solved = sequencer.as_ref().is_none_or(|s| s.done());
        if phase == Phase::Running && consumer.complete() && solved && supervisor.all_up() {
            t_done = Some(Instant::now());
            phase = Phase::Done;
            return Ok(Step::Stop);
        }
        if wakes.contains(&Wake::Tick) || wakes.contains(&Wake::Timeout) {
            let now = Instant::now();
            let now_s = since_start(now, t_running);
            if phase == Phase::Starting {
                // A failure during the initial startup fails the run.
                let exited = children.iter_mut().position(|c| c.poll_exit());
                if let Some(c) = exited.map(|i| &children[i]) {
                    failure = Some(format!(
                        "service {} exited unexpectedly during startup: {}\n{}",
                        c.id.name(),
                        c.ending.label(),
                        c.log_tail(8)
                    ));
                    return Ok(Step::Stop);
                }
            }
            if phase == Phase::Running {
                let seen: Vec<Observation> = children
                    .iter_mut()
                    .map(|c| Observation {
                        id: c.id,
                        exited: (!c.is_running()).then(|| c.exit_ok.unwrap_or(false)),
                        heartbeat: consumer
                            .seen
                            .get(&c.id)
                            .filter(|s| s.heartbeat.pid == c.pid)
                            .map(|s| (s.at, s.heartbeat.state)),
                    })
                    .collect();
                for action in supervisor.step(now, &seen) {
                    let Some(c) = children.iter_mut().find(|c| c.id == action.service()) else {
                        continue;
                    };
                    match action {
                        Action::Noticed { id, how } => {
                            tracing::warn!(
                                service = id.name(),
                                how = how.label(),
                                "service failed"
                            );
                            injector.detected(id, how.label(), now_s);
                        }
                        Action::Kill(_) => c.signal(rustix::process::Signal::KILL),
                        Action::Respawn(id) => {
                            // The dead process's ports go before the new one opens its own.
                            node.try_cleanup_dead_nodes();
                            let n = supervisor.restarts(id);
                            tracing::info!(service = id.name(), restart = n, "restarting");
                            *c = ServiceProcess::spawn(exe, id, prefix, resolved, &log_dir, n)?;
                        }
                        Action::Resume(id) => {
                            if sim_clock {
                                for topic in deployment::inputs(scenario, id) {
                                    let order = Replay {
                                        consumer: id,
                                        topic,
                                        from_seq: 0,
                                    };
                                    if let Some(producer) = deployment::producer(topic) {
                                        consumer.replay(producer, order)?;
                                    }
                                }
                            }
                            consumer.command(Command::Start, id as u32)?;
                            injector.restarted(id, now_s);
                            let serves_solve = deployment::producer(TopicId::Solve) == Some(id);
                            if let (true, Some(seq)) = (serves_solve, sequencer.as_mut()) {
                                seq.server_restarted();
                            }
                            tracing::info!(service = id.name(), "restarted service resumed");
                        }
                        Action::GiveUp { id, how, why } => {
                            let what = match how {
                                Noticed::Exit => {
                                    format!("exited unexpectedly: {}", c.ending.label())
                                }
                                Noticed::HeartbeatDeadline => format!(
                                    "sent no heartbeat for run.heartbeat_deadline_ms = {} ms",
                                    limits.heartbeat_deadline_ms
                                ),
                                Noticed::RestartTimeout => format!(
                                    "was not ready again within run.startup_timeout_ms = {} ms",
                                    limits.startup_timeout_ms
                                ),
                            };
                            failure = Some(format!(
                                "service {} {what}{}; not restarted: {why}\n{}",
                                id.name(),
                                injected_note(&injector, id),
                                c.log_tail(8)
                            ));
                            return Ok(Step::Stop);
                        }
                    }
                }
            }
            if now.duration_since(scanned) >= MEMBERSHIP_SCAN {
                scanned = now;
                let mut ours: Vec<u32> = children.iter().map(|c| c.pid).collect();
                ours.push(std::process::id());
                if let Some(f) = membership.scan(prefix, &ours, now_s) {
                    failure = Some(f);
                    return Ok(Step::Stop);
                }
            }
            if now.duration_since(acks_refreshed) >= hb_period {
                consumer.refresh_acks()?;
                acks_refreshed = now;
            }
            if t_start.elapsed().as_secs_f64() > limits.timeout_s {
                failure = Some(format!(
                    "run exceeded run.timeout_s = {} s",
                    limits.timeout_s
                ));
                return Ok(Step::Stop);
            }
        }
        Ok(Step::Wait)
    })?;
    // Production ends here for a run that did not complete (a failure, a signal).
    let t_stopped = Instant::now();
    if let Some(b) = &bar {
        b.finish_and_clear();
    }
    if exit == glint_runtime::Exit::Terminated {
        INTERRUPTED.store(true, std::sync::atomic::Ordering::SeqCst);
        if failure.is_none() {
            failure = Some("interrupted by a signal".into());
        }
    }

    // A service still SIGSTOPped by a fault is continued, so that it can obey the ladder.
    for a in injector.release(since_start(t_stopped, t_running)) {
        if let (Some(c), Act::Signal(sig)) = (children.iter().find(|c| c.id == a.service), a.act) {
            c.signal(sig);
        }
    }
    // Stop ladder; drain final heartbeats while waiting so the last counters are captured.
    let grace = Duration::from_millis(limits.shutdown_grace_ms);
    let shutdown_sent = std::cell::Cell::new(Ok(()));
    let consumer_cell = std::cell::RefCell::new(&mut consumer);
    stop_ladder(
        &mut children,
        grace,
        &mut || {
            shutdown_sent.set(
                consumer_cell
                    .borrow_mut()
                    .command(Command::Shutdown, Control::ALL),
            )
        },
        &mut || {
            let _ = consumer_cell.borrow_mut().poll();
        },
    );
    shutdown_sent.into_inner()?;
    consumer.poll()?;

    // A run that failed produced until it stopped: its rates are over that time.
    let production_s = t_running.map_or(0.0, |a| (t_done.unwrap_or(t_stopped) - a).as_secs_f64());
    let server =
        deployment::producer(TopicId::Solve).and_then(|p| consumer.reported(p, TopicId::Solve));
    let solve_tampered = match (&sequencer, server) {
        (Some(seq), Some(c)) => [
            c.dropped[shared_types::DropReason::Injected as usize],
            c.dropped[shared_types::DropReason::Malformed as usize],
            seq.unanswered,
            seq.malformed,
        ],
        _ => [0; 4],
    };
    let mut facts = RunFacts::collect(
        &consumer,
        &children,
        scenario,
        sequencer
            .as_ref()
            .map(|s| s.responses.clone())
            .unwrap_or_default(),
        failure,
        injector.faults,
        Outcome {
            startup_s: t_running.map_or(0.0, |t| (t - t_start).as_secs_f64()),
            production_s,
        },
    );
    facts.solve_tampered = solve_tampered;
    facts.membership = membership.report();
    if children.iter().any(|c| c.ending == Ending::Running) {
        bail!("a child survived the stop ladder");
    }
    drop(children);
    drop(sequencer);
    drop(consumer);
    drop(listeners);
    drop(solve_reply);
    drop(node);
    Ok(facts)
}

/// " (injected fault: …)" when faults were injected into `id`.
fn injected_note(injector: &Injector, id: shared_types::ServiceId) -> String {
    let faults = injector.injected_into(id);
    if faults.is_empty() {
        String::new()
    } else {
        format!(" (injected fault: {})", faults.join(", "))
    }
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
