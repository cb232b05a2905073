//! What every service does besides its own work: obey `control`, publish heartbeats with its
//! counters, and acknowledge what it consumed (the sim-clock credit its producers wait for).

use anyhow::Result;
use iceoryx2::port::listener::Listener;
use shared_types::scenario::FaultKind;
use shared_types::topics::{Ipc, IpcNode};
use shared_types::{
    Ack, Command, Control, Heartbeat, InBandFault, Replay, ServiceId, ServiceTime, TopicCounters,
    TopicId, MAX_TOPICS,
};

use crate::ports::{Inbox, Outbox};
use crate::stats::TopicStats;

pub struct Housekeeping {
    pub id: ServiceId,
    heartbeat: Outbox<Heartbeat>,
    control: Inbox<Control>,
    acks: Outbox<Ack>,
    /// Per consumed topic: acknowledged up to, and covered by this service's checkpoint up to.
    acked: Vec<(TopicId, u64, u64)>,
    /// Replays ordered and not yet taken ([`Housekeeping::take_replays`]).
    replays: Vec<Replay>,
    /// Stream ends ordered and not yet taken ([`Housekeeping::take_ends`]).
    ends: Vec<(TopicId, u64)>,
    /// Continue orders not yet taken ([`Housekeeping::take_continues`]).
    continues: Vec<(TopicId, u64, u64)>,
    /// `Shutdown` has arrived (possibly while the service waited outside its loop).
    pub shutdown_requested: bool,
    /// A `Shutdown` addressed to this service alone (not to all) has arrived.
    pub shutdown_addressed: bool,
    /// Obey in-band fault commands (the scenario's `faults.enabled`); refused ones are counted.
    pub faults_enabled: bool,
    /// In-band fault commands refused because faults are not enabled.
    pub faults_refused: u32,
    /// In-band fault commands obeyed.
    pub faults_obeyed: u32,
    /// An injected delay: added before each message until it ends.
    delay: Option<(std::time::Duration, DelayEnd)>,
    /// Inputs the current delay has slowed.
    slowed: u64,
    /// Drop and corrupt orders not yet armed on an output ([`Housekeeping::take_output_faults`]).
    output_faults: Vec<InBandFault>,
    /// The scenario's `run.heartbeat_period_ms`: a slowed service still beats this often.
    pub heartbeat_period: std::time::Duration,
    /// The last heartbeat: when, and the counters it carried.
    last_beat: Option<(std::time::Instant, [TopicCounters; MAX_TOPICS])>,
    /// Heartbeat state (`Heartbeat::STARTING` …).
    pub state: u32,
    /// Last end-to-end latency seen by this service [ns].
    pub last_latency_ns: u64,
    /// Where the service's time went, as of its last heartbeat.
    pub time: ServiceTime,
    /// A delay applied outside [`Housekeeping::pace`] (the bridge's egress thread paces its
    /// puts): the heartbeat says `delaying` while it is on.
    pub delaying_elsewhere: bool,
}

/// When an injected delay ends.
#[derive(Debug, Clone, Copy)]
enum DelayEnd {
    /// At this instant.
    At(std::time::Instant),
    /// After this many more messages.
    After(u32),
}

impl Housekeeping {
    /// Opens the housekeeping ports; the returned listener wakes the loop on control messages.
    pub fn open(node: &IpcNode, id: ServiceId) -> Result<(Self, Listener<Ipc>)> {
        let heartbeat = Outbox::open(node, TopicId::Heartbeat, id)?;
        let (mut control, listener) = Inbox::open(node, TopicId::Control)?;
        // A restarted service joins the control topic at whatever seq it has reached.
        control.stats.peers_restart();
        let acks = Outbox::open(node, TopicId::Ack, id)?;
        Ok((
            Housekeeping {
                id,
                heartbeat,
                control,
                acks,
                acked: vec![],
                replays: vec![],
                ends: vec![],
                continues: vec![],
                shutdown_requested: false,
                shutdown_addressed: false,
                faults_enabled: false,
                faults_refused: 0,
                faults_obeyed: 0,
                delay: None,
                slowed: 0,
                output_faults: vec![],
                heartbeat_period: std::time::Duration::from_millis(100),
                last_beat: None,
                state: Heartbeat::STARTING,
                last_latency_ns: 0,
                time: ServiceTime::default(),
                delaying_elsewhere: false,
            },
            listener,
        ))
    }

