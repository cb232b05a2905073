//! The orchestrator's taps: one per data topic it reads (the table's orchestrator row), each
//! accounting for every message, folding its content into the topic's digest so two runs
//! compare byte for byte, timing it, and handing it to the report sections' folds
//! ([`Fold`]), which score while the run goes: nothing here grows with the run's length. A tap
//! is opened for a topic generically ([`open`]); a section reads its fold back by type
//! ([`Taps::fold`]) and the frame it wants drawn ([`Taps::snapshot`]).

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

use crate::run::latency::Latency;
use crate::run::record::Recorder;

/// The pixels of one frame, kept for a picture.
#[derive(Debug, Clone)]
pub struct Snapshot {
    pub frame_index: u64,
    pub width_px: u32,
    pub height_px: u32,
    pub pixels: Vec<u16>,
}

/// What every tap records of the messages it takes: their digest and latencies, in constant
/// memory.
#[derive(Default)]
pub struct Record {
    digest: Xxh3,
    latency: Latency,
}

/// Where a tap hands what it takes: the report sections' folds, the stages' join and the
/// recording (`glint run --record`).
pub struct Takers<'a> {
    folds: &'a mut [Box<dyn Fold>],
    stages: &'a mut Stages,
    recorder: Option<&'a mut Recorder>,
}

impl Takers<'_> {
    fn take(&mut self, topic: TopicId, seq: u64, send_mono_ns: u64, msg: &dyn Any) {
        self.stages.take(topic, seq, send_mono_ns);
        for f in self.folds.iter_mut() {
            f.take(topic, msg);
        }
    }
}

/// What a report section folds of the messages the taps take while the run goes: its score
/// in constant memory (the debris chain), or the few messages its scenario bounds (an Earth
/// sweep's answers, a solve's spectra). A section reads its fold back by type
/// ([`Taps::fold`]) once the run has ended.
pub trait Fold: Any {
    /// One message taken on `topic`; a fold downcasts to the types it reads.
    fn take(&mut self, topic: TopicId, msg: &dyn Any);
    /// Everything taken: the run has ended.
    fn finish(&mut self) {}
    fn as_any(&self) -> &dyn Any;
}

