//! Where a service's time goes, measured by its loop: asleep (held back by a consumer's credit,
//! or idle) or handling a wake-up, with the ports' and the RPC client's parts of the latter
//! (`shared_types::ServiceTime`, carried in every heartbeat).

use std::time::Instant;

use shared_types::ServiceTime;

use crate::service::{all_stats, Service};

/// Where the service's time goes: asleep (held by credit, or idle) or handling a wake-up.
pub(crate) struct LoopTimer {
    /// Since the last change between asleep and awake.
    since: Instant,
    asleep: bool,
    held: bool,
    busy_ns: u64,
    credit_wait_ns: u64,
    idle_ns: u64,
}

impl LoopTimer {
    /// Awake (starting up) from now.
    pub(crate) fn new() -> Self {
        LoopTimer {
            since: Instant::now(),
            asleep: false,
            held: false,
            busy_ns: 0,
            credit_wait_ns: 0,
            idle_ns: 0,
        }
    }

    fn lap(&mut self) -> u64 {
        let now = Instant::now();
        let ns = (now - self.since).as_nanos() as u64;
        self.since = now;
        ns
    }

    /// A wake-up: the sleep since [`LoopTimer::asleep`] ends.
    pub(crate) fn woke(&mut self) {
        if self.asleep {
            let ns = self.lap();
            match self.held {
                true => self.credit_wait_ns += ns,
                false => self.idle_ns += ns,
            }
            self.asleep = false;
        }
    }

    /// Going to sleep, `held` back by a consumer's credit or not.
    pub(crate) fn asleep(&mut self, held: bool) {
        if !self.asleep {
            self.busy_ns += self.lap();
            self.asleep = true;
        }
        self.held = held;
    }

    /// The totals so far (the current stretch included), with the ports' and RPC parts.
    pub(crate) fn time<S: Service>(&self, input: &S::Input, svc: &S) -> ServiceTime {
        let now_ns = self.since.elapsed().as_nanos() as u64;
        let (mut busy_ns, mut credit_wait_ns, mut idle_ns) =
            (self.busy_ns, self.credit_wait_ns, self.idle_ns);
        match (self.asleep, self.held) {
            (false, _) => busy_ns += now_ns,
            (true, true) => credit_wait_ns += now_ns,
            (true, false) => idle_ns += now_ns,
        }
        let ports = all_stats(input, svc);
        ServiceTime {
            busy_ns,
            credit_wait_ns,
            idle_ns,
            publish_ns: ports.iter().map(|s| s.publish_ns).sum(),
            checksum_ns: ports.iter().map(|s| s.checksum_ns).sum(),
            rpc_wait_ns: svc.rpc_wait_ns(),
        }
    }
}
