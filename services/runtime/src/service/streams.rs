//! The ports of a service as the skeleton sees them: a produced topic ([`Output`]: its
//! accounting, credit, replays, log and faults) and a consumed one ([`Input`]), for message
//! and frame topics alike.

use anyhow::Result;
use shared_types::{DropReason, FrameHeader, Message};

use crate::checkpoint::OutputSnapshot;
use crate::ports::{FrameInbox, FrameOutbox, Inbox, Outbox};
use crate::stats::TopicStats;
use crate::tamper::Tamper;

/// A produced topic, as the skeleton sees it.
pub trait Output {
    fn stats(&self) -> &TopicStats;
    fn next_seq(&self) -> u64;
    /// Sends again from `seq` (a consumer restarted).
    fn rewind(&mut self, seq: u64);
    /// Whether messages below `stats().published` are still to be sent again.
    fn replaying(&self) -> bool;
    /// Whether replays are re-sent from a log ([`Output::resend`]) rather than re-made by the
    /// service.
    fn logged(&self) -> bool;
    /// Re-sends at most `limit` logged messages; how many were sent.
    fn resend(&mut self, limit: u64) -> Result<u64>;
    fn tamper(&mut self) -> &mut Tamper;
    /// Its accounting and log for a checkpoint (the skeleton adds the credit).
    fn snapshot(&self) -> OutputSnapshot;
    /// Takes up a checkpoint's accounting and log.
    fn restore(&mut self, s: &OutputSnapshot) -> Result<()>;
    /// Forgets logged messages below `seq` (every consumer's checkpoint covers them).
    fn trim(&mut self, seq: u64);
    /// Hands new subscribers the topic's history now ([`Outbox::connect`]).
    fn connect(&self) -> Result<()>;
}

impl<T: Message> Output for Outbox<T> {
    fn connect(&self) -> Result<()> {
        Outbox::connect(self)
    }
    fn stats(&self) -> &TopicStats {
        &self.stats
    }
    fn next_seq(&self) -> u64 {
        Outbox::next_seq(self)
    }
    fn rewind(&mut self, seq: u64) {
        Outbox::rewind(self, seq)
    }
    fn replaying(&self) -> bool {
        Outbox::replaying(self)
    }
    fn logged(&self) -> bool {
        self.has_log()
    }
    fn resend(&mut self, limit: u64) -> Result<u64> {
        Outbox::resend(self, limit)
    }
    fn tamper(&mut self) -> &mut Tamper {
        &mut self.tamper
    }
    fn snapshot(&self) -> OutputSnapshot {
        OutputSnapshot {
            stats: self.stats.snapshot(),
            credit: vec![],
            log_base: self.log_span().0,
            log: self.log_bytes(),
        }
    }
    fn restore(&mut self, s: &OutputSnapshot) -> Result<()> {
        Outbox::restore(self, &s.stats, s.log_base, &s.log)
    }
    fn trim(&mut self, seq: u64) {
        self.trim_log(seq)
    }
}

impl Output for FrameOutbox {
    fn connect(&self) -> Result<()> {
        FrameOutbox::connect(self)
    }
    fn stats(&self) -> &TopicStats {
        &self.stats
    }
    fn next_seq(&self) -> u64 {
        FrameOutbox::next_seq(self)
    }
    fn rewind(&mut self, seq: u64) {
        FrameOutbox::rewind(self, seq)
    }
    fn replaying(&self) -> bool {
        FrameOutbox::replaying(self)
    }
    fn logged(&self) -> bool {
        false
    }
    fn resend(&mut self, _limit: u64) -> Result<u64> {
        Ok(0)
    }
    fn tamper(&mut self) -> &mut Tamper {
        &mut self.tamper
    }
    fn snapshot(&self) -> OutputSnapshot {
        OutputSnapshot {
            stats: self.stats.snapshot(),
            credit: vec![],
            log_base: 0,
            log: vec![],
        }
    }
    fn restore(&mut self, s: &OutputSnapshot) -> Result<()> {
        self.restore_stats(&s.stats);
        Ok(())
    }
    fn trim(&mut self, _seq: u64) {}
}

/// One frame handed to a consumer: header and pixels, read in place in shared memory.
pub struct Frame<'a> {
    pub header: &'a FrameHeader,
    pub pixels: &'a [u16],
}

/// A consumed topic, as the skeleton sees it.
pub trait Input {
    /// What one message is handed to the service as.
    type Item<'a>;
    fn stats(&self) -> Option<&TopicStats>;
    fn stats_mut(&mut self) -> Option<&mut TopicStats>;
    /// The simulated time of an item [ns].
    fn t_ns(item: &Self::Item<'_>) -> u64;
    /// Takes at most `limit` messages: `handle` gets each valid, new one with its latency and
    /// returns `Err(reason)` to drop it (counted).
    fn take<F>(&mut self, limit: usize, handle: F) -> Result<()>
    where
        F: for<'a> FnMut(Self::Item<'a>, u64) -> Result<(), DropReason>;
}

impl<T: Message> Input for Inbox<T> {
    type Item<'a> = &'a T;
    fn stats(&self) -> Option<&TopicStats> {
        Some(&self.stats)
    }
    fn stats_mut(&mut self) -> Option<&mut TopicStats> {
        Some(&mut self.stats)
    }
    fn t_ns(item: &&T) -> u64 {
        item.meta().t_ns
    }
    fn take<F>(&mut self, limit: usize, mut handle: F) -> Result<()>
    where
        F: for<'a> FnMut(&'a T, u64) -> Result<(), DropReason>,
    {
        self.drain_up_to(limit, |r| handle(r.msg, r.latency_ns))?;
        Ok(())
    }
}

impl Input for FrameInbox {
    type Item<'a> = Frame<'a>;
    fn stats(&self) -> Option<&TopicStats> {
        Some(&self.stats)
    }
    fn stats_mut(&mut self) -> Option<&mut TopicStats> {
        Some(&mut self.stats)
    }
    fn t_ns(item: &Frame<'_>) -> u64 {
        item.header.meta.t_ns
    }
    fn take<F>(&mut self, limit: usize, mut handle: F) -> Result<()>
    where
        F: for<'a> FnMut(Frame<'a>, u64) -> Result<(), DropReason>,
    {
        self.drain_up_to(limit, |header, pixels, latency_ns| {
            handle(Frame { header, pixels }, latency_ns)
        })?;
        Ok(())
    }
}

/// The input of a source (the sensor): none.
pub struct NoInput;

impl Input for NoInput {
    type Item<'a> = ();
    fn stats(&self) -> Option<&TopicStats> {
        None
    }
    fn stats_mut(&mut self) -> Option<&mut TopicStats> {
        None
    }
    fn t_ns(_: &()) -> u64 {
        0
    }
    fn take<F>(&mut self, _limit: usize, _handle: F) -> Result<()>
    where
        F: for<'a> FnMut((), u64) -> Result<(), DropReason>,
    {
        Ok(())
    }
}
