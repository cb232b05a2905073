//! The bridge of a host other than the orchestrator's, kept there: supervised as
//! `[supervision]` says once it was first ready (killed or hung, it is restarted, and the other
//! hosts' bridges put again what it may have lost), and fired into by the scenario's faults
//! that name this host (`[[fault]] service = "bridge", host = "<this host>"`), with the same
//! state machines the orchestrator's host uses ([`Supervisor`], [`Injector`]).

use std::time::Instant;

use anyhow::Result;
use shared_types::{deployment, Heartbeat, Scenario, ServiceId, TopicId};

use crate::run::deploy::ServiceProcess;
use crate::run::faults::{Act, Heard, Injector};
use crate::run::supervise::{Action, Observation, Supervisor};

/// The bridge's exit status when the orchestrator's host was lost (its part ends); no bridge
/// runs in a glint built without the `hosts` feature.
fn lost_orchestrator() -> Option<i32> {
    #[cfg(feature = "hosts")]
    return Some(i32::from(glint_bridge::node::EXIT_ORCHESTRATOR_LOST));
    #[cfg(not(feature = "hosts"))]
    return None;
}

pub struct Keeper {
    supervisor: Supervisor,
    injector: Injector,
    /// The bridge was ready once: supervision runs from then on.
    supervised: bool,
    /// The bridge's latest heartbeat, and when it came.
    beat: Option<(Instant, Heartbeat)>,
    /// The run's `Start`, as heard over control: fault times count from it.
    started: Option<Instant>,
    period: std::time::Duration,
    /// The topic a fault's `at_seq` counts, and how many of it the bridge passed on: its
    /// earlier incarnations' (each one's counters start from zero) and the current one's.
    trigger: Option<TopicId>,
    carried_before: u64,
    carried_now: (u32, u64),
}

impl Keeper {
    pub fn new(scenario: &Scenario, host: &str) -> Self {
        let limits = &scenario.run;
        Keeper {
            supervisor: Supervisor::new(
                &scenario.supervision,
                &[ServiceId::Bridge],
                std::time::Duration::from_millis(limits.heartbeat_deadline_ms),
                std::time::Duration::from_millis(limits.startup_timeout_ms),
            ),
            injector: Injector::new(scenario, Some(host)),
            supervised: false,
            beat: None,
            started: None,
            period: std::time::Duration::from_millis(limits.heartbeat_period_ms),
            trigger: deployment::trigger_topic(scenario, ServiceId::Bridge),
            carried_before: 0,
            carried_now: (0, 0),
        }
    }

    /// A heartbeat of the bridge.
    pub fn heard(&mut self, hb: Heartbeat) {
        let now = Instant::now();
        self.beat = Some((now, hb));
        let counters = (self.trigger).and_then(|t| hb.topics.iter().find(|c| c.topic == t as u32));
        let passed_on = counters.map_or(0, |c| c.published);
        match self.carried_now {
            (pid, n) if pid == hb.pid => self.carried_now = (pid, n.max(passed_on)),
            (_, n) => {
                self.carried_before += n;
                self.carried_now = (hb.pid, passed_on);
            }
        }
        if let Some(at_s) = self.since_start(now) {
            // Its progress: what it passed on, over its incarnations (a restarted bridge has
            // recovered once it carries again).
            let carried = self.carried();
            let heard = Heard {
                at_s,
                faults_obeyed: hb.faults_obeyed,
                delaying: hb.delaying != 0,
                progress: carried,
                carried,
                done: 0,
            };
            self.injector.heard_from(ServiceId::Bridge, heard);
        }
    }

    fn carried(&self) -> u64 {
        self.carried_before + self.carried_now.1
    }

    /// The orchestrator of record started the run.
    pub fn met(&self) -> bool {
        self.started.is_some()
    }

    /// The run's `Start` arrived.
    pub fn start(&mut self) {
        self.started.get_or_insert_with(Instant::now);
    }

    fn since_start(&self, t: Instant) -> Option<f64> {
        (self.started).map(|s| t.saturating_duration_since(s).as_secs_f64())
    }

