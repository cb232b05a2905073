//! `[matrix]`: a fault-injection campaign. `glint run` first runs the scenario fault-free (the
//! baseline), then one deployment per (service × kind), each with one fault, and tabulates
//! whether each fault was detected, recovered from, what it lost, and whether the science
//! equals the baseline's.
//!
//! ```toml
//! [matrix]
//! services = ["sensor", "detector", "tracker", "inversion"]   # default: every deployed one
//! kinds = ["kill", "stop", "panic", "delay", "drop", "corrupt"] # default: all
//! ```
//!
//! In a deployment split across hosts (`[hosts]`) the matrix faults the orchestrator's host's
//! services and every host's bridge (`"bridge"`: kill, stop — the link cut — and delay — a
//! slow link); every host runs `glint run` on the same file and runs its part of each case.

use serde::{Deserialize, Serialize};

use super::{Checker, Corruption, FaultKind, FaultSpec};
use crate::{deployment, ServiceId};

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct FaultMatrix {
    /// Services to fault (default: every service the scenario deploys).
    pub services: Vec<String>,
    /// Kinds of fault (default: all six).
    pub kinds: Vec<FaultKind>,
    /// How long a stop lasts [s] (default 1.0: past a short heartbeat deadline).
    pub stop_s: Option<f64>,
    /// A delay's added time per message [ms] (default 5 ms), and how many messages it slows
    /// (default 10) — or, with `delay_s`, how long it lasts [s] (then its end may race the end
    /// of a short run on a fast host: a case reports it as not reached).
    pub delay_ms: Option<u64>,
    pub delay_count: Option<u32>,
    pub delay_s: Option<f64>,
    /// A bridge's delay (a slow link) as a link of this bandwidth [Mbit/s] instead of
    /// `delay_ms` per message (split deployments).
    pub bandwidth_mbit_s: Option<f64>,
    /// Outputs dropped, and every how many (default 2, every 3rd).
    pub drop_count: Option<u32>,
    pub drop_every: Option<u32>,
    /// Outputs corrupted (default 2); the way rotates over the services (nan, count, version).
    pub corrupt_count: Option<u32>,
}

/// One case of a matrix: one fault, on one service (the bridge: of one host).
#[derive(Debug, Clone, PartialEq)]
pub struct MatrixCase {
    /// `<service>-<kind>`, or `bridge-<host>-<kind>` in a deployment split across hosts.
    pub name: String,
    pub service: ServiceId,
    /// The host whose part fires the fault (`None`: not split).
    pub host: Option<String>,
    pub kind: FaultKind,
    pub fault: FaultSpec,
}

/// The kinds of fault a bridge takes: killed, stopped (the link cut), delayed (a slow link).
const BRIDGE_KINDS: [FaultKind; 3] = [FaultKind::Kill, FaultKind::Stop, FaultKind::Delay];

impl FaultMatrix {
    /// Every case, in order: each service of the matrix (in deployment order) with each kind.
    /// In a deployment split across hosts the orchestrator's host's services, and each host's
    /// bridge (kill, stop, delay) where the first data topic that crosses hosts passes it (a
    /// bridge's `at_seq` counts that topic). Every host computes the same list from the same
    /// scenario: each runs its part of each case in this order.
    pub fn cases(&self, scenario: &super::Scenario) -> Vec<MatrixCase> {
        let mut cases = vec![];
        for (index, service) in self.services_of(scenario).into_iter().enumerate() {
            let trigger = deployment::trigger_topic(scenario, service);
            let at_seq = trigger.map_or(0, |t| deployment::expected_messages(scenario, t)) * 3 / 10;
            // Where its faults fire: each host's bridge; another service on the orchestrator's
            // host only.
            let hosts: Vec<Option<String>> = if service == ServiceId::Bridge {
                (scenario.hosts.keys())
                    .filter(|h| bridge_passes(scenario, trigger, h))
                    .map(|h| Some(h.clone()))
                    .collect()
            } else if scenario.host_of(service) == scenario.orchestrator_host() {
                vec![None]
            } else {
                vec![]
            };
            for host in hosts {
                for kind in self.kinds_of() {
                    if service == ServiceId::Bridge && !BRIDGE_KINDS.contains(&kind) {
                        continue;
                    }
                    let mut fault = self.fault(service, index, kind, at_seq);
                    fault.host = host.clone();
                    let slow_link = service == ServiceId::Bridge && kind == FaultKind::Delay;
                    if let Some(r) = self.bandwidth_mbit_s.filter(|_| slow_link) {
                        fault.bandwidth_mbit_s = Some(r);
                        fault.delay_ms = self.delay_ms;
                    }
                    let name = match &host {
                        Some(h) => format!("{}-{h}-{}", service.name(), kind.name()),
                        None => format!("{}-{}", service.name(), kind.name()),
                    };
                    cases.push(MatrixCase {
                        name,
                        service,
                        host: host.clone(),
                        kind,
                        fault,
                    });
                }
            }
        }
        cases
    }

    /// The scenario of one case: `base` (the matrix's scenario, `[matrix]` removed) with that
    /// one fault.
    pub fn case_scenario(base: &super::Scenario, case: &MatrixCase) -> super::Scenario {
        let mut sc = base.clone();
        sc.matrix = None;
        sc.fault = vec![case.fault.clone()];
        sc.faults.enabled |= case.kind.in_band();
        sc
    }

    /// The services of the matrix, in deployment order.
    pub fn services_of(&self, scenario: &super::Scenario) -> Vec<ServiceId> {
        deployment::services(scenario)
            .into_iter()
            .filter(|s| self.services.is_empty() || self.services.iter().any(|n| n == s.name()))
            .collect()
    }

