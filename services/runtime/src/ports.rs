//! Typed ports: an [`Outbox`] is a publisher plus the notifier that wakes its consumers; an
//! [`Inbox`] is a subscriber whose `drain` validates, sequence-accounts and hands over each
//! message. Frames have their own pair ([`FrameOutbox`], [`FrameInbox`]) because their payload
//! is a `[u16]` slice rendered in place in the loaned sample.

use anyhow::{anyhow, Result};
use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::port::update_connections::UpdateConnections;
use iceoryx2::prelude::*;
use shared_types::table::Replay;
use shared_types::topics::{
    event_service, frames, messages, EventService, Ipc, IpcNode, EVENT_DATA,
};
use shared_types::{DropReason, FrameHeader, Message, Meta, Reject, ServiceId, TopicId};

use crate::clock::mono_ns;
use crate::stats::{SeqVerdict, TopicStats};
use crate::tamper::{Tamper, Verdict};

/// The listener a consumer attaches to its WaitSet for a topic.
pub fn listener(node: &IpcNode, topic: TopicId) -> Result<Listener<Ipc>> {
    let ev: EventService = event_service(node, topic, false)?;
    ev.listener_builder()
        .create()
        .map_err(|e| anyhow!("listener for {}: {e:?}", topic.name()))
}

fn notifier(node: &IpcNode, topic: TopicId) -> Result<Notifier<Ipc>> {
    let ev: EventService = event_service(node, topic, false)?;
    ev.notifier_builder()
        .create()
        .map_err(|e| anyhow!("notifier for {}: {e:?}", topic.name()))
}

pub struct Outbox<T: Message> {
    publisher: Publisher<Ipc, T, ()>,
    notifier: Notifier<Ipc>,
    producer: ServiceId,
    /// Seq of the next message: `stats.published` except while replaying.
    next_seq: u64,
    /// Messages sent from seq `log_base` on, kept for replays to a restarted consumer
    /// ([`Outbox::keep_log`]); trimmed to what a consumer may still be sent again
    /// ([`Outbox::trim_log`]).
    log: Option<std::collections::VecDeque<T>>,
    log_base: u64,
    /// Injected drops and corruptions still to apply.
    pub tamper: Tamper,
    pub stats: TopicStats,
}

/// A publisher's [`UpdateConnections`]: new subscribers connected, and handed the history.
fn connect(publisher: &impl UpdateConnections, topic: TopicId) -> Result<()> {
    (publisher.update_connections())
        .map_err(|e| anyhow!("connecting {}'s subscribers: {e:?}", topic.name()))
}

impl<T: Message> Outbox<T> {
    /// Connects subscribers that joined since the last send and hands them the topic's
    /// history now, not at the next send (which a held producer may never make: a restarted
    /// bridge's subscriber waits for what was in flight).
    pub fn connect(&self) -> Result<()> {
        connect(&self.publisher, self.stats.topic)
    }

    /// A publisher on message topic `topic`, from `producer`. A topic the table replays from a
    /// log ([`Replay::Logged`]) keeps every message sent, so that a restarted consumer can be
    /// sent them again.
    pub fn open(node: &IpcNode, topic: TopicId, producer: ServiceId) -> Result<Self> {
        let publisher = messages::<T>(node, topic)?
            .publisher_builder()
            .create()
            .map_err(|e| anyhow!("publisher for {}: {e:?}", topic.name()))?;
        let mut out = Outbox {
            publisher,
            notifier: notifier(node, topic)?,
            producer,
            next_seq: 0,
            log: None,
            log_base: 0,
            tamper: Tamper::default(),
            stats: TopicStats::new(topic),
        };
        if topic.spec().replay == Replay::Logged && topic.spec().producer() == Some(producer) {
            out.keep_log();
        }
        Ok(out)
    }

    /// Keeps every message sent, so that a restarted consumer can be sent them again
    /// ([`Outbox::rewind`], [`Outbox::resend`]) when the producer cannot re-make them.
    pub fn keep_log(&mut self) {
        self.log.get_or_insert_with(Default::default);
    }

    /// Forgets the logged messages below `seq`: every consumer's checkpoint covers them, so no
    /// replay will ask for them again. Keeps the log as long as the consumers' checkpoint
    /// interval, however long the run.
    pub fn trim_log(&mut self, seq: u64) {
        let Some(log) = self.log.as_mut() else {
            return;
        };
        let drop = seq.saturating_sub(self.log_base).min(log.len() as u64);
        log.drain(..drop as usize);
        self.log_base += drop;
    }

