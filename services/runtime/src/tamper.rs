//! In-band faults on a service's output ([`shared_types::InBandFault`]): drops and corruptions
//! armed by a fault command and applied to the next outputs, each counted on the producer's
//! side (`dropped[injected]` for a drop, `dropped[malformed]` for a message sent invalid) so
//! the report can check that its consumers counted exactly as many.

use shared_types::scenario::{Corruption, FaultKind};
use shared_types::InBandFault;

/// What to do with the next output.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    Send,
    /// Consume its seq and send nothing.
    Drop,
    /// Send it made invalid.
    Corrupt(Corruption),
}

/// The drops and corruptions still to apply to one output.
#[derive(Debug, Clone, Default)]
pub struct Tamper {
    drops_left: u32,
    drop_every: u16,
    since_drop: u16,
    corrupt_left: u32,
    how: Corruption,
}

impl Tamper {
    /// Arms a `drop` or `corrupt` order (other kinds are not about outputs).
    pub fn arm(&mut self, f: &InBandFault) {
        match f.kind {
            FaultKind::Drop => {
                self.drops_left += f.count;
                self.drop_every = f.every.max(1);
                self.since_drop = 0;
            }
            FaultKind::Corrupt => {
                self.corrupt_left += f.count;
                self.how = f.how;
            }
            _ => {}
        }
    }

    /// The verdict on the next output, or `Send` for a replay (what a restarted consumer is
    /// sent again is never tampered with).
    pub fn verdict_unless_replay(&mut self, replay: bool) -> Verdict {
        if replay {
            Verdict::Send
        } else {
            self.verdict()
        }
    }

    /// The verdict on the next output.
    pub fn verdict(&mut self) -> Verdict {
        if self.corrupt_left > 0 {
            self.corrupt_left -= 1;
            return Verdict::Corrupt(self.how);
        }
        if self.drops_left > 0 {
            self.since_drop += 1;
            if self.since_drop >= self.drop_every {
                self.since_drop = 0;
                self.drops_left -= 1;
                return Verdict::Drop;
            }
        }
        Verdict::Send
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn order(kind: FaultKind, count: u32, every: u16) -> InBandFault {
        InBandFault {
            kind,
            how: Corruption::Nan,
            count,
            every,
            delay_ms: 0,
            duration_ms: 0,
        }
    }

    #[test]
    fn drops_every_kth_output_count_times_and_corrupts_first() {
        let mut t = Tamper::default();
        t.arm(&order(FaultKind::Drop, 2, 3));
        let v: Vec<Verdict> = (0..8).map(|_| t.verdict()).collect();
        let drops: Vec<usize> = (0..8).filter(|i| v[*i] == Verdict::Drop).collect();
        assert_eq!(drops, [2, 5]);
        t.arm(&order(FaultKind::Corrupt, 1, 1));
        assert_eq!(t.verdict(), Verdict::Corrupt(Corruption::Nan));
        assert_eq!(t.verdict(), Verdict::Send);
    }
}
