//! Liveness, accounting and control: heartbeats, acknowledgements, control commands.

use iceoryx2::prelude::ZeroCopySend;

use super::*;

/// Reasons a consumer drops a message; index into [`Heartbeat::dropped`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(usize)]
pub enum DropReason {
    /// A sequence gap (realtime mode): the transport overwrote samples the consumer had not
    /// read; at a source, messages that came due while it was down and were never made.
    Overflow = 0,
    /// The message failed validation.
    Malformed = 1,
    /// Dropped on purpose by an injected fault.
    Injected = 2,
    /// Arrived after its deadline.
    Late = 3,
    /// Duplicate or out-of-order sequence number.
    Stale = 4,
    /// Lost on a link between hosts: a gap in a bridge's link sequence.
    Link = 5,
}

impl DropReason {
    pub const ALL: [DropReason; 6] = [
        DropReason::Overflow,
        DropReason::Malformed,
        DropReason::Injected,
        DropReason::Late,
        DropReason::Stale,
        DropReason::Link,
    ];

    pub fn name(self) -> &'static str {
        match self {
            DropReason::Overflow => "overflow",
            DropReason::Malformed => "malformed",
            DropReason::Injected => "injected",
            DropReason::Late => "late",
            DropReason::Stale => "stale",
            DropReason::Link => "link",
        }
    }
}

/// Per-topic counters of one consumer, carried in a [`Heartbeat`].
#[derive(
    Debug, Default, Clone, Copy, PartialEq, Eq, ZeroCopySend, bytemuck::Pod, bytemuck::Zeroable,
)]
#[type_name("glint.v8.TopicCounters")]
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

/// Where a service's wall-clock time went since its process started (cumulative, ns). The
/// first three add up to the time since start; the others are parts of `busy_ns`.
#[derive(
    Debug, Default, Clone, Copy, PartialEq, Eq, ZeroCopySend, bytemuck::Pod, bytemuck::Zeroable,
)]
#[type_name("glint.v8.ServiceTime")]
#[repr(C)]
pub struct ServiceTime {
    /// Handling wake-ups: its own work, checksums, publishing, waiting for RPC answers.
    pub busy_ns: u64,
    /// Asleep with an output's credit used up: held back by a consumer (sim clock).
    pub credit_wait_ns: u64,
    /// Asleep otherwise: waiting for input, for its clock, or for the run to end.
    pub idle_ns: u64,
    /// Of busy: loaning and sending messages (a frame's render into its loan excluded).
    pub publish_ns: u64,
    /// Of busy: frame checksums, computed before sending or verified on receipt.
    pub checksum_ns: u64,
    /// Of busy: waiting for RPC answers (the tracker's laser round trips).
    pub rpc_wait_ns: u64,
}

/// Periodic liveness and counters of a service.
#[derive(
    Debug, Default, Clone, Copy, PartialEq, Eq, ZeroCopySend, bytemuck::Pod, bytemuck::Zeroable,
)]
#[type_name("glint.v8.Heartbeat")]
#[repr(C)]
pub struct Heartbeat {
    pub meta: Meta,
    pub pid: u32,
    /// 0 = starting, 1 = ready, 2 = running, 3 = finished (producer done), 4 = stopping.
    pub state: u32,
    /// Last end-to-end latency observed by this service [ns] (send → processed).
    pub last_latency_ns: u64,
    pub topics: [TopicCounters; MAX_TOPICS],
    /// Where its time went so far.
    pub time: ServiceTime,
    /// In-band fault orders (`panic`, `delay`, `drop`, `corrupt`) this process obeyed.
    pub faults_obeyed: u32,
    /// In-band fault orders it refused (`faults.enabled` false).
    pub faults_refused: u32,
    /// 1 while an injected delay slows it, else 0.
    pub delaying: u32,
    pub _reserved: u32,
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
        if self.delaying > 1 {
            return Err(Reject::new("heartbeat.delaying", "out of range 0..=1"));
        }
        Ok(())
    }
}