    /// One tick: the faults due (once the run started), supervision's actions on `bridge`
    /// (once it was first ready; `respawn(n)` starts its n-th restart). `Some(why)` when this
    /// host's part must end: the bridge failed past what `[supervision]` allows, or ended
    /// because the orchestrator's host is gone.
    pub fn step(
        &mut self,
        bridge: &mut ServiceProcess,
        mut respawn: impl FnMut(u32) -> Result<ServiceProcess>,
    ) -> Result<Option<String>> {
        let now = Instant::now();
        if !self.supervised
            && self
                .beat
                .is_some_and(|(_, hb)| hb.state >= Heartbeat::READY)
        {
            self.supervisor.started(now);
            self.supervised = true;
        }
        let now_s = self.since_start(now);
        if let Some(now_s) = now_s {
            let carried = self.carried();
            for a in self.injector.step(now_s, |_| carried, |_, _| (0, 0)) {
                match a.act {
                    Act::Signal(sig) => bridge.signal(sig),
                    // The bridge fires its own delays from the scenario.
                    Act::Order(_) => {}
                }
            }
        }
        if !self.supervised {
            return Ok(None);
        }
        let now_s = now_s.unwrap_or(0.0);
        // A stopped bridge cuts the link: silent for three heartbeat periods, it is noticed
        // (before supervision's deadline, which a short stop never reaches).
        if self
            .beat
            .is_some_and(|(at, _)| now.saturating_duration_since(at) > 3 * self.period)
        {
            self.injector
                .detected(ServiceId::Bridge, "heartbeat silent", now_s);
        }
        bridge.poll_exit();
        if let Some(code) = bridge.exit_code.filter(|c| Some(*c) == lost_orchestrator()) {
            return Ok(Some(format!(
                "the bridge ended (status {code}): the orchestrator's host is gone\n{}",
                bridge.log_tail(8)
            )));
        }
        let seen = Observation {
            id: ServiceId::Bridge,
            exited: (!bridge.is_running()).then(|| bridge.exit_ok.unwrap_or(false)),
            heartbeat: (self.beat.filter(|(_, hb)| hb.pid == bridge.pid))
                .map(|(at, hb)| (at, hb.state)),
        };
        for action in self.supervisor.step(now, &[seen]) {
            match action {
                Action::Noticed { id, how } => {
                    tracing::warn!(how = how.label(), "the bridge failed");
                    self.injector.detected(id, how.label(), now_s);
                }
                Action::Kill(_) => bridge.signal(rustix::process::Signal::KILL),
                Action::Respawn(id) => {
                    let n = self.supervisor.restarts(id);
                    tracing::info!(restart = n, "restarting the bridge");
                    *bridge = respawn(n)?;
                }
                Action::Resume(id) => {
                    tracing::info!("the restarted bridge is ready");
                    self.injector.restarted(id, now_s, self.carried());
                }
                Action::GiveUp { why, .. } => {
                    return Ok(Some(format!(
                        "the bridge failed and is not restarted: {why}\n{}",
                        bridge.log_tail(8)
                    )))
                }
            }
        }
        Ok(None)
    }

    /// Whether the bridge is under supervision (it was ready once): its exit is the keeper's.
    pub fn supervising(&self) -> bool {
        self.supervised
    }

    /// The run is over: the faults that never fired (the part did not test what it was asked to).
    pub fn finish(&mut self) -> Vec<String> {
        self.injector.finish()
    }

    /// The bridge's last heartbeat.
    pub fn last_beat(&self) -> Option<Heartbeat> {
        self.beat.map(|(_, hb)| hb)
    }

    pub fn restarts(&self) -> u32 {
        self.supervisor.restarts(ServiceId::Bridge)
    }

    /// The faults this host fired, as report entries: their timelines (what they lost is
    /// counted end to end by the orchestrator of record: `lost` none here).
    pub fn fault_reports(&self) -> Vec<crate::report::FaultReport> {
        (self.injector.faults.iter())
            .map(|f| f.report(None, false))
            .collect()
    }

    /// The summary's table of the faults this host fired, times after the run's `Start`.
    pub fn faults_table(&self) -> String {
        if self.injector.faults.is_empty() {
            return String::new();
        }
        let s = |t: Option<f64>| t.map_or("—".to_string(), |t| format!("{t:.3}"));
        let mut t = "\nFaults fired on this host (seconds after the run's start; what they \
                     lost is counted end to end in the orchestrator's report):\n\n\
                     | fault | injected | detected (by) | recovered | restarts |\n\
                     |---|---|---|---|---|\n"
            .to_string();
        for f in &self.injector.faults {
            let by = f.detected_by.map_or(String::new(), |b| format!(" ({b})"));
            t += &format!(
                "| {} | {} | {}{by} | {} | {} |\n",
                f.label(),
                s(f.injected_s),
                s(f.detected_s),
                match (f.recovered_s, &f.not_reached) {
                    (Some(r), _) => format!("{r:.3}"),
                    (None, Some(why)) => why.clone(),
                    (None, None) => "no".to_string(),
                },
                f.restarts
            );
        }
        t
    }
}
