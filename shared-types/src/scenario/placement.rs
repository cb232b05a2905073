//! `[services.<name>]`: where a process of the deployment runs. `cpu` pins it (every thread
//! it starts) to one CPU of the host, so two busy services need not share a core's caches or
//! take turns on it; unset, the kernel places it.
//!
//! ```toml
//! [services.sensor]
//! cpu = 0
//! [services.detector]
//! cpu = 1
//! ```
//!
//! Which CPUs exist is the host's: `glint run` refuses a CPU this host does not give glint
//! (exit 2, naming the field and the CPUs it has).

use serde::{Deserialize, Serialize};

use super::Checker;
use crate::ServiceId;

/// Placement of one process.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct ServicePlacement {
    /// The CPU it runs on, 0–1023 (as numbered in /proc/cpuinfo); unset: any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cpu: Option<u32>,
    /// The host it runs on, a name of `[hosts]` (a split deployment); unset: the
    /// orchestrator's host.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub host: Option<String>,
}

/// The highest CPU number a placement may name.
pub const MAX_CPU: u32 = 1023;

impl super::Scenario {
    /// The CPU `service` is pinned to, if any.
    pub fn cpu_of(&self, service: ServiceId) -> Option<u32> {
        self.services.get(service.name()).and_then(|p| p.cpu)
    }
}

pub(super) fn check_placement(c: &mut Checker, scenario: &super::Scenario) {
    for (name, p) in &scenario.services {
        c.deployed_service(&format!("services.{name}"), name, scenario);
        if let Some(cpu) = p.cpu {
            c.range_u(
                &format!("services.{name}.cpu"),
                u64::from(cpu),
                0,
                u64::from(MAX_CPU),
            );
        }
    }
}
