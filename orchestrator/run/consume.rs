//! The orchestrator as a consumer: it reads the heartbeats of every service and taps every
//! data topic its row of the table lists ([`crate::run::taps`]): accounting, digests, and what the
//! report scores. It acknowledges what it took (the producers' sim-clock credit) and sends the
//! control messages.

use std::collections::BTreeMap;
use std::time::Instant;

use anyhow::Result;
use glint_runtime::ports::{Inbox, Outbox};
use glint_runtime::TopicStats;
use iceoryx2::port::listener::Listener;
use shared_types::scenario::FaultKind;
use shared_types::table::Count;
use shared_types::topics::{Ipc, IpcNode};
use shared_types::{
    deployment, Ack, Command, Control, DropReason, Heartbeat, InBandFault, Replay, Scenario,
    ServiceId, TopicCounters, TopicId,
};

use crate::run::taps::{Fold, Taps};

/// The last heartbeat of a service and when it arrived.
pub struct Seen {
    pub heartbeat: Heartbeat,
    pub at: Instant,
}

pub struct Consumer {
    pub taps: Taps,
    heartbeats: Inbox<Heartbeat>,
    control: Outbox<Control>,
    acks: Outbox<Ack>,
    pub seen: BTreeMap<ServiceId, Seen>,
    /// Messages on each consumed topic the run must account for.
    pub expected: BTreeMap<TopicId, u64>,
    acked: BTreeMap<TopicId, u64>,
}

impl Consumer {
    /// Opens the heartbeats, control, acks and a tap per consumed topic; `snapshots`: the
    /// frame of a frame topic whose pixels the report draws; `folds`: the report sections'
    /// folds the taps hand every message to. The listeners to wait on: heartbeats first, then
    /// the taps'.
    pub fn open(
        node: &IpcNode,
        scenario: &Scenario,
        snapshots: &[(TopicId, u64)],
        folds: Vec<Box<dyn Fold>>,
    ) -> Result<(Self, Vec<Listener<Ipc>>)> {
        let me = ServiceId::Orchestrator;
        let (mut heartbeats, hb_l) = Inbox::open(node, TopicId::Heartbeat)?;
        // A restarted service's heartbeats start again at seq 0.
        heartbeats.stats.peers_restart();
        let mut listeners = vec![hb_l];
        let mut taps = Taps::new(folds);
        let mut expected = BTreeMap::new();
        for t in deployment::inputs(scenario, me) {
            let want = snapshots.iter().find(|(s, _)| *s == t).map(|(_, k)| *k);
            let (tap, l) = crate::run::taps::open(node, scenario, t, want)?;
            taps.insert(t, tap);
            listeners.push(l);
            expected.insert(t, deployment::expected_messages(scenario, t));
        }
        let control = Outbox::open(node, TopicId::Control, me)?;
        let acks = Outbox::open(node, TopicId::Ack, me)?;
        Ok((
            Consumer {
                taps,
                heartbeats,
                control,
                acks,
                seen: BTreeMap::new(),
                expected,
                acked: BTreeMap::new(),
            },
            listeners,
        ))
    }

    /// Orders `producer` to send a topic again to a restarted consumer.
    pub fn replay(&mut self, producer: ServiceId, order: Replay) -> Result<()> {
        self.control.send(Control::replay(producer, order), 0)?;
        Ok(())
    }

    /// Orders `service`, restarted in realtime mode, to continue `topic`'s accounting at
    /// `next_seq` (`received` of them processed, on an input).
    pub fn continue_at(
        &mut self,
        service: ServiceId,
        topic: TopicId,
        next_seq: u64,
        received: u64,
    ) -> Result<()> {
        let order = Control::continue_at(service, topic, next_seq, received);
        self.control.send(order, 0)?;
        Ok(())
    }

    /// Orders `producer` to end `topic` after `messages` (a soak's end).
    pub fn end_stream(&mut self, producer: ServiceId, topic: TopicId, messages: u64) -> Result<()> {
        self.control
            .send(Control::end(producer, topic, messages), 0)?;
        Ok(())
    }

    /// What the run must account for, from `scenario` (a soak's, once its stream was ended).
    pub fn expect(&mut self, scenario: &Scenario) {
        for (topic, n) in self.expected.iter_mut() {
            *n = deployment::expected_messages(scenario, *topic);
        }
    }

    /// Sends an in-band fault command to `service`.
    pub fn order_fault(&mut self, service: ServiceId, f: InBandFault) -> Result<()> {
        self.control.send(Control::fault(service, f), 0)?;
        Ok(())
    }

    /// Outputs of `topic` its producer reported dropping (`Drop`) or sending invalid
    /// (`Corrupt`) on purpose, and how many of them the orchestrator, a consumer of `topic`,
    /// counted (as sequence gaps, or as `malformed`): (made, counted).
    pub fn tampered(&self, topic: TopicId, kind: FaultKind) -> (u64, u64) {
        let (theirs, ours) = match kind {
            FaultKind::Drop => (DropReason::Injected, DropReason::Overflow),
            _ => (DropReason::Malformed, DropReason::Malformed),
        };
        let made = deployment::producer(topic)
            .and_then(|p| self.reported(p, topic))
            .map_or(0, |c| c.dropped[theirs as usize]);
        let seen = self
            .own_stats()
            .iter()
            .find(|s| s.topic == topic)
            .map_or(0, |s| s.dropped[ours as usize]);
        (made, seen)
    }

