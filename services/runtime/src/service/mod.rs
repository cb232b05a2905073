//! The one way a glint service runs. A service says what it consumes (one [`Input`]), what it
//! produces (its [`Output`]s) and what it does with each input and on each wake-up; the
//! skeleton, [`run_service`], owns everything else: the node, control, heartbeats, the
//! acknowledgements of what it consumed, the sim-clock credit of what it produces, replays to
//! a restarted consumer, in-band faults, and shutdown.
//!
//! Per wake-up, in this order:
//! 1. control: `Start`/`Pause`/`Resume` go to [`Service::on_command`]; `Shutdown` sends a last
//!    heartbeat and leaves the loop;
//! 2. acknowledgements from the consumers of each output feed that output's credit;
//! 3. in-band `drop`/`corrupt` orders are armed ([`Service::arm`]); replay orders (a consumer
//!    restarted) reset its credit and rewind the output; a logged output is re-sent first, and
//!    new inputs wait until the restarted consumer has caught up;
//! 4. inputs are taken, at most as many as every output has credit for (one output message
//!    per input), each handed to [`Service::on_input`] after an injected delay, if any;
//!    what was taken is acknowledged;
//! 5. [`Service::on_tick`] (a source produces here; a server answers);
//! 6. on the heartbeat tick, a heartbeat with every counter (and between two inputs whenever
//!    one is due, so that a long burst of work never looks like a hang).
//!
//! Recovery is by checkpoint and deterministic replay (docs/adr/0032, 0036): every
//! `supervision.checkpoint_every_inputs` inputs (or `checkpoint_every_ms`) the skeleton writes
//! the service's state with its ports' accounting ([`crate::checkpoint`]); a restarted service
//! restores the last one and is fed only the inputs that came after it, rebuilding its state
//! exactly; consumers skip what they already have as duplicates. A kept log is trimmed to what
//! its consumers' checkpoints do not cover.

use std::time::Duration;

use anyhow::Result;
use iceoryx2::port::listener::Listener;
use shared_types::scenario::Clock as ClockMode;
use shared_types::topics::{credit_window, Ipc, IpcNode};
use shared_types::{
    deployment, Command, DropReason, Heartbeat, InBandFault, Scenario, ServiceId, TopicId,
};

use crate::checkpoint::{Checkpoint, Policy, Schedule};
use crate::credit::{AckReader, Credit};
use crate::housekeeping::Housekeeping;
use crate::loop_timer::LoopTimer;
use crate::stats::TopicStats;
use crate::waitloop::{run_loop, Exit, Step, Wake};

mod streams;
pub use streams::{Frame, Input, NoInput, Output};

/// Where a service reads the time it does not take from its messages (realtime pacing).
pub trait Clock {
    /// Nanoseconds on a monotonic scale.
    fn now_ns(&self) -> u64;
}

/// `CLOCK_MONOTONIC`: the clock of a deployed service.
pub struct Monotonic;

impl Clock for Monotonic {
    fn now_ns(&self) -> u64 {
        crate::clock::mono_ns()
    }
}

/// What a service opens its ports with.
pub struct Setup<'a> {
    pub node: &'a IpcNode,
    pub scenario: &'a Scenario,
    /// A new incarnation after a crash.
    pub restarted: bool,
    listeners: Vec<Listener<Ipc>>,
}

impl Setup<'_> {
    /// Wakes the loop on this listener (an input's, or a server's requests).
    pub fn listen(&mut self, listener: Listener<Ipc>) {
        self.listeners.push(listener);
    }

    /// Whether the deployment runs on the simulated clock (lockstep, nothing dropped).
    pub fn sim_clock(&self) -> bool {
        self.scenario.clock == ClockMode::Sim
    }
}

/// What a service reaches of the skeleton while it works.
pub struct Io<'a> {
    hk: &'a mut Housekeeping,
    credits: &'a [(TopicId, Credit)],
    clock: &'a dyn Clock,
    pub node: &'a IpcNode,
    /// Realtime deployment (paced by the wall clock, drops counted) rather than sim clock.
    pub realtime: bool,
}