/// Per-message acknowledgement from a consumer to a producer: credit for lockstep flow control
/// in sim-clock mode (the producer never has more than the subscriber buffer in flight).
#[derive(
    Debug, Default, Clone, Copy, PartialEq, Eq, ZeroCopySend, bytemuck::Pod, bytemuck::Zeroable,
)]
#[type_name("glint.v8.Ack")]
#[repr(C)]
pub struct Ack {
    pub meta: Meta,
    /// Topic acknowledged ([`crate::TopicId`] as u32).
    pub topic: u32,
    /// Consumer ([`crate::ServiceId`] as u32).
    pub consumer: u32,
    /// Every message with `seq < next_seq` has been processed or counted as dropped.
    pub next_seq: u64,
    /// Every message with `seq < checkpoint_seq` is in the consumer's checkpoint: a replay to
    /// it never starts below, so its producer may forget them (a kept log stays bounded).
    pub checkpoint_seq: u64,
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
    /// An in-band fault (`arg`: see [`Control::fault`]); obeyed only where the scenario sets
    /// `faults.enabled = true`.
    Fault = 6,
    /// End a stream early (the producer): a soak's end (`arg`: see [`Control::end`]).
    End = 7,
    /// A service restarted in realtime mode (nothing is replayed to it) continues a topic's
    /// accounting where its last incarnation left it (`arg`: see [`Control::continue_at`]).
    Continue = 8,
}

impl Command {
    pub fn from_u32(v: u32) -> Option<Self> {
        match v {
            1 => Some(Command::Shutdown),
            2 => Some(Command::Pause),
            3 => Some(Command::Resume),
            4 => Some(Command::Start),
            5 => Some(Command::Replay),
            6 => Some(Command::Fault),
            7 => Some(Command::End),
            8 => Some(Command::Continue),
            _ => None,
        }
    }
}

/// A control message; `target` is a [`crate::ServiceId`] as u32 or [`Control::ALL`].
#[derive(
    Debug, Default, Clone, Copy, PartialEq, Eq, ZeroCopySend, bytemuck::Pod, bytemuck::Zeroable,
)]
#[type_name("glint.v8.Control")]
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

/// An in-band fault order ([`Command::Fault`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct InBandFault {
    /// `panic`, `delay`, `drop` or `corrupt`.
    pub kind: crate::scenario::FaultKind,
    pub how: crate::scenario::Corruption,
    /// Outputs dropped or corrupted.
    pub count: u32,
    /// Drop every this many-th output.
    pub every: u16,
    pub delay_ms: u32,
    /// A delay by time [ms]; 0 with a delay by inputs (`count`).
    pub duration_ms: u32,
}

impl InBandFault {
    /// The order for a fault of the scenario.
    pub fn of(spec: &crate::scenario::FaultSpec) -> InBandFault {
        InBandFault {
            kind: spec.kind,
            how: spec.how.unwrap_or_default(),
            // A delay's count is the inputs it slows (0: it lasts `duration_ms`).
            count: spec.count.unwrap_or(match spec.kind {
                crate::scenario::FaultKind::Delay => 0,
                _ => 1,
            }),
            every: spec.every.unwrap_or(1).min(u32::from(u16::MAX)) as u16,
            delay_ms: spec.delay_ms.unwrap_or(0).min(u64::from(u32::MAX)) as u32,
            duration_ms: (spec.duration_s.unwrap_or(0.0) * 1e3).round() as u32,
        }
    }
}

impl Control {
    pub const ALL: u32 = u32::MAX;

    /// The in-band fault order to `service`.
    pub fn fault(service: crate::ServiceId, f: InBandFault) -> Control {
        Control {
            command: Command::Fault as u32,
            target: service as u32,
            arg: [
                u64::from(f.kind.code())
                    | (u64::from(f.how.code()) << 8)
                    | (u64::from(f.every) << 16)
                    | (u64::from(f.count) << 32),
                u64::from(f.delay_ms) | (u64::from(f.duration_ms) << 32),
            ],
            ..Default::default()
        }
    }

    /// The in-band fault this message orders, if it is a well-formed [`Command::Fault`].
    pub fn as_fault(&self) -> Option<InBandFault> {
        if self.command != Command::Fault as u32 {
            return None;
        }
        let kind = crate::scenario::FaultKind::from_code(self.arg[0] as u8)?;
        Some(InBandFault {
            kind: kind.in_band().then_some(kind)?,
            how: crate::scenario::Corruption::from_code((self.arg[0] >> 8) as u8)?,
            every: ((self.arg[0] >> 16) as u16).max(1),
            count: (self.arg[0] >> 32) as u32,
            delay_ms: self.arg[1] as u32,
            duration_ms: (self.arg[1] >> 32) as u32,
        })
    }

    /// The order to `producer` to end `topic` after `messages` messages (or where it is, if
    /// it has already sent more).
    pub fn end(producer: crate::ServiceId, topic: crate::TopicId, messages: u64) -> Control {
        Control {
            command: Command::End as u32,
            target: producer as u32,
            arg: [u64::from(topic as u32), messages],
            ..Default::default()
        }
    }

