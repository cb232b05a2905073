//! Membership: the deployment knows its processes (the orchestrator and each service's current
//! incarnation). Any other live node under the deployment's prefix is a stranger. One named as
//! a glint service (it may publish or serve on the deployment's topics) is an impostor: it is
//! named in the report and fails the run. Any other is an observer (a Python client, a live
//! view): named in the report, and never able to hold a producer back, since the sim-clock
//! credit counts only the deployment's own consumers.

use std::collections::BTreeMap;

use shared_types::ServiceId;

/// A node under the prefix that is not the deployment's.
#[derive(Debug, Clone)]
pub struct Stranger {
    pub name: String,
    pub pid: Option<u32>,
    pub impostor: bool,
    /// When it was first seen [s after the services were started].
    pub seen_s: f64,
}

#[derive(Default)]
pub struct Membership {
    /// By (name, pid): each stranger once.
    pub strangers: BTreeMap<(String, Option<u32>), Stranger>,
}

impl Membership {
    /// Looks at the live nodes of `prefix`; `ours` are the deployment's pids. Returns the
    /// failure when a new impostor is seen.
    pub fn scan(&mut self, prefix: &str, ours: &[u32], now_s: f64) -> Option<String> {
        let mut failure = None;
        for (name, pid) in glint_runtime::live_nodes(prefix) {
            if pid.is_some_and(|p| ours.contains(&p)) {
                continue;
            }
            let key = (name.clone(), pid);
            if self.strangers.contains_key(&key) {
                continue;
            }
            let impostor = ServiceId::from_name(&name).is_some();
            let who = pid.map_or("another user's process".to_string(), |p| format!("pid {p}"));
            if impostor {
                tracing::error!(node = name, ?pid, "a stranger joined the deployment");
                failure = Some(format!(
                    "a process outside the deployment ({who}) joined it as node `{name}` under \
                     prefix {prefix}: it could publish or serve on the deployment's topics"
                ));
            } else {
                tracing::info!(node = name, ?pid, "an observer joined the deployment");
            }
            self.strangers.insert(
                key,
                Stranger {
                    name,
                    pid,
                    impostor,
                    seen_s: now_s,
                },
            );
        }
        failure
    }

    pub fn report(&self) -> crate::report::MembershipReport {
        crate::report::MembershipReport {
            strangers: (self.strangers.values())
                .map(|s| crate::report::StrangerReport {
                    name: s.name.clone(),
                    pid: s.pid,
                    role: if s.impostor { "impostor" } else { "observer" }.to_string(),
                    seen_s: s.seen_s,
                })
                .collect(),
        }
    }
}
