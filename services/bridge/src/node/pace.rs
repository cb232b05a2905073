//! A slow link, injected: the scenario's `delay` faults on this host's bridge
//! (`[[fault]] service = "bridge", kind = "delay"`, `host` this host). The bridge fires them
//! itself when their trigger is reached (an order to `bridge` over control would reach every
//! host's bridge): `delay_ms` before each data message its egress puts on the wire, for
//! `count` messages or `duration_s`. The link then carries at most one message per `delay_ms`;
//! with `bandwidth_mbit_s`, each message also waits the time its bytes take at that rate
//! (one message on the wire at a time, as through a link of that bandwidth).

use std::sync::Mutex;
use std::time::{Duration, Instant};

use shared_types::scenario::{FaultKind, FaultSpec};
use shared_types::{deployment, Scenario, ServiceId, TopicId};

/// When a pace ends.
#[derive(Debug, Clone, Copy, PartialEq)]
enum End {
    After(u32),
    At(Instant),
}

/// A slow link in force.
#[derive(Debug, Clone, Copy)]
struct Slow {
    /// Waited before each data message.
    delay: Duration,
    /// The link's bandwidth [bit/s] (`None`: not limited).
    bandwidth_bit_s: Option<f64>,
    end: End,
    /// When it held its first message, messages and bytes it slowed so far.
    first: Option<Instant>,
    slowed: u64,
    bytes: u64,
    /// A message is held now (a pace by time ends once it is out).
    holding: bool,
}

impl Slow {
    /// The log line of its end: what it slowed, and the rate its data crossed at (from its
    /// first held message to now).
    fn over(&self) {
        let (slowed, bytes) = (self.slowed, self.bytes);
        let s = self.first.map_or(0.0, |t| t.elapsed().as_secs_f64());
        let mbit_s = bytes as f64 * 8.0 / s.max(1e-9) / 1e6;
        tracing::info!(
            slowed,
            bytes,
            "slow link over: {slowed} messages slowed, {bytes} bytes at {mbit_s:.2} Mbit/s"
        );
    }
}

/// The pace in force: shared by the main thread (which starts it) and the egress (which keeps
/// it before each data put).
#[derive(Default)]
pub struct Pace {
    on: Mutex<Option<Slow>>,
}

impl Pace {
    /// Starts pacing: `delay_ms` and the bytes' time at `bandwidth_mbit_s` before each data
    /// put, until `count` messages or `duration_s`.
    fn start(&self, f: &FaultSpec) {
        let end = match (f.count, f.duration_s) {
            (Some(n), _) => End::After(n),
            (None, d) => End::At(Instant::now() + Duration::from_secs_f64(d.unwrap_or(0.0))),
        };
        *self.lock() = Some(Slow {
            delay: Duration::from_millis(f.delay_ms.unwrap_or(0)),
            bandwidth_bit_s: f.bandwidth_mbit_s.map(|r| r * 1e6),
            end,
            first: None,
            slowed: 0,
            bytes: 0,
            holding: false,
        });
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Option<Slow>> {
        self.on.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Before a data put of `bytes`: waits what the slow link in force takes, if any.
    pub fn keep(&self, bytes: usize) {
        let wait = {
            let mut on = self.lock();
            let Some(slow) = on.as_mut() else {
                return;
            };
            let over = match slow.end {
                End::At(t) => Instant::now() >= t,
                End::After(n) => n == 0,
            };
            if over {
                slow.over();
                *on = None;
                return;
            }
            if let End::After(n) = &mut slow.end {
                *n -= 1;
            }
            slow.first.get_or_insert_with(Instant::now);
            slow.slowed += 1;
            slow.bytes += bytes as u64;
            slow.holding = true;
            let on_the_wire = (slow.bandwidth_bit_s).map_or(Duration::ZERO, |r| {
                Duration::from_secs_f64(bytes as f64 * 8.0 / r)
            });
            slow.delay + on_the_wire
        };
        std::thread::sleep(wait);
        // The last message of a pace by count: over now, not at the next message.
        let mut on = self.lock();
        if let Some(slow) = on.as_mut() {
            slow.holding = false;
        }
        if let Some(slow) = on.filter(|s| s.end == End::After(0)) {
            slow.over();
            *on = None;
        }
    }

    /// Whether a pace is in force (the heartbeat's `delaying`).
    pub fn on(&self) -> bool {
        let mut on = self.lock();
        // A pace by time ends at its time, messages or not, once the message it holds is out.
        let due = |s: &Slow| !s.holding && matches!(s.end, End::At(t) if Instant::now() >= t);
        if let Some(slow) = on.filter(due) {
            slow.over();
            *on = None;
        }
        on.is_some()
    }
}

/// This host's bridge's `delay` faults, fired in order when their trigger is reached.
pub struct Delays {
    due: Vec<FaultSpec>,
    trigger: Option<TopicId>,
    /// The run's `Start`: `at_s` counts from it.
    started: Option<Instant>,
}

impl Delays {
    pub fn new(scenario: &Scenario, host: &str) -> Self {
        let mine = |f: &&FaultSpec| {
            f.service_id() == Some(ServiceId::Bridge)
                && f.kind == FaultKind::Delay
                && f.on_host(scenario) == Some(host)
        };
        Delays {
            due: scenario.fault.iter().filter(mine).cloned().rev().collect(),
            trigger: deployment::trigger_topic(scenario, ServiceId::Bridge),
            started: None,
        }
    }

    pub fn start(&mut self) {
        self.started.get_or_insert_with(Instant::now);
    }

    /// The trigger topic: `at_seq` counts what this bridge passed on of it.
    pub fn trigger(&self) -> Option<TopicId> {
        self.trigger
    }

    /// Fires the next fault if due (`passed_on`: messages of the trigger topic this bridge has
    /// passed on); whether it did.
    pub fn step(&mut self, passed_on: u64, pace: &Pace) -> bool {
        let (Some(started), Some(next)) = (self.started, self.due.last()) else {
            return false;
        };
        let due = match (next.at_seq, next.at_s) {
            (Some(seq), _) => passed_on > seq,
            (None, Some(s)) => started.elapsed().as_secs_f64() >= s,
            (None, None) => false,
        };
        if due {
            tracing::warn!(
                delay_ms = next.delay_ms,
                bandwidth_mbit_s = next.bandwidth_mbit_s,
                count = next.count,
                duration_s = next.duration_s,
                "injected fault: slow link"
            );
            pace.start(next);
            self.due.pop();
        }
        due
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn slow_link(delay_ms: Option<u64>, bandwidth_mbit_s: Option<f64>, count: u32) -> FaultSpec {
        let mut f = FaultSpec::parse("bridge:delay@0").unwrap();
        (f.delay_ms, f.bandwidth_mbit_s, f.count) = (delay_ms, bandwidth_mbit_s, Some(count));
        f
    }

    /// A link of 80 Mbit/s holds each 100 kB message for the 10 ms its bits take, and `delay_ms`
    /// on top; after `count` messages it is over (a lower bound on the time: any host).
    #[test]
    fn a_bandwidth_limit_holds_each_message_for_its_bits() {
        let pace = Pace::default();
        pace.start(&slow_link(Some(2), Some(80.0), 3));
        assert!(pace.on());
        let t0 = Instant::now();
        for _ in 0..3 {
            pace.keep(100_000);
        }
        assert!(t0.elapsed() >= Duration::from_millis(3 * (10 + 2)));
        assert!(!pace.on());
    }
}
