//! `[hosts.<name>]`: a deployment split across machines (docs/hosts.md). Each host runs
//! `glint run SCENARIO --host <name>` with the same scenario file; its services and one bridge
//! (ADR 0038) run there, and the bridges carry the topics that cross hosts over Zenoh. The
//! host marked `orchestrator` runs the orchestrator of record: it starts the run, accounts for
//! every message on every host and writes the one report.
//!
//! ```toml
//! [hosts.ground]
//! endpoint = "tcp/10.0.0.1:7447"
//! orchestrator = true
//! [hosts.board]
//! endpoint = "tcp/10.0.0.2:7447"
//!
//! [services.detector]
//! host = "board"
//! [services.tracker]
//! host = "board"
//! ```
//!
//! A service without `host` runs on the orchestrator's host.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use super::Checker;
use crate::ServiceId;

/// One machine of a split deployment.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HostSpec {
    /// Where this host's bridge listens, and the other hosts' bridges connect:
    /// `tcp/<IPv4 address>:<port>` (a Zenoh TCP locator).
    pub endpoint: String,
    /// Whether this host runs the orchestrator of record (exactly one host does).
    #[serde(default)]
    pub orchestrator: bool,
}

/// Hosts at most in one deployment (a bridge connects to every other host).
pub const MAX_HOSTS: usize = 8;

impl super::Scenario {
    /// Whether the deployment is split across hosts.
    pub fn split(&self) -> bool {
        !self.hosts.is_empty()
    }

    /// The host that runs the orchestrator of record (`None`: one host, not split).
    pub fn orchestrator_host(&self) -> Option<&str> {
        (self.hosts.iter())
            .find(|(_, h)| h.orchestrator)
            .map(|(n, _)| n.as_str())
    }

    /// The host `service` runs on (`None`: one host, not split). The orchestrator, and a
    /// service without `services.<name>.host`, run on the orchestrator's host. The bridge
    /// runs on every host and has none.
    pub fn host_of(&self, service: ServiceId) -> Option<&str> {
        let orchestrator = self.orchestrator_host()?;
        let placed = (self.services.get(service.name())).and_then(|p| p.host.as_deref());
        Some(placed.unwrap_or(orchestrator))
    }

    /// Whether `service` runs on `host` (any service does when not split).
    pub fn runs_on(&self, service: ServiceId, host: Option<&str>) -> bool {
        match (self.host_of(service), host) {
            (Some(h), Some(on)) => h == on,
            _ => true,
        }
    }

    /// How long a host of a split deployment may go unheard before it is lost: the heartbeat
    /// deadline, then what that host's own supervision may take to notice a failed bridge and
    /// bring a new one up (its backoff and startup limits). The orchestrator fails the run
    /// when another host's services are silent this long; another host's part ends when the
    /// orchestrator's host has been away this long.
    pub fn host_silence_limit(&self) -> std::time::Duration {
        std::time::Duration::from_millis(
            self.run.heartbeat_deadline_ms
                + self.supervision.backoff_max_ms
                + self.run.startup_timeout_ms,
        )
    }

    /// The key under which this deployment's hosts meet on Zenoh (`glint/<key>/…`): 16 hex
    /// digits of the xxh3 of the scenario as glint reads it, so every host that runs the same
    /// scenario agrees without talking first, and different scenarios never meet.
    pub fn deployment_key(&self) -> String {
        format!(
            "{:016x}",
            xxhash_rust::xxh3::xxh3_64(self.to_toml().as_bytes())
        )
    }
}

/// `tcp/<a.b.c.d>:<port>`, port 1–65535.
fn endpoint_ok(endpoint: &str) -> bool {
    let Some(addr) = endpoint.strip_prefix("tcp/") else {
        return false;
    };
    // The others connect to it: an unspecified address (0.0.0.0) names no host.
    addr.parse::<std::net::SocketAddrV4>()
        .is_ok_and(|a| a.port() != 0 && !a.ip().is_unspecified())
}

