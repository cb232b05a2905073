//! A deployment while it runs: a polled state machine, stepped once per wake-up of the run
//! loop (a message, a solve answer, the tick). Starting → (every service ready) Running →
//! (every message accounted for, the solve done, every service up) Done; any failure stops it
//! with its reason. Each step reads what arrived, fires the faults that are due, starts the
//! services, sequences the solve, and on the tick supervises (typed [`Action`]s), checks the
//! membership and the run's limits. [`Live::stop`] then runs the stop ladder and
//! [`Live::facts`] gives what the report needs.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{bail, Result};
use glint_runtime::{Exit, Step, Wake};
use shared_types::scenario::Clock;
use shared_types::table::Count;
use shared_types::topics::IpcNode;
use shared_types::{deployment, Command, Control, Heartbeat, Scenario, ServiceId, TopicId};

use crate::report::{Outcome, RunFacts};
use crate::run::consume::Consumer;
use crate::run::deploy::{stop_ladder, Ending, ServiceProcess};
use crate::run::faults::{Act, Heard, Injector};
use crate::run::membership::Membership;
use crate::run::memory::Memory;
use crate::run::remote::Remote;
use crate::run::sequence::Sequencer;
use crate::run::supervise::Supervisor;

mod restart;

/// How often the live nodes under the prefix are checked against the deployment.
const MEMBERSHIP_SCAN: Duration = Duration::from_millis(250);

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    /// Spawned; waiting for every service's ready heartbeat.
    Starting,
    /// Started; supervised until every message is accounted for.
    Running,
    /// Every message accounted for, the solve done, every service up.
    Done,
}

/// How a service process is spawned (again, after a failure).
pub struct Spawner<'a> {
    pub exe: &'a Path,
    pub prefix: &'a str,
    /// The resolved scenario file the services read.
    pub scenario_file: &'a Path,
    pub log_dir: PathBuf,
    /// This host, in a deployment split across hosts.
    pub host: Option<&'a str>,
}

impl Spawner<'_> {
    pub fn spawn(&self, id: ServiceId, restarts: u32) -> Result<ServiceProcess> {
        ServiceProcess::spawn(
            self.exe,
            id,
            self.prefix,
            self.scenario_file,
            &self.log_dir,
            restarts,
            self.host,
        )
    }
}

pub struct Live<'a> {
    scenario: &'a Scenario,
    node: &'a IpcNode,
    spawner: Spawner<'a>,
    pub consumer: Consumer,
    sequencer: Option<Sequencer>,
    children: Vec<ServiceProcess>,
    /// Services of the deployment on other hosts (a split deployment), heard through the
    /// bridge.
    remote: Remote,
    injector: Injector,
    supervisor: Supervisor,
    membership: Membership,
    phase: Phase,
    failure: Option<String>,
    t_start: Instant,
    t_running: Option<Instant>,
    t_done: Option<Instant>,
    t_stopped: Option<Instant>,
    acks_refreshed: Instant,
    scanned: Instant,
    bar: Option<indicatif::ProgressBar>,
    /// Every process's resident memory over the run.
    memory: Memory,
    /// A soak's end: when the camera's stream was ended, and after how many frames.
    soak_end: Option<SoakEnd>,
    /// Each restarted service's last heartbeat before its restart.
    last_heard: std::collections::BTreeMap<ServiceId, Heartbeat>,
}

/// When a soak's time was up: the camera's stream ended after `frames`.
#[derive(Debug, Clone, Copy)]
pub struct SoakEnd {
    pub at_s: f64,
    pub frames: u64,
}

