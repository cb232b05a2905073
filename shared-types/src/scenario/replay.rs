//! `[replay]`: the sensor's streams published from a recording (`glint run --record`'s
//! `run.mcap`) instead of rendered, into a deployment of the consumers named. `glint replay`
//! writes this section into the scenario it takes from the recording; a scenario file may
//! carry it too.
//!
//! ```toml
//! [replay]
//! recording = "runs/debris-…/run.mcap"
//! services = ["detector", "tracker"]   # default: every consumer the scenario deploys
//! speed = 0.0                          # 0: as fast as the consumers take it; else × recorded time
//! ```
//!
//! Every message keeps its recorded bytes (a frame its header's fields and its pixels); its
//! sequence number and send time are the replay's. In sim-clock mode the replayed streams run
//! in lockstep with their consumers as the sensor's do, so their results are the recorded
//! run's, bit for bit.

use serde::{Deserialize, Serialize};

use super::{Checker, Scenario};
use crate::ServiceId;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReplayScenario {
    /// The recording (an MCAP file written by `glint run --record`).
    pub recording: String,
    /// Consumers to deploy (default: every one the scenario deploys). Each one's inputs must
    /// come from the recording or from another service named.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub services: Vec<String>,
    /// Pace [× recorded simulated time]: 0 (default) publishes as fast as the consumers take
    /// it; else 0.01–1000.
    #[serde(default)]
    pub speed: f64,
}

impl ReplayScenario {
    /// Whether the replay deploys `service` (the sensor always: it publishes the recording;
    /// the orchestrator always).
    pub fn runs(&self, service: ServiceId) -> bool {
        service == ServiceId::Sensor
            || service == ServiceId::Orchestrator
            || self.services.is_empty()
            || self.services.iter().any(|s| s == service.name())
    }
}

pub(super) fn check_replay(c: &mut Checker, scenario: &Scenario) {
    let Some(r) = &scenario.replay else {
        return;
    };
    if r.recording.is_empty() {
        c.fail("replay.recording", "must name an MCAP file".into());
    }
    if r.speed != 0.0 {
        c.range("replay.speed", r.speed, 0.01, 1000.0);
    }
    let consumers: Vec<ServiceId> = ServiceId::spawnable()
        .filter(|s| *s != ServiceId::Sensor && s.spec().section.present(scenario))
        .collect();
    for (i, name) in r.services.iter().enumerate() {
        if !consumers.iter().any(|s| s.name() == name) {
            let allowed: Vec<&str> = consumers.iter().map(|s| s.name()).collect();
            c.fail(
                &format!("replay.services[{i}]"),
                format!(
                    "'{name}' is not a consumer this scenario deploys; allowed: {}",
                    allowed.join(", ")
                ),
            );
        }
    }
    if !c.errors.is_empty() {
        return;
    }
    // A consumer's inputs come from the recording (the sensor's topics) or from a service
    // that runs.
    for s in consumers.iter().filter(|s| r.runs(**s)) {
        for t in s.spec().inputs {
            if let Some(p) = t.spec().producer() {
                if p != ServiceId::Sensor && p != ServiceId::Orchestrator && !r.runs(p) {
                    c.fail(
                        "replay.services",
                        format!(
                            "{} takes {} from {}: name {} too",
                            s.name(),
                            t.name(),
                            p.name(),
                            p.name()
                        ),
                    );
                }
            }
        }
    }
}