pub(super) fn check_hosts(c: &mut Checker, scenario: &super::Scenario) {
    let hosts: &BTreeMap<String, HostSpec> = &scenario.hosts;
    if hosts.is_empty() {
        for (name, p) in &scenario.services {
            if p.host.is_some() {
                c.fail(
                    &format!("services.{name}.host"),
                    "names a host, but the scenario has no [hosts.<name>] section".into(),
                );
            }
        }
        return;
    }
    c.range_u("hosts (count)", hosts.len() as u64, 2, MAX_HOSTS as u64);
    for (name, h) in hosts {
        if !endpoint_ok(&h.endpoint) {
            c.fail(
                &format!("hosts.{name}.endpoint"),
                format!(
                    "`{}` is not a TCP endpoint; allowed: tcp/<IPv4 address, not 0.0.0.0>:<port 1-65535>",
                    h.endpoint
                ),
            );
        }
        if !name
            .chars()
            .all(|ch| ch.is_ascii_alphanumeric() || ch == '-' || ch == '_')
        {
            c.fail(
                &format!("hosts.{name}"),
                "a host name has letters, digits, '-' and '_' only".into(),
            );
        }
    }
    let orchestrators: Vec<&String> = (hosts.iter())
        .filter(|(_, h)| h.orchestrator)
        .map(|(n, _)| n)
        .collect();
    if orchestrators.len() != 1 {
        c.fail(
            "hosts.<name>.orchestrator",
            format!(
                "exactly one host runs the orchestrator of record; {} do ({})",
                orchestrators.len(),
                join(orchestrators.iter().map(|s| s.as_str()))
            ),
        );
    }
    let mut endpoints: Vec<&str> = hosts.values().map(|h| h.endpoint.as_str()).collect();
    endpoints.sort_unstable();
    if endpoints.windows(2).any(|w| w[0] == w[1]) {
        c.fail(
            "hosts.<name>.endpoint",
            "two hosts give the same endpoint".into(),
        );
    }
    for (name, p) in &scenario.services {
        if let Some(host) = &p.host {
            if !hosts.contains_key(host) {
                c.fail(
                    &format!("services.{name}.host"),
                    format!(
                        "`{host}` is not a host of [hosts]; allowed: {}",
                        join(hosts.keys().map(|s| s.as_str()))
                    ),
                );
            }
        }
    }
    if scenario
        .services
        .get("bridge")
        .is_some_and(|p| p.host.is_some())
    {
        c.fail(
            "services.bridge.host",
            "every host runs its own bridge; it is placed by [hosts], not here".into(),
        );
    }
    if !c.errors.is_empty() {
        return;
    }
    // A host runs something: a host without a service would have nothing to carry, not even
    // the orchestrator's Shutdown.
    let deployed = crate::deployment::services(scenario);
    for (name, h) in hosts.iter().filter(|(_, h)| !h.orchestrator) {
        let runs_one = (deployed.iter())
            .any(|s| *s != ServiceId::Bridge && scenario.host_of(*s) == Some(name.as_str()));
        if !runs_one {
            c.fail(
                &format!("hosts.{name}"),
                format!(
                    "runs no service of this scenario; place one there with \
                     [services.<name>] host = \"{name}\" (endpoint {}), or remove the host",
                    h.endpoint
                ),
            );
        }
    }
    check_what_crosses(c, scenario);
}

/// What a bridge cannot carry yet is refused here, with the placement that would work.
fn check_what_crosses(c: &mut Checker, scenario: &super::Scenario) {
    use super::FaultKind;
    let orchestrator = scenario.orchestrator_host().unwrap_or_default();
    // Calls cross hosts as topics do (the bridges carry them): nothing to refuse here.
    // Faults act on the processes of the orchestrator's host, and on any host's bridge (that
    // host's part fires it): `kill`; `stop`, the link cut while it is stopped; `delay`, a slow
    // link (the bridge paces its puts).
    for (i, f) in scenario.fault.iter().enumerate() {
        let service = ServiceId::from_name(&f.service);
        let at = |field: &str| format!("fault[{i}].{field}");
        if service == Some(ServiceId::Bridge) {
            // `at_seq` counts the first data topic that crosses hosts: it must pass this bridge.
            let trigger = crate::deployment::trigger_topic(scenario, ServiceId::Bridge);
            let on = f.on_host(scenario);
            let passes = trigger.is_some_and(|t| {
                let producer = crate::deployment::producer(t).and_then(|p| scenario.host_of(p));
                let consumers = crate::deployment::consumers(scenario, t);
                producer == on || consumers.iter().any(|c| scenario.host_of(*c) == on)
            });
            if f.at_seq.is_some() && !passes {
                c.fail(
                    &at("at_seq"),
                    format!(
                        "at_seq counts the first data topic that crosses hosts ({}), which does \
                         not pass through host {}'s bridge: give at_s",
                        trigger.map_or("none", |t| t.name()),
                        on.unwrap_or("?")
                    ),
                );
            }
            if f.kind.in_band() && f.kind != FaultKind::Delay {
                c.fail(
                    &at("kind"),
                    format!(
                        "the bridge takes kill, stop (the link cut) and delay (a slow link), \
                         not {}",
                        f.kind.name()
                    ),
                );
            }
        } else if service.is_some_and(|s| scenario.host_of(s) != Some(orchestrator)) {
            c.fail(
                &at("service"),
                format!(
                    "`{}` runs on another host than the orchestrator's; faults act on the \
                     orchestrator's host's services and on any host's bridge so far",
                    f.service
                ),
            );
        }
    }
    for (what, present) in [
        ("[soak]", scenario.soak.is_some()),
        ("[campaign]", scenario.campaign.is_some()),
        ("[replay]", scenario.replay.is_some()),
    ] {
        if present {
            c.fail(
                "hosts",
                format!("{what} runs on one host so far: remove [hosts] or {what}"),
            );
        }
    }
}

