//! Supervision: a polled state machine per service. Liveness comes from the process's exit
//! (waitpid) and from its heartbeats (a SIGSTOPped or hung process still exists; only the
//! heartbeat deadline catches it). A failed service is restarted as `[supervision]` says —
//! killed first if it is hung, restarted after a backoff, resumed once its new incarnation is
//! ready — or the run fails. The state machine decides; the run loop signals, spawns and
//! sends the replay orders.

use std::time::{Duration, Instant};

use shared_types::scenario::{Restart, Supervision};
use shared_types::{Heartbeat, ServiceId};

/// What the run loop sees of one service on a tick.
#[derive(Debug, Clone, Copy)]
pub struct Observation {
    pub id: ServiceId,
    /// The process has exited: `Some(true)` with status 0.
    pub exited: Option<bool>,
    /// The last heartbeat of the current process (its pid): when, and its state.
    pub heartbeat: Option<(Instant, u32)>,
}

/// How supervision noticed a failure.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Noticed {
    /// The process exited.
    Exit,
    /// No heartbeat within `run.heartbeat_deadline_ms`.
    HeartbeatDeadline,
    /// A restarted incarnation was not ready within `run.startup_timeout_ms`.
    RestartTimeout,
}

impl Noticed {
    /// As the report names it (`faults[].detected_by`).
    pub fn label(self) -> &'static str {
        match self {
            Noticed::Exit => "exit",
            Noticed::HeartbeatDeadline => "heartbeat deadline",
            Noticed::RestartTimeout => "restart timeout",
        }
    }
}

/// What the run loop must do.
#[derive(Debug, Clone, PartialEq)]
pub enum Action {
    /// Supervision noticed a failure of `id`.
    Noticed { id: ServiceId, how: Noticed },
    /// SIGKILL the process group of `id` (hung: it is restarted once it has exited).
    Kill(ServiceId),
    /// Spawn a new incarnation of `id`.
    Respawn(ServiceId),
    /// The new incarnation of `id` is ready: order its producers' replays, then `Start` it.
    Resume(ServiceId),
    /// The run fails: `id` failed and may not be restarted (`why` says which rule).
    GiveUp {
        id: ServiceId,
        how: Noticed,
        why: String,
    },
}

