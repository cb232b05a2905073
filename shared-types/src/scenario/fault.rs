//! Faults to inject into a deployment: `[[fault]]` entries of the scenario, or `--fault` on the
//! command line (`SERVICE:KIND@AT[,duration_s=S]`, see [`FaultSpec::parse`]).
//!
//! A fault targets one service. It fires once the service's input topic has carried message
//! `at_seq` (for the sensor: once it has published it), as the orchestrator sees it, or
//! `at_s` seconds after the services were started. Signal faults come from the orchestrator:
//! `kill` is SIGKILL, `stop` is SIGSTOP for `duration_s`, then SIGCONT.

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
}

impl FaultKind {
    pub const ALL: [FaultKind; 2] = [FaultKind::Kill, FaultKind::Stop];

    pub fn name(self) -> &'static str {
        match self {
            FaultKind::Kill => "kill",
            FaultKind::Stop => "stop",
        }
    }

    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.name() == name)
    }
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
    /// How long a `stop` lasts [s], 0.001–3600; not used by `kill`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub duration_s: Option<f64>,
}

impl FaultSpec {
    /// The targeted service (valid after [`check_faults`]).
    pub fn service_id(&self) -> Option<ServiceId> {
        ServiceId::from_name(&self.service).filter(|s| *s != ServiceId::Orchestrator)
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
        let mut duration_s = None;
        for opt in options.into_iter().flat_map(|o| o.split(',')) {
            match opt.split_once('=') {
                Some(("duration_s", v)) => {
                    duration_s = Some(
                        v.parse::<f64>()
                            .map_err(|_| format!("duration_s `{v}` is not a number"))?,
                    )
                }
                _ => return Err(format!("unknown option `{opt}`; allowed: duration_s=S")),
            }
        }
        Ok(FaultSpec {
            service: service.to_string(),
            kind,
            at_seq,
            at_s,
            duration_s,
        })
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
        match (f.kind, f.duration_s) {
            (FaultKind::Stop, Some(d)) => c.range(&at("duration_s"), d, 0.001, 3600.0),
            (FaultKind::Stop, None) => c.fail(
                &at("duration_s"),
                "a stop needs its duration; allowed 0.001..=3600".into(),
            ),
            (FaultKind::Kill, Some(_)) => c.fail(
                &at("duration_s"),
                "a kill has no duration; leave it out".into(),
            ),
            (FaultKind::Kill, None) => {}
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
                "unknown kind `explode`; allowed: kill, stop",
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