    /// Whether the orchestrator has counted every output the producer of `topic` reported
    /// tampering with since `base` ([`Consumer::tampered`] when the fault was injected).
    pub fn counted(&self, topic: TopicId, kind: FaultKind, base: (u64, u64)) -> bool {
        let (made, seen) = self.tampered(topic, kind);
        let made = made.saturating_sub(base.0);
        made > 0 && seen.saturating_sub(base.1) >= made
    }

    /// Acknowledges again everything acknowledged so far: a restarted producer learns where
    /// the orchestrator is (its credit).
    pub fn refresh_acks(&mut self) -> Result<()> {
        for (topic, next_seq) in self.acked.clone() {
            self.send_ack(topic, next_seq)?;
        }
        Ok(())
    }

    pub fn command(&mut self, command: Command, target: u32) -> Result<()> {
        let c = Control {
            command: command as u32,
            target,
            ..Default::default()
        };
        self.control.send(c, 0)?;
        Ok(())
    }

    /// Reads every input, accounts for it, and acknowledges it (the producers' credit).
    pub fn poll(&mut self) -> Result<()> {
        self.poll_heartbeats()?;
        for (topic, next) in self.taps.poll()? {
            self.ack(topic, next)?;
        }
        Ok(())
    }

    pub fn poll_heartbeats(&mut self) -> Result<()> {
        let (seen, taps) = (&mut self.seen, &mut self.taps);
        self.heartbeats.drain(|r| {
            taps.record_message(TopicId::Heartbeat, r.msg);
            if let Some(id) = ServiceId::from_u32(r.msg.meta.producer) {
                if !seen.contains_key(&id) {
                    tracing::debug!(service = id.name(), state = r.msg.state, "first heartbeat");
                }
                seen.insert(
                    id,
                    Seen {
                        heartbeat: *r.msg,
                        at: Instant::now(),
                    },
                );
            }
            Ok(())
        })?;
        Ok(())
    }

    fn ack(&mut self, topic: TopicId, next_seq: u64) -> Result<()> {
        // Send only when something new arrived.
        if self.acked.get(&topic) == Some(&next_seq) {
            return Ok(());
        }
        self.acked.insert(topic, next_seq);
        self.send_ack(topic, next_seq)
    }

    fn send_ack(&mut self, topic: TopicId, next_seq: u64) -> Result<()> {
        // The orchestrator is never restarted: nothing it took is ever replayed to it.
        let a = Ack {
            topic: topic as u32,
            consumer: ServiceId::Orchestrator as u32,
            next_seq,
            checkpoint_seq: next_seq,
            ..Default::default()
        };
        self.acks.send(a, 0)?;
        Ok(())
    }

    /// Own statistics per consumed topic.
    pub fn own_stats(&self) -> Vec<&TopicStats> {
        self.taps.iter().map(|(_, t)| t.stats()).collect()
    }

    /// True once every expected message of every consumed topic is accounted for.
    pub fn complete(&self) -> bool {
        self.own_stats()
            .iter()
            .all(|s| s.next_seq >= self.expected_now(s.topic))
    }

    /// Messages of `topic` the run will carry: the scenario's count, less what the services
    /// upstream of it dropped with a counted reason (a detector publishes one message per frame
    /// it processed; a dropped or malformed frame makes none).
    pub fn expected_now(&self, topic: TopicId) -> u64 {
        let want = self.expected.get(&topic).copied().unwrap_or(0);
        match topic.spec().count {
            Count::PerInput(input) => {
                let upstream = self.expected_now(input).min(want);
                let dropped = deployment::producer(topic)
                    .and_then(|p| self.reported(p, input))
                    .map_or(0, |c| c.dropped.iter().sum::<u64>());
                upstream.saturating_sub(dropped)
            }
            Count::Stream { .. } | Count::Truth | Count::Open => want,
        }
    }

    /// How many messages of `topic` the orchestrator has taken so far (0 if it does not
    /// consume it).
    pub fn carried(&self, topic: TopicId) -> u64 {
        self.own_stats()
            .iter()
            .find(|s| s.topic == topic)
            .map_or(0, |s| s.next_seq)
    }

    /// (accepted, expected) over all consumed topics, for progress display.
    pub fn progress(&self) -> (u64, u64) {
        let done: u64 = self.own_stats().iter().map(|s| s.next_seq).sum();
        let want: u64 = self.expected.values().sum();
        (done, want)
    }

    pub fn digests(&self) -> BTreeMap<TopicId, u64> {
        self.taps
            .iter()
            .map(|(t, tap)| (*t, tap.digest()))
            .collect()
    }

    /// Counters a service reported for a topic in its last heartbeat.
    pub fn reported(&self, id: ServiceId, topic: TopicId) -> Option<TopicCounters> {
        self.seen.get(&id).and_then(|s| {
            s.heartbeat
                .topics
                .iter()
                .find(|c| c.topic == topic as u32)
                .copied()
        })
    }
}