impl<'a> Live<'a> {
    /// Spawns every service of the scenario (the services and ports already exist).
    pub fn spawn(
        scenario: &'a Scenario,
        node: &'a IpcNode,
        spawner: Spawner<'a>,
        consumer: Consumer,
        sequencer: Option<Sequencer>,
        progress: bool,
    ) -> Result<Self> {
        let children = (crate::run::hosts::local_services(scenario, spawner.host).into_iter())
            .map(|id| spawner.spawn(id, 0))
            .collect::<Result<Vec<_>>>()?;
        let remote = Remote::new(scenario, spawner.host);
        let injector = Injector::new(scenario, spawner.host);
        tracing::info!(
            prefix = spawner.prefix,
            services = children.len(),
            "deployed"
        );
        let limits = &scenario.run;
        let ids: Vec<ServiceId> = children.iter().map(|c| c.id).collect();
        let supervisor = Supervisor::new(
            &scenario.supervision,
            &ids,
            Duration::from_millis(limits.heartbeat_deadline_ms),
            Duration::from_millis(limits.startup_timeout_ms),
        );
        let bar = progress.then(|| match &scenario.soak {
            Some(soak) => crate::progress::seconds_bar(soak.duration_s.ceil() as u64),
            None => crate::progress::bar(consumer.progress().1),
        });
        let now = Instant::now();
        Ok(Live {
            scenario,
            node,
            spawner,
            consumer,
            sequencer,
            children,
            remote,
            injector,
            supervisor,
            membership: Membership::default(),
            phase: Phase::Starting,
            failure: None,
            t_start: now,
            t_running: None,
            t_done: None,
            t_stopped: None,
            acks_refreshed: now,
            scanned: now,
            bar,
            memory: Memory::new(now),
            soak_end: None,
            last_heard: Default::default(),
        })
    }

    /// Seconds from the start of the services to `t` (0 before they started).
    fn since_start(&self, t: Instant) -> f64 {
        self.t_running
            .map_or(0.0, |t0| t.saturating_duration_since(t0).as_secs_f64())
    }

    /// Stops the run with `why`.
    fn fail(&mut self, why: String) -> Step {
        self.failure = Some(why);
        Step::Stop
    }

    /// One step: what arrived, then the phase's work; on the tick, supervision and limits.
    pub fn step(&mut self, wakes: &[Wake]) -> Result<Step> {
        self.consumer.poll()?;
        if self.phase == Phase::Running {
            self.inject_faults()?;
            self.end_soak_when_due()?;
        }
        if let Some(b) = &self.bar {
            b.set_position(match self.scenario.soak {
                Some(_) => self.since_start(Instant::now()) as u64,
                None => self.consumer.progress().0,
            });
        }
        if self.phase == Phase::Starting {
            if let Some(stop) = self.start_when_ready()? {
                return Ok(stop);
            }
        }
        if self.phase == Phase::Running {
            if let Some(stop) = self.sequence()? {
                return Ok(stop);
            }
            let solved = self.sequencer.as_ref().is_none_or(|s| s.done());
            if self.consumer.complete() && solved && self.supervisor.all_up() {
                self.t_done = Some(Instant::now());
                self.phase = Phase::Done;
                return Ok(Step::Stop);
            }
        }
        if wakes.contains(&Wake::Tick) || wakes.contains(&Wake::Timeout) {
            if let Some(stop) = self.on_tick()? {
                return Ok(stop);
            }
        }
        Ok(Step::Wait)
    }

    /// Fires the faults that are due; notes the drops and corruptions counted downstream and
    /// the services heard from.
    fn inject_faults(&mut self) -> Result<()> {
        let now_s = self.since_start(Instant::now());
        let consumer = &self.consumer;
        let due = self.injector.step(
            now_s,
            |t| consumer.carried(t),
            |t, kind| consumer.tampered(t, kind),
        );
        for a in due {
            tracing::info!(service = a.service.name(), act = ?a.act, "fault injected");
            match a.act {
                Act::Signal(sig) => {
                    if let Some(c) = self.children.iter().find(|c| c.id == a.service) {
                        c.signal(sig);
                    }
                }
                // A bridge fires its own delays from the scenario (an order to `bridge` over
                // control would reach every host's bridge).
                Act::Order(_) if a.service == ServiceId::Bridge => {}
                Act::Order(f) => self.consumer.order_fault(a.service, f)?,
            }
        }
        // Drops and corruptions are noticed where they are counted.
        for a in self.injector.awaiting_count() {
            // The solve answers' one client is the sequencer.
            let counted = match (a.output, &self.sequencer) {
                (Some(TopicId::Solve), Some(seq)) => seq.counted(a.kind),
                (Some(topic), _) => self.consumer.counted(topic, a.kind, a.base),
                (None, _) => false,
            };
            if counted {
                self.injector.counted(a.index, now_s);
            }
        }
        self.hear_from_services();
        Ok(())
    }

