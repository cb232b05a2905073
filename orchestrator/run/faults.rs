//! Fault injection: the scenario's `[[fault]]` entries fired at their trigger, and what the
//! orchestrator saw of each: when it was injected, when supervision noticed it (the child's
//! exit, or a missed heartbeat deadline), when the service was heard from again. A polled
//! state machine per fault, driven by the run loop; it decides, the loop signals.

use rustix::process::Signal;
use shared_types::scenario::{FaultKind, FaultSpec};
use shared_types::{deployment, InBandFault, Scenario, ServiceId, TopicId};

/// Where a fault is in its life.
#[derive(Debug, Clone, Copy, PartialEq)]
enum State {
    Armed,
    /// SIGSTOPped, or delayed; it ends (SIGCONT for a stop) at this time [s since start].
    Stopped {
        until_s: f64,
    },
    /// Injected (and, for a stop, continued): waiting to hear from the service again.
    Injected,
    Done,
}

/// One fault and its timeline [s since the services were started].
#[derive(Debug, Clone)]
pub struct Fault {
    pub spec: FaultSpec,
    pub service: ServiceId,
    state: State,
    pub injected_s: Option<f64>,
    pub ended_s: Option<f64>,
    pub detected_s: Option<f64>,
    pub detected_by: Option<&'static str>,
    pub recovered_s: Option<f64>,
    /// Restarts of the service after this fault.
    pub restarts: u32,
    /// The topic whose progress fires an `at_seq` fault (the table's main input of the
    /// service; a source's main output).
    pub trigger: Option<TopicId>,
    /// The output an in-band drop or corruption hits (the service's main output).
    pub output: Option<TopicId>,
}

/// What the loop sends to a service.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Act {
    /// A signal to its process group.
    Signal(Signal),
    /// An in-band fault command.
    Order(InBandFault),
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Action {
    pub service: ServiceId,
    pub act: Act,
}

pub struct Injector {
    pub faults: Vec<Fault>,
}

impl Injector {
    /// The scenario's faults (already validated).
    pub fn new(scenario: &Scenario) -> Self {
        let faults = scenario
            .fault
            .iter()
            .filter_map(|spec| {
                let service = spec.service_id()?;
                Some(Fault {
                    trigger: deployment::trigger_topic(scenario, service),
                    output: deployment::fault_output(scenario, service),
                    service,
                    spec: spec.clone(),
                    state: State::Armed,
                    injected_s: None,
                    ended_s: None,
                    detected_s: None,
                    detected_by: None,
                    recovered_s: None,
                    restarts: 0,
                })
            })
            .collect();
        Injector { faults }
    }

    /// The signals due at `now_s`; `carried(topic)` is how many messages of a fault's
    /// trigger topic have been seen.
    pub fn step(&mut self, now_s: f64, carried: impl Fn(TopicId) -> u64) -> Vec<Action> {
        let mut actions = vec![];
        for f in &mut self.faults {
            match f.state {
                State::Armed => {
                    let due = match (f.spec.at_seq, f.spec.at_s) {
                        (Some(seq), _) => f.trigger.is_some_and(|t| carried(t) > seq),
                        (None, Some(at)) => now_s >= at,
                        (None, None) => false,
                    };
                    if !due {
                        continue;
                    }
                    f.injected_s = Some(now_s);
                    let until_s = now_s + f.spec.duration_s.unwrap_or(0.0);
                    let (act, next) = match f.spec.kind {
                        FaultKind::Kill => (Act::Signal(Signal::KILL), State::Injected),
                        FaultKind::Stop => (Act::Signal(Signal::STOP), State::Stopped { until_s }),
                        FaultKind::Delay => (
                            Act::Order(InBandFault::of(&f.spec)),
                            State::Stopped { until_s },
                        ),
                        _ => (Act::Order(InBandFault::of(&f.spec)), State::Injected),
                    };
                    if !matches!(next, State::Stopped { .. }) {
                        f.ended_s = Some(now_s);
                    }
                    f.state = next;
                    actions.push(Action {
                        service: f.service,
                        act,
                    });
                }
                State::Stopped { until_s } if now_s >= until_s => {
                    f.state = State::Injected;
                    f.ended_s = Some(now_s);
                    if f.spec.kind == FaultKind::Stop {
                        actions.push(Action {
                            service: f.service,
                            act: Act::Signal(Signal::CONT),
                        });
                    }
                }
                _ => {}
            }
        }
        actions
    }

