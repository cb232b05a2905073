//! A link's own accounting: each bridge numbers what it puts on the wire per (topic, origin
//! host) without gaps, so the receiving bridge counts what the link lost (a gap) and what it
//! repeated, whatever Zenoh did underneath. A receiver counts from the first message it sees
//! of each (topic, origin): a bridge restarted mid-run joins the stream where it stands (what
//! its dead incarnation missed is counted end to end, by the consumers' seq gaps).

use shared_types::TopicId;

/// What to do with a message off the wire, by its link sequence.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LinkVerdict {
    /// In order; `lost` messages before it never arrived.
    Take { lost: u64 },
    /// Already taken (a repeat): skip it.
    Repeat,
}

/// Next expected link sequence per (topic, origin host).
#[derive(Debug, Default, Clone)]
pub struct LinkSeqs {
    next: Vec<((TopicId, u16), u64)>,
}

impl LinkSeqs {
    /// The next link sequence a sender stamps on `topic` (from 0, gap-free).
    pub fn stamp(&mut self, topic: TopicId, origin: u16) -> u64 {
        let next = self.slot(topic, origin);
        let seq = *next;
        *next += 1;
        seq
    }

    /// A receiver's verdict on `link_seq` of `topic` from `origin`.
    pub fn observe(&mut self, topic: TopicId, origin: u16, link_seq: u64) -> LinkVerdict {
        if !self.next.iter().any(|(k, _)| *k == (topic, origin)) {
            self.next.push(((topic, origin), link_seq + 1));
            return LinkVerdict::Take { lost: 0 };
        }
        let next = self.slot(topic, origin);
        // A sender that starts again from 0 is a new incarnation of that host's bridge.
        if link_seq == 0 && *next > 0 {
            *next = 1;
            return LinkVerdict::Take { lost: 0 };
        }
        if link_seq < *next {
            return LinkVerdict::Repeat;
        }
        let lost = link_seq - *next;
        *next = link_seq + 1;
        LinkVerdict::Take { lost }
    }

    fn slot(&mut self, topic: TopicId, origin: u16) -> &mut u64 {
        let i = match self.next.iter().position(|(k, _)| *k == (topic, origin)) {
            Some(i) => i,
            None => {
                self.next.push(((topic, origin), 0));
                self.next.len() - 1
            }
        };
        &mut self.next[i].1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gaps_are_lost_repeats_are_skipped_per_topic_and_origin() {
        let mut tx = LinkSeqs::default();
        let sent: Vec<u64> = (0..4).map(|_| tx.stamp(TopicId::Frame, 0)).collect();
        assert_eq!(sent, [0, 1, 2, 3]);
        assert_eq!(tx.stamp(TopicId::Ack, 0), 0);
        let mut rx = LinkSeqs::default();
        assert_eq!(
            rx.observe(TopicId::Frame, 0, 0),
            LinkVerdict::Take { lost: 0 }
        );
        assert_eq!(
            rx.observe(TopicId::Frame, 0, 3),
            LinkVerdict::Take { lost: 2 }
        );
        assert_eq!(rx.observe(TopicId::Frame, 0, 2), LinkVerdict::Repeat);
        assert_eq!(
            rx.observe(TopicId::Frame, 1, 0),
            LinkVerdict::Take { lost: 0 }
        );
        // a receiver joins a stream where it stands (a bridge restarted mid-run)
        assert_eq!(
            rx.observe(TopicId::Ack, 0, 7),
            LinkVerdict::Take { lost: 0 }
        );
        assert_eq!(
            rx.observe(TopicId::Ack, 0, 9),
            LinkVerdict::Take { lost: 1 }
        );
        // a restarted sender begins again at 0
        assert_eq!(
            rx.observe(TopicId::Frame, 0, 0),
            LinkVerdict::Take { lost: 0 }
        );
        assert_eq!(
            rx.observe(TopicId::Frame, 0, 1),
            LinkVerdict::Take { lost: 0 }
        );
    }
}
