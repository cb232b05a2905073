//! The sensor's streams played back from a recording (`[replay]`): message `k` of a topic is
//! the recording's message `k`, byte for byte — a frame's header fields and pixels copied from
//! the mapped file into the loan, a message read whole — with the truth the recorded run sent
//! with it. Only the sequence number and send time are the replay's. Each is a [`FrameStream`]
//! or a [`MessageStream`], so the node paces, credits and replays them as it does the
//! rendered ones.

use std::sync::Arc;

use anyhow::{bail, Context, Result};
use shared_types::deployment::expected_messages;
use shared_types::table::{visit, PayloadVisitor, TopicSpec};
use shared_types::{FrameHeader, Message, Scenario, TopicId, Truth};

use crate::recording::{meta_of, split_frame, Recording};
use crate::streams::{FrameStream, MessageStream, Stream};

/// One recorded topic: its messages' places in the recording and their truths.
struct Recorded {
    recording: Arc<Recording>,
    topic: TopicId,
    t_ns: Vec<u64>,
    truths: Vec<Truth>,
}

impl Recorded {
    /// The first `n` messages of `topic` (the scenario's count: a `--scenario` may ask for
    /// fewer than were recorded).
    fn open(recording: Arc<Recording>, topic: TopicId, n: u64) -> Result<Self> {
        let messages = recording.first(topic, n)?;
        let t_ns = messages
            .iter()
            .map(|m| meta_of(m).map(|meta| meta.t_ns).unwrap_or(0))
            .collect::<Vec<_>>();
        let kind = topic.spec().truth;
        let truths = match kind {
            Some(kind) => recording.truths(kind)?,
            None => vec![],
        };
        if kind.is_some() && truths.len() < t_ns.len() {
            bail!(
                "{}: {} messages of topic {} but {} truths of them",
                recording.path().display(),
                t_ns.len(),
                topic.name(),
                truths.len()
            );
        }
        Ok(Recorded {
            recording,
            topic,
            t_ns,
            truths,
        })
    }

    fn bytes(&self, k: u64) -> &[u8] {
        // Checked when opened: every `k < messages()` is there.
        self.recording.message(self.topic, k).unwrap_or(&[])
    }

    fn truth(&self, k: u64) -> Truth {
        self.truths.get(k as usize).copied().unwrap_or_default()
    }
}

impl Stream for Recorded {
    fn topic(&self) -> TopicId {
        self.topic
    }
    fn messages(&self) -> u64 {
        self.t_ns.len() as u64
    }
    fn t_ns(&self, k: u64) -> u64 {
        self.t_ns.get(k as usize).copied().unwrap_or(0)
    }
}

/// A recorded frame topic.
pub struct RecordedFrames(Recorded);

impl RecordedFrames {
    /// `topic`'s frames in `recording`, each checked against the scenario's frame size.
    pub fn open(recording: Arc<Recording>, topic: TopicId, sc: &Scenario) -> Result<Self> {
        let r = Recorded::open(recording, topic, expected_messages(sc, topic))?;
        let want = shared_types::topics::frame_pixels(topic, sc);
        for k in 0..r.messages() {
            let (h, _) = split_frame(r.bytes(k)).with_context(|| {
                format!("{}: topic {}", r.recording.path().display(), topic.name())
            })?;
            let px = h.width_px as usize * h.height_px as usize;
            if px != want {
                bail!(
                    "{}: frame {k} of topic {} has {}×{} pixels; the scenario's frames have {want}",
                    r.recording.path().display(),
                    topic.name(),
                    h.width_px,
                    h.height_px
                );
            }
        }
        Ok(RecordedFrames(r))
    }
}

impl Stream for RecordedFrames {
    fn topic(&self) -> TopicId {
        self.0.topic()
    }
    fn messages(&self) -> u64 {
        self.0.messages()
    }
    fn t_ns(&self, k: u64) -> u64 {
        self.0.t_ns(k)
    }
}

impl FrameStream for RecordedFrames {
    fn render(&self, k: u64, header: &mut FrameHeader, pixels: &mut [u16]) {
        let Ok((h, recorded)) = split_frame(self.0.bytes(k)) else {
            return;
        };
        // Every field the stream fills; the port sets the meta and the checksum.
        *header = FrameHeader {
            meta: header.meta,
            pixels_xxh3: header.pixels_xxh3,
            ..h
        };
        bytemuck::cast_slice_mut::<u16, u8>(pixels).copy_from_slice(recorded);
    }
    fn truth(&self, k: u64) -> Truth {
        self.0.truth(k)
    }
}

/// A recorded message topic of type `T`.
pub struct RecordedMessages<T: Message> {
    recorded: Recorded,
    messages: Vec<T>,
}

impl<T: Message> RecordedMessages<T> {
    pub fn open(recording: Arc<Recording>, topic: TopicId, sc: &Scenario) -> Result<Self> {
        let n = expected_messages(sc, topic);
        let messages = recording.typed::<T>(topic, Some(n))?;
        Ok(RecordedMessages {
            recorded: Recorded::open(recording, topic, n)?,
            messages,
        })
    }
}

impl<T: Message> Stream for RecordedMessages<T> {
    fn topic(&self) -> TopicId {
        self.recorded.topic()
    }
    fn messages(&self) -> u64 {
        self.recorded.messages()
    }
    fn t_ns(&self, k: u64) -> u64 {
        self.recorded.t_ns(k)
    }
}

impl<T: Message> MessageStream for RecordedMessages<T> {
    type Msg = T;
    fn make(&self, k: u64) -> Result<(T, Truth)> {
        let msg = (self.messages.get(k as usize).copied())
            .with_context(|| format!("no message {k} of topic {}", self.topic().name()))?;
        Ok((msg, self.recorded.truth(k)))
    }
}

/// What to do with each kind of recorded stream: the node opens its port around it.
pub trait RecordedVisitor {
    type Out;
    fn frames(self, stream: RecordedFrames) -> Result<Self::Out>;
    fn messages<T: Message>(self, stream: RecordedMessages<T>) -> Result<Self::Out>;
}

/// Opens `topic`'s recorded stream with its payload type (the table's [`visit`]) and hands it
/// to `v`.
pub fn open<V: RecordedVisitor>(
    recording: &Arc<Recording>,
    topic: TopicId,
    sc: &Scenario,
    v: V,
) -> Result<V::Out> {
    struct Open<'a, V> {
        recording: &'a Arc<Recording>,
        topic: TopicId,
        sc: &'a Scenario,
        v: V,
    }
    impl<V: RecordedVisitor> PayloadVisitor for Open<'_, V> {
        type Out = Result<V::Out>;
        fn frames(self, _: &'static TopicSpec) -> Self::Out {
            let s = RecordedFrames::open(self.recording.clone(), self.topic, self.sc)?;
            self.v.frames(s)
        }
        fn messages<T: Message>(self, _: &'static TopicSpec) -> Self::Out {
            self.v.messages(RecordedMessages::<T>::open(
                self.recording.clone(),
                self.topic,
                self.sc,
            )?)
        }
        fn calls<Req: Message, Resp: Message>(self, _: &'static TopicSpec) -> Self::Out {
            bail!(
                "topic {} is a call: it is answered, not replayed",
                self.topic.name()
            )
        }
    }
    visit(
        topic,
        Open {
            recording,
            topic,
            sc,
            v,
        },
    )
}
