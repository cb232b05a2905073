//! `[supervision]`: what the orchestrator does when a service fails while the run is going —
//! it exits, is killed, or misses its heartbeat deadline (hung, or stopped). It restarts it
//! (the producers replay what the new incarnation needs, so in sim-clock mode nothing is lost),
//! up to `max_restarts` times within `restart_window_s`, waiting `backoff_ms` before the first
//! restart and twice as long before each further one (at most `backoff_max_ms`). A failure
//! during the initial startup always fails the run.
//!
//! ```toml
//! [supervision]
//! restart = "on-failure"      # never | on-failure | always
//! max_restarts = 3
//! [supervision.services.tracker]
//! restart = "never"
//! ```

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use super::Checker;
use crate::ServiceId;

/// When a service is restarted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Restart {
    /// Never: a failed service fails the run.
    Never,
    /// When it crashes, is killed, or misses its heartbeat deadline (the default).
    #[default]
    OnFailure,
    /// As `on-failure`, and also when it exits with status 0 before it was told to shut down.
    Always,
}

/// The supervision of one service; every field falls back to the section's.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct ServiceSupervision {
    #[serde(skip_serializing_if = "Option::is_none")]
    pub restart: Option<Restart>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_restarts: Option<u32>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Supervision {
    /// `never`, `on-failure` (default) or `always`.
    pub restart: Restart,
    /// Restarts allowed per service within `restart_window_s`, 0–100 (default 3).
    pub max_restarts: u32,
    /// The window `max_restarts` counts in [s], 1–86400 (default 60).
    pub restart_window_s: f64,
    /// Wait before the first restart [ms], 0–60000 (default 100); doubled for each further one.
    pub backoff_ms: u64,
    /// Longest wait before a restart [ms], `backoff_ms`–600000 (default 2000).
    pub backoff_max_ms: u64,
    /// A service checkpoints its state every this many inputs (a source: messages sent),
    /// 1–10⁶ (default 256), or every `checkpoint_every_ms`, whichever comes first: a restart
    /// replays at most that much. Sim-clock mode.
    pub checkpoint_every_inputs: u64,
    /// 10–600000 (default 1000).
    pub checkpoint_every_ms: u64,
    /// Per-service overrides (`[supervision.services.detector]`).
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub services: BTreeMap<String, ServiceSupervision>,
}

impl Default for Supervision {
    fn default() -> Self {
        Supervision {
            restart: Restart::OnFailure,
            max_restarts: 3,
            restart_window_s: 60.0,
            backoff_ms: 100,
            backoff_max_ms: 2000,
            checkpoint_every_inputs: 256,
            checkpoint_every_ms: 1000,
            services: BTreeMap::new(),
        }
    }
}

impl Supervision {
    /// The restart policy of `service`.
    pub fn restart_of(&self, service: ServiceId) -> Restart {
        self.services
            .get(service.name())
            .and_then(|s| s.restart)
            .unwrap_or(self.restart)
    }

    /// The restart budget of `service` within the window.
    pub fn max_restarts_of(&self, service: ServiceId) -> u32 {
        self.services
            .get(service.name())
            .and_then(|s| s.max_restarts)
            .unwrap_or(self.max_restarts)
    }

    /// The wait before restart number `n` (0-based) within the window [ms].
    pub fn backoff_ms_of(&self, n: u32) -> u64 {
        self.backoff_ms
            .saturating_mul(1u64 << n.min(20))
            .min(self.backoff_max_ms)
    }
}

pub(super) fn check_supervision(c: &mut Checker, scenario: &super::Scenario) {
    let s = &scenario.supervision;
    c.range_u(
        "supervision.max_restarts",
        u64::from(s.max_restarts),
        0,
        100,
    );
    c.range(
        "supervision.restart_window_s",
        s.restart_window_s,
        1.0,
        86400.0,
    );
    c.range_u("supervision.backoff_ms", s.backoff_ms, 0, 60_000);
    c.range_u(
        "supervision.checkpoint_every_inputs",
        s.checkpoint_every_inputs,
        1,
        1_000_000,
    );
    c.range_u(
        "supervision.checkpoint_every_ms",
        s.checkpoint_every_ms,
        10,
        600_000,
    );
    c.range_u(
        "supervision.backoff_max_ms",
        s.backoff_max_ms,
        s.backoff_ms,
        600_000,
    );
    for (name, o) in &s.services {
        c.deployed_service(&format!("supervision.services.{name}"), name, scenario);
        if let Some(m) = o.max_restarts {
            c.range_u(
                &format!("supervision.services.{name}.max_restarts"),
                u64::from(m),
                0,
                100,
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn backoff_doubles_up_to_its_cap_and_overrides_fall_back_to_the_section() {
        let mut s = Supervision::default();
        assert_eq!(
            (0..6).map(|n| s.backoff_ms_of(n)).collect::<Vec<_>>(),
            [100, 200, 400, 800, 1600, 2000]
        );
        s.services.insert(
            "tracker".into(),
            ServiceSupervision {
                restart: Some(Restart::Never),
                max_restarts: None,
            },
        );
        assert_eq!(s.restart_of(ServiceId::Tracker), Restart::Never);
        assert_eq!(s.restart_of(ServiceId::Detector), Restart::OnFailure);
        assert_eq!(s.max_restarts_of(ServiceId::Tracker), 3);
    }
}
