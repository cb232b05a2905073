//! Faults to inject into a deployment: `[[fault]]` entries of the scenario, or `--fault` on the
//! command line (`SERVICE:KIND@AT[,duration_s=S]`, see [`FaultSpec::parse`]).
//!
//! A fault targets one service. It fires once the service's input topic has carried message
//! `at_seq` (for the sensor: once it has published it), as the orchestrator sees it, or
//! `at_s` seconds after the services were started. Signal faults come from the orchestrator:
//! `kill` is SIGKILL, `stop` is SIGSTOP for `duration_s`, then SIGCONT. In-band faults are
//! control commands the service's runtime obeys only when the scenario sets
//! `faults.enabled = true`: `panic` (it panics in its loop), `delay` (`delay_ms` before each
//! message it processes, for `duration_s` or for `count` messages), `drop` (`count` of its outputs, every `every`-th,
//! are not sent), `corrupt` (`count` outputs sent invalid: `how` = `nan`, a non-finite value;
//! `count`, a count or length field out of range; `version`, a wrong contract version).

use serde::{Deserialize, Serialize};

use super::Checker;
use crate::{deployment, ServiceId};

/// The most faults one deployment takes.
pub const MAX_FAULTS: usize = 64;

/// What a fault does to its service.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum FaultKind {
    /// SIGKILL.
    Kill,
    /// SIGSTOP for `duration_s`, then SIGCONT.
    Stop,
    /// The service panics in its loop.
    Panic,
    /// `delay_ms` before each message the service processes, for `duration_s` or for `count`
    /// messages.
    Delay,
    /// `count` outputs not sent (every `every`-th).
    Drop,
    /// `count` outputs sent invalid (`how`).
    Corrupt,
}

impl FaultKind {
    pub const ALL: [FaultKind; 6] = [
        FaultKind::Kill,
        FaultKind::Stop,
        FaultKind::Panic,
        FaultKind::Delay,
        FaultKind::Drop,
        FaultKind::Corrupt,
    ];

    pub fn name(self) -> &'static str {
        match self {
            FaultKind::Kill => "kill",
            FaultKind::Stop => "stop",
            FaultKind::Panic => "panic",
            FaultKind::Delay => "delay",
            FaultKind::Drop => "drop",
            FaultKind::Corrupt => "corrupt",
        }
    }

    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.name() == name)
    }

    /// Obeyed by the service's runtime (a control command), not a signal.
    pub fn in_band(self) -> bool {
        !matches!(self, FaultKind::Kill | FaultKind::Stop)
    }

    /// It ends the process or hangs it: supervision notices it and restarts the service.
    pub fn ends_a_process(self) -> bool {
        match self {
            FaultKind::Kill | FaultKind::Stop | FaultKind::Panic => true,
            FaultKind::Delay | FaultKind::Drop | FaultKind::Corrupt => false,
        }
    }

    /// Its wire code in [`crate::InBandFault`].
    pub fn code(self) -> u8 {
        Self::ALL.iter().position(|k| *k == self).unwrap_or(0) as u8
    }

    pub fn from_code(code: u8) -> Option<Self> {
        Self::ALL.get(code as usize).copied()
    }
}

/// How a `corrupt` fault makes an output invalid.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Corruption {
    /// A non-finite value (a frame: a zero exposure time, its pixels being integers).
    Nan,
    /// A count or length field out of range (a frame: a width that does not match its pixels).
    Count,
    /// A wrong contract version.
    #[default]
    Version,
}

impl Corruption {
    pub const ALL: [Corruption; 3] = [Corruption::Nan, Corruption::Count, Corruption::Version];

    pub fn name(self) -> &'static str {
        match self {
            Corruption::Nan => "nan",
            Corruption::Count => "count",
            Corruption::Version => "version",
        }
    }

    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.name() == name)
    }

    pub fn code(self) -> u8 {
        Self::ALL.iter().position(|k| *k == self).unwrap_or(0) as u8
    }

    pub fn from_code(code: u8) -> Option<Self> {
        Self::ALL.get(code as usize).copied()
    }
}

/// `[faults]`: whether the services obey in-band fault commands at all.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct FaultsSection {
    /// Obey `panic`, `delay`, `drop` and `corrupt` commands (default false: a deployment that
    /// did not ask for them ignores such commands and counts them). `glint run --fault` with an
    /// in-band kind sets it.
    pub enabled: bool,
}

