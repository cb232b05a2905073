//! The orchestrator's side of a deployment split across hosts: the services of the other
//! hosts, never spawned or signalled from here, heard only through their heartbeats across the
//! bridges. When they are ready, when they went silent, when they stopped, and what the report
//! says of them.

use std::time::{Duration, Instant};

use anyhow::Result;
use shared_types::{Heartbeat, Scenario, ServiceId};

use crate::report::{RunFacts, ServiceFact};
use crate::run::consume::Consumer;
use crate::run::deploy::Ending;
use crate::run::links::Links;

/// How long another host's services may go unheard before the run fails: the heartbeat
/// deadline, then what that host's own supervision may take to notice a failed bridge and bring
/// a new one up (its backoff and startup limits). A bridge killed or stopped on that host, or a
/// partition, shorter than this is an outage the run rides out.
pub fn silence_limit(scenario: &Scenario) -> Duration {
    Duration::from_millis(
        scenario.run.heartbeat_deadline_ms
            + scenario.supervision.backoff_max_ms
            + scenario.run.startup_timeout_ms,
    )
}

pub struct Remote {
    /// Services of the deployment on other hosts than this one.
    pub services: Vec<ServiceId>,
    /// When each other host was cut off.
    links: Links,
}

impl Remote {
    /// The other hosts' services of `scenario`, seen from `host` (none when not split).
    pub fn new(scenario: &Scenario, host: Option<&str>) -> Self {
        let services = crate::run::hosts::remote_services(scenario, host);
        let links = Links::new(scenario, host, &services);
        Remote { services, links }
    }

    pub fn is_empty(&self) -> bool {
        self.services.is_empty()
    }

    pub fn contains(&self, id: &ServiceId) -> bool {
        self.services.contains(id)
    }

    /// Whether every one has said it is ready.
    pub fn ready(&self, consumer: &Consumer) -> bool {
        (self.services.iter()).all(|id| {
            (consumer.seen.get(id)).is_some_and(|s| s.heartbeat.state >= Heartbeat::READY)
        })
    }

    /// Notes outages, and the failure of a service whose heartbeats stopped crossing for
    /// longer than [`silence_limit`] (it cannot be signalled or restarted from here). `bridge`:
    /// since when this host's bridge has been up (`None`: it is being restarted, which
    /// explains any silence; the limit counts from its return).
    pub fn check(
        &mut self,
        scenario: &Scenario,
        consumer: &Consumer,
        now: Instant,
        bridge: Option<Instant>,
        since_start: impl Fn(Instant) -> f64,
    ) -> Option<String> {
        self.links.step(now, &consumer.seen, since_start);
        let bridge = bridge?;
        let limit = silence_limit(scenario);
        let silent = (self.services.iter()).find(|id| {
            let heard = (consumer.seen.get(id)).map_or(bridge, |s| s.at.max(bridge));
            now.saturating_duration_since(heard) > limit
        })?;
        Some(format!(
            "service {} on host {} sent no heartbeat across the bridge for {} ms \
             (run.heartbeat_deadline_ms, then supervision.backoff_max_ms and \
             run.startup_timeout_ms for that host to bring its bridge back)",
            silent.name(),
            scenario.host_of(*silent).unwrap_or("?"),
            limit.as_millis()
        ))
    }

    /// Waits up to `grace` for every one to say in a heartbeat that it is stopping (its
    /// counters final), reading what arrives meanwhile.
    pub fn await_stopping(&self, consumer: &mut Consumer, grace: Duration) -> Result<()> {
        let t0 = Instant::now();
        loop {
            consumer.poll()?;
            let stopping = |id: &ServiceId| {
                (consumer.seen.get(id)).is_some_and(|s| s.heartbeat.state == Heartbeat::STOPPING)
            };
            if self.services.iter().all(stopping) || t0.elapsed() >= grace {
                return Ok(());
            }
            std::thread::sleep(Duration::from_millis(5));
        }
    }

    /// Their part of the report: each as its heartbeats across the bridge last told, and each
    /// host with its outages and this host's bridge per hop.
    pub fn add_facts(
        &self,
        facts: &mut RunFacts,
        scenario: &Scenario,
        consumer: &Consumer,
        host: Option<&str>,
    ) {
        let bridge = consumer.seen.get(&ServiceId::Bridge);
        facts.hosts = (self.links).report(scenario, host, bridge.map(|s| &s.heartbeat));
        for &id in &self.services {
            let seen = consumer.seen.get(&id);
            let stopped = seen.is_some_and(|s| s.heartbeat.state == Heartbeat::STOPPING);
            let on = scenario.host_of(id).unwrap_or("?");
            facts.services.push(ServiceFact {
                name: id.name().to_string(),
                pid: seen.map_or(0, |s| s.heartbeat.pid),
                restarts: 0,
                ending: match stopped {
                    true => Ending::Shutdown,
                    false => Ending::Exited(format!("no last heartbeat from host {on}")),
                },
                cpu_s: None,
                time: seen.map(|s| s.heartbeat.time),
            });
        }
    }
}
