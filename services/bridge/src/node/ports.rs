//! A topic's iceoryx2 ports as bytes: what the bridge takes from its host's shared memory and
//! puts there, through the same openers and QoS as every service (shared-types' `topics`),
//! bound to each topic's payload type by the table's `visit`.

use anyhow::{anyhow, Result};
use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;
use shared_types::table::{visit, PayloadVisitor, TopicSpec};
use shared_types::topics::{
    event_service, frame_pixels, frames, messages, Ipc, IpcNode, EVENT_DATA,
};
use shared_types::{FrameHeader, Message, Scenario, TopicId};

use crate::envelope::type_digest;

/// One message taken from shared memory, as bytes.
pub struct Taken {
    /// Its producer ([`shared_types::ServiceId`] as u32) and seq, from its header.
    pub producer: u32,
    pub seq: u64,
}

/// A subscriber of one topic whose messages leave as bytes.
pub trait TakeBytes {
    fn topic(&self) -> TopicId;
    /// Fingerprint of the payload's type and sizes ([`type_digest`]).
    fn digest(&self) -> u64;
    /// The next queued message into `buf` (cleared first): header bytes, then payload bytes.
    fn take(&mut self, buf: &mut Vec<u8>) -> Result<Option<Taken>>;
}

/// A publisher of one topic whose messages arrive as bytes.
pub trait PutBytes {
    fn topic(&self) -> TopicId;
    fn digest(&self) -> u64;
    /// Bytes of one message (header and payload).
    fn len(&self) -> usize;
    /// Loans a sample, copies `parts` into it one after the other (`len()` bytes in all, as
    /// they arrived off the wire, without joining them first), sends and notifies.
    fn put(&mut self, parts: &mut dyn Iterator<Item = &[u8]>) -> Result<()>;
}

/// Copies `parts` into `dst` from its start; the bytes copied.
fn fill(dst: &mut [u8], parts: &mut dyn Iterator<Item = &[u8]>) -> usize {
    let mut at = 0;
    for p in parts {
        let n = p.len().min(dst.len() - at);
        dst[at..at + n].copy_from_slice(&p[..n]);
        at += n;
        if at == dst.len() {
            break;
        }
    }
    at
}

fn listener(node: &IpcNode, t: TopicId) -> Result<Listener<Ipc>> {
    (event_service(node, t, false)?.listener_builder().create())
        .map_err(|e| anyhow!("listener for {}: {e:?}", t.name()))
}

fn notifier(node: &IpcNode, t: TopicId) -> Result<Notifier<Ipc>> {
    (event_service(node, t, false)?.notifier_builder().create())
        .map_err(|e| anyhow!("notifier for {}: {e:?}", t.name()))
}

struct FrameTake {
    topic: TopicId,
    subscriber: Subscriber<Ipc, [u16], FrameHeader>,
}

impl TakeBytes for FrameTake {
    fn topic(&self) -> TopicId {
        self.topic
    }
    fn digest(&self) -> u64 {
        frame_digest(self.topic)
    }
    fn take(&mut self, buf: &mut Vec<u8>) -> Result<Option<Taken>> {
        let Some(sample) = (self.subscriber.receive())
            .map_err(|e| anyhow!("{} receive: {e:?}", self.topic.name()))?
        else {
            return Ok(None);
        };
        let header = *sample.user_header();
        buf.clear();
        buf.extend_from_slice(bytemuck::bytes_of(&header));
        buf.extend_from_slice(bytemuck::cast_slice::<u16, u8>(sample.payload()));
        Ok(Some(Taken {
            producer: header.meta.producer,
            seq: header.meta.seq,
        }))
    }
}

struct MessageTake<T: Message> {
    topic: TopicId,
    subscriber: Subscriber<Ipc, T, ()>,
}