/// One fault.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FaultSpec {
    /// The service: `sensor`, `detector`, `tracker` or `inversion` (one the scenario deploys).
    pub service: String,
    /// `kill` or `stop`.
    pub kind: FaultKind,
    /// Fire once the service's input has carried this message (0-based), 0–10⁹.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub at_seq: Option<u64>,
    /// Or fire this long after the services were started [s], 0–86400.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub at_s: Option<f64>,
    /// How long a `stop` or a `delay` lasts [s], 0.001–3600; only for those.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub duration_s: Option<f64>,
    /// `delay`: added before each message the service processes [ms], 1–10000.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub delay_ms: Option<u64>,
    /// `drop`, `corrupt`: how many outputs, 1–1000 (default 1). `delay`: how many messages
    /// it slows, 1–10⁶ (instead of `duration_s`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub count: Option<u32>,
    /// `drop`: every this many-th output, 1–1000 (default 1: a burst of `count`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub every: Option<u32>,
    /// `corrupt`: `nan`, `count` or `version` (default).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub how: Option<Corruption>,
    /// A bridge's `delay` (a slow link): the link's bandwidth while it lasts [Mbit/s],
    /// 1–100000: each data message waits the time its bytes take at that rate (and
    /// `delay_ms`, if given, on top).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bandwidth_mbit_s: Option<f64>,
    /// A split deployment: which host's `bridge` (default: the orchestrator's host); that
    /// host's part fires the fault. Only for the bridge.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub host: Option<String>,
}

impl FaultSpec {
    /// The targeted service (valid after [`check_faults`]).
    pub fn service_id(&self) -> Option<ServiceId> {
        ServiceId::from_name(&self.service).filter(|s| *s != ServiceId::Orchestrator)
    }

    /// The host whose part fires this fault: `host`, or where its service runs (`None`: the
    /// deployment is not split).
    pub fn on_host<'a>(&'a self, scenario: &'a super::Scenario) -> Option<&'a str> {
        let service = self.service_id()?;
        self.host.as_deref().or(scenario.host_of(service))
    }

    /// `SERVICE:KIND@AT[,duration_s=S]`, where `AT` is a message number (`20`) or a time
    /// after the start (`1.5s`): `detector:kill@20`, `tracker:stop@0.8s,duration_s=0.3`.
    /// Ranges are checked with the scenario ([`check_faults`]).
    pub fn parse(text: &str) -> Result<FaultSpec, String> {
        let form = "expected SERVICE:KIND@AT[,duration_s=S], e.g. detector:kill@20 or \
                    tracker:stop@1.5s,duration_s=0.3";
        let (head, options) = match text.split_once(',') {
            Some((h, o)) => (h, Some(o)),
            None => (text, None),
        };
        let (service, rest) = head.split_once(':').ok_or(format!("no `:`; {form}"))?;
        let (kind, at) = rest.split_once('@').ok_or(format!("no `@`; {form}"))?;
        let kind = FaultKind::from_name(kind).ok_or(format!(
            "unknown kind `{kind}`; allowed: {}",
            FaultKind::ALL.map(FaultKind::name).join(", ")
        ))?;
        let (at_seq, at_s) = match at.strip_suffix('s') {
            Some(secs) => (
                None,
                Some(
                    secs.parse::<f64>()
                        .map_err(|_| format!("`{at}` is not a time in seconds; {form}"))?,
                ),
            ),
            None => (
                Some(
                    at.parse::<u64>()
                        .map_err(|_| format!("`{at}` is not a message number; {form}"))?,
                ),
                None,
            ),
        };
        let mut f = FaultSpec {
            service: service.to_string(),
            kind,
            at_seq,
            at_s,
            duration_s: None,
            delay_ms: None,
            count: None,
            every: None,
            how: None,
            bandwidth_mbit_s: None,
            host: None,
        };
        let int = |name: &str, v: &str| {
            v.parse::<u32>()
                .map_err(|_| format!("{name} `{v}` is not a whole number"))
        };
        for opt in options.into_iter().flat_map(|o| o.split(',')) {
            match opt.split_once('=') {
                Some(("duration_s", v)) => {
                    f.duration_s = Some(
                        v.parse::<f64>()
                            .map_err(|_| format!("duration_s `{v}` is not a number"))?,
                    )
                }
                Some(("delay_ms", v)) => f.delay_ms = Some(u64::from(int("delay_ms", v)?)),
                Some(("count", v)) => f.count = Some(int("count", v)?),
                Some(("every", v)) => f.every = Some(int("every", v)?),
                Some(("host", v)) => f.host = Some(v.to_string()),
                Some(("bandwidth_mbit_s", v)) => {
                    f.bandwidth_mbit_s = Some(
                        v.parse::<f64>()
                            .map_err(|_| format!("bandwidth_mbit_s `{v}` is not a number"))?,
                    )
                }
                Some(("how", v)) => {
                    f.how = Some(Corruption::from_name(v).ok_or(format!(
                        "how `{v}` is not one of {}",
                        Corruption::ALL.map(Corruption::name).join(", ")
                    ))?)
                }
                _ => {
                    return Err(format!(
                        "unknown option `{opt}`; allowed: duration_s=S, delay_ms=N, count=N, \
                         every=N, how=nan|count|version, host=NAME, bandwidth_mbit_s=X"
                    ))
                }
            }
        }
        Ok(f)
    }
}