    /// Supervision noticed `service` (`how`: "exit", "heartbeat deadline") at `now_s`.
    pub fn detected(&mut self, service: ServiceId, how: &'static str, now_s: f64) {
        for f in self.faults.iter_mut().filter(|f| f.service == service) {
            if f.injected_s.is_some() && f.detected_s.is_none() && f.state != State::Done {
                f.detected_s = Some(now_s);
                f.detected_by = Some(how);
            }
        }
    }

    /// `service` was last heard from (a heartbeat arrived) at `heard_s`: a stop is recovered
    /// once the service is heard from after its SIGCONT.
    pub fn heard_from(&mut self, service: ServiceId, heard_s: f64) {
        for f in self.faults.iter_mut().filter(|f| f.service == service) {
            let continued = f.ended_s.is_some_and(|e| heard_s >= e);
            let timed = matches!(f.spec.kind, FaultKind::Stop | FaultKind::Delay);
            if f.state == State::Injected && timed && continued {
                f.recovered_s = Some(heard_s);
                f.state = State::Done;
            }
        }
    }

    /// Supervision restarted `service`, and its new incarnation was resumed at `now_s`: the
    /// faults it had been injected with are recovered from (a stop that supervision ended by
    /// killing the process ends when it was detected).
    pub fn restarted(&mut self, service: ServiceId, now_s: f64) {
        for f in self.faults.iter_mut().filter(|f| f.service == service) {
            // Supervision acted on it: noticed, or not yet over.
            let acted_on = f.state != State::Done || (f.detected_s.is_some() && f.restarts == 0);
            if f.injected_s.is_none() || !acted_on {
                continue;
            }
            f.restarts += 1;
            f.recovered_s = Some(now_s);
            if f.ended_s.is_none() {
                f.ended_s = f.detected_s.or(Some(now_s));
            }
            f.state = State::Done;
        }
    }

    /// The drop and corrupt faults injected and not yet seen counted: (index, the output
    /// they hit, kind).
    pub fn awaiting_count(&self) -> Vec<(usize, Option<TopicId>, FaultKind)> {
        self.faults
            .iter()
            .enumerate()
            .filter(|(_, f)| {
                matches!(f.spec.kind, FaultKind::Drop | FaultKind::Corrupt)
                    && f.state == State::Injected
            })
            .map(|(i, f)| (i, f.output, f.spec.kind))
            .collect()
    }

    /// Fault `i`'s drops or corruptions were all counted by the consumers at `now_s`: noticed,
    /// and (the chain having gone on) recovered from.
    pub fn counted(&mut self, i: usize, now_s: f64) {
        if let Some(f) = self.faults.get_mut(i) {
            f.detected_s = Some(now_s);
            f.detected_by = Some(match f.spec.kind {
                FaultKind::Drop => "sequence gap",
                _ => "validation",
            });
            f.recovered_s = Some(now_s);
            f.state = State::Done;
        }
    }

    /// The faults injected into `service` so far, as the user wrote them (for messages).
    pub fn injected_into(&self, service: ServiceId) -> Vec<String> {
        self.faults
            .iter()
            .filter(|f| f.service == service && f.injected_s.is_some())
            .map(|f| f.label())
            .collect()
    }

    /// A fault still stopped when the run ends: continue it, so the stop ladder can act.
    pub fn release(&mut self, now_s: f64) -> Vec<Action> {
        let mut actions = vec![];
        for f in &mut self.faults {
            if let State::Stopped { .. } = f.state {
                f.state = State::Injected;
                f.ended_s = Some(now_s);
                if f.spec.kind == FaultKind::Stop {
                    actions.push(Action {
                        service: f.service,
                        act: Act::Signal(Signal::CONT),
                    });
                }
            }
        }
        actions
    }
}