    /// How far `id` had got on its fault trigger topic by heartbeat `hb`: inputs taken, or (a
    /// source) messages sent.
    fn progress(&self, id: ServiceId, hb: &Heartbeat) -> u64 {
        deployment::trigger_topic(self.scenario, id).map_or(0, |t| {
            let c = hb.topics.iter().find(|c| c.topic == t as u32);
            match deployment::producer(t) == Some(id) {
                true => c.map_or(0, |c| c.published),
                false => c.map_or(0, |c| c.next_seq),
            }
        })
    }

    /// How far `id` has got as the orchestrator sees it, between heartbeats: a source's
    /// messages taken, a service's outputs of one per input taken.
    fn done_as_seen(&self, id: ServiceId) -> u64 {
        let Some(trigger) = deployment::trigger_topic(self.scenario, id) else {
            return 0;
        };
        if deployment::producer(trigger) == Some(id) {
            return self.consumer.carried(trigger);
        }
        deployment::fault_output(self.scenario, id)
            .filter(|o| matches!(o.spec().count, Count::PerInput(t) if t == trigger))
            .map_or(0, |o| self.consumer.carried(o))
    }

    /// Hands each service's latest heartbeat to the faults.
    fn hear_from_services(&mut self) {
        let current = |id: &ServiceId, pid: u32| {
            self.remote.contains(id) || self.children.iter().any(|c| c.id == *id && c.pid == pid)
        };
        let heard: Vec<(ServiceId, Heard)> = (self.consumer.seen.iter())
            // The current incarnation's heartbeats only (a dead one's last may linger).
            .filter(|(id, seen)| current(id, seen.heartbeat.pid))
            .map(|(id, seen)| {
                let trigger = deployment::trigger_topic(self.scenario, *id);
                let hb = &seen.heartbeat;
                let heard = Heard {
                    at_s: self.since_start(seen.at),
                    faults_obeyed: hb.faults_obeyed,
                    delaying: hb.delaying != 0,
                    progress: self.progress(*id, hb),
                    done: self.done_as_seen(*id),
                    carried: trigger.map_or(0, |t| self.consumer.carried(t)),
                };
                (*id, heard)
            })
            .collect();
        for (id, heard) in heard {
            self.injector.heard_from(id, heard);
        }
    }

    /// Sends `Start` once every service is ready; fails the run past the startup timeout.
    fn start_when_ready(&mut self) -> Result<Option<Step>> {
        let seen = &self.consumer.seen;
        let ready = self.children.iter().all(|c| {
            seen.get(&c.id)
                .is_some_and(|s| s.heartbeat.state >= Heartbeat::READY)
        }) && self.remote.ready(&self.consumer);
        // Another host's part may start later than this one, or still be ending its previous
        // run (a matrix's case): it has the host silence limit more.
        let timeout_ms = self.scenario.run.startup_timeout_ms
            + match self.remote.is_empty() {
                true => 0,
                false => self.scenario.host_silence_limit().as_millis() as u64,
            };
        if ready {
            self.consumer.command(Command::Start, Control::ALL)?;
            let now = Instant::now();
            self.t_running = Some(now);
            self.supervisor.started(now);
            self.phase = Phase::Running;
            tracing::info!(
                startup_ms = self.t_start.elapsed().as_millis() as u64,
                "all services ready; started"
            );
        } else if self.t_start.elapsed() > Duration::from_millis(timeout_ms) {
            // Hosts that run different scenarios (another file, --seed, --fault) never meet.
            let hint = match self.remote.is_empty() {
                true => "",
                false => {
                    " (a split deployment: is every host's part running, with the same \
                     scenario file, --seed and --fault?)"
                }
            };
            return Ok(Some(self.fail(format!(
                "services not ready within {timeout_ms} ms (run.startup_timeout_ms, and the \
                 host silence limit when split){hint}"
            ))));
        }
        Ok(None)
    }

    /// The solve's next call, once its server is up.
    fn sequence(&mut self) -> Result<Option<Step>> {
        // A server on another host is up as its heartbeats say; one here as supervision does.
        let server_up = deployment::producer(TopicId::Solve).is_some_and(|server| {
            match self.remote.contains(&server) {
                true => self.remote.is_up(&self.consumer, server),
                false => self.supervisor.is_up(server),
            }
        });
        let Some(seq) = self.sequencer.as_mut() else {
            return Ok(None);
        };
        seq.step(&self.consumer, server_up)?;
        match seq.failure.clone() {
            Some(f) => Ok(Some(self.fail(f))),
            None => Ok(None),
        }
    }

