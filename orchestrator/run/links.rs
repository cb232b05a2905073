//! The orchestrator's view of the other hosts of a split deployment: each host is heard
//! through its services' heartbeats across the bridges. A host none of whose services has
//! been heard for three heartbeat periods is *cut off* (an outage opens: the link is down, or
//! its bridge stopped); the next heartbeat from it closes the outage. What the report tells
//! of each host, with its outages and the local bridge's per-hop counters.

use std::collections::BTreeMap;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use shared_types::{DropReason, Heartbeat, Scenario, ServiceId, TopicId};

use crate::run::consume::Seen;

/// Heartbeat periods without a word from a host before it counts as cut off.
const SILENT_PERIODS: u32 = 3;

/// One time a host was cut off.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct Outage {
    /// When the last heartbeat before it arrived [s after the services were started].
    pub last_heard_s: f64,
    /// When the silence was noticed [s after the start] (`SILENT_PERIODS` periods later, at
    /// most one orchestrator tick more).
    pub detected_s: f64,
    /// When a heartbeat arrived again [s after the start]; absent: the host never came back.
    pub recovered_s: Option<f64>,
    /// The same instants on the wall clock [ms since the Unix epoch], to set beside another
    /// machine's log of what happened to the link.
    pub detected_unix_ms: u64,
    pub recovered_unix_ms: Option<u64>,
}

/// One host of a split deployment, as the orchestrator of record saw it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct HostReport {
    pub name: String,
    /// The Zenoh endpoint its bridge listens on.
    pub endpoint: String,
    /// This host runs the orchestrator of record.
    pub orchestrator: bool,
    /// The services placed on it (its bridge aside).
    pub services: Vec<String>,
    /// Any of its services was heard across the bridge (another host; the orchestrator's
    /// host: true).
    #[serde(default = "yes")]
    pub heard: bool,
    /// The times it was cut off (another host only).
    pub outages: Vec<Outage>,
    /// This host's bridge, per data topic that crossed (the orchestrator's host only).
    pub hops: Vec<HopReport>,
}

/// One data topic through a bridge: its side of the hop.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct HopReport {
    pub topic: String,
    /// Taken: from shared memory (exported) or off the wire (imported). A call: the requests
    /// this bridge took (from a caller on its host, or off the wire).
    pub taken: u64,
    /// Passed on: put on the wire, or published into shared memory here. A call: the answers
    /// passed on (to the caller here, or onto the wire).
    pub passed_on: u64,
    /// Lost on the link (gaps in the link sequence). A call: the calls that got no answer
    /// through this bridge (their caller asked again).
    pub link_lost: u64,
    /// Refused off the wire (envelope, contract, type or size).
    pub refused: u64,
}

fn yes() -> bool {
    true
}

struct Watched {
    host: String,
    services: Vec<ServiceId>,
    /// One of its services was heard.
    heard: bool,
    open: Option<Outage>,
    outages: Vec<Outage>,
    /// When it was last heard again after an outage.
    back: Option<Instant>,
}

/// Outages of every other host, noticed as the run goes.
pub struct Links {
    hosts: Vec<Watched>,
    silence: Duration,
}

fn unix_ms(at: Instant) -> u64 {
    let ago = Instant::now().saturating_duration_since(at);
    (SystemTime::now() - ago)
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_millis() as u64)
}

impl Links {
    /// Watches every host of `scenario` but `here` that runs a service.
    pub fn new(scenario: &Scenario, here: Option<&str>, remote: &[ServiceId]) -> Self {
        let mut by_host: BTreeMap<String, Vec<ServiceId>> = BTreeMap::new();
        for &s in remote {
            if let Some(h) = scenario.host_of(s).filter(|h| Some(*h) != here) {
                by_host.entry(h.to_string()).or_default().push(s);
            }
        }
        let period = Duration::from_millis(scenario.run.heartbeat_period_ms);
        Links {
            hosts: (by_host.into_iter())
                .map(|(host, services)| Watched {
                    host,
                    services,
                    heard: false,
                    open: None,
                    outages: vec![],
                    back: None,
                })
                .collect(),
            silence: period * SILENT_PERIODS,
        }
    }

    /// When `host` was last heard again after an outage (`None`: never cut off).
    pub fn back_since(&self, host: Option<&str>) -> Option<Instant> {
        (self.hosts.iter())
            .find(|h| Some(h.host.as_str()) == host)
            .and_then(|h| h.back)
    }