    /// Messages in the log (first seq, count).
    pub fn log_span(&self) -> (u64, usize) {
        (self.log_base, self.log.as_ref().map_or(0, |l| l.len()))
    }

    /// The log as bytes, for a checkpoint.
    pub fn log_bytes(&self) -> Vec<u8> {
        self.log.as_ref().map_or_else(Vec::new, |log| {
            log.iter()
                .flat_map(|m| bytemuck::bytes_of(m).iter().copied())
                .collect()
        })
    }

    /// Takes up a checkpoint: its accounting, and its log from `base` on.
    pub fn restore(
        &mut self,
        stats: &crate::stats::StatsSnapshot,
        base: u64,
        log: &[u8],
    ) -> Result<()> {
        self.stats.restore(stats);
        self.next_seq = self.stats.published;
        if let Some(l) = self.log.as_mut() {
            let size = std::mem::size_of::<T>();
            if !log.len().is_multiple_of(size) {
                return Err(anyhow!(
                    "a checkpoint's log of {} bytes is not whole {}-byte messages",
                    log.len(),
                    size
                ));
            }
            *l = log
                .chunks_exact(size)
                .map(bytemuck::pod_read_unaligned::<T>)
                .collect();
            self.log_base = base;
        }
        Ok(())
    }

    /// Whether every message sent is kept ([`Outbox::keep_log`]).
    pub fn has_log(&self) -> bool {
        self.log.is_some()
    }

    /// Whether messages below `stats.published` are still to be sent again.
    pub fn replaying(&self) -> bool {
        self.next_seq < self.stats.published
    }

    /// Sends logged messages again, exactly as first sent but for the send time (now: a
    /// restarted consumer tells the replay from stale copies by it), from the rewound seq on,
    /// at most `limit` of them (the consumers' credit). Returns how many were sent.
    pub fn resend(&mut self, limit: u64) -> Result<u64> {
        let Some(log) = self.log.as_ref() else {
            return Ok(0);
        };
        let mut n = 0;
        while n < limit && self.next_seq < self.stats.published {
            let Some(msg) =
                (self.next_seq.checked_sub(self.log_base)).and_then(|i| log.get(i as usize))
            else {
                // Trimmed: below every consumer's checkpoint, so nobody asks for it.
                break;
            };
            let mut copy = *msg;
            copy.meta_mut().send_mono_ns = mono_ns();
            self.publisher
                .send_copy(copy)
                .map_err(|e| anyhow!("resend on {}: {e:?}", self.stats.topic.name()))?;
            self.next_seq += 1;
            n += 1;
        }
        if n > 0 {
            self.notifier
                .notify_with_custom_event_id(EVENT_DATA)
                .map_err(|e| anyhow!("notify on {}: {e:?}", self.stats.topic.name()))?;
        }
        Ok(n)
    }

    /// Fills the header (next seq, `t_ns`, send time), seals and sends a copy, wakes consumers.
    /// Returns the seq used.
    pub fn send(&mut self, msg: T, t_ns: u64) -> Result<u64> {
        let t0 = std::time::Instant::now();
        let sent = self.send_timed(msg, t_ns);
        self.stats.publish_ns += t0.elapsed().as_nanos() as u64;
        sent
    }

    fn send_timed(&mut self, mut msg: T, t_ns: u64) -> Result<u64> {
        let seq = self.next_seq;
        *msg.meta_mut() = Meta::new(seq, t_ns, mono_ns(), self.producer);
        msg.seal();
        if let Some(log) = self.log.as_mut() {
            if seq == self.log_base + log.len() as u64 {
                log.push_back(msg);
            }
        }
        match self
            .tamper
            .verdict_unless_replay(seq < self.stats.published)
        {
            Verdict::Send => {}
            Verdict::Drop => {
                tracing::info!(topic = self.stats.topic.name(), seq, "injected drop");
                self.stats.drop_for(DropReason::Injected);
                self.next_seq += 1;
                self.stats.published = self.stats.published.max(self.next_seq);
                return Ok(seq);
            }
            Verdict::Corrupt(how) => {
                tracing::info!(
                    topic = self.stats.topic.name(),
                    seq,
                    how = how.name(),
                    "injected corruption"
                );
                msg.corrupt(how);
                self.stats.drop_for(DropReason::Malformed);
            }
        }
        let delivered = self
            .publisher
            .send_copy(msg)
            .map_err(|e| anyhow!("send on {}: {e:?}", self.stats.topic.name()))?;
        tracing::trace!(topic = self.stats.topic.name(), seq, delivered, "sent");
        self.next_seq += 1;
        self.stats.published = self.stats.published.max(self.next_seq);
        self.notifier
            .notify_with_custom_event_id(EVENT_DATA)
            .map_err(|e| anyhow!("notify on {}: {e:?}", self.stats.topic.name()))?;
        Ok(seq)
    }