    /// Commands addressed to this service (or to all) since the last call. A
    /// [`Command::Replay`]'s order is kept for [`Housekeeping::take_replays`].
    pub fn poll_control(&mut self) -> Result<Vec<Command>> {
        let me = self.id as u32;
        let mut cmds = vec![];
        let (replays, shutdown, addressed, ends, continues) = (
            &mut self.replays,
            &mut self.shutdown_requested,
            &mut self.shutdown_addressed,
            &mut self.ends,
            &mut self.continues,
        );
        let mut faults = vec![];
        self.control.drain(|r| {
            if r.msg.target == me || r.msg.target == Control::ALL {
                if let Some(c) = Command::from_u32(r.msg.command) {
                    *shutdown |= c == Command::Shutdown;
                    *addressed |= c == Command::Shutdown && r.msg.target == me;
                    cmds.push(c);
                }
                if let Some(order) = r.msg.as_replay() {
                    replays.push(order);
                }
                if let Some(f) = r.msg.as_fault() {
                    faults.push(f);
                }
                if let Some(end) = r.msg.as_end() {
                    ends.push(end);
                }
                if let Some(c) = r.msg.as_continue() {
                    continues.push(c);
                }
            }
            Ok(())
        })?;
        for f in faults {
            self.obey_fault(f);
        }
        Ok(cmds)
    }

    fn obey_fault(&mut self, f: InBandFault) {
        if !self.faults_enabled {
            self.faults_refused += 1;
            tracing::warn!(
                kind = f.kind.name(),
                "fault command refused: faults.enabled is false"
            );
            return;
        }
        tracing::warn!(kind = f.kind.name(), "injected fault");
        self.faults_obeyed += 1;
        match f.kind {
            FaultKind::Panic => panic!("injected fault: panic"),
            FaultKind::Delay => {
                let end = if f.count > 0 {
                    DelayEnd::After(f.count)
                } else {
                    DelayEnd::At(
                        std::time::Instant::now()
                            + std::time::Duration::from_millis(u64::from(f.duration_ms)),
                    )
                };
                self.slowed = 0;
                self.delay = Some((std::time::Duration::from_millis(u64::from(f.delay_ms)), end));
            }
            FaultKind::Drop | FaultKind::Corrupt => self.output_faults.push(f),
            FaultKind::Kill | FaultKind::Stop => {}
        }
    }

    /// An injected delay, before a message is processed (nothing without one). A service
    /// slowed this way still beats on time (with the counters of its last heartbeat): slow is
    /// not hung.
    pub fn pace(&mut self) -> Result<()> {
        let Some((d, end)) = self.delay.as_mut() else {
            return Ok(());
        };
        let over = match end {
            DelayEnd::At(t) => std::time::Instant::now() >= *t,
            DelayEnd::After(0) => true,
            DelayEnd::After(n) => {
                *n -= 1;
                false
            }
        };
        if over {
            self.end_delay("its time or count ran out");
            return Ok(());
        }
        std::thread::sleep(*d);
        self.slowed += 1;
        // The last input of a delay by inputs: over now, not at the next message.
        if matches!(self.delay, Some((_, DelayEnd::After(0)))) {
            self.end_delay("its count ran out");
        }
        self.beat_if_due()
    }

    /// Ends the delay, and logs how many inputs it slowed (what shows it took effect).
    fn end_delay(&mut self, why: &str) {
        if let Some((d, _)) = self.delay.take() {
            tracing::info!(
                slowed = self.slowed,
                delay_ms = d.as_millis() as u64,
                "delay over ({why}): {} inputs slowed",
                self.slowed
            );
        }
        self.slowed = 0;
    }

    /// The run is over (`Shutdown`): no input is left to slow, so a delay counted in inputs is
    /// over — its order may have landed with fewer inputs left than it counts (sim-clock
    /// producers run ahead of the orders by up to their credit window, more on a faster host).
    /// A delay by time that outlasts the run is still on.
    pub fn inputs_ended(&mut self) {
        if matches!(self.delay, Some((_, DelayEnd::After(_)))) {
            self.end_delay("the run's inputs ended first");
        }
    }