impl Io<'_> {
    /// The credit of an output topic (everything allowed for a topic without consumers).
    pub fn allows(&self, topic: TopicId, seq: u64) -> bool {
        self.credit(topic).is_none_or(|c| c.allows(seq))
    }

    fn credit(&self, topic: TopicId) -> Option<&Credit> {
        self.credits
            .iter()
            .find(|(t, _)| *t == topic)
            .map(|(_, c)| c)
    }

    /// An injected delay before producing one message (the skeleton does it before each input).
    pub fn pace(&mut self) -> Result<()> {
        self.hk.pace()
    }

    /// Repeats the last heartbeat when one is due (a long piece of work between wake-ups).
    pub fn beat_if_due(&mut self) -> Result<()> {
        self.hk.beat_if_due()
    }

    /// For a service blocked in a retried call: obeys control, beats when one is due;
    /// `false` once `Shutdown` arrived.
    pub fn keepalive(&mut self) -> Result<bool> {
        self.hk.keepalive()
    }

    pub fn now_ns(&self) -> u64 {
        self.clock.now_ns()
    }

    /// Heartbeat state (`Heartbeat::READY` …).
    pub fn state(&self) -> u32 {
        self.hk.state
    }

    /// Marks the service done with its work (a source that produced everything).
    pub fn finish(&mut self) {
        if self.hk.state == Heartbeat::RUNNING {
            self.hk.state = Heartbeat::FINISHED;
        }
    }
}

/// A glint service on the skeleton.
pub trait Service: Sized {
    const ID: ServiceId;
    type Input: Input;

    /// Opens the service's ports and builds its core. A restarted consumer is fed its input
    /// again from the start: the skeleton has it wait for that replay.
    fn open(setup: &mut Setup<'_>) -> Result<(Self, Self::Input)>;

    /// The produced topics (credit, replays, faults).
    fn outputs(&mut self) -> Vec<&mut dyn Output>;

    /// Every counter the service keeps besides its input's (outputs, servers), for heartbeats.
    fn stats(&self) -> Vec<&TopicStats>;

    /// Time spent waiting for RPC answers so far [ns] (a service that calls one).
    fn rpc_wait_ns(&self) -> u64 {
        0
    }

    /// Its state after the inputs it has taken, as checkpoint bytes ([`crate::checkpoint::encode`]);
    /// empty for a service whose state is its ports' accounting alone (the sensor: message
    /// `k` is a function of `k`). `None` (the default): it takes no checkpoints, and a restart
    /// replays its inputs from the first.
    fn checkpoint(&self) -> Result<Option<Vec<u8>>> {
        Ok(None)
    }

    /// Takes up the state of a checkpoint [`Service::checkpoint`] made.
    fn restore(&mut self, _state: &[u8]) -> Result<()> {
        Ok(())
    }

    /// Arms an in-band `drop` or `corrupt` on the service's main output (its first).
    fn arm(&mut self, fault: &InBandFault) {
        if let Some(out) = self.outputs().into_iter().next() {
            out.tamper().arm(fault);
        }
    }

    /// `Start`, `Pause`, `Resume` (after the skeleton marked the service running on `Start`).
    fn on_command(&mut self, _io: &mut Io<'_>, _cmd: Command) -> Result<()> {
        Ok(())
    }

    /// `End`: `topic` (one of its outputs) ends after `messages` messages, or where it is if
    /// it has sent more (a soak's end). Only producers of streams have anything to end.
    fn on_end(&mut self, _topic: TopicId, _messages: u64) {}

    /// One input message, in seq order. `Ok(Err(reason))` drops it with a counted reason; an
    /// error ends the service.
    fn on_input(
        &mut self,
        io: &mut Io<'_>,
        item: <Self::Input as Input>::Item<'_>,
    ) -> Result<Result<(), DropReason>>;

    /// Every wake-up, after the inputs: what to wait for next.
    fn on_tick(&mut self, _io: &mut Io<'_>, _wakes: &[Wake]) -> Result<Step> {
        Ok(Step::Wait)
    }
}

/// How a service process was started.
pub struct ServiceArgs<'a> {
    pub prefix: &'a str,
    pub scenario: &'a Scenario,
    pub restarted: bool,
}

/// Runs service `S` until `Shutdown` or a termination signal, on the monotonic clock.
pub fn run_service<S: Service>(args: ServiceArgs<'_>) -> Result<()> {
    run_service_with::<S>(args, &Monotonic)
}