    /// Seq of the next message sent.
    pub fn next_seq(&self) -> u64 {
        self.next_seq
    }

    /// Sends again from `seq` (a consumer restarted): messages below `stats.published` are
    /// replays, which the consumers that have them skip as duplicates.
    pub fn rewind(&mut self, seq: u64) {
        self.next_seq = seq.min(self.stats.published);
    }

    /// Sends a message exactly as given (fault injection and tests: no header rewrite, no seal).
    pub fn send_raw(&mut self, msg: T) -> Result<()> {
        self.publisher
            .send_copy(msg)
            .map_err(|e| anyhow!("send on {}: {e:?}", self.stats.topic.name()))?;
        self.notifier
            .notify_with_custom_event_id(EVENT_DATA)
            .map_err(|e| anyhow!("notify: {e:?}"))?;
        Ok(())
    }
}

/// One accepted message handed to a consumer.
pub struct Received<'a, T> {
    pub msg: &'a T,
    /// Transport + queueing latency: consumer's receive time − producer's send time [ns].
    pub latency_ns: u64,
}

pub struct Inbox<T: Message> {
    subscriber: Subscriber<Ipc, T, ()>,
    pub stats: TopicStats,
    /// Last rejection, for logs.
    pub last_reject: Option<Reject>,
}

impl<T: Message> Inbox<T> {
    /// Opens a subscriber on message topic `topic` and the listener to wait on.
    pub fn open(node: &IpcNode, topic: TopicId) -> Result<(Self, Listener<Ipc>)> {
        let subscriber = messages::<T>(node, topic)?
            .subscriber_builder()
            .create()
            .map_err(|e| anyhow!("subscriber for {}: {e:?}", topic.name()))?;
        Ok((
            Inbox {
                subscriber,
                stats: TopicStats::new(topic),
                last_reject: None,
            },
            listener(node, topic)?,
        ))
    }

