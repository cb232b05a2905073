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
    /// Copies of messages already accounted for (a producer's replay): skipped, not dropped.
    pub duplicates: u64,
    per_producer: Vec<(u32, u64)>,
    /// A restarted consumer: everything before its producer's replay reaches this seq (its
    /// checkpoint's `next_seq`, or 0; history, messages in flight) is skipped as a duplicate;
    /// the replay brings it again in order.
    awaiting_replay: Option<AwaitedReplay>,
    /// Many-to-one housekeeping topics (heartbeat, ack, control): a producer joins at whatever
    /// seq it is at, and a seq going back means that producer restarted.
    peers_restart: bool,
    /// Messages rejected as malformed since the last accepted one: each held a seq the
    /// consumer could not trust, so the gap they leave is theirs, not an overflow.
    unread_malformed: u64,
    /// Time spent loaning and sending on this topic [ns] (producer side; a frame's render into
    /// its loan excluded).
    pub publish_ns: u64,
    /// Time spent on frame checksums on this topic [ns]: computed (producer) or verified.
    pub checksum_ns: u64,
}

/// A topic's accounting as a checkpoint keeps it.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StatsSnapshot {
    pub topic: u32,
    pub published: u64,
    pub received: u64,
    pub dropped: [u64; DROP_REASONS],
    pub next_seq: u64,
    pub duplicates: u64,
    pub per_producer: Vec<(u32, u64)>,
}

/// Where a restarted consumer's replay starts, and when the consumer started waiting for it.
#[derive(Debug, Clone, Copy)]
struct AwaitedReplay {
    seq: u64,
    /// `CLOCK_MONOTONIC` [ns] when the consumer began to wait. A copy of `seq` sent before is
    /// not the replay's but a stale one (the topic's history, or one in flight to the dead
    /// incarnation): accepting it would start the consumer on a stream whose next messages
    /// the producer's credit no longer counts as in flight, and the replay's copies of them
    /// would push out the rest of the replay from the subscriber's buffer.
    since_mono_ns: u64,
}

/// What the consumer should do with a message after sequence accounting.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SeqVerdict {
    /// In order (possibly after a counted gap): process it.
    Accept,
    /// Already accounted for (a replay): counted as a duplicate, skip it.
    Duplicate,
}

impl TopicStats {
    pub fn new(topic: TopicId) -> Self {
        TopicStats {
            topic,
            published: 0,
            received: 0,
            dropped: [0; DROP_REASONS],
            next_seq: 0,
            duplicates: 0,
            per_producer: Vec::new(),
            awaiting_replay: None,
            peers_restart: false,
            unread_malformed: 0,
            publish_ns: 0,
            checksum_ns: 0,
        }
    }

    /// A message failed validation: counted as `malformed`; the seq it held is accounted for
    /// by the next gap.
    pub fn malformed(&mut self) {
        self.dropped[DropReason::Malformed as usize] += 1;
        self.unread_malformed += 1;
    }

    /// Accounting of a restarted consumer whose producer replays from its `next_seq` (0, or
    /// where its restored checkpoint left it), every copy sent from now on.
    pub fn await_replay(&mut self) {
        self.await_replay_since(crate::clock::mono_ns());
    }

    /// As [`TopicStats::await_replay`], for copies sent from `since_mono_ns` on.
    pub fn await_replay_since(&mut self, since_mono_ns: u64) {
        self.awaiting_replay = Some(AwaitedReplay {
            seq: self.next_seq,
            since_mono_ns,
        });
    }

    /// The accounting a checkpoint keeps.
    pub fn snapshot(&self) -> StatsSnapshot {
        StatsSnapshot {
            topic: self.topic as u32,
            published: self.published,
            received: self.received,
            dropped: self.dropped,
            next_seq: self.next_seq,
            duplicates: self.duplicates,
            per_producer: self.per_producer.clone(),
        }
    }

    /// Takes up a checkpoint's accounting (timings start again).
    pub fn restore(&mut self, s: &StatsSnapshot) {
        self.published = s.published;
        self.received = s.received;
        self.dropped = s.dropped;
        self.next_seq = s.next_seq;
        self.duplicates = s.duplicates;
        self.per_producer = s.per_producer.clone();
    }

    /// Accounting of a many-to-one housekeeping topic whose producers may restart.
    pub fn peers_restart(&mut self) {
        self.peers_restart = true;
    }

    /// Accounts for the arrival of `seq` from the topic's single producer: gaps before it
    /// become `Overflow` drops.
    pub fn observe_seq(&mut self, seq: u64) -> SeqVerdict {
        self.observe(0, seq)
    }

    /// Accounts for the arrival of `seq` from `producer` (sequence numbers are per producer),
    /// sent at `sent_mono_ns` (`CLOCK_MONOTONIC`).
    pub fn observe_sent(&mut self, producer: u32, seq: u64, sent_mono_ns: u64) -> SeqVerdict {
        if let Some(awaited) = self.awaiting_replay {
            if seq != awaited.seq || sent_mono_ns < awaited.since_mono_ns {
                self.duplicates += 1;
                return SeqVerdict::Duplicate;
            }
            self.awaiting_replay = None;
        }
        self.observe_in_order(producer, seq)
    }

    /// Accounts for the arrival of `seq` from `producer` on a topic whose consumer waits for no
    /// replay (housekeeping).
    pub fn observe(&mut self, producer: u32, seq: u64) -> SeqVerdict {
        self.observe_sent(producer, seq, u64::MAX)
    }