impl<T: Message> TakeBytes for MessageTake<T> {
    fn topic(&self) -> TopicId {
        self.topic
    }
    fn digest(&self) -> u64 {
        type_digest(self.topic, 0, std::mem::size_of::<T>())
    }
    fn take(&mut self, buf: &mut Vec<u8>) -> Result<Option<Taken>> {
        let Some(sample) = (self.subscriber.receive())
            .map_err(|e| anyhow!("{} receive: {e:?}", self.topic.name()))?
        else {
            return Ok(None);
        };
        let msg: &T = sample.payload();
        buf.clear();
        buf.extend_from_slice(bytemuck::bytes_of(msg));
        Ok(Some(Taken {
            producer: msg.meta().producer,
            seq: msg.meta().seq,
        }))
    }
}

fn frame_digest(topic: TopicId) -> u64 {
    type_digest(topic, std::mem::size_of::<FrameHeader>(), 2)
}

/// A subscriber of `topic` on `node`, its messages as bytes, and the listener its producers
/// notify.
pub fn taker(
    node: &IpcNode,
    scenario: &Scenario,
    topic: TopicId,
) -> Result<(Box<dyn TakeBytes>, Listener<Ipc>)> {
    struct Open<'a> {
        node: &'a IpcNode,
        scenario: &'a Scenario,
    }
    impl PayloadVisitor for Open<'_> {
        type Out = Result<(Box<dyn TakeBytes>, Listener<Ipc>)>;
        fn frames(self, spec: &'static TopicSpec) -> Self::Out {
            let t = spec.id;
            let subscriber = (frames(self.node, t, self.scenario)?.subscriber_builder())
                .create()
                .map_err(|e| anyhow!("{} subscriber: {e:?}", t.name()))?;
            let take = FrameTake {
                topic: t,
                subscriber,
            };
            Ok((Box::new(take), listener(self.node, t)?))
        }
        fn messages<T: Message>(self, spec: &'static TopicSpec) -> Self::Out {
            let t = spec.id;
            let subscriber = (messages::<T>(self.node, t)?.subscriber_builder())
                .create()
                .map_err(|e| anyhow!("{} subscriber: {e:?}", t.name()))?;
            let take = MessageTake::<T> {
                topic: t,
                subscriber,
            };
            Ok((Box::new(take), listener(self.node, t)?))
        }
        fn calls<Req: Message, Resp: Message>(self, spec: &'static TopicSpec) -> Self::Out {
            Err(anyhow!("`{}` is a call; calls are not bridged", spec.name))
        }
    }
    visit(topic, Open { node, scenario })
}

struct FramePut {
    topic: TopicId,
    publisher: Publisher<Ipc, [u16], FrameHeader>,
    notifier: Notifier<Ipc>,
    pixels: usize,
}

const HEADER_BYTES: usize = std::mem::size_of::<FrameHeader>();

impl PutBytes for FramePut {
    fn topic(&self) -> TopicId {
        self.topic
    }
    fn digest(&self) -> u64 {
        frame_digest(self.topic)
    }
    fn len(&self) -> usize {
        HEADER_BYTES + 2 * self.pixels
    }
    fn put(&mut self, parts: &mut dyn Iterator<Item = &[u8]>) -> Result<()> {
        let name = self.topic.name();
        let mut sample = (self.publisher.loan_slice_uninit(self.pixels))
            .map_err(|e| anyhow!("{name} loan: {e:?}"))?;
        // The header's bytes first (they may span parts), then the pixels straight into the
        // loan.
        let mut header = [0u8; HEADER_BYTES];
        let mut parts = parts.peekable();
        let mut rest: &[u8] = &[];
        let mut at = 0;
        while at < HEADER_BYTES {
            let Some(p) = parts.next() else { break };
            let n = p.len().min(HEADER_BYTES - at);
            header[at..at + n].copy_from_slice(&p[..n]);
            at += n;
            rest = &p[n..];
        }
        *sample.user_header_mut() = bytemuck::pod_read_unaligned(&header);
        let slots = sample.payload_mut();
        // SAFETY: `slots` is `pixels` u16 slots of mapped shared memory (every byte
        // initialised at the OS level, any bit pattern a valid u16), viewed as bytes only to
        // be overwritten; `assume_init` follows only once all of them were (checked below).
        let bytes: &mut [u8] = unsafe {
            std::slice::from_raw_parts_mut(slots.as_mut_ptr() as *mut u8, 2 * slots.len())
        };
        let copied = fill(bytes, &mut std::iter::once(rest).chain(parts));
        anyhow::ensure!(
            at == HEADER_BYTES && copied == bytes.len(),
            "{name}: not a frame of the topic's size"
        );
        // SAFETY: every pixel was written above.
        let sample = unsafe { sample.assume_init() };
        sample.send().map_err(|e| anyhow!("{name} send: {e:?}"))?;
        (self.notifier.notify_with_custom_event_id(EVENT_DATA))
            .map_err(|e| anyhow!("{name} notify: {e:?}"))?;
        Ok(())
    }
}