/// [`run_service`] with the clock given.
pub fn run_service_with<S: Service>(args: ServiceArgs<'_>, clock: &dyn Clock) -> Result<()> {
    let ServiceArgs {
        prefix,
        scenario,
        restarted,
    } = args;
    let name = S::ID.name();
    if restarted {
        tracing::info!("restarted");
    }
    // Before any thread of its own: they inherit the CPU.
    crate::placement::apply(name, scenario.cpu_of(S::ID))?;
    let node = crate::open_node(prefix, name)?;
    let (mut hk, control_l) = Housekeeping::open(&node, S::ID)?;
    hk.faults_enabled = scenario.faults.enabled;
    let tick = Duration::from_millis(scenario.run.heartbeat_period_ms);
    hk.heartbeat_period = tick;
    let (mut acks, ack_l) = AckReader::open(&node)?;
    let mut setup = Setup {
        node: &node,
        scenario,
        restarted,
        listeners: vec![control_l, ack_l],
    };
    let (mut svc, mut input) = S::open(&mut setup)?;
    let listeners = std::mem::take(&mut setup.listeners);
    let realtime = scenario.clock == ClockMode::Realtime;
    let input_topic = input.stats().map(|s| s.topic);
    let mut credits: Vec<(TopicId, Credit)> = svc
        .outputs()
        .iter()
        .map(|o| {
            let topic = o.stats().topic;
            let consumers = deployment::consumers(scenario, topic);
            (
                topic,
                Credit::new(credit_window(topic, scenario), consumers),
            )
        })
        .collect();
    if restarted && !realtime {
        if let Some(c) = Checkpoint::read(prefix, S::ID)? {
            restore(&mut svc, &mut input, &mut credits, &c)?;
        }
        if let Some(stats) = input.stats_mut() {
            stats.await_replay();
        }
    }
    let sup = &scenario.supervision;
    let mut schedule = (!realtime).then(|| {
        let policy = Policy {
            every_inputs: sup.checkpoint_every_inputs,
            every: Duration::from_millis(sup.checkpoint_every_ms),
        };
        Schedule::new(policy, progress(&input, &mut svc))
    });
    // Everything below it is in this incarnation's last checkpoint (realtime: nothing is
    // ever replayed, so everything taken).
    let mut checkpointed_seq = input.stats().map_or(0, |s| s.next_seq);
    hk.state = Heartbeat::READY;
    let mut timer = LoopTimer::new();
    // A first heartbeat at once: a service blocked before its first tick still has one to repeat.
    hk.time = timer.time(&input, &svc);
    hk.beat(0, &all_stats(&input, &svc))?;
    tracing::info!("{name} ready");

    let waits: Vec<(&Listener<Ipc>, Option<Duration>)> =
        listeners.iter().map(|l| (l, None)).collect();
    let exit = run_loop(&waits, tick, |wakes| {
        timer.woke();
        // 1. Control.
        for cmd in hk.poll_control()? {
            if cmd == Command::Start && hk.state == Heartbeat::READY {
                hk.state = Heartbeat::RUNNING;
            }
            if matches!(cmd, Command::Start | Command::Pause | Command::Resume) {
                let mut io = Io {
                    hk: &mut hk,
                    credits: &credits,
                    clock,
                    node: &node,
                    realtime,
                };
                svc.on_command(&mut io, cmd)?;
            }
        }
        for (topic, messages) in hk.take_ends() {
            svc.on_end(topic, messages);
        }
        for (topic, next_seq, received) in hk.take_continues() {
            continue_at(&mut input, &mut svc, topic, next_seq, received)?;
        }
        if hk.shutdown_requested {
            hk.state = Heartbeat::STOPPING;
            hk.inputs_ended();
            timer.asleep(false);
            hk.time = timer.time(&input, &svc);
            hk.beat(0, &all_stats(&input, &svc))?;
            return Ok(Step::Stop);
        }
        // 2. Credit, and the logs trimmed to what a replay may still ask for.
        {
            let mut feed: Vec<(TopicId, &mut Credit)> =
                credits.iter_mut().map(|(t, c)| (*t, c)).collect();
            acks.poll(&mut feed)?;
        }
        for out in svc.outputs() {
            let topic = out.stats().topic;
            if let Some((_, c)) = credits.iter().find(|(t, _)| *t == topic) {
                out.trim(c.replayable_from());
            }
        }
        // 3. Faults and replays.
        for f in hk.take_output_faults() {
            svc.arm(&f);
        }
        for r in hk.take_replays() {
            let mut outputs = svc.outputs();
            let Some(out) = outputs.iter_mut().find(|o| o.stats().topic == r.topic) else {
                continue;
            };
            tracing::info!(
                consumer = r.consumer.name(),
                topic = r.topic.name(),
                from = r.from_seq,
                "replay"
            );
            if let Some((_, c)) = credits.iter_mut().find(|(t, _)| *t == r.topic) {
                c.reset(r.consumer, r.from_seq);
            }
            out.rewind(r.from_seq);
        }
        let mut hold_input = false;
        for out in svc.outputs() {
            if out.logged() && out.replaying() {
                let topic = out.stats().topic;
                let limit = credits
                    .iter()
                    .find(|(t, _)| *t == topic)
                    .map_or(u64::MAX, |(_, c)| c.available(out.next_seq()));
                out.resend(limit)?;
                // New inputs wait until the restarted consumer has caught up.
                hold_input |= out.replaying();
            }
        }
        // 4. Inputs, within the outputs' credit; none before `Start` (a restarted service
        // first takes the orchestrator's replay or continue orders).
        hold_input |= hk.state == Heartbeat::READY;
        let mut last_t_ns = 0;
        if !hold_input {
            let limit = svc
                .outputs()
                .iter()
                .map(|o| {
                    let topic = o.stats().topic;
                    credits
                        .iter()
                        .find(|(t, _)| *t == topic)
                        .map_or(usize::MAX, |(_, c)| {
                            c.input_limit(o.stats().published, realtime)
                        })
                })
                .min()
                .unwrap_or(usize::MAX);
            // No further than the next checkpoint by count.
            let limit = match schedule.as_ref() {
                Some(s) => limit.min(s.remaining(progress(&input, &mut svc))),
                None => limit,
            };
            let mut fatal: Option<anyhow::Error> = None;
            let mut io = Io {
                hk: &mut hk,
                credits: &credits,
                clock,
                node: &node,
                realtime,
            };
            input.take(limit, |item, latency_ns| {
                if fatal.is_some() {
                    return Err(DropReason::Stale);
                }
                if let Err(e) = io.hk.pace().and_then(|_| io.hk.beat_if_due()) {
                    fatal = Some(e);
                    return Err(DropReason::Stale);
                }
                io.hk.last_latency_ns = latency_ns;
                last_t_ns = <S::Input as Input>::t_ns(&item);
                match svc.on_input(&mut io, item) {
                    Ok(verdict) => verdict,
                    Err(e) => {
                        fatal = Some(e);
                        Err(DropReason::Stale)
                    }
                }
            })?;
            if let Some(e) = fatal {
                return Err(e);
            }
            // 4b. A checkpoint when one is due (not while a restarted consumer is replayed).
            if let Some(s) = schedule.as_mut() {
                let now = progress(&input, &mut svc);
                if s.due(now) && take_checkpoint(prefix, &input, &mut svc, &credits)? {
                    s.taken_at(now);
                    checkpointed_seq = input.stats().map_or(0, |st| st.next_seq);
                }
            }
            if let (Some(topic), Some(stats)) = (input_topic, input.stats()) {
                let next = stats.next_seq;
                let covered = if realtime { next } else { checkpointed_seq };
                hk.ack(topic, next, covered, last_t_ns)?;
            }
        }
        // 5. The service's own work.
        let step = {
            let mut io = Io {
                hk: &mut hk,
                credits: &credits,
                clock,
                node: &node,
                realtime,
            };
            svc.on_tick(&mut io, wakes)?
        };
        // 6. Heartbeat.
        if wakes.contains(&Wake::Tick) {
            hk.time = timer.time(&input, &svc);
            hk.beat(last_t_ns, &all_stats(&input, &svc))?;
        }
        // Asleep next with an output's credit used up: held back by a consumer. A subscriber
        // that joined meanwhile (a restarted bridge) is handed the history now, and on every
        // tick (a producer done, or idle, sends nothing that would hand it over).
        let mut held = false;
        for o in svc.outputs() {
            let topic = o.stats().topic;
            let credit = credits.iter().find(|(t, _)| *t == topic);
            let out_of_credit = credit.is_some_and(|(_, c)| c.available(o.next_seq()) == 0);
            held |= out_of_credit;
            if out_of_credit || wakes.contains(&Wake::Tick) {
                o.connect()?;
            }
        }
        timer.asleep(held);
        Ok(step)
    })?;
    if exit == Exit::Terminated {
        tracing::info!("{name} terminated by signal");
    }
    Ok(())
}