/// One tapped topic.
pub trait Tap {
    fn stats(&self) -> &TopicStats;
    fn record(&self) -> &Record;
    /// Receives everything queued; accounts for and digests each message and hands it on.
    fn poll(&mut self, takers: &mut Takers<'_>) -> Result<()>;
    fn as_any(&self) -> &dyn Any;

    fn digest(&self) -> u64 {
        self.record().digest.digest()
    }
    /// Send → receive latencies of the messages taken.
    fn latency(&self) -> &Latency {
        &self.record().latency
    }
}

/// A message topic.
pub struct MessageTap<T: Message> {
    topic: TopicId,
    inbox: Inbox<T>,
    record: Record,
}

impl<T: Message> Tap for MessageTap<T> {
    fn stats(&self) -> &TopicStats {
        &self.inbox.stats
    }
    fn record(&self) -> &Record {
        &self.record
    }
    fn poll(&mut self, takers: &mut Takers<'_>) -> Result<()> {
        let (record, topic) = (&mut self.record, self.topic);
        self.inbox.drain(|r| {
            r.msg.fold_digest(&mut record.digest);
            record.latency.record(r.latency_ns);
            let meta = r.msg.meta();
            if let Some(rec) = takers.recorder.as_deref_mut() {
                rec.message(topic, r.msg);
            }
            takers.take(topic, meta.seq, meta.send_mono_ns, r.msg);
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
    topic: TopicId,
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
    fn poll(&mut self, takers: &mut Takers<'_>) -> Result<()> {
        let (record, snap, want, topic) =
            (&mut self.record, &mut self.snapshot, self.want, self.topic);
        self.inbox.drain(|h, pixels, latency_ns| {
            record.digest.update(&h.meta.seq.to_le_bytes());
            record.digest.update(&h.pixels_xxh3.to_le_bytes());
            record.latency.record(latency_ns);
            if let Some(rec) = takers.recorder.as_deref_mut() {
                rec.frame(topic, h, pixels);
            }
            takers.take(topic, h.meta.seq, h.meta.send_mono_ns, h);
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

/// The debris pipeline's stages, each between the send times of two topics' messages of the
/// same seq (one CLOCK_MONOTONIC on this host): `detect` = frame sent → its detections sent
/// (the hop, the checksum and the detection), `track` = detections sent → tracks sent (the
/// hop, the filters and the laser round trip), `end_to_end` = frame sent → tracks sent.
const STAGES: [(&str, TopicId, TopicId); 3] = [
    ("detect", TopicId::Frame, TopicId::Detections),
    ("track", TopicId::Detections, TopicId::Tracks),
    ("end_to_end", TopicId::Frame, TopicId::Tracks),
];

/// Seqs whose stages are still open, at most: a seq a dropped message left open is forgotten
/// past this many (memory stays bounded in realtime mode).
const STAGES_OPEN_MAX: usize = 4096;

/// The stages' latencies, joined by seq as the messages arrive.
#[derive(Default)]
pub struct Stages {
    /// Per open seq: the send time on each of [`STAGES`]'s three topics.
    sent: BTreeMap<u64, [Option<u64>; 3]>,
    latency: [Latency; 3],
}

impl Stages {
    const TOPICS: [TopicId; 3] = [TopicId::Frame, TopicId::Detections, TopicId::Tracks];

    fn take(&mut self, topic: TopicId, seq: u64, send_ns: u64) {
        let Some(slot) = Self::TOPICS.iter().position(|t| *t == topic) else {
            return;
        };
        let sent = self.sent.entry(seq).or_default();
        sent[slot] = Some(send_ns);
        let at = |t: TopicId| sent[Self::TOPICS.iter().position(|x| *x == t).unwrap_or(0)];
        for ((_, from, to), latency) in STAGES.iter().zip(&mut self.latency) {
            if *from != topic && *to != topic {
                continue;
            }
            if let (Some(t0), Some(t1)) = (at(*from), at(*to)) {
                latency.record(t1.saturating_sub(t0));
            }
        }
        if sent.iter().all(Option::is_some) {
            self.sent.remove(&seq);
        }
        while self.sent.len() > STAGES_OPEN_MAX {
            self.sent.pop_first();
        }
    }

    /// Each stage's latencies (none if the run had no detections).
    pub fn latencies(&self) -> Vec<(&'static str, Latency)> {
        if self.latency[0].is_empty() {
            return vec![];
        }
        (STAGES.iter().zip(&self.latency))
            .map(|((name, _, _), l)| (*name, l.clone()))
            .collect()
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
                topic: spec.id,
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
                topic: spec.id,
                inbox,
                record: Record::default(),
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

/// Every tap of a deployment, by topic, and what they hand on to.
#[derive(Default)]
pub struct Taps {
    taps: BTreeMap<TopicId, Box<dyn Tap>>,
    folds: Vec<Box<dyn Fold>>,
    stages: Stages,
    recorder: Option<Recorder>,
}

impl Taps {
    pub fn new(folds: Vec<Box<dyn Fold>>) -> Self {
        Taps {
            folds,
            ..Default::default()
        }
    }

    /// Records a message the orchestrator took outside the taps (a heartbeat).
    pub fn record_message<T: Message>(&mut self, topic: TopicId, msg: &T) {
        if let Some(r) = self.recorder.as_mut() {
            r.message(topic, msg);
        }
    }

    /// Writes every message the taps take into `recorder` from now on.
    pub fn record_into(&mut self, recorder: Recorder) {
        self.recorder = Some(recorder);
    }

    pub fn insert(&mut self, topic: TopicId, tap: Box<dyn Tap>) {
        self.taps.insert(topic, tap);
    }

    pub fn get(&self, topic: TopicId) -> Option<&dyn Tap> {
        self.taps.get(&topic).map(|t| t.as_ref())
    }

    pub fn iter(&self) -> impl Iterator<Item = (&TopicId, &Box<dyn Tap>)> {
        self.taps.iter()
    }

    /// Polls every tap; returns each topic's next expected seq (what to acknowledge).
    pub fn poll(&mut self) -> Result<Vec<(TopicId, u64)>> {
        let mut takers = Takers {
            folds: &mut self.folds,
            stages: &mut self.stages,
            recorder: self.recorder.as_mut(),
        };
        let mut taken = vec![];
        for (topic, tap) in self.taps.iter_mut() {
            tap.poll(&mut takers)?;
            taken.push((*topic, tap.stats().next_seq));
        }
        Ok(taken)
    }

    /// Tells every fold the run has ended.
    pub fn finish(&mut self) {
        for f in &mut self.folds {
            f.finish();
        }
    }

    /// The recorder, to be closed once the report is written.
    pub fn take_recorder(&mut self) -> Option<Recorder> {
        self.recorder.take()
    }

    /// The fold of type `F` (a section's), if the run has one.
    pub fn fold<F: Fold>(&self) -> Option<&F> {
        self.folds
            .iter()
            .find_map(|f| f.as_any().downcast_ref::<F>())
    }

    /// The frame kept on `topic` for a picture.
    pub fn snapshot(&self, topic: TopicId) -> Option<&Snapshot> {
        self.get(topic)
            .and_then(|t| t.as_any().downcast_ref::<FrameTap>())
            .and_then(|t| t.snapshot.as_ref())
    }

    /// Latencies of `topic` (none if not tapped).
    pub fn latency(&self, topic: TopicId) -> Latency {
        self.get(topic)
            .map(|t| t.latency().clone())
            .unwrap_or_default()
    }

    /// The debris pipeline's stages' latencies.
    pub fn stages(&self) -> Vec<(&'static str, Latency)> {
        self.stages.latencies()
    }
}