    pub fn kinds_of(&self) -> Vec<FaultKind> {
        if self.kinds.is_empty() {
            FaultKind::ALL.to_vec()
        } else {
            self.kinds.clone()
        }
    }

    /// The fault of one case, at message `at_seq` of the service's trigger topic.
    pub fn fault(
        &self,
        service: ServiceId,
        index: usize,
        kind: FaultKind,
        at_seq: u64,
    ) -> FaultSpec {
        let mut f = FaultSpec {
            service: service.name().to_string(),
            kind,
            at_seq: Some(at_seq),
            at_s: None,
            duration_s: None,
            delay_ms: None,
            count: None,
            every: None,
            how: None,
            bandwidth_mbit_s: None,
            host: None,
        };
        match kind {
            FaultKind::Stop => f.duration_s = Some(self.stop_s.unwrap_or(1.0)),
            FaultKind::Delay => {
                f.delay_ms = Some(self.delay_ms.unwrap_or(5));
                match self.delay_s {
                    Some(s) => f.duration_s = Some(s),
                    None => f.count = Some(self.delay_count.unwrap_or(10)),
                }
            }
            FaultKind::Drop => {
                f.count = Some(self.drop_count.unwrap_or(2));
                f.every = Some(self.drop_every.unwrap_or(3));
            }
            FaultKind::Corrupt => {
                f.count = Some(self.corrupt_count.unwrap_or(2));
                f.how = Some(Corruption::ALL[index % Corruption::ALL.len()]);
            }
            FaultKind::Kill | FaultKind::Panic => {}
        }
        f
    }
}

/// Whether `trigger` (the topic a bridge fault's `at_seq` counts) passes `host`'s bridge: its
/// producer or one of its consumers runs there.
fn bridge_passes(scenario: &super::Scenario, trigger: Option<crate::TopicId>, host: &str) -> bool {
    trigger.is_some_and(|t| {
        let producer = deployment::producer(t).and_then(|p| scenario.host_of(p));
        producer == Some(host)
            || (deployment::consumers(scenario, t).iter())
                .any(|c| scenario.host_of(*c) == Some(host))
    })
}

/// Every name in `section.services` is a service the scenario deploys.
pub(super) fn check_services(
    c: &mut Checker,
    section: &str,
    services: &[String],
    scenario: &super::Scenario,
) {
    let deployed = deployment::services(scenario);
    let names: Vec<&str> = deployed.iter().map(|s| s.name()).collect();
    for (i, s) in services.iter().enumerate() {
        if !names.contains(&s.as_str()) {
            c.fail(
                &format!("{section}.services[{i}]"),
                format!(
                    "`{s}` is not a service this scenario deploys; allowed: {}",
                    names.join(", ")
                ),
            );
        }
    }
}

pub(super) fn check_matrix(c: &mut Checker, scenario: &super::Scenario) {
    let Some(m) = &scenario.matrix else {
        return;
    };
    check_services(c, "matrix", &m.services, scenario);
    // Faults act on the orchestrator's host's services and on every host's bridge.
    for (i, name) in m.services.iter().enumerate() {
        let service = ServiceId::from_name(name).filter(|s| *s != ServiceId::Bridge);
        if service.is_some_and(|s| scenario.host_of(s) != scenario.orchestrator_host()) {
            c.fail(
                &format!("matrix.services[{i}]"),
                format!(
                    "`{name}` runs on another host than the orchestrator's; a matrix faults the \
                     orchestrator's host's services and every host's bridge"
                ),
            );
        }
    }
    if let Some(v) = m.stop_s {
        c.range("matrix.stop_s", v, 0.001, 3600.0);
    }
    if let Some(v) = m.delay_ms {
        c.range_u("matrix.delay_ms", v, 1, 10_000);
    }
    if let Some(v) = m.bandwidth_mbit_s {
        c.range("matrix.bandwidth_mbit_s", v, 1.0, 100_000.0);
        let slows = (m.services.is_empty() || m.services.iter().any(|s| s == "bridge"))
            && m.kinds_of().contains(&FaultKind::Delay);
        if !scenario.split() {
            c.fail(
                "matrix.bandwidth_mbit_s",
                "a bandwidth limit slows the link between hosts: the scenario has no [hosts]"
                    .into(),
            );
        } else if !slows {
            c.fail(
                "matrix.bandwidth_mbit_s",
                "it slows the bridge's delay cases: the matrix has none (add \"bridge\" to \
                 services, or leave services out, and \"delay\" to kinds)"
                    .into(),
            );
        }
    }
    for (i, k) in m.kinds.iter().enumerate() {
        if m.kinds[..i].contains(k) {
            c.fail(
                &format!("matrix.kinds[{i}]"),
                format!("`{}` is named twice", k.name()),
            );
        }
    }
    if let Some(v) = m.delay_s {
        c.range("matrix.delay_s", v, 0.001, 3600.0);
    }
    if let Some(v) = m.delay_count {
        c.range_u("matrix.delay_count", u64::from(v), 1, 1_000_000);
        if m.delay_s.is_some() {
            c.fail(
                "matrix.delay_count",
                "a delay lasts delay_s or delay_count messages, not both".into(),
            );
        }
    }
    for (field, v) in [
        ("matrix.drop_count", m.drop_count),
        ("matrix.drop_every", m.drop_every),
        ("matrix.corrupt_count", m.corrupt_count),
    ] {
        if let Some(v) = v {
            c.range_u(field, u64::from(v), 1, 1000);
        }
    }
    if scenario.campaign.is_some() {
        c.fail(
            "matrix",
            "a scenario has a [matrix] or a [campaign], not both".into(),
        );
    }
    if !scenario.fault.is_empty() {
        c.fail(
            "matrix",
            "a [matrix] makes its own faults; leave [[fault]] and --fault out".into(),
        );
    }
}
