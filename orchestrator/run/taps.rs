//! The orchestrator's taps: one per data topic it reads (the table's orchestrator row), each
//! accounting for every message, folding its content into the topic's digest so two runs
//! compare byte for byte, timing it, and keeping what the report needs. A tap is opened for a
//! topic generically ([`open`]); the report asks a tap for its messages by type
//! ([`Taps::messages`]) or for the frame a section wants drawn ([`Taps::snapshot`]).

use std::any::Any;
use std::collections::BTreeMap;

use anyhow::{anyhow, Result};
use glint_runtime::ports::{FrameInbox, Inbox};
use glint_runtime::TopicStats;
use iceoryx2::port::listener::Listener;
use shared_types::table::{visit, PayloadVisitor, TopicSpec};
use shared_types::topics::{Ipc, IpcNode};
use shared_types::{deployment, Message, Scenario, ServiceId, TopicId};
use xxhash_rust::xxh3::Xxh3;

/// The pixels of one frame, kept for a picture.
#[derive(Debug, Clone)]
pub struct Snapshot {
    pub frame_index: u64,
    pub width_px: u32,
    pub height_px: u32,
    pub pixels: Vec<u16>,
}

/// What every tap records of the messages it takes: their digest, latencies and send times.
#[derive(Default)]
pub struct Record {
    digest: Xxh3,
    latency_ns: Vec<u64>,
    send_ns: Vec<(u64, u64)>,
}

impl Record {
    fn take(&mut self, seq: u64, send_mono_ns: u64, latency_ns: u64) {
        self.latency_ns.push(latency_ns);
        self.send_ns.push((seq, send_mono_ns));
    }
}

/// One tapped topic.
pub trait Tap {
    fn stats(&self) -> &TopicStats;
    fn record(&self) -> &Record;
    /// Receives everything queued; accounts for, digests and keeps each message.
    fn poll(&mut self) -> Result<()>;
    fn as_any(&self) -> &dyn Any;

    fn digest(&self) -> u64 {
        self.record().digest.digest()
    }
    /// Send → receive latency of every message taken [ns].
    fn latency_ns(&self) -> &[u64] {
        &self.record().latency_ns
    }
    /// Per message taken: (seq, the producer's send time [ns, CLOCK_MONOTONIC]).
    fn send_ns(&self) -> &[(u64, u64)] {
        &self.record().send_ns
    }
}

/// A message topic: every message kept.
pub struct MessageTap<T: Message> {
    inbox: Inbox<T>,
    record: Record,
    pub kept: Vec<T>,
}

impl<T: Message> Tap for MessageTap<T> {
    fn stats(&self) -> &TopicStats {
        &self.inbox.stats
    }
    fn record(&self) -> &Record {
        &self.record
    }
    fn poll(&mut self) -> Result<()> {
        let (record, kept) = (&mut self.record, &mut self.kept);
        self.inbox.drain(|r| {
            r.msg.fold_digest(&mut record.digest);
            record.take(r.msg.meta().seq, r.msg.meta().send_mono_ns, r.latency_ns);
            kept.push(*r.msg);
            Ok(())
        })?;
        Ok(())
    }
    fn as_any(&self) -> &dyn Any {
        self
    }
}

/// A frame topic: headers digested (seq and pixel checksum), one frame's pixels kept when a
/// report section asked for it.
pub struct FrameTap {
    inbox: FrameInbox,
    record: Record,
    want: Option<u64>,
    pub snapshot: Option<Snapshot>,
}

impl Tap for FrameTap {
    fn stats(&self) -> &TopicStats {
        &self.inbox.stats
    }
    fn record(&self) -> &Record {
        &self.record
    }
    fn poll(&mut self) -> Result<()> {
        let (record, snap, want) = (&mut self.record, &mut self.snapshot, self.want);
        self.inbox.drain(|h, pixels, latency_ns| {
            record.digest.update(&h.meta.seq.to_le_bytes());
            record.digest.update(&h.pixels_xxh3.to_le_bytes());
            record.take(h.meta.seq, h.meta.send_mono_ns, latency_ns);
            if Some(h.frame_index) == want {
                *snap = Some(Snapshot {
                    frame_index: h.frame_index,
                    width_px: h.width_px,
                    height_px: h.height_px,
                    pixels: pixels.to_vec(),
                });
            }
            Ok(())
        })?;
        Ok(())
    }
    fn as_any(&self) -> &dyn Any {
        self
    }
}