/// Checks every fault against the scenario: a deployed service, one trigger, the ranges.
pub(super) fn check_faults(c: &mut Checker, scenario: &super::Scenario) {
    c.range_u(
        "fault (count)",
        scenario.fault.len() as u64,
        0,
        MAX_FAULTS as u64,
    );
    let deployed = deployment::services(scenario);
    let names: Vec<&str> = deployed.iter().map(|s| s.name()).collect();
    for (i, f) in scenario.fault.iter().enumerate() {
        let at = |field: &str| format!("fault[{i}].{field}");
        match f.service_id() {
            Some(s) if deployed.contains(&s) => {}
            _ => c.fail(
                &at("service"),
                format!(
                    "`{}` is not a service this scenario deploys; allowed: {}",
                    f.service,
                    names.join(", ")
                ),
            ),
        }
        match (f.at_seq, f.at_s) {
            (Some(seq), None) => c.range_u(&at("at_seq"), seq, 0, 1_000_000_000),
            (None, Some(s)) => c.range(&at("at_s"), s, 0.0, 86400.0),
            _ => c.fail(&at("at_seq"), "give exactly one of at_seq and at_s".into()),
        }
        let kind = f.kind.name();
        let timed = matches!(f.kind, FaultKind::Stop | FaultKind::Delay);
        // A delay lasts a time or a number of inputs (which no host's speed can outrun).
        let counted_delay = f.kind == FaultKind::Delay && f.count.is_some();
        match (timed, f.duration_s) {
            (true, Some(_)) if counted_delay => c.fail(
                &at("duration_s"),
                "a delay lasts duration_s or count inputs, not both".into(),
            ),
            (true, Some(d)) => c.range(&at("duration_s"), d, 0.001, 3600.0),
            (true, None) if counted_delay => {}
            (true, None) if f.kind == FaultKind::Delay => c.fail(
                &at("duration_s"),
                "a delay needs its length: duration_s (0.001..=3600) or count inputs \
                 (1..=1000000)"
                    .into(),
            ),
            (true, None) => c.fail(
                &at("duration_s"),
                format!("a {kind} needs its duration; allowed 0.001..=3600"),
            ),
            (false, Some(_)) => c.fail(
                &at("duration_s"),
                format!("a {kind} has no duration; leave it out"),
            ),
            (false, None) => {}
        }
        let only = |c: &mut Checker, field: &str, set: bool, kinds: &[FaultKind]| {
            if set && !kinds.contains(&f.kind) {
                let names: Vec<&str> = kinds.iter().map(|k| k.name()).collect();
                c.fail(
                    &at(field),
                    format!("only for {}; a {kind} has none", names.join(" and ")),
                );
            }
        };
        only(c, "delay_ms", f.delay_ms.is_some(), &[FaultKind::Delay]);
        only(
            c,
            "count",
            f.count.is_some(),
            &[FaultKind::Drop, FaultKind::Corrupt, FaultKind::Delay],
        );
        only(c, "every", f.every.is_some(), &[FaultKind::Drop]);
        only(c, "how", f.how.is_some(), &[FaultKind::Corrupt]);
        let slow_link = f.kind == FaultKind::Delay && f.service_id() == Some(ServiceId::Bridge);
        if f.kind == FaultKind::Delay {
            if let Some(ms) = f.delay_ms {
                c.range_u(&at("delay_ms"), ms, 1, 10_000);
            } else if !slow_link {
                c.fail(
                    &at("delay_ms"),
                    "a delay needs delay_ms; allowed 1..=10000".into(),
                );
            } else if f.bandwidth_mbit_s.is_none() {
                c.fail(
                    &at("delay_ms"),
                    "a bridge's delay needs delay_ms (1..=10000) or bandwidth_mbit_s \
                     (1..=100000)"
                        .into(),
                );
            }
        }
        if let Some(r) = f.bandwidth_mbit_s {
            if slow_link {
                c.range(&at("bandwidth_mbit_s"), r, 1.0, 100_000.0);
            } else {
                c.fail(
                    &at("bandwidth_mbit_s"),
                    "a bandwidth limit is a slow link: only for the bridge's delay".into(),
                );
            }
        }
        match (f.kind, f.count) {
            (FaultKind::Delay, Some(n)) => c.range_u(&at("count"), u64::from(n), 1, 1_000_000),
            (_, Some(n)) => c.range_u(&at("count"), u64::from(n), 1, 1000),
            _ => {}
        }
        // A fault at a message its trigger never carries would never fire.
        if let (Some(seq), Some(s)) = (f.at_seq, f.service_id()) {
            let carried = deployment::trigger_topic(scenario, s)
                .map(|t| (t, deployment::expected_messages(scenario, t)));
            if let Some((t, n)) = carried.filter(|(_, n)| seq >= *n) {
                c.fail(
                    &at("at_seq"),
                    format!(
                        "{} carries {n} messages ({}), so a fault at message {seq} would never \
                         fire; allowed 0..={}",
                        f.service,
                        t.name(),
                        n.saturating_sub(1)
                    ),
                );
            }
        }
        if let Some(k) = f.every {
            c.range_u(&at("every"), u64::from(k), 1, 1000);
        }
        if let Some(h) = f.host.as_ref().filter(|h| !scenario.hosts.contains_key(*h)) {
            let hosts: Vec<&str> = scenario.hosts.keys().map(|k| k.as_str()).collect();
            let why = match scenario.split() {
                true => format!(
                    "`{h}` is not a host of [hosts]; allowed: {}",
                    hosts.join(", ")
                ),
                false => format!("`{h}`: the scenario has no [hosts.<name>] (it runs on one host)"),
            };
            c.fail(&at("host"), why);
        } else if f.host.is_some() && f.service_id() != Some(ServiceId::Bridge) {
            c.fail(
                &at("host"),
                "only a bridge fault names its host (a service runs where it is placed)".into(),
            );
        }
        if f.kind.in_band() && !scenario.faults.enabled {
            c.fail(
                &at("kind"),
                format!(
                    "a {kind} fault is obeyed only with faults.enabled = true (add [faults] \
                     enabled = true; glint run --fault sets it)"
                ),
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_command_line_form_parses_and_names_what_is_wrong() {
        let f = FaultSpec::parse("detector:kill@20").unwrap();
        assert_eq!(
            (f.service.as_str(), f.kind, f.at_seq, f.at_s, f.duration_s),
            ("detector", FaultKind::Kill, Some(20), None, None)
        );
        let f = FaultSpec::parse("tracker:stop@1.5s,duration_s=0.3").unwrap();
        assert_eq!(
            (f.kind, f.at_seq, f.at_s, f.duration_s),
            (FaultKind::Stop, None, Some(1.5), Some(0.3))
        );
        for (bad, says) in [
            ("detector-kill@20", "no `:`"),
            ("detector:kill", "no `@`"),
            (
                "detector:explode@3",
                "unknown kind `explode`; allowed: kill, stop, panic, delay, drop, corrupt",
            ),
            ("detector:kill@x", "`x` is not a message number"),
            ("detector:kill@xs", "`xs` is not a time in seconds"),
            ("detector:stop@3,for=2", "unknown option `for=2`"),
            (
                "detector:stop@3,duration_s=y",
                "duration_s `y` is not a number",
            ),
        ] {
            let e = FaultSpec::parse(bad).unwrap_err();
            assert!(e.contains(says), "{bad}: {e}");
        }
    }
}