fn join<'a>(names: impl Iterator<Item = &'a str>) -> String {
    names.collect::<Vec<_>>().join(", ")
}

#[cfg(test)]
mod tests {
    use crate::Scenario;

    const SPLIT: &str = r#"
name = "split"
[camera]
width_px = 64
height_px = 64
fov_deg = 10.0
exposure_s = 0.02
interval_s = 0.02
frames = 2
background_dn = 100.0
read_noise_dn = 5.0
psf_sigma_px = 0.8
reference_signal_dn = 40000.0
orbit_semi_major_axis_km = 42164.1696
[[camera.debris]]
x_m = 9000.0
y_m = 600.0
z_m = -500.0
vx_mps = -100.0
vy_mps = -600.0
vz_mps = 400.0
size_m = 0.1
[camera.tracker]
laser = false
[hosts.a]
endpoint = "tcp/127.0.0.1:7501"
orchestrator = true
[hosts.b]
endpoint = "tcp/127.0.0.1:7502"
[services.detector]
host = "b"
"#;

    /// The fields a placement names in its errors, for `SPLIT` with `(from, to)` replaced.
    fn errors(from: &str, to: &str) -> Vec<String> {
        errors_of(&[(from, to)])
    }

    fn errors_of(replacements: &[(&str, &str)]) -> Vec<String> {
        let mut text = SPLIT.to_string();
        for (from, to) in replacements {
            assert!(text.contains(from), "{from}");
            text = text.replace(from, to);
        }
        match Scenario::from_toml_str(&text, "split.toml") {
            Ok(_) => vec![],
            Err(crate::scenario::ScenarioError::Invalid { errors, .. }) => {
                errors.into_iter().map(|e| e.field).collect()
            }
            Err(e) => vec![e.to_string()],
        }
    }

    #[test]
    fn a_placement_is_checked_field_by_field() {
        assert_eq!(errors("", ""), Vec::<String>::new());
        assert_eq!(
            errors("host = \"b\"", "host = \"c\""),
            ["services.detector.host"]
        );
        assert_eq!(
            errors("127.0.0.1:7502", "0.0.0.0:7502"),
            ["hosts.b.endpoint"]
        );
        assert_eq!(
            errors("127.0.0.1:7502", "127.0.0.1:0"),
            ["hosts.b.endpoint"]
        );
        assert_eq!(
            errors("tcp/127.0.0.1:7502", "udp/127.0.0.1:7502"),
            ["hosts.b.endpoint"]
        );
        assert_eq!(
            errors("127.0.0.1:7502", "127.0.0.1:7501"),
            ["hosts.<name>.endpoint"]
        );
        assert_eq!(
            errors("orchestrator = true", ""),
            ["hosts.<name>.orchestrator"]
        );
        // a host that runs nothing
        assert_eq!(errors("host = \"b\"", "host = \"a\""), ["hosts.b"]);
        // the laser's calls cross hosts
        let tracker_on_b = "[services.tracker]\nhost = \"b\"\n[services.detector]";
        let laser = [
            ("laser = false", "laser = true"),
            ("[services.detector]", tracker_on_b),
        ];
        assert_eq!(errors_of(&laser), Vec::<String>::new());
        // the bridge is placed by [hosts]
        let bridge = "[services.detector]\nhost = \"b\"\n[services.bridge]\nhost = \"a\"";
        assert_eq!(
            errors("[services.detector]\nhost = \"b\"", bridge),
            ["services.bridge.host"]
        );
        // faults: the orchestrator's host's services and its bridge (kill, stop; at a time)
        let fault = |f: &str| {
            let faulted = format!("[services.detector]\nhost = \"b\"\n[[fault]]\n{f}");
            errors("[services.detector]\nhost = \"b\"", &faulted)
        };
        assert_eq!(
            fault("service = \"bridge\"\nkind = \"kill\"\nat_s = 0.5"),
            Vec::<String>::new()
        );
        assert_eq!(
            fault("service = \"bridge\"\nkind = \"stop\"\nat_s = 0.5\nduration_s = 1.0"),
            Vec::<String>::new()
        );
        assert_eq!(
            fault("service = \"bridge\"\nhost = \"b\"\nkind = \"kill\"\nat_seq = 1"),
            Vec::<String>::new()
        );
        assert_eq!(
            fault("service = \"bridge\"\nhost = \"c\"\nkind = \"kill\"\nat_seq = 1"),
            ["fault[0].host"]
        );
        assert_eq!(
            fault("service = \"sensor\"\nhost = \"a\"\nkind = \"kill\"\nat_seq = 1"),
            ["fault[0].host"]
        );
        // a slow link (delay) yes, an in-band panic or drop no
        let enabled = |f: &str| {
            let faulted = format!(
                "[services.detector]\nhost = \"b\"\n[faults]\nenabled = true\n[[fault]]\n{f}"
            );
            errors("[services.detector]\nhost = \"b\"", &faulted)
        };
        assert_eq!(
            enabled("service = \"bridge\"\nkind = \"delay\"\nat_seq = 1\ndelay_ms = 5\ncount = 3"),
            Vec::<String>::new()
        );
        assert_eq!(
            enabled("service = \"bridge\"\nkind = \"panic\"\nat_seq = 1"),
            ["fault[0].kind"]
        );
        assert_eq!(
            fault("service = \"detector\"\nkind = \"kill\"\nat_seq = 1"),
            ["fault[0].service"]
        );
        // a slow link by bandwidth: the bridge's delay only, in range
        let slow = "service = \"bridge\"\nkind = \"delay\"\nat_seq = 1\ncount = 3\n";
        assert_eq!(
            enabled(&format!("{slow}bandwidth_mbit_s = 20.0")),
            Vec::<String>::new()
        );
        assert_eq!(
            enabled(&format!("{slow}bandwidth_mbit_s = 0.0")),
            ["fault[0].bandwidth_mbit_s"]
        );
        assert_eq!(enabled(slow), ["fault[0].delay_ms"]);
        assert_eq!(
            enabled(
                "service = \"sensor\"\nkind = \"delay\"\nat_seq = 1\ncount = 3\n\
                     delay_ms = 5\nbandwidth_mbit_s = 20.0"
            ),
            ["fault[0].bandwidth_mbit_s"]
        );
    }