/// How far a service has got: inputs taken, or (a source) messages sent.
fn progress<S: Service>(input: &S::Input, svc: &mut S) -> u64 {
    match input.stats() {
        Some(s) => s.next_seq,
        None => svc.outputs().iter().map(|o| o.stats().published).sum(),
    }
}

/// Writes the service's checkpoint: its state, its input's and outputs' accounting, the
/// outputs' credit and logs. `false`: the service takes none.
fn take_checkpoint<S: Service>(
    prefix: &str,
    input: &S::Input,
    svc: &mut S,
    credits: &[(TopicId, Credit)],
) -> Result<bool> {
    let Some(state) = svc.checkpoint()? else {
        return Ok(false);
    };
    let outputs = (svc.outputs().iter())
        .map(|o| {
            let mut snap = o.snapshot();
            let topic = o.stats().topic;
            if let Some((_, c)) = credits.iter().find(|(t, _)| *t == topic) {
                snap.credit = c.snapshot();
            }
            snap
        })
        .collect();
    let c = Checkpoint {
        contract: shared_types::CONTRACT_VERSION,
        service: S::ID as u32,
        input: input.stats().map(|s| s.snapshot()),
        outputs,
        state,
    };
    c.write(prefix, S::ID)?;
    tracing::debug!(
        input_seq = c.input.as_ref().map(|s| s.next_seq),
        "checkpoint"
    );
    Ok(true)
}

