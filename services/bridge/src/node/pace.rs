//! A slow link, injected: the scenario's `delay` faults on this host's bridge
//! (`[[fault]] service = "bridge", kind = "delay"`, `host` this host). The bridge fires them
//! itself when their trigger is reached (an order to `bridge` over control would reach every
//! host's bridge): `delay_ms` before each data message its egress puts on the wire, for
//! `count` messages or `duration_s`. The link then carries at most one message per `delay_ms`.

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

/// The pace in force: shared by the main thread (which starts it) and the egress (which keeps
/// it before each data put).
#[derive(Default)]
pub struct Pace {
    on: Mutex<Option<(Duration, End, u64)>>,
}

impl Pace {
    /// Starts pacing: `delay` before each data put, until `end`.
    fn start(&self, f: &FaultSpec) {
        let delay = Duration::from_millis(f.delay_ms.unwrap_or(0));
        let end = match (f.count, f.duration_s) {
            (Some(n), _) => End::After(n),
            (None, d) => End::At(Instant::now() + Duration::from_secs_f64(d.unwrap_or(0.0))),
        };
        *self.lock() = Some((delay, end, 0));
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Option<(Duration, End, u64)>> {
        self.on.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Before a data put: waits the delay in force, if any.
    pub fn keep(&self) {
        let delay = {
            let mut on = self.lock();
            let Some((delay, end, slowed)) = on.as_mut() else {
                return;
            };
            let over = match end {
                End::At(t) => Instant::now() >= *t,
                End::After(n) => *n == 0,
            };
            if over {
                tracing::info!(slowed = *slowed, "slow link over: {slowed} messages slowed");
                *on = None;
                return;
            }
            if let End::After(n) = end {
                *n -= 1;
            }
            *slowed += 1;
            *delay
        };
        std::thread::sleep(delay);
        // The last message of a pace by count: over now, not at the next message.
        let mut on = self.lock();
        if let Some((_, End::After(0), slowed)) = *on {
            tracing::info!(slowed, "slow link over: {slowed} messages slowed");
            *on = None;
        }
    }

    /// Whether a pace is in force (the heartbeat's `delaying`).
    pub fn on(&self) -> bool {
        let mut on = self.lock();
        // A pace by time ends at its time, messages or not.
        if let Some((_, End::At(t), _)) = *on {
            if Instant::now() >= t {
                *on = None;
            }
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
