//! Sim-clock credit (docs/adr/0001): a producer publishes message `k` on a topic only while
//! `k − acked < window` for every consumer of that topic, so no subscriber buffer overflows.

use std::collections::BTreeMap;

use anyhow::Result;
use iceoryx2::port::listener::Listener;
use shared_types::topics::{Ipc, IpcNode};
use shared_types::{Ack, ServiceId, TopicId};

use crate::ports::Inbox;

/// Credit of one produced topic.
#[derive(Debug, Clone)]
pub struct Credit {
    window: u64,
    acked: BTreeMap<ServiceId, u64>,
    /// Per consumer: everything below is in its checkpoint.
    checkpointed: BTreeMap<ServiceId, u64>,
}

impl Credit {
    pub fn new(window: usize, consumers: Vec<ServiceId>) -> Self {
        Credit {
            window: window as u64,
            checkpointed: consumers.iter().map(|c| (*c, 0)).collect(),
            acked: consumers.into_iter().map(|c| (c, 0)).collect(),
        }
    }

    /// May message number `published` (0-based) be sent now?
    pub fn allows(&self, published: u64) -> bool {
        self.acked
            .values()
            .all(|&a| published.saturating_sub(a) < self.window)
    }

    /// How many more messages may be sent now.
    pub fn available(&self, published: u64) -> u64 {
        self.acked
            .values()
            .map(|&a| (a + self.window).saturating_sub(published))
            .min()
            .unwrap_or(u64::MAX)
    }

    /// How many inputs a service that publishes one message per input may take now: the credit
    /// in sim-clock mode, everything in realtime mode (drops are counted downstream there).
    pub fn input_limit(&self, published: u64, realtime: bool) -> usize {
        if realtime {
            usize::MAX
        } else {
            self.available(published).min(usize::MAX as u64) as usize
        }
    }

    /// A restarted consumer starts again at `next_seq`: its credit restarts there.
    pub fn reset(&mut self, consumer: ServiceId, next_seq: u64) {
        if let Some(a) = self.acked.get_mut(&consumer) {
            *a = next_seq;
        }
    }

    pub fn record(&mut self, consumer: ServiceId, next_seq: u64, checkpoint_seq: u64) {
        if let Some(a) = self.acked.get_mut(&consumer) {
            *a = (*a).max(next_seq);
        }
        if let Some(c) = self.checkpointed.get_mut(&consumer) {
            *c = (*c).max(checkpoint_seq);
        }
    }

    /// The first message a replay may still ask for: every consumer's checkpoint covers what
    /// is below.
    pub fn replayable_from(&self) -> u64 {
        self.checkpointed
            .values()
            .copied()
            .min()
            .unwrap_or(u64::MAX)
    }

    /// Per consumer: (id, acknowledged up to, checkpointed up to), for a checkpoint.
    pub fn snapshot(&self) -> Vec<(u32, u64, u64)> {
        self.acked
            .iter()
            .map(|(c, a)| {
                (
                    *c as u32,
                    *a,
                    self.checkpointed.get(c).copied().unwrap_or(0),
                )
            })
            .collect()
    }

    /// Takes up a checkpoint's credit (acks only grow, so it is a lower bound of the present).
    pub fn restore(&mut self, credit: &[(u32, u64, u64)]) {
        for &(c, a, k) in credit {
            if let Some(c) = ServiceId::from_u32(c) {
                self.record(c, a, k);
            }
        }
    }
}

/// Reads the `ack` topic and feeds the credits of the topics this service produces.
pub struct AckReader {
    inbox: Inbox<Ack>,
}

impl AckReader {
    pub fn open(node: &IpcNode) -> Result<(Self, Listener<Ipc>)> {
        let (mut inbox, l) = Inbox::open(node, TopicId::Ack)?;
        inbox.stats.peers_restart();
        Ok((AckReader { inbox }, l))
    }

    /// Applies every pending ack to the matching credit in `credits`.
    pub fn poll(&mut self, credits: &mut [(TopicId, &mut Credit)]) -> Result<()> {
        self.inbox.drain(|r| {
            let a = r.msg;
            if let (Some(topic), Some(consumer)) =
                (TopicId::from_u32(a.topic), ServiceId::from_u32(a.consumer))
            {
                for (t, c) in credits.iter_mut() {
                    if *t == topic {
                        c.record(consumer, a.next_seq, a.checkpoint_seq);
                    }
                }
            }
            Ok(())
        })?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn credit_is_the_slowest_consumers_window() {
        let mut c = Credit::new(4, vec![ServiceId::Detector, ServiceId::Orchestrator]);
        assert_eq!(c.available(0), 4);
        assert!(c.allows(3) && !c.allows(4));
        c.record(ServiceId::Detector, 3, 0);
        assert!(!c.allows(4), "the orchestrator has not acked");
        c.record(ServiceId::Orchestrator, 2, 0);
        assert_eq!(c.available(4), 2);
        c.record(ServiceId::Tracker, 100, 0); // not a consumer of this topic: ignored
        assert_eq!(c.available(4), 2);
        // A restarted detector starts over: its window is counted from 0 again.
        c.record(ServiceId::Orchestrator, 4, 0);
        c.reset(ServiceId::Detector, 0);
        assert!(c.allows(3) && !c.allows(4));
    }
}