    fn observe_in_order(&mut self, producer: u32, seq: u64) -> SeqVerdict {
        let slot = match self.per_producer.iter().position(|(p, _)| *p == producer) {
            Some(i) => i,
            None => {
                // The first producer heard from starts where the topic's accounting stands (0,
                // or where a restart's continue order put it); another one at 0.
                let first = match (self.peers_restart, self.per_producer.is_empty()) {
                    (true, _) => seq,
                    (false, true) => self.next_seq,
                    (false, false) => 0,
                };
                self.per_producer.push((producer, first));
                self.per_producer.len() - 1
            }
        };
        let next = &mut self.per_producer[slot].1;
        if seq < *next && self.peers_restart {
            // A new incarnation of that producer.
            *next = seq;
        }
        if seq < *next {
            self.duplicates += 1;
            return SeqVerdict::Duplicate;
        }
        if seq > *next {
            let gap = seq - *next;
            let theirs = gap.min(self.unread_malformed);
            self.dropped[DropReason::Overflow as usize] += gap - theirs;
        }
        self.unread_malformed = 0;
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
            duplicates: self.duplicates.min(u64::from(u32::MAX)) as u32,
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
        assert_eq!(s.observe(2, 1), SeqVerdict::Duplicate);
    }

    #[test]
    fn a_restarted_consumer_skips_everything_before_the_replay_starts() {
        let mut s = TopicStats::new(TopicId::Frame);
        s.await_replay();
        // History and frames in flight first, then the replay from 0.
        for seq in [36, 37, 38, 0, 1, 2, 3] {
            if s.observe_seq(seq) == SeqVerdict::Accept {
                s.accept();
            }
        }
        assert_eq!((s.received, s.duplicates, s.dropped_total()), (4, 3, 0));
        assert_eq!(s.next_seq, 4);
    }

    #[test]
    fn a_consumer_restored_from_a_checkpoint_takes_the_replay_from_where_it_left_off() {
        let mut before = TopicStats::new(TopicId::Frame);
        for seq in 0..40 {
            before.observe_seq(seq);
            before.accept();
        }
        let at_checkpoint = before.snapshot();
        let mut s = TopicStats::new(TopicId::Frame);
        s.restore(&at_checkpoint);
        s.await_replay();
        // In flight when it died, then the replay from its checkpoint on.
        for seq in [52, 53, 40, 41, 42] {
            if s.observe_seq(seq) == SeqVerdict::Accept {
                s.accept();
            }
        }
        assert_eq!((s.received, s.duplicates, s.dropped_total()), (43, 2, 0));
        assert_eq!(s.next_seq, 43);
        assert_eq!(s.received + s.dropped_total(), s.next_seq);
    }

    #[test]
    fn stale_copies_of_the_replays_first_messages_are_not_the_replay() {
        // Restored at 28: the topic's history still holds 27, 28 and 29, sent to the dead
        // incarnation (before t = 1000 ns); the replay sends 28, 29, … again after it.
        let mut before = TopicStats::new(TopicId::EarthFrame);
        for seq in 0..28 {
            before.observe_seq(seq);
            before.accept();
        }
        let mut s = TopicStats::new(TopicId::EarthFrame);
        s.restore(&before.snapshot());
        s.await_replay_since(1000);
        let arrivals = [
            (27, 400),
            (28, 500),
            (29, 600),
            (28, 1100),
            (29, 1200),
            (30, 1300),
        ];
        let taken: Vec<(u64, u64)> = arrivals
            .into_iter()
            .filter(|&(seq, sent)| s.observe_sent(0, seq, sent) == SeqVerdict::Accept)
            .collect();
        assert_eq!(
            taken,
            [(28, 1100), (29, 1200), (30, 1300)],
            "the replay's copies"
        );
        assert_eq!((s.duplicates, s.dropped_total(), s.next_seq), (3, 0, 31));
    }

    #[test]
    fn a_malformed_message_accounts_for_the_gap_it_leaves() {
        let mut s = TopicStats::new(TopicId::Detections);
        for seq in 0..3 {
            s.observe_seq(seq);
            s.accept();
        }
        s.malformed(); // seq 3, unreadable
        s.observe_seq(4);
        s.accept();
        // seqs 5 and 6 lost in the transport
        s.observe_seq(7);
        s.accept();
        assert_eq!(s.received, 5);
        assert_eq!(s.dropped[DropReason::Malformed as usize], 1);
        assert_eq!(s.dropped[DropReason::Overflow as usize], 2);
        assert_eq!(s.received + s.dropped_total(), s.next_seq);
    }

    #[test]
    fn housekeeping_peers_join_late_and_restart() {
        let mut s = TopicStats::new(TopicId::Heartbeat);
        s.peers_restart();
        // The orchestrator's control seq is at 7 when a restarted service subscribes.
        assert_eq!(s.observe(1, 7), SeqVerdict::Accept);
        assert_eq!(s.observe(1, 8), SeqVerdict::Accept);
        // Producer 2 restarted: its seq starts over.
        for seq in [0, 1, 2, 0, 1] {
            assert_eq!(s.observe(2, seq), SeqVerdict::Accept);
        }
        assert_eq!((s.dropped_total(), s.duplicates), (0, 0));
        s.observe(2, 4);
        assert_eq!(
            s.dropped[DropReason::Overflow as usize],
            2,
            "a real gap still counts"
        );
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
        assert_eq!(s.duplicates, 1);
        // invariant: every seq below next_seq is received or dropped (duplicates are extra)
        assert_eq!(
            s.received + s.dropped[DropReason::Overflow as usize],
            s.next_seq
        );
    }
}
