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

pub struct Remote {
    /// Services of the deployment on other hosts than this one.
    pub services: Vec<ServiceId>,
    /// When each other host was cut off.
    links: Links,
    /// A host was found cut off since [`Remote::take_cut_off`] was last asked.
    cut_off: bool,
}

impl Remote {
    /// The other hosts' services of `scenario`, seen from `host` (none when not split).
    pub fn new(scenario: &Scenario, host: Option<&str>) -> Self {
        let services = crate::run::hosts::remote_services(scenario, host);
        let links = Links::new(scenario, host, &services);
        Remote {
            services,
            links,
            cut_off: false,
        }
    }

    pub fn is_empty(&self) -> bool {
        self.services.is_empty()
    }

    pub fn contains(&self, id: &ServiceId) -> bool {
        self.services.contains(id)
    }

    /// Whether `id`, a service of another host, is up as its last heartbeat across the bridges
    /// says (ready, running or finished: not starting, not stopping).
    pub fn is_up(&self, consumer: &Consumer, id: ServiceId) -> bool {
        (consumer.seen.get(&id))
            .is_some_and(|s| (Heartbeat::READY..=Heartbeat::FINISHED).contains(&s.heartbeat.state))
    }

    /// Whether every one has said it is ready.
    pub fn ready(&self, consumer: &Consumer) -> bool {
        (self.services.iter()).all(|id| {
            (consumer.seen.get(id)).is_some_and(|s| s.heartbeat.state >= Heartbeat::READY)
        })
    }

    /// Notes outages, and the failure of a service whose heartbeats stopped crossing (it
    /// cannot be signalled or restarted from here): for `run.heartbeat_deadline_ms` while
    /// another service of its host is heard (it hung), or for the host's silence limit
    /// ([`Scenario::host_silence_limit`]) when the whole host is silent (its bridge may be
    /// restarting there, or the link cut). `bridge`: since when this host's bridge has been
    /// up (`None`: it is being restarted, which explains any silence; limits count from its
    /// return).
    pub fn check(
        &mut self,
        scenario: &Scenario,
        consumer: &Consumer,
        now: Instant,
        bridge: Option<Instant>,
        since_start: impl Fn(Instant) -> f64,
    ) -> Option<String> {
        self.cut_off |= self.links.step(now, &consumer.seen, since_start);
        let bridge = bridge?;
        let deadline = Duration::from_millis(scenario.run.heartbeat_deadline_ms);
        let period = Duration::from_millis(scenario.run.heartbeat_period_ms);
        // Silence counts from its last heartbeat, or from when this host's bridge or its own
        // host (after an outage) was back, whichever came last.
        let heard = |id: &ServiceId| {
            let back = self
                .links
                .back_since(scenario.host_of(*id))
                .max(Some(bridge));
            (consumer.seen.get(id))
                .map(|s| s.at)
                .max(back)
                .unwrap_or(bridge)
        };
        // Its host went on talking after it fell silent: another service of the host was heard
        // well after it (two heartbeat periods: not the same last round) and lately.
        let alone = |id: &ServiceId| {
            (self.services.iter()).any(|s| {
                scenario.host_of(*s) == scenario.host_of(*id)
                    && heard(s) > heard(id) + 2 * period
                    && now.saturating_duration_since(heard(s)) <= deadline
            })
        };
        let (silent, limit, why) = (self.services.iter()).find_map(|id| {
            let (limit, why) = match alone(id) {
                true => (
                    deadline,
                    "run.heartbeat_deadline_ms, while its host was heard",
                ),
                false => (
                    scenario.host_silence_limit(),
                    "run.heartbeat_deadline_ms + supervision.backoff_max_ms + \
                     run.startup_timeout_ms: its host was silent, and had that long to bring \
                     its bridge back",
                ),
            };
            (now.saturating_duration_since(heard(id)) > limit).then_some((*id, limit, why))
        })?;
        Some(format!(
            "service {} on host {} sent no heartbeat across the bridge for {} ms ({why})",
            silent.name(),
            scenario.host_of(silent).unwrap_or("?"),
            limit.as_millis()
        ))
    }

    /// Whether a host was found cut off since the last call (a bridge fault's detection: the
    /// link it carries went silent).
    pub fn take_cut_off(&mut self) -> bool {
        std::mem::take(&mut self.cut_off)
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
