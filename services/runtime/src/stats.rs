//! Per-topic accounting: every message is processed or dropped with a counted reason.
//!
//! Sequence numbers are gap-free per producer, so a consumer can tell exactly how many samples
//! the transport overwrote (safe overflow, realtime mode) without any help from the producer.

use shared_types::{DropReason, TopicCounters, TopicId, DROP_REASONS};

#[derive(Debug, Clone)]
pub struct TopicStats {
    pub topic: TopicId,
    /// Producer side: messages sent.
    pub published: u64,
    /// Consumer side: messages accepted.
    pub received: u64,
    pub dropped: [u64; DROP_REASONS],
    /// Next expected sequence number (everything below is accounted for). On a topic with one
    /// producer (every data topic) this is that producer's; many-to-one topics (heartbeat, ack)
    /// are accounted per producer in `per_producer`.
    pub next_seq: u64,
    per_producer: Vec<(u32, u64)>,
}

/// What the consumer should do with a message after sequence accounting.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SeqVerdict {
    /// In order (possibly after a counted gap): process it.
    Accept,
    /// Already seen: counted as stale, skip it.
    Stale,
}

impl TopicStats {
    pub fn new(topic: TopicId) -> Self {
        TopicStats {
            topic,
            published: 0,
            received: 0,
            dropped: [0; DROP_REASONS],
            next_seq: 0,
            per_producer: Vec::new(),
        }
    }

    /// Accounts for the arrival of `seq` from the topic's single producer: gaps before it
    /// become `Overflow` drops.
    pub fn observe_seq(&mut self, seq: u64) -> SeqVerdict {
        self.observe(0, seq)
    }

    /// Accounts for the arrival of `seq` from `producer` (sequence numbers are per producer).
    pub fn observe(&mut self, producer: u32, seq: u64) -> SeqVerdict {
        let slot = match self.per_producer.iter().position(|(p, _)| *p == producer) {
            Some(i) => i,
            None => {
                self.per_producer.push((producer, 0));
                self.per_producer.len() - 1
            }
        };
        let next = &mut self.per_producer[slot].1;
        if seq < *next {
            self.dropped[DropReason::Stale as usize] += 1;
            return SeqVerdict::Stale;
        }
        if seq > *next {
            self.dropped[DropReason::Overflow as usize] += seq - *next;
        }
        *next = seq + 1;
        self.next_seq = *next;
        SeqVerdict::Accept
    }

    /// A message whose seq was accepted, then processed.
    pub fn accept(&mut self) {
        self.received += 1;
    }

    /// A message whose seq was accepted, then dropped for `reason`.
    pub fn drop_for(&mut self, reason: DropReason) {
        self.dropped[reason as usize] += 1;
    }

    pub fn dropped_total(&self) -> u64 {
        self.dropped.iter().sum()
    }

    pub fn counters(&self) -> TopicCounters {
        TopicCounters {
            topic: self.topic as u32,
            _pad: 0,
            published: self.published,
            received: self.received,
            dropped: self.dropped,
            next_seq: self.next_seq,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn producers_are_accounted_separately() {
        let mut s = TopicStats::new(TopicId::Heartbeat);
        for (producer, seq) in [(1, 0), (2, 0), (1, 1), (2, 1), (2, 2), (1, 2)] {
            assert_eq!(s.observe(producer, seq), SeqVerdict::Accept);
            s.accept();
        }
        assert_eq!(s.received, 6);
        assert_eq!(s.dropped_total(), 0);
        assert_eq!(s.observe(2, 1), SeqVerdict::Stale);
    }

    #[test]
    fn gaps_and_duplicates_are_counted() {
        let mut s = TopicStats::new(TopicId::Frame);
        for seq in [0, 1, 4, 4, 5] {
            if s.observe_seq(seq) == SeqVerdict::Accept {
                s.accept();
            }
        }
        assert_eq!(s.received, 4);
        assert_eq!(s.dropped[DropReason::Overflow as usize], 2);
        assert_eq!(s.dropped[DropReason::Stale as usize], 1);
        // invariant: every seq below next_seq is received or dropped (duplicates are extra)
        assert_eq!(
            s.received + s.dropped[DropReason::Overflow as usize],
            s.next_seq
        );
    }
}