/// Opens the tap of `topic`; `snapshot`: the frame index whose pixels to keep.
pub fn open(
    node: &IpcNode,
    scenario: &Scenario,
    topic: TopicId,
    snapshot: Option<u64>,
) -> Result<(Box<dyn Tap>, Listener<Ipc>)> {
    struct Open<'a> {
        node: &'a IpcNode,
        scenario: &'a Scenario,
        snapshot: Option<u64>,
    }
    type Opened = Result<(Box<dyn Tap>, Listener<Ipc>)>;
    impl PayloadVisitor for Open<'_> {
        type Out = Opened;
        fn frames(self, spec: &'static TopicSpec) -> Opened {
            let (mut inbox, l) = FrameInbox::open(self.node, spec.id, self.scenario)?;
            // A service that reads the pixels verifies their checksum; the orchestrator then
            // reads headers only (accounting and the digest).
            let services = deployment::consumers(self.scenario, spec.id);
            inbox.verify_checksum = services.iter().all(|s| *s == ServiceId::Orchestrator);
            let tap = FrameTap {
                inbox,
                record: Record::default(),
                want: self.snapshot,
                snapshot: None,
            };
            Ok((Box::new(tap), l))
        }
        fn messages<T: Message>(self, spec: &'static TopicSpec) -> Opened {
            let (inbox, l) = Inbox::<T>::open(self.node, spec.id)?;
            let tap = MessageTap {
                inbox,
                record: Record::default(),
                kept: vec![],
            };
            Ok((Box::new(tap), l))
        }
        fn calls<Req: Message, Resp: Message>(self, spec: &'static TopicSpec) -> Opened {
            Err(anyhow!(
                "the orchestrator taps data topics, not calls (`{}`)",
                spec.name
            ))
        }
    }
    visit(
        topic,
        Open {
            node,
            scenario,
            snapshot,
        },
    )
}

/// Every tap of a deployment, by topic.
#[derive(Default)]
pub struct Taps {
    taps: BTreeMap<TopicId, Box<dyn Tap>>,
}

impl Taps {
    pub fn insert(&mut self, topic: TopicId, tap: Box<dyn Tap>) {
        self.taps.insert(topic, tap);
    }

    pub fn get(&self, topic: TopicId) -> Option<&dyn Tap> {
        self.taps.get(&topic).map(|t| t.as_ref())
    }

    pub fn iter_mut(&mut self) -> impl Iterator<Item = (&TopicId, &mut Box<dyn Tap>)> {
        self.taps.iter_mut()
    }

    pub fn iter(&self) -> impl Iterator<Item = (&TopicId, &Box<dyn Tap>)> {
        self.taps.iter()
    }

    /// The messages taken on `topic` (none if it is not tapped or carries another type).
    pub fn messages<T: Message>(&self, topic: TopicId) -> &[T] {
        self.get(topic)
            .and_then(|t| t.as_any().downcast_ref::<MessageTap<T>>())
            .map_or(&[], |t| &t.kept)
    }

    /// The frame kept on `topic` for a picture.
    pub fn snapshot(&self, topic: TopicId) -> Option<&Snapshot> {
        self.get(topic)
            .and_then(|t| t.as_any().downcast_ref::<FrameTap>())
            .and_then(|t| t.snapshot.as_ref())
    }

    /// Latencies of `topic` (empty if not tapped).
    pub fn latency_ns(&self, topic: TopicId) -> &[u64] {
        self.get(topic).map_or(&[], |t| t.latency_ns())
    }
}