    /// The tick: a child lost during startup, supervision, membership, the acks again, the
    /// run's time limit.
    fn on_tick(&mut self) -> Result<Option<Step>> {
        let now = Instant::now();
        let now_s = self.since_start(now);
        match self.phase {
            Phase::Starting => {
                // A failure during the initial startup fails the run.
                let exited = self.children.iter_mut().position(|c| c.poll_exit());
                if let Some(c) = exited.map(|i| &self.children[i]) {
                    let why = format!(
                        "service {} exited unexpectedly during startup: {}\n{}",
                        c.id.name(),
                        c.ending.label(),
                        c.log_tail(8)
                    );
                    return Ok(Some(self.fail(why)));
                }
            }
            Phase::Running => {
                if let Some(stop) = self.supervise(now, now_s)? {
                    return Ok(Some(stop));
                }
                let t_running = self.t_running;
                let since = |t: Instant| {
                    t_running.map_or(0.0, |t0| t.saturating_duration_since(t0).as_secs_f64())
                };
                let bridge = self.supervisor.up_since(ServiceId::Bridge);
                let remote = &mut self.remote;
                let silent = remote.check(self.scenario, &self.consumer, now, bridge, since);
                if let Some(why) = silent {
                    return Ok(Some(self.fail(why)));
                }
                // A stopped bridge cuts the link: the other hosts fall silent.
                if self.remote.take_cut_off() {
                    self.injector
                        .detected(ServiceId::Bridge, "host cut off", now_s);
                }
            }
            Phase::Done => {}
        }
        if now.duration_since(self.scanned) >= MEMBERSHIP_SCAN {
            self.scanned = now;
            let mut ours: Vec<u32> = self.children.iter().map(|c| c.pid).collect();
            ours.push(std::process::id());
            if let Some(f) = self.membership.scan(self.spawner.prefix, &ours, now_s) {
                return Ok(Some(self.fail(f)));
            }
        }
        let period = Duration::from_millis(self.scenario.run.heartbeat_period_ms);
        if now.duration_since(self.acks_refreshed) >= period {
            self.consumer.refresh_acks()?;
            self.acks_refreshed = now;
        }
        let children = self
            .children
            .iter()
            .map(|c| (c.id.name().to_string(), c.pid));
        self.memory.sample(now, children);
        // A soak's time is added to the run's limit.
        let soak_s = self.scenario.soak.as_ref().map_or(0.0, |s| s.duration_s);
        let timeout_s = self.scenario.run.timeout_s + soak_s;
        if self.t_start.elapsed().as_secs_f64() > timeout_s {
            return Ok(Some(
                self.fail(format!("run exceeded run.timeout_s = {timeout_s} s")),
            ));
        }
        Ok(None)
    }

    /// A soak whose time is up ends the camera's stream where it safely can: past every frame
    /// the sensor may have sent (the orchestrator's own count, plus the credit it may run ahead
    /// by, plus a second of frames in realtime); the run then accounts for that many.
    fn end_soak_when_due(&mut self) -> Result<()> {
        let Some(soak) = &self.scenario.soak else {
            return Ok(());
        };
        let at_s = self.since_start(Instant::now());
        if self.soak_end.is_some() || at_s < soak.duration_s {
            return Ok(());
        }
        let Some(cam) = &self.scenario.camera else {
            return Ok(());
        };
        let realtime_frames = match self.scenario.clock {
            Clock::Realtime => (1e9 / cam.frame_period_ns().max(1) as f64).ceil() as u64,
            Clock::Sim => 0,
        };
        let ahead = shared_types::topics::credit_window(TopicId::Frame, self.scenario) as u64
            + realtime_frames;
        let frames = self.consumer.carried(TopicId::Frame) + ahead;
        self.consumer
            .end_stream(ServiceId::Sensor, TopicId::Frame, frames)?;
        let mut ended = self.scenario.clone();
        if let Some(cam) = &mut ended.camera {
            cam.frames = frames;
        }
        self.consumer.expect(&ended);
        tracing::info!(frames, at_s, "soak: the camera's stream ends");
        self.soak_end = Some(SoakEnd { at_s, frames });
        Ok(())
    }