/// A service restarted in realtime mode continues `topic`'s accounting where its last
/// incarnation left it, as the orchestrator saw it: on its input, `received` processed and
/// the rest of `next_seq` dropped (its next message counts the gap it missed while down, as
/// overflow); on an output, the next seq at `next_seq` (so none collides with what the last
/// one sent), of which it sent `received` (a realtime source skips what came due while it was
/// down: dropped as overflow).
fn continue_at<S: Service>(
    input: &mut S::Input,
    svc: &mut S,
    topic: TopicId,
    next_seq: u64,
    received: u64,
) -> Result<()> {
    if let Some(stats) = input.stats_mut().filter(|s| s.topic == topic) {
        let mut dropped = [0; shared_types::DROP_REASONS];
        dropped[DropReason::Overflow as usize] = next_seq - received;
        stats.restore(&crate::stats::StatsSnapshot {
            topic: topic as u32,
            published: 0,
            received,
            dropped,
            next_seq,
            duplicates: 0,
            // Its producer, first heard from, starts at `next_seq`.
            per_producer: vec![],
        });
        tracing::info!(topic = topic.name(), next_seq, received, "input continues");
    }
    for out in svc.outputs() {
        if out.stats().topic == topic {
            let mut snap = out.snapshot();
            // Those it skips it never made: dropped at the source, a gap its consumers count.
            snap.stats.dropped[DropReason::Overflow as usize] += next_seq - received;
            snap.stats.published = next_seq;
            snap.stats.next_seq = next_seq;
            snap.log_base = next_seq;
            snap.log.clear();
            out.restore(&snap)?;
            tracing::info!(
                topic = topic.name(),
                next_seq,
                skipped = next_seq - received,
                "output continues"
            );
        }
    }
    Ok(())
}

/// A restarted service takes up its last checkpoint.
fn restore<S: Service>(
    svc: &mut S,
    input: &mut S::Input,
    credits: &mut [(TopicId, Credit)],
    c: &Checkpoint,
) -> Result<()> {
    svc.restore(&c.state)?;
    if let (Some(stats), Some(snap)) = (input.stats_mut(), c.input.as_ref()) {
        stats.restore(snap);
    }
    for out in svc.outputs() {
        let topic = out.stats().topic as u32;
        if let Some(snap) = c.outputs.iter().find(|o| o.stats.topic == topic) {
            out.restore(snap)?;
            if let Some((_, credit)) = credits.iter_mut().find(|(t, _)| *t as u32 == topic) {
                credit.restore(&snap.credit);
            }
        }
    }
    tracing::info!(
        input_seq = c.input.as_ref().map(|s| s.next_seq),
        "restored its checkpoint"
    );
    Ok(())
}

/// The input's counters, then the service's.
pub(crate) fn all_stats<'a, S: Service>(input: &'a S::Input, svc: &'a S) -> Vec<&'a TopicStats> {
    let mut all: Vec<&TopicStats> = input.stats().into_iter().collect();
    all.extend(svc.stats());
    all
}