    /// The (topic, messages) this message ends, if it is a well-formed [`Command::End`].
    pub fn as_end(&self) -> Option<(crate::TopicId, u64)> {
        if self.command != Command::End as u32 {
            return None;
        }
        let topic = crate::TopicId::from_u32(u32::try_from(self.arg[0]).ok()?)?;
        Some((topic, self.arg[1]))
    }

    /// The order to a service restarted in realtime mode: its input `topic` continues at
    /// `next_seq`, of which its last incarnation processed `received` (the rest it dropped);
    /// or its output `topic` continues at `next_seq` (`received` = `next_seq`).
    pub fn continue_at(
        service: crate::ServiceId,
        topic: crate::TopicId,
        next_seq: u64,
        received: u64,
    ) -> Control {
        Control {
            command: Command::Continue as u32,
            target: service as u32,
            arg: [
                (u64::from(topic as u32) << 56) | (next_seq & ((1 << 56) - 1)),
                received,
            ],
            ..Default::default()
        }
    }

    /// (topic, next_seq, received), if this is a well-formed [`Command::Continue`].
    pub fn as_continue(&self) -> Option<(crate::TopicId, u64, u64)> {
        if self.command != Command::Continue as u32 {
            return None;
        }
        let topic = crate::TopicId::from_u32((self.arg[0] >> 56) as u32)?;
        let next_seq = self.arg[0] & ((1 << 56) - 1);
        (self.arg[1] <= next_seq).then_some((topic, next_seq, self.arg[1]))
    }

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
        if self.command == Command::Fault as u32 && self.as_fault().is_none() {
            return Err(Reject::new("control.arg", "an unknown in-band fault"));
        }
        if self.command == Command::End as u32 && self.as_end().is_none() {
            return Err(Reject::new("control.arg", "the end of an unknown topic"));
        }
        if self.command == Command::Continue as u32 && self.as_continue().is_none() {
            return Err(Reject::new(
                "control.arg",
                "an unknown topic, or more received than its next seq",
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::{Corruption, FaultKind, FaultSpec};
    use crate::{ServiceId, TopicId};

    #[test]
    fn replay_and_fault_orders_survive_the_wire() {
        let r = Replay {
            consumer: ServiceId::Tracker,
            topic: TopicId::Detections,
            from_seq: 17,
        };
        let mut c = Control::replay(ServiceId::Detector, r);
        assert_eq!(c.as_replay(), Some(r));
        c.meta.contract_version = crate::CONTRACT_VERSION; // what the outbox stamps
        assert!(c.validate().is_ok());
        let spec = FaultSpec::parse("detector:drop@10,count=3,every=2").unwrap();
        let f = InBandFault::of(&spec);
        let c = Control::fault(ServiceId::Detector, f);
        assert_eq!(c.as_fault(), Some(f));
        assert_eq!((f.count, f.every), (3, 2));
        let spec = FaultSpec::parse("tracker:corrupt@1,how=nan").unwrap();
        assert_eq!(InBandFault::of(&spec).how, Corruption::Nan);
        // A signal fault is not an in-band order; garbage is rejected, not trusted.
        let mut bad = Control::fault(ServiceId::Detector, f);
        bad.arg[0] = (bad.arg[0] & !0xff) | FaultKind::Kill.code() as u64;
        assert_eq!(bad.as_fault(), None);
        bad.meta.contract_version = crate::CONTRACT_VERSION;
        assert!(bad.validate().is_err());
        // An end order names its topic and count; an unknown topic is rejected.
        let mut end = Control::end(ServiceId::Sensor, TopicId::Frame, 12_345);
        assert_eq!(end.as_end(), Some((TopicId::Frame, 12_345)));
        end.meta.contract_version = crate::CONTRACT_VERSION;
        assert!(end.validate().is_ok());
        end.arg[0] = u64::from(u32::MAX);
        assert_eq!(end.as_end(), None);
        assert!(end.validate().is_err());
        // A continue order: where the restarted service's accounting of a topic resumes.
        let mut c = Control::continue_at(ServiceId::Detector, TopicId::Frame, 1_234, 1_200);
        assert_eq!(c.as_continue(), Some((TopicId::Frame, 1_234, 1_200)));
        c.meta.contract_version = crate::CONTRACT_VERSION;
        assert!(c.validate().is_ok());
        c.arg[1] = 1_235;
        assert!(c.validate().is_err(), "more received than sent");
    }
}