impl Fault {
    /// `service:kind@at[,duration_s=d]`, the `--fault` form.
    pub fn label(&self) -> String {
        let at = match (self.spec.at_seq, self.spec.at_s) {
            (Some(seq), _) => seq.to_string(),
            (_, Some(s)) => format!("{s}s"),
            _ => String::new(),
        };
        let d = self
            .spec
            .duration_s
            .map_or(String::new(), |d| format!(",duration_s={d}"));
        format!("{}:{}@{at}{d}", self.service.name(), self.spec.kind.name())
    }

    /// The report's entry; `lost` is what the service's inputs carried and it never
    /// processed, `invariant_held` the run's accounting.
    pub fn report(&self, lost: Option<u64>, invariant_held: bool) -> crate::report::FaultReport {
        crate::report::FaultReport {
            service: self.service.name().to_string(),
            kind: self.spec.kind.name().to_string(),
            at_seq: self.spec.at_seq,
            at_s: self.spec.at_s,
            duration_s: self.spec.duration_s,
            injected_s: self.injected_s,
            ended_s: self.ended_s,
            detected_s: self.detected_s,
            detected_by: self.detected_by.map(str::to_string),
            recovered_s: self.recovered_s,
            restarts: self.restarts,
            lost,
            invariant_held,
            // Against a fault-free run of the same seed: a campaign's comparison.
            science_equal: None,
            injected: None,
            counted: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn injector(specs: &[&str]) -> Injector {
        let mut sc = Scenario::from_toml_str(
            include_str!("../../scenarios/debris-geo.toml"),
            "debris-geo.toml",
        )
        .unwrap();
        sc.fault = specs.iter().map(|s| FaultSpec::parse(s).unwrap()).collect();
        sc.validate().unwrap();
        Injector::new(&sc)
    }

    #[test]
    fn a_stop_fires_at_its_message_and_continues_after_its_duration() {
        let mut inj = injector(&["detector:stop@5,duration_s=0.5"]);
        assert!(inj.step(1.0, |_| 5).is_empty(), "message 5 not yet carried");
        let a = inj.step(1.1, |_| 6);
        assert_eq!(
            a,
            [Action {
                service: ServiceId::Detector,
                act: Act::Signal(Signal::STOP)
            }]
        );
        assert!(inj.step(1.5, |_| 6).is_empty());
        let a = inj.step(1.6, |_| 6);
        assert_eq!(
            a,
            [Action {
                service: ServiceId::Detector,
                act: Act::Signal(Signal::CONT)
            }]
        );
        inj.heard_from(ServiceId::Detector, 1.55);
        assert_eq!(
            inj.faults[0].recovered_s, None,
            "a heartbeat from before SIGCONT"
        );
        inj.heard_from(ServiceId::Tracker, 1.7);
        assert_eq!(inj.faults[0].recovered_s, None, "another service");
        inj.heard_from(ServiceId::Detector, 1.7);
        let f = &inj.faults[0];
        assert_eq!(
            (f.injected_s, f.ended_s, f.recovered_s),
            (Some(1.1), Some(1.6), Some(1.7))
        );
        assert!(inj.step(9.0, |_| 50).is_empty(), "fired once");
    }

    #[test]
    fn a_kill_at_a_time_is_detected_once() {
        let mut inj = injector(&["tracker:kill@0.25s"]);
        assert!(inj.step(0.2, |_| 100).is_empty());
        assert_eq!(inj.step(0.25, |_| 0)[0].act, Act::Signal(Signal::KILL));
        inj.detected(ServiceId::Tracker, "exit", 0.27);
        inj.detected(ServiceId::Tracker, "heartbeat deadline", 5.0);
        let f = &inj.faults[0];
        assert_eq!((f.detected_s, f.detected_by), (Some(0.27), Some("exit")));
    }
}