struct MessagePut<T: Message> {
    topic: TopicId,
    publisher: Publisher<Ipc, T, ()>,
    notifier: Notifier<Ipc>,
}

impl<T: Message> PutBytes for MessagePut<T> {
    fn topic(&self) -> TopicId {
        self.topic
    }
    fn digest(&self) -> u64 {
        type_digest(self.topic, 0, std::mem::size_of::<T>())
    }
    fn len(&self) -> usize {
        std::mem::size_of::<T>()
    }
    fn put(&mut self, parts: &mut dyn Iterator<Item = &[u8]>) -> Result<()> {
        let name = self.topic.name();
        let mut bytes = vec![0u8; std::mem::size_of::<T>()];
        anyhow::ensure!(
            fill(&mut bytes, parts) == bytes.len(),
            "{name}: not a message of the topic's size"
        );
        let msg: T = bytemuck::pod_read_unaligned(&bytes);
        let sample = (self.publisher.loan_uninit()).map_err(|e| anyhow!("{name} loan: {e:?}"))?;
        (sample.write_payload(msg).send()).map_err(|e| anyhow!("{name} send: {e:?}"))?;
        (self.notifier.notify_with_custom_event_id(EVENT_DATA))
            .map_err(|e| anyhow!("{name} notify: {e:?}"))?;
        Ok(())
    }
}

/// A publisher of `topic` on `node`, its messages from bytes.
pub fn putter(node: &IpcNode, scenario: &Scenario, topic: TopicId) -> Result<Box<dyn PutBytes>> {
    struct Open<'a> {
        node: &'a IpcNode,
        scenario: &'a Scenario,
    }
    impl PayloadVisitor for Open<'_> {
        type Out = Result<Box<dyn PutBytes>>;
        fn frames(self, spec: &'static TopicSpec) -> Self::Out {
            let t = spec.id;
            let pixels = frame_pixels(t, self.scenario);
            let publisher = (frames(self.node, t, self.scenario)?.publisher_builder())
                .initial_max_slice_len(pixels)
                .allocation_strategy(AllocationStrategy::Static)
                .max_loaned_samples(1)
                .create()
                .map_err(|e| anyhow!("{} publisher: {e:?}", t.name()))?;
            Ok(Box::new(FramePut {
                topic: t,
                publisher,
                notifier: notifier(self.node, t)?,
                pixels,
            }))
        }
        fn messages<T: Message>(self, spec: &'static TopicSpec) -> Self::Out {
            let t = spec.id;
            let publisher = (messages::<T>(self.node, t)?.publisher_builder())
                .create()
                .map_err(|e| anyhow!("{} publisher: {e:?}", t.name()))?;
            Ok(Box::new(MessagePut::<T> {
                topic: t,
                publisher,
                notifier: notifier(self.node, t)?,
            }))
        }
        fn calls<Req: Message, Resp: Message>(self, spec: &'static TopicSpec) -> Self::Out {
            Err(anyhow!("`{}` is a call; calls are not bridged", spec.name))
        }
    }
    visit(topic, Open { node, scenario })
}