    /// A matrix of a split deployment faults the orchestrator's host's services and each
    /// host's bridge (kill, stop, delay); every host computes the same cases.
    #[test]
    fn a_split_matrix_faults_every_bridge_and_the_orchestrators_host() {
        let matrix = |m: &str| {
            let text = SPLIT.replace("[hosts.a]", &format!("[matrix]\n{m}\n[hosts.a]"));
            Scenario::from_toml_str(&text, "split.toml")
        };
        let sc =
            matrix("kinds = [\"kill\", \"panic\", \"delay\"]\nbandwidth_mbit_s = 5.0").unwrap();
        let cases = sc.matrix.as_ref().unwrap().cases(&sc);
        let names: Vec<&str> = cases.iter().map(|c| c.name.as_str()).collect();
        assert_eq!(
            names,
            [
                "sensor-kill",
                "sensor-panic",
                "sensor-delay",
                "tracker-kill",
                "tracker-panic",
                "tracker-delay",
                "bridge-a-kill",
                "bridge-a-delay",
                "bridge-b-kill",
                "bridge-b-delay",
            ]
        );
        let slow = &cases[9].fault;
        assert_eq!(
            (slow.host.as_deref(), slow.bandwidth_mbit_s, slow.delay_ms),
            (Some("b"), Some(5.0), None)
        );
        // the sensor's delay stays a delay per message
        assert_eq!(cases[2].fault.bandwidth_mbit_s, None);
        // the frame (the bridge's trigger) has 2 messages: a fault at the first
        assert_eq!(cases[6].fault.at_seq, Some(0));
        assert_eq!(
            errors_of(&[(
                "[hosts.a]",
                "[matrix]\nservices = [\"detector\"]\n[hosts.a]"
            )]),
            ["matrix.services[0]"]
        );
        // a bandwidth no case uses, a kind named twice
        let fields = |m: &str| -> Vec<String> {
            match matrix(m) {
                Err(crate::scenario::ScenarioError::Invalid { errors, .. }) => {
                    errors.into_iter().map(|e| e.field).collect()
                }
                other => panic!("{other:?}"),
            }
        };
        assert_eq!(
            fields("kinds = [\"kill\"]\nbandwidth_mbit_s = 5.0"),
            ["matrix.bandwidth_mbit_s"]
        );
        assert_eq!(
            fields("kinds = [\"kill\", \"stop\", \"kill\"]"),
            ["matrix.kinds[2]"]
        );
    }
}
