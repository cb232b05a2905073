//! Liveness, accounting and control: heartbeats, acknowledgements, control commands.

use iceoryx2::prelude::ZeroCopySend;

use super::*;

/// Reasons a consumer drops a message; index into [`Heartbeat::dropped`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(usize)]
pub enum DropReason {
    /// A sequence gap: the transport overwrote samples the consumer had not read (realtime mode).
    Overflow = 0,
    /// The message failed validation.
    Malformed = 1,
    /// Dropped on purpose by an injected fault.
    Injected = 2,
    /// Arrived after its deadline.
    Late = 3,
    /// Duplicate or out-of-order sequence number.
    Stale = 4,
}

impl DropReason {
    pub const ALL: [DropReason; 5] = [
        DropReason::Overflow,
        DropReason::Malformed,
        DropReason::Injected,
        DropReason::Late,
        DropReason::Stale,
    ];

    pub fn name(self) -> &'static str {
        match self {
            DropReason::Overflow => "overflow",
            DropReason::Malformed => "malformed",
            DropReason::Injected => "injected",
            DropReason::Late => "late",
            DropReason::Stale => "stale",
        }
    }
}

/// Per-topic counters of one consumer, carried in a [`Heartbeat`].
#[derive(
    Debug, Default, Clone, Copy, PartialEq, Eq, ZeroCopySend, bytemuck::Pod, bytemuck::Zeroable,
)]
#[type_name("glint.v2.TopicCounters")]
#[repr(C)]
pub struct TopicCounters {
    /// [`crate::TopicId`] as u32, or `u32::MAX` for an unused slot.
    pub topic: u32,
    /// Copies of messages already accounted for (a producer replaying after a consumer's
    /// restart): skipped, neither received nor dropped.
    pub duplicates: u32,
    /// Messages published (producer side) on this topic.
    pub published: u64,
    /// Messages received and accepted.
    pub received: u64,
    /// Messages dropped, by [`DropReason`].
    pub dropped: [u64; DROP_REASONS],
    /// Highest sequence number seen + 1 (0 = none yet).
    pub next_seq: u64,
}

/// Periodic liveness and counters of a service.
#[derive(
    Debug, Default, Clone, Copy, PartialEq, Eq, ZeroCopySend, bytemuck::Pod, bytemuck::Zeroable,
)]
#[type_name("glint.v2.Heartbeat")]
#[repr(C)]
pub struct Heartbeat {
    pub meta: Meta,
    pub pid: u32,
    /// 0 = starting, 1 = ready, 2 = running, 3 = finished (producer done), 4 = stopping.
    pub state: u32,
    /// Last end-to-end latency observed by this service [ns] (send → processed).
    pub last_latency_ns: u64,
    pub topics: [TopicCounters; MAX_TOPICS],
}

impl Heartbeat {
    pub const STARTING: u32 = 0;
    pub const READY: u32 = 1;
    pub const RUNNING: u32 = 2;
    pub const FINISHED: u32 = 3;
    pub const STOPPING: u32 = 4;

    pub fn validate(&self) -> Result<(), Reject> {
        self.meta.validate()?;
        if self.state > Self::STOPPING {
            return Err(Reject::new("heartbeat.state", "out of range 0..=4"));
        }
        Ok(())
    }
}

/// Per-message acknowledgement from a consumer to a producer: credit for lockstep flow control
/// in sim-clock mode (the producer never has more than the subscriber buffer in flight).
#[derive(
    Debug, Default, Clone, Copy, PartialEq, Eq, ZeroCopySend, bytemuck::Pod, bytemuck::Zeroable,
)]
#[type_name("glint.v2.Ack")]
#[repr(C)]
pub struct Ack {
    pub meta: Meta,
    /// Topic acknowledged ([`crate::TopicId`] as u32).
    pub topic: u32,
    /// Consumer ([`crate::ServiceId`] as u32).
    pub consumer: u32,
    /// Every message with `seq < next_seq` has been processed or counted as dropped.
    pub next_seq: u64,
}

/// Orchestrator → services commands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum Command {
    /// Stop gracefully: finish the current message, publish a last heartbeat, exit 0.
    Shutdown = 1,
    /// Stop producing until `Resume` (sensor).
    Pause = 2,
    Resume = 3,
    /// Start producing (sensor): sent once every consumer is ready.
    Start = 4,
    /// Send a topic again from a seq on, to a consumer that restarted (`arg`: see
    /// [`Control::replay`]).
    Replay = 5,
}

impl Command {
    pub fn from_u32(v: u32) -> Option<Self> {
        match v {
            1 => Some(Command::Shutdown),
            2 => Some(Command::Pause),
            3 => Some(Command::Resume),
            4 => Some(Command::Start),
            5 => Some(Command::Replay),
            _ => None,
        }
    }
}

/// A control message; `target` is a [`crate::ServiceId`] as u32 or [`Control::ALL`].
#[derive(
    Debug, Default, Clone, Copy, PartialEq, Eq, ZeroCopySend, bytemuck::Pod, bytemuck::Zeroable,
)]
#[type_name("glint.v2.Control")]
#[repr(C)]
pub struct Control {
    pub meta: Meta,
    pub command: u32,
    pub target: u32,
    pub arg: [u64; 2],
}

/// A [`Command::Replay`]: the producer sends `topic` again from `from_seq` on, and counts the
/// consumer's credit from there.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Replay {
    pub consumer: crate::ServiceId,
    pub topic: crate::TopicId,
    pub from_seq: u64,
}

impl Control {
    pub const ALL: u32 = u32::MAX;

    /// The replay order to `producer` for a restarted consumer.
    pub fn replay(producer: crate::ServiceId, r: Replay) -> Control {
        Control {
            command: Command::Replay as u32,
            target: producer as u32,
            arg: [
                u64::from(r.consumer as u32) | (u64::from(r.topic as u32) << 32),
                r.from_seq,
            ],
            ..Default::default()
        }
    }

    /// The replay this message orders, if it is a well-formed [`Command::Replay`].
    pub fn as_replay(&self) -> Option<Replay> {
        if self.command != Command::Replay as u32 {
            return None;
        }
        Some(Replay {
            consumer: crate::ServiceId::from_u32(self.arg[0] as u32)?,
            topic: crate::TopicId::from_u32((self.arg[0] >> 32) as u32)?,
            from_seq: self.arg[1],
        })
    }

    pub fn validate(&self) -> Result<(), Reject> {
        self.meta.validate()?;
        if Command::from_u32(self.command).is_none() {
            return Err(Reject::new("control.command", "unknown command"));
        }
        if self.command == Command::Replay as u32 && self.as_replay().is_none() {
            return Err(Reject::new(
                "control.arg",
                "replay of an unknown consumer or topic",
            ));
        }
        Ok(())
    }
}