    /// The run loop ended (`exit`): continue what a fault stopped, then the stop ladder,
    /// draining the final heartbeats so that the last counters are captured.
    pub fn stop(&mut self, exit: Exit) -> Result<()> {
        let t_stopped = Instant::now();
        self.t_stopped = Some(t_stopped);
        if let Some(b) = &self.bar {
            b.finish_and_clear();
        }
        if exit == Exit::Terminated {
            super::INTERRUPTED.store(true, std::sync::atomic::Ordering::SeqCst);
            if self.failure.is_none() {
                self.failure = Some("interrupted by a signal".into());
            }
        }
        // A service still SIGSTOPped by a fault is continued, so that it can obey the ladder.
        for a in self.injector.release(self.since_start(t_stopped)) {
            let child = self.children.iter().find(|c| c.id == a.service);
            if let (Some(c), Act::Signal(sig)) = (child, a.act) {
                c.signal(sig);
            }
        }
        let grace = Duration::from_millis(self.scenario.run.shutdown_grace_ms);
        // A split deployment's other hosts stop on this Shutdown too, however the local
        // services end.
        if !self.remote.is_empty() {
            self.consumer.command(Command::Shutdown, Control::ALL)?;
        }
        // The bridge (last of the children) goes last: the services' last heartbeats cross it.
        let bridges = (self.children.iter())
            .filter(|c| c.id == ServiceId::Bridge)
            .count();
        let (n, split) = (self.children.len(), self.children.len() - bridges);
        for (range, target) in [
            (0..split, Control::ALL),
            (split..n, ServiceId::Bridge as u32),
        ] {
            let shutdown_sent = std::cell::Cell::new(Ok(()));
            let consumer = std::cell::RefCell::new(&mut self.consumer);
            stop_ladder(
                &mut self.children[range],
                grace,
                &mut || {
                    shutdown_sent.set((consumer.borrow_mut()).command(Command::Shutdown, target))
                },
                &mut || {
                    let _ = consumer.borrow_mut().poll();
                },
            );
            shutdown_sent.into_inner()?;
            if target == Control::ALL {
                self.remote.await_stopping(&mut self.consumer, grace)?;
            }
        }
        self.consumer.poll()?;
        // The last heartbeats may settle a fault's verdict; a fault that never fired fails
        // the run (it did not test what it was asked to).
        self.hear_from_services();
        let never = self.injector.finish();
        if self.failure.is_none() && !never.is_empty() {
            self.failure = Some(never.join("; "));
        }
        if self.children.iter().any(|c| c.ending == Ending::Running) {
            bail!("a child survived the stop ladder");
        }
        Ok(())
    }

    /// What the report needs of the stopped run.
    pub fn facts(mut self) -> RunFacts {
        self.consumer.taps.finish();
        let recorder = self.consumer.taps.take_recorder();
        let t_stopped = self.t_stopped.unwrap_or_else(Instant::now);
        // A run that failed produced until it stopped: its rates are over that time.
        let production_s = (self.t_running).map_or(0.0, |a| {
            (self.t_done.unwrap_or(t_stopped) - a).as_secs_f64()
        });
        let consumer = &self.consumer;
        let server =
            deployment::producer(TopicId::Solve).and_then(|p| consumer.reported(p, TopicId::Solve));
        let solve_tampered = match (&self.sequencer, server) {
            (Some(seq), Some(c)) => [
                c.dropped[shared_types::DropReason::Injected as usize],
                c.dropped[shared_types::DropReason::Malformed as usize],
                seq.unanswered,
                seq.malformed,
            ],
            _ => [0; 4],
        };
        let solve = (self.sequencer.as_ref())
            .map(|s| s.responses.clone())
            .unwrap_or_default();
        let mut facts = RunFacts::collect(
            consumer,
            &self.children,
            self.scenario,
            solve,
            self.failure,
            self.injector.faults,
            Outcome {
                startup_s: (self.t_running).map_or(0.0, |t| (t - self.t_start).as_secs_f64()),
                production_s,
            },
        );
        facts.solve_tampered = solve_tampered;
        (self.remote).add_facts(&mut facts, self.scenario, &self.consumer, self.spawner.host);
        facts.membership = self.membership.report();
        facts.memory = self.memory.traces();
        facts.soak_end = self.soak_end;
        facts.recording = recorder.as_ref().map(|r| r.summary());
        facts.recorder = recorder;
        facts
    }
}