    /// Repeats the last heartbeat's counters when a heartbeat is due: a service working
    /// through a burst of inputs, or slowed, still beats on time (busy is not hung).
    pub fn beat_if_due(&mut self) -> Result<()> {
        if let Some((at, topics)) = self.last_beat {
            if at.elapsed() >= self.heartbeat_period {
                self.send_beat(0, topics)?;
            }
        }
        Ok(())
    }

    /// For a service blocked outside its loop (a call being retried): obeys control (`Start`
    /// marks it running), sends a heartbeat with its last counters when one is due; `false`
    /// once `Shutdown` arrived.
    pub fn keepalive(&mut self) -> Result<bool> {
        if self.poll_control()?.contains(&Command::Start) && self.state == Heartbeat::READY {
            self.state = Heartbeat::RUNNING;
        }
        self.beat_if_due()?;
        Ok(!self.shutdown_requested)
    }

    /// Drop and corrupt orders to arm on this service's output.
    pub fn take_output_faults(&mut self) -> Vec<InBandFault> {
        std::mem::take(&mut self.output_faults)
    }

    /// The continue orders since the last call: (topic, next_seq, received).
    pub fn take_continues(&mut self) -> Vec<(TopicId, u64, u64)> {
        std::mem::take(&mut self.continues)
    }

    /// The stream ends ordered since the last call: (topic, messages).
    pub fn take_ends(&mut self) -> Vec<(TopicId, u64)> {
        std::mem::take(&mut self.ends)
    }

    /// The replays ordered since the last call (a consumer of this service's output restarted).
    pub fn take_replays(&mut self) -> Vec<Replay> {
        std::mem::take(&mut self.replays)
    }

    /// Publishes a heartbeat carrying `stats` (at most [`MAX_TOPICS`] topics).
    pub fn beat(&mut self, t_ns: u64, stats: &[&TopicStats]) -> Result<()> {
        let mut topics = [TopicCounters {
            topic: u32::MAX,
            ..Default::default()
        }; MAX_TOPICS];
        for (slot, s) in topics.iter_mut().zip(stats.iter()) {
            *slot = s.counters();
        }
        self.send_beat(t_ns, topics)?;
        // Acks again with every heartbeat: a restarted producer learns where its consumers are.
        for (topic, next_seq, checkpoint_seq) in self.acked.clone() {
            self.send_ack(topic, next_seq, checkpoint_seq, t_ns)?;
        }
        Ok(())
    }

    fn send_beat(&mut self, t_ns: u64, topics: [TopicCounters; MAX_TOPICS]) -> Result<()> {
        self.last_beat = Some((std::time::Instant::now(), topics));
        let hb = Heartbeat {
            pid: std::process::id(),
            state: self.state,
            last_latency_ns: self.last_latency_ns,
            topics,
            time: self.time,
            faults_obeyed: self.faults_obeyed,
            faults_refused: self.faults_refused,
            delaying: u32::from(self.delay.is_some() || self.delaying_elsewhere),
            ..Default::default()
        };
        self.heartbeat.send(hb, t_ns)?;
        tracing::trace!(state = self.state, "heartbeat");
        Ok(())
    }

    /// Acknowledges everything below `next_seq` on `topic`, and that everything below
    /// `checkpoint_seq` is in this service's checkpoint (its producer need not keep it to
    /// replay); sent only when either advanced.
    pub fn ack(
        &mut self,
        topic: TopicId,
        next_seq: u64,
        checkpoint_seq: u64,
        t_ns: u64,
    ) -> Result<()> {
        let prev = self.acked.iter_mut().find(|(t, _, _)| *t == topic);
        match prev {
            Some((_, n, c)) if *n >= next_seq && *c >= checkpoint_seq => return Ok(()),
            Some((_, n, c)) => {
                *n = (*n).max(next_seq);
                *c = (*c).max(checkpoint_seq);
            }
            None => self.acked.push((topic, next_seq, checkpoint_seq)),
        }
        self.send_ack(topic, next_seq, checkpoint_seq, t_ns)
    }

    fn send_ack(
        &mut self,
        topic: TopicId,
        next_seq: u64,
        checkpoint_seq: u64,
        t_ns: u64,
    ) -> Result<()> {
        let ack = Ack {
            topic: topic as u32,
            consumer: self.id as u32,
            next_seq,
            checkpoint_seq,
            ..Default::default()
        };
        self.acks.send(ack, t_ns)?;
        Ok(())
    }
}
