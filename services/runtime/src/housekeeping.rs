//! What every service does besides its own work: obey `control`, publish heartbeats with its
//! counters, and acknowledge what it consumed (the sim-clock credit its producers wait for).

use anyhow::Result;
use iceoryx2::port::listener::Listener;
use shared_types::topics::{ack_service, control_service, heartbeat_service, Ipc, IpcNode};
use shared_types::{
    Ack, Command, Control, Heartbeat, ServiceId, TopicCounters, TopicId, MAX_TOPICS,
};

use crate::ports::{Inbox, Outbox};
use crate::stats::TopicStats;

pub struct Housekeeping {
    pub id: ServiceId,
    heartbeat: Outbox<Heartbeat>,
    control: Inbox<Control>,
    acks: Outbox<Ack>,
    acked: Vec<(TopicId, u64)>,
    /// Heartbeat state (`Heartbeat::STARTING` …).
    pub state: u32,
    /// Last end-to-end latency seen by this service [ns].
    pub last_latency_ns: u64,
}

impl Housekeeping {
    /// Opens the housekeeping ports; the returned listener wakes the loop on control messages.
    pub fn open(node: &IpcNode, id: ServiceId) -> Result<(Self, Listener<Ipc>)> {
        let heartbeat = Outbox::open(node, TopicId::Heartbeat, &heartbeat_service(node)?, id)?;
        let (control, listener) = Inbox::open(node, TopicId::Control, &control_service(node)?)?;
        let acks = Outbox::open(node, TopicId::Ack, &ack_service(node)?, id)?;
        Ok((
            Housekeeping {
                id,
                heartbeat,
                control,
                acks,
                acked: vec![],
                state: Heartbeat::STARTING,
                last_latency_ns: 0,
            },
            listener,
        ))
    }

    /// Commands addressed to this service (or to all) since the last call.
    pub fn poll_control(&mut self) -> Result<Vec<Command>> {
        let me = self.id as u32;
        let mut cmds = vec![];
        self.control.drain(|r| {
            if r.msg.target == me || r.msg.target == Control::ALL {
                if let Some(c) = Command::from_u32(r.msg.command) {
                    cmds.push(c);
                }
            }
            Ok(())
        })?;
        Ok(cmds)
    }

    /// The control handling of a consuming service: `Start` marks it running; `Shutdown` sends a
    /// last heartbeat with `stats` and returns `true` (leave the loop). Other commands are for
    /// producers and are ignored here.
    pub fn obey(&mut self, stats: &[&TopicStats]) -> Result<bool> {
        for cmd in self.poll_control()? {
            match cmd {
                Command::Start => self.state = Heartbeat::RUNNING,
                Command::Shutdown => {
                    self.state = Heartbeat::STOPPING;
                    self.beat(0, stats)?;
                    return Ok(true);
                }
                _ => {}
            }
        }
        Ok(false)
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
        let hb = Heartbeat {
            pid: std::process::id(),
            state: self.state,
            last_latency_ns: self.last_latency_ns,
            topics,
            ..Default::default()
        };
        self.heartbeat.send(hb, t_ns)?;
        tracing::trace!(state = self.state, "heartbeat");
        Ok(())
    }

    /// Acknowledges everything below `next_seq` on `topic` (sent only when it advanced).
    pub fn ack(&mut self, topic: TopicId, next_seq: u64, t_ns: u64) -> Result<()> {
        let prev = self.acked.iter_mut().find(|(t, _)| *t == topic);
        match prev {
            Some((_, n)) if *n >= next_seq => return Ok(()),
            Some((_, n)) => *n = next_seq,
            None => self.acked.push((topic, next_seq)),
        }
        let ack = Ack {
            topic: topic as u32,
            consumer: self.id as u32,
            next_seq,
            ..Default::default()
        };
        self.acks.send(ack, t_ns)?;
        Ok(())
    }
}