impl Action {
    /// The service the action concerns.
    pub fn service(&self) -> ServiceId {
        match self {
            Action::Noticed { id, .. } | Action::GiveUp { id, .. } => *id,
            Action::Kill(id) | Action::Respawn(id) | Action::Resume(id) => *id,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Life {
    /// Running since this instant (the current incarnation was started or resumed).
    Up(Instant),
    /// SIGKILLed for a missed deadline; restarted once it has exited.
    Killing,
    /// Down; respawned at this instant.
    Down(Instant),
    /// Respawned at this instant; waiting for its ready heartbeat.
    Starting(Instant),
    Failed,
}

struct Supervised {
    id: ServiceId,
    life: Life,
    /// When each restart happened (the budget counts those within the window).
    restarts_at: Vec<Instant>,
}

pub struct Supervisor {
    spec: Supervision,
    services: Vec<Supervised>,
    deadline: Duration,
    startup: Duration,
}

impl Supervisor {
    pub fn new(
        spec: &Supervision,
        ids: &[ServiceId],
        deadline: Duration,
        startup: Duration,
    ) -> Self {
        Supervisor {
            spec: spec.clone(),
            services: ids
                .iter()
                .map(|&id| Supervised {
                    id,
                    life: Life::Starting(Instant::now()),
                    restarts_at: vec![],
                })
                .collect(),
            deadline,
            startup,
        }
    }

    /// Every service is up (the run was started at `now`).
    pub fn started(&mut self, now: Instant) {
        for s in &mut self.services {
            s.life = Life::Up(now);
        }
    }

    /// Whether `id` is up (its current incarnation running and resumed).
    pub fn is_up(&self, id: ServiceId) -> bool {
        self.services
            .iter()
            .any(|s| s.id == id && matches!(s.life, Life::Up(_)))
    }

    /// Since when `id`'s current incarnation has been up (`None`: it is down or restarting).
    pub fn up_since(&self, id: ServiceId) -> Option<Instant> {
        (self.services.iter().find(|s| s.id == id)).and_then(|s| match s.life {
            Life::Up(since) => Some(since),
            Life::Killing | Life::Down(_) | Life::Starting(_) | Life::Failed => None,
        })
    }

    /// Whether every service is up (none failed, down or restarting).
    pub fn all_up(&self) -> bool {
        self.services.iter().all(|s| matches!(s.life, Life::Up(_)))
    }

    /// Restarts of `id` so far.
    pub fn restarts(&self, id: ServiceId) -> u32 {
        self.services
            .iter()
            .find(|s| s.id == id)
            .map_or(0, |s| s.restarts_at.len() as u32)
    }

    /// One tick of every service's state machine, after the initial startup.
    pub fn step(&mut self, now: Instant, seen: &[Observation]) -> Vec<Action> {
        let mut actions = vec![];
        for o in seen {
            let Some(i) = self.services.iter().position(|s| s.id == o.id) else {
                continue;
            };
            let life = self.services[i].life;
            let next = match life {
                Life::Up(since) => match o.exited {
                    Some(clean) => self.failed(i, now, Noticed::Exit, clean, &mut actions),
                    None => {
                        let last = o.heartbeat.map_or(since, |(at, _)| at.max(since));
                        if now.saturating_duration_since(last) > self.deadline {
                            self.hung(i, now, Noticed::HeartbeatDeadline, &mut actions)
                        } else {
                            life
                        }
                    }
                },
                Life::Killing => match o.exited {
                    Some(_) => self.down(i, now),
                    None => life,
                },
                Life::Down(at) if now >= at => {
                    self.services[i].restarts_at.push(now);
                    actions.push(Action::Respawn(o.id));
                    Life::Starting(now)
                }
                Life::Down(_) => life,
                Life::Starting(since) => match (o.exited, o.heartbeat) {
                    (Some(clean), _) => self.failed(i, now, Noticed::Exit, clean, &mut actions),
                    (None, Some((_, state))) if state >= Heartbeat::READY => {
                        actions.push(Action::Resume(o.id));
                        Life::Up(now)
                    }
                    _ if now.saturating_duration_since(since) > self.startup => {
                        self.hung(i, now, Noticed::RestartTimeout, &mut actions)
                    }
                    _ => life,
                },
                Life::Failed => life,
            };
            self.services[i].life = next;
        }
        actions
    }

    /// `why` not `None`: the rule that forbids another restart of service `i`.
    fn refusal(&self, i: usize, now: Instant, clean_exit: bool) -> Option<String> {
        let s = &self.services[i];
        let policy = self.spec.restart_of(s.id);
        match policy {
            Restart::Never => return Some("supervision.restart = \"never\"".into()),
            Restart::OnFailure if clean_exit => {
                return Some(
                    "it exited with status 0 before Shutdown, and supervision.restart = \
                     \"on-failure\" restarts only failures"
                        .into(),
                )
            }
            _ => {}
        }
        let window = Duration::from_secs_f64(self.spec.restart_window_s);
        let recent = s
            .restarts_at
            .iter()
            .filter(|t| now.saturating_duration_since(**t) <= window)
            .count() as u32;
        let max = self.spec.max_restarts_of(s.id);
        (recent >= max).then(|| {
            format!(
                "{recent} restart(s) within supervision.restart_window_s = {} s already \
                 (supervision.max_restarts = {max})",
                self.spec.restart_window_s
            )
        })
    }

    /// Service `i` failed (`how`): given up on, or — `hung`: killed first — restarted.
    fn failed(
        &mut self,
        i: usize,
        now: Instant,
        how: Noticed,
        clean_exit: bool,
        actions: &mut Vec<Action>,
    ) -> Life {
        let id = self.services[i].id;
        actions.push(Action::Noticed { id, how });
        match self.refusal(i, now, clean_exit) {
            Some(why) => {
                actions.push(Action::GiveUp { id, how, why });
                Life::Failed
            }
            None => self.down(i, now),
        }
    }

    /// Service `i` is alive but silent (`how`): killed, then restarted once it has exited.
    fn hung(&mut self, i: usize, now: Instant, how: Noticed, actions: &mut Vec<Action>) -> Life {
        match self.failed(i, now, how, false, actions) {
            Life::Failed => Life::Failed,
            _ => {
                actions.push(Action::Kill(self.services[i].id));
                Life::Killing
            }
        }
    }

    /// Down: respawned after the backoff of this restart.
    fn down(&self, i: usize, now: Instant) -> Life {
        let window = Duration::from_secs_f64(self.spec.restart_window_s);
        let recent = self.services[i]
            .restarts_at
            .iter()
            .filter(|t| now.saturating_duration_since(**t) <= window)
            .count() as u32;
        Life::Down(now + Duration::from_millis(self.spec.backoff_ms_of(recent)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const D: ServiceId = ServiceId::Detector;

    fn obs(exited: Option<bool>, heartbeat: Option<(Instant, u32)>) -> Observation {
        Observation {
            id: D,
            exited,
            heartbeat,
        }
    }

    fn supervisor(spec: Supervision) -> (Supervisor, Instant) {
        let mut s = Supervisor::new(
            &spec,
            &[D],
            Duration::from_millis(300),
            Duration::from_secs(5),
        );
        let t0 = Instant::now();
        s.started(t0);
        (s, t0)
    }

    #[test]
    fn a_crash_is_restarted_after_the_backoff_and_resumed_once_ready() {
        let (mut s, t0) = supervisor(Supervision::default());
        let ms = |n| t0 + Duration::from_millis(n);
        assert!(s.step(ms(10), &[obs(None, Some((ms(5), 2)))]).is_empty());
        let a = s.step(ms(20), &[obs(Some(false), None)]);
        assert_eq!(
            a,
            [Action::Noticed {
                id: D,
                how: Noticed::Exit
            }]
        );
        assert!(!s.is_up(D));
        assert!(
            s.step(ms(119), &[obs(Some(false), None)]).is_empty(),
            "backoff 100 ms"
        );
        assert_eq!(
            s.step(ms(121), &[obs(Some(false), None)]),
            [Action::Respawn(D)]
        );
        // The new process: starting, then ready.
        assert!(s.step(ms(150), &[obs(None, Some((ms(140), 0)))]).is_empty());
        assert_eq!(
            s.step(ms(200), &[obs(None, Some((ms(190), 1)))]),
            [Action::Resume(D)]
        );
        assert!(s.is_up(D));
        assert_eq!(s.restarts(D), 1);
        // A second crash waits twice as long.
        s.step(ms(300), &[obs(Some(false), None)]);
        assert!(s.step(ms(499), &[obs(Some(false), None)]).is_empty());
        assert_eq!(
            s.step(ms(501), &[obs(Some(false), None)]),
            [Action::Respawn(D)]
        );
    }

    #[test]
    fn a_hung_service_is_killed_then_restarted() {
        let (mut s, t0) = supervisor(Supervision::default());
        let ms = |n| t0 + Duration::from_millis(n);
        assert!(s.step(ms(350), &[obs(None, Some((ms(100), 2)))]).is_empty());
        let a = s.step(ms(401), &[obs(None, Some((ms(100), 2)))]);
        assert_eq!(
            a,
            [
                Action::Noticed {
                    id: D,
                    how: Noticed::HeartbeatDeadline
                },
                Action::Kill(D)
            ]
        );
        assert!(
            s.step(ms(420), &[obs(None, None)]).is_empty(),
            "not yet exited"
        );
        assert!(
            s.step(ms(430), &[obs(Some(false), None)]).is_empty(),
            "noticed once"
        );
        assert_eq!(
            s.step(ms(531), &[obs(Some(false), None)]),
            [Action::Respawn(D)]
        );
    }

    #[test]
    fn never_and_an_exhausted_budget_give_up() {
        let spec = Supervision {
            restart: Restart::Never,
            ..Default::default()
        };
        let (mut s, t0) = supervisor(spec);
        let a = s.step(t0, &[obs(Some(false), None)]);
        assert!(
            matches!(&a[1], Action::GiveUp { why, .. } if why.contains("never")),
            "{a:?}"
        );
        let spec = Supervision {
            max_restarts: 1,
            ..Default::default()
        };
        let (mut s, t0) = supervisor(spec);
        let ms = |n| t0 + Duration::from_millis(n);
        s.step(ms(0), &[obs(Some(false), None)]);
        assert_eq!(
            s.step(ms(100), &[obs(Some(false), None)]),
            [Action::Respawn(D)]
        );
        s.step(ms(110), &[obs(None, Some((ms(105), 1)))]);
        let a = s.step(ms(200), &[obs(Some(false), None)]);
        assert!(
            matches!(&a[1], Action::GiveUp { why, .. } if why.contains("max_restarts = 1")),
            "{a:?}"
        );
        // A clean exit is not a failure to restart under on-failure.
        let (mut s, t0) = supervisor(Supervision::default());
        let a = s.step(t0, &[obs(Some(true), None)]);
        assert!(matches!(&a[1], Action::GiveUp { .. }), "{a:?}");
    }

    #[test]
    fn always_restarts_a_clean_exit_that_on_failure_gives_up_on() {
        let always = Supervision {
            restart: Restart::Always,
            ..Default::default()
        };
        let (mut s, t0) = supervisor(always);
        let ms = |n| t0 + Duration::from_millis(n);
        let a = s.step(ms(0), &[obs(Some(true), None)]);
        assert_eq!(
            a,
            [Action::Noticed {
                id: D,
                how: Noticed::Exit
            }]
        );
        assert_eq!(
            s.step(ms(101), &[obs(Some(true), None)]),
            [Action::Respawn(D)]
        );
        // The negative control: the same clean exit under on-failure is not restarted.
        let (mut s, t0) = supervisor(Supervision::default());
        let a = s.step(t0, &[obs(Some(true), None)]);
        assert!(
            matches!(&a[1], Action::GiveUp { why, .. } if why.contains("on-failure")),
            "{a:?}"
        );
    }

    #[test]
    fn restarts_older_than_the_window_no_longer_count_against_the_budget() {
        let spec = Supervision {
            max_restarts: 1,
            restart_window_s: 1.0,
            ..Default::default()
        };
        let (mut s, t0) = supervisor(spec);
        let ms = |n| t0 + Duration::from_millis(n);
        s.step(ms(0), &[obs(Some(false), None)]);
        assert_eq!(
            s.step(ms(100), &[obs(Some(false), None)]),
            [Action::Respawn(D)]
        );
        s.step(ms(110), &[obs(None, Some((ms(105), 1)))]);
        // 1.5 s after that restart it is out of the 1 s window: one more is allowed.
        s.step(ms(1600), &[obs(Some(false), None)]);
        assert_eq!(
            s.step(ms(1700), &[obs(Some(false), None)]),
            [Action::Respawn(D)]
        );
        s.step(ms(1710), &[obs(None, Some((ms(1705), 1)))]);
        // Within the window of the second restart: the budget of one is spent.
        let a = s.step(ms(1800), &[obs(Some(false), None)]);
        assert!(
            matches!(&a[1], Action::GiveUp { why, .. } if why.contains("restart_window_s = 1")),
            "{a:?}"
        );
    }

    #[test]
    fn a_restart_not_ready_within_the_startup_timeout_is_killed_and_restarted() {
        let (mut s, t0) = supervisor(Supervision::default());
        let ms = |n| t0 + Duration::from_millis(n);
        s.step(ms(0), &[obs(Some(false), None)]);
        assert_eq!(
            s.step(ms(100), &[obs(Some(false), None)]),
            [Action::Respawn(D)]
        );
        // Starting heartbeats but never ready: within the 5 s startup timeout, nothing.
        let starting = obs(None, Some((ms(4000), 0)));
        assert!(s.step(ms(5100), &[starting]).is_empty());
        let a = s.step(ms(5101), &[starting]);
        assert_eq!(
            a,
            [
                Action::Noticed {
                    id: D,
                    how: Noticed::RestartTimeout
                },
                Action::Kill(D)
            ]
        );
        // Once it has exited it is restarted (the second restart waits twice the backoff).
        assert!(s.step(ms(5110), &[obs(Some(false), None)]).is_empty());
        assert_eq!(
            s.step(ms(5311), &[obs(Some(false), None)]),
            [Action::Respawn(D)]
        );
    }
}