    /// Receives everything queued. Malformed messages are counted and skipped; the handler
    /// returns `Err(reason)` to drop an accepted message with a counted reason.
    pub fn drain(
        &mut self,
        handle: impl FnMut(Received<'_, T>) -> Result<(), DropReason>,
    ) -> Result<usize> {
        self.drain_up_to(usize::MAX, handle)
    }

    /// As [`Inbox::drain`], taking at most `limit` samples (the rest stay queued).
    pub fn drain_up_to(
        &mut self,
        limit: usize,
        mut handle: impl FnMut(Received<'_, T>) -> Result<(), DropReason>,
    ) -> Result<usize> {
        let mut n = 0;
        while n < limit {
            let Some(sample) = self
                .subscriber
                .receive()
                .map_err(|e| anyhow!("receive on {}: {e:?}", self.stats.topic.name()))?
            else {
                break;
            };
            n += 1;
            let msg: &T = sample.payload();
            if let Err(r) = msg.check() {
                // A corrupted message cannot be trusted to carry a valid seq; count it only.
                self.stats.malformed();
                self.last_reject = Some(r);
                continue;
            }
            let (producer, seq) = (msg.meta().producer, msg.meta().seq);
            let sent_mono_ns = msg.meta().send_mono_ns;
            if self.stats.observe_sent(producer, seq, sent_mono_ns) == SeqVerdict::Duplicate {
                continue;
            }
            let latency_ns = mono_ns().saturating_sub(msg.meta().send_mono_ns);
            match handle(Received { msg, latency_ns }) {
                Ok(()) => self.stats.accept(),
                Err(reason) => self.stats.drop_for(reason),
            }
        }
        Ok(n)
    }
}

/// The sensor's frame publisher: pixels are rendered straight into the loaned sample.
pub struct FrameOutbox {
    publisher: Publisher<Ipc, [u16], FrameHeader>,
    notifier: Notifier<Ipc>,
    pixels: usize,
    /// Seq of the next frame: `stats.published` except while replaying.
    next_seq: u64,
    /// Injected drops and corruptions still to apply.
    pub tamper: Tamper,
    pub stats: TopicStats,
}

impl FrameOutbox {
    /// As [`Outbox::connect`].
    pub fn connect(&self) -> Result<()> {
        connect(&self.publisher, self.stats.topic)
    }

    /// A frame publisher on `topic`, frames of the size `scenario` gives it.
    pub fn open(node: &IpcNode, topic: TopicId, scenario: &shared_types::Scenario) -> Result<Self> {
        let pixels = shared_types::topics::frame_pixels(topic, scenario);
        let publisher = frames(node, topic, scenario)?
            .publisher_builder()
            .initial_max_slice_len(pixels)
            .allocation_strategy(AllocationStrategy::Static)
            .max_loaned_samples(1)
            .create()
            .map_err(|e| anyhow!("frame publisher: {e:?}"))?;
        Ok(FrameOutbox {
            publisher,
            notifier: notifier(node, topic)?,
            pixels,
            next_seq: 0,
            tamper: Tamper::default(),
            stats: TopicStats::new(topic),
        })
    }

    /// Seq (frame number) of the next frame published.
    pub fn next_seq(&self) -> u64 {
        self.next_seq
    }

    /// Takes up a checkpoint's accounting: the next frame is the first it had not published.
    pub fn restore_stats(&mut self, s: &crate::stats::StatsSnapshot) {
        self.stats.restore(s);
        self.next_seq = self.stats.published;
    }

    /// Whether frames below `stats.published` are still to be published again.
    pub fn replaying(&self) -> bool {
        self.next_seq < self.stats.published
    }

    /// Publishes again from frame `seq` (a consumer restarted): frames below
    /// `stats.published` are replays, which the consumers that have them skip as duplicates.
    pub fn rewind(&mut self, seq: u64) {
        self.next_seq = seq.min(self.stats.published);
    }

    /// Loans a sample, lets `render` write every pixel in place and fill the header, then sends.
    /// `render` must write all pixels: the sample memory is reused shared memory.
    pub fn publish(
        &mut self,
        t_ns: u64,
        render: impl FnOnce(&mut FrameHeader, &mut [u16]),
    ) -> Result<u64> {
        let seq = self.next_seq;
        let t_loan = std::time::Instant::now();
        let mut sample = self
            .publisher
            .loan_slice_uninit(self.pixels)
            .map_err(|e| anyhow!("frame loan: {e:?}"))?;
        let uninit = sample.payload_mut();
        // SAFETY: the payload is `pixels` u16 slots of mapped shared memory (the kernel zero-fills
        // fresh pages and reused samples hold earlier frames), so every byte is initialised at the
        // OS level and every bit pattern is a valid u16. `render` overwrites all of them before
        // `assume_init` below, which the renderers' tests check (every pixel written once).
        let pixels: &mut [u16] = unsafe {
            std::slice::from_raw_parts_mut(uninit.as_mut_ptr() as *mut u16, uninit.len())
        };
        let mut header = FrameHeader {
            meta: Meta::new(seq, t_ns, 0, ServiceId::Sensor),
            ..Default::default()
        };
        let t_render = std::time::Instant::now();
        self.stats.publish_ns += (t_render - t_loan).as_nanos() as u64;
        render(&mut header, pixels);
        let t_sum = std::time::Instant::now();
        header.pixels_xxh3 = shared_types::pixels_xxh3(pixels);
        let t_send = std::time::Instant::now();
        self.stats.checksum_ns += (t_send - t_sum).as_nanos() as u64;
        header.meta.send_mono_ns = mono_ns();
        match self.tamper.verdict_unless_replay(self.replaying()) {
            Verdict::Send => {}
            Verdict::Drop => {
                tracing::info!(seq, "injected frame drop");
                self.stats.drop_for(DropReason::Injected);
                self.next_seq += 1;
                self.stats.published = self.stats.published.max(self.next_seq);
                return Ok(seq);
            }
            Verdict::Corrupt(how) => {
                tracing::info!(seq, how = how.name(), "injected frame corruption");
                header.corrupt(how);
                self.stats.drop_for(DropReason::Malformed);
            }
        }
        *sample.user_header_mut() = header;
        // SAFETY: see above; all pixels were written by `render`.
        let sample = unsafe { sample.assume_init() };
        sample.send().map_err(|e| anyhow!("frame send: {e:?}"))?;
        self.next_seq += 1;
        self.stats.published = self.stats.published.max(self.next_seq);
        self.notifier
            .notify_with_custom_event_id(EVENT_DATA)
            .map_err(|e| anyhow!("frame notify: {e:?}"))?;
        self.stats.publish_ns += t_send.elapsed().as_nanos() as u64;
        Ok(seq)
    }
}

pub struct FrameInbox {
    subscriber: Subscriber<Ipc, [u16], FrameHeader>,
    pub stats: TopicStats,
    pub last_reject: Option<Reject>,
    /// Verify `pixels_xxh3` on every frame (costs one pass over the pixels).
    pub verify_checksum: bool,
}

impl FrameInbox {
    /// A frame subscriber on `topic` (frames of the size `scenario` gives it), verifying
    /// every frame's checksum unless told otherwise.
    pub fn open(
        node: &IpcNode,
        topic: TopicId,
        scenario: &shared_types::Scenario,
    ) -> Result<(Self, Listener<Ipc>)> {
        let subscriber = frames(node, topic, scenario)?
            .subscriber_builder()
            .create()
            .map_err(|e| anyhow!("frame subscriber: {e:?}"))?;
        Ok((
            FrameInbox {
                subscriber,
                stats: TopicStats::new(topic),
                last_reject: None,
                verify_checksum: true,
            },
            listener(node, topic)?,
        ))
    }

    /// Whether the pixels hash to the header's `pixels_xxh3` (timed).
    fn checksum_holds(&mut self, header: &FrameHeader, pixels: &[u16]) -> bool {
        let t0 = std::time::Instant::now();
        let holds = shared_types::pixels_xxh3(pixels) == header.pixels_xxh3;
        self.stats.checksum_ns += t0.elapsed().as_nanos() as u64;
        holds
    }

    /// Receives every queued frame and hands header + pixels (read in place) to `handle`.
    pub fn drain(
        &mut self,
        handle: impl FnMut(&FrameHeader, &[u16], u64) -> Result<(), DropReason>,
    ) -> Result<usize> {
        self.drain_up_to(usize::MAX, handle)
    }

    /// As [`FrameInbox::drain`], taking at most `limit` frames (the rest stay queued).
    pub fn drain_up_to(
        &mut self,
        limit: usize,
        mut handle: impl FnMut(&FrameHeader, &[u16], u64) -> Result<(), DropReason>,
    ) -> Result<usize> {
        let mut n = 0;
        while n < limit {
            let Some(sample) = self
                .subscriber
                .receive()
                .map_err(|e| anyhow!("frame receive: {e:?}"))?
            else {
                break;
            };
            n += 1;
            let header = *sample.user_header();
            let latency_ns = mono_ns().saturating_sub(header.meta.send_mono_ns);
            let pixels: &[u16] = sample.payload();
            if let Err(r) = header.validate(pixels.len()) {
                self.stats.malformed();
                self.last_reject = Some(r);
                continue;
            }
            if self.verify_checksum && !self.checksum_holds(&header, pixels) {
                let meta = header.meta;
                // A stale copy (already accounted for) is a duplicate, not a second drop.
                if self.stats.observe_sent(0, meta.seq, meta.send_mono_ns) == SeqVerdict::Accept {
                    self.stats.drop_for(DropReason::Malformed);
                }
                self.last_reject = Some(Reject {
                    field: "frame.pixels_xxh3",
                    what: "does not match the pixels",
                });
                continue;
            }
            let meta = header.meta;
            if self.stats.observe_sent(0, meta.seq, meta.send_mono_ns) == SeqVerdict::Duplicate {
                continue;
            }
            match handle(&header, pixels, latency_ns) {
                Ok(()) => self.stats.accept(),
                Err(reason) => self.stats.drop_for(reason),
            }
        }
        Ok(n)
    }
}