    /// Opens and closes outages from the services' latest heartbeats; `since_start` turns an
    /// instant into seconds after the start. Whether a host was found cut off just now.
    pub fn step(
        &mut self,
        now: Instant,
        seen: &BTreeMap<ServiceId, Seen>,
        since_start: impl Fn(Instant) -> f64,
    ) -> bool {
        let mut cut = false;
        for h in &mut self.hosts {
            let Some(last) = (h.services.iter())
                .filter_map(|s| seen.get(s).map(|x| x.at))
                .max()
            else {
                continue;
            };
            h.heard = true;
            match &mut h.open {
                None if now.saturating_duration_since(last) > self.silence => {
                    tracing::warn!(
                        host = h.host,
                        "host cut off: no heartbeat across the bridge"
                    );
                    cut = true;
                    h.open = Some(Outage {
                        last_heard_s: since_start(last),
                        detected_s: since_start(now),
                        recovered_s: None,
                        detected_unix_ms: unix_ms(now),
                        recovered_unix_ms: None,
                    });
                }
                Some(o) if since_start(last) > o.detected_s => {
                    o.recovered_s = Some(since_start(last));
                    o.recovered_unix_ms = Some(unix_ms(last));
                    tracing::info!(host = h.host, "host heard again");
                    h.back = Some(last);
                    h.outages.extend(h.open.take());
                }
                _ => {}
            }
        }
        cut
    }

    /// Each host's report; `bridge`: the local bridge's last heartbeat.
    pub fn report(
        &self,
        scenario: &Scenario,
        here: Option<&str>,
        bridge: Option<&Heartbeat>,
    ) -> Vec<HostReport> {
        (scenario.hosts.iter())
            .map(|(name, spec)| {
                let watched = self.hosts.iter().find(|h| &h.host == name);
                let outages = watched.map_or(vec![], |w| {
                    w.outages.iter().chain(w.open.as_ref()).cloned().collect()
                });
                let services = (shared_types::deployment::services(scenario).into_iter())
                    .filter(|s| *s != ServiceId::Bridge && scenario.host_of(*s) == Some(name))
                    .map(|s| s.name().to_string())
                    .collect();
                let is_here = Some(name.as_str()) == here;
                HostReport {
                    name: name.clone(),
                    endpoint: spec.endpoint.clone(),
                    orchestrator: spec.orchestrator,
                    services,
                    heard: watched.is_none_or(|w| w.heard),
                    outages,
                    hops: bridge.filter(|_| is_here).map_or(vec![], hops),
                }
            })
            .collect()
    }
}

fn hops(hb: &Heartbeat) -> Vec<HopReport> {
    (hb.topics.iter())
        .filter_map(|c| Some((TopicId::from_u32(c.topic)?, c)))
        .map(|(t, c)| HopReport {
            topic: t.name().to_string(),
            taken: c.received,
            passed_on: c.published,
            link_lost: c.dropped[DropReason::Link as usize],
            refused: c.dropped[DropReason::Malformed as usize],
        })
        .collect()
}

/// The hosts' part of summary.md (empty for a run on one host).
pub fn markdown(hosts: &[HostReport]) -> String {
    if hosts.is_empty() {
        return String::new();
    }
    let mut s = String::from(
        "\n## Hosts\n\nThe deployment ran on these hosts, the remote services heard through \
         their heartbeats across the bridges (docs/hosts.md).\n\n\
         | host | endpoint | services | cut off |\n|---|---|---|---|\n",
    );
    for h in hosts {
        let role = if h.orchestrator {
            " (orchestrator)"
        } else {
            ""
        };
        let cut = match h.outages.as_slice() {
            [] if h.orchestrator => "—".to_string(),
            [] => "never".to_string(),
            o => (o.iter())
                .map(|o| match o.recovered_s {
                    Some(r) => format!(
                        "{:.2}–{r:.2} s (noticed {:.2} s after its last heartbeat)",
                        o.last_heard_s,
                        o.detected_s - o.last_heard_s
                    ),
                    None => format!("from {:.2} s, never back", o.last_heard_s),
                })
                .collect::<Vec<_>>()
                .join("; "),
        };
        s += &format!(
            "| {}{role} | `{}` | {} | {cut} |\n",
            h.name,
            h.endpoint,
            h.services.join(", ")
        );
    }
    for h in hosts.iter().filter(|h| !h.hops.is_empty()) {
        s += &format!(
            "\nHost `{}`'s bridge, per hop:\n\n| topic | taken | passed on | lost on the link | \
             refused |\n|---|---|---|---|---|\n",
            h.name
        );
        for p in &h.hops {
            s += &format!(
                "| {} | {} | {} | {} | {} |\n",
                p.topic, p.taken, p.passed_on, p.link_lost, p.refused
            );
        }
    }
    s
}
