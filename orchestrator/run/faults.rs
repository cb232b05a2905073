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
    /// A delay ordered (the service's `order`-th in-band order since it started): waiting for
    /// a heartbeat that says the service obeyed it and is no longer slowed.
    Delaying {
        order: u32,
    },
    /// A delay over: waiting for the service to have taken every input that had arrived by
    /// then (`to`, the orchestrator's count of its trigger topic).
    CatchingUp {
        to: u64,
    },
    /// Injected (and, for a stop, continued): waiting to hear from the service again.
    Injected,
    Done,
}

/// What the orchestrator knows of a service when it hears from it.
#[derive(Debug, Clone, Copy)]
pub struct Heard {
    /// When its latest heartbeat arrived [s since start].
    pub at_s: f64,
    /// In-band orders it obeyed, and whether a delay slows it (that heartbeat's).
    pub faults_obeyed: u32,
    pub delaying: bool,
    /// Its progress on its fault's trigger topic (inputs taken; a source: messages published).
    pub progress: u64,
    /// Messages of the trigger topic the orchestrator has seen so far.
    pub carried: u64,
    /// How far the service has got as the orchestrator sees it (its outputs, one per input;
    /// a source's messages), over all its incarnations: sharper than a heartbeat for where a
    /// fault found it.
    pub done: u64,
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
    /// From the fault's end (a restart: the new incarnation resumed) to recovered: the
    /// backlog worked off, or the inputs replayed.
    pub catch_up_s: Option<f64>,
    catch_up_from_s: Option<f64>,
    /// Inputs the restarted service was fed again (from its checkpoint to where the fault
    /// found it).
    pub replayed: Option<u64>,
    /// Why the run ended before the fault's verdict could be reached (`None`: reached).
    pub not_reached: Option<String>,
    /// Restarts of the service after this fault.
    pub restarts: u32,
    /// The topic whose progress fires an `at_seq` fault (the table's main input of the
    /// service; a source's main output).
    pub trigger: Option<TopicId>,
    /// The output an in-band drop or corruption hits (the service's main output).
    pub output: Option<TopicId>,
    /// A drop or corruption: the output's (made, counted) tampered messages when it was
    /// injected; what it made and its consumers counted is what came after.
    pub tamper_base: Option<(u64, u64)>,
}

/// A drop or corrupt fault injected and not yet seen counted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Awaiting {
    /// Its index in [`Injector::faults`].
    pub index: usize,
    /// The output it hits.
    pub output: Option<TopicId>,
    pub kind: FaultKind,
    /// The output's (made, counted) tampered messages when it was injected.
    pub base: (u64, u64),
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
    /// In-band orders sent to each service's current incarnation.
    orders: Vec<(ServiceId, u32)>,
    /// The furthest each service has been heard to get on its trigger topic, over all its
    /// incarnations: where a fault that ended one found it.
    furthest: Vec<(ServiceId, u64)>,
}

impl Injector {
    /// The scenario's faults (already validated) that `host`'s part fires (every fault when
    /// the deployment is not split).
    pub fn new(scenario: &Scenario, host: Option<&str>) -> Self {
        let faults = scenario
            .fault
            .iter()
            .filter(|spec| host.is_none() || spec.on_host(scenario) == host)
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
                    catch_up_s: None,
                    catch_up_from_s: None,
                    replayed: None,
                    not_reached: None,
                    restarts: 0,
                    tamper_base: None,
                })
            })
            .collect();
        Injector {
            faults,
            orders: vec![],
            furthest: vec![],
        }
    }

    /// Counts an in-band order to `service`; its number since the service (re)started.
    fn ordered(&mut self, service: ServiceId) -> u32 {
        match self.orders.iter_mut().find(|(s, _)| *s == service) {
            Some((_, n)) => {
                *n += 1;
                *n
            }
            None => {
                self.orders.push((service, 1));
                1
            }
        }
    }

    /// The signals and orders due at `now_s`; `carried(topic)` is how many messages of a
    /// fault's trigger topic have been seen, `tampered(output, kind)` how many drops or
    /// corruptions an output's producer has made and its consumers counted so far.
    pub fn step(
        &mut self,
        now_s: f64,
        carried: impl Fn(TopicId) -> u64,
        tampered: impl Fn(TopicId, FaultKind) -> (u64, u64),
    ) -> Vec<Action> {
        let mut actions = vec![];
        for i in 0..self.faults.len() {
            let f = &self.faults[i];
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
                    let (kind, service) = (f.spec.kind, f.service);
                    let order = kind.in_band().then(|| self.ordered(service));
                    let f = &mut self.faults[i];
                    f.injected_s = Some(now_s);
                    if matches!(kind, FaultKind::Drop | FaultKind::Corrupt) {
                        f.tamper_base = f.output.map(|o| tampered(o, kind));
                    }
                    let until_s = now_s + f.spec.duration_s.unwrap_or(0.0);
                    let (act, next) = match kind {
                        FaultKind::Kill => (Act::Signal(Signal::KILL), State::Injected),
                        FaultKind::Stop => (Act::Signal(Signal::STOP), State::Stopped { until_s }),
                        // The service says when its delay is over (a time, or a count of inputs).
                        FaultKind::Delay => (
                            Act::Order(InBandFault::of(&f.spec)),
                            State::Delaying {
                                order: order.unwrap_or(1),
                            },
                        ),
                        FaultKind::Panic | FaultKind::Drop | FaultKind::Corrupt => {
                            (Act::Order(InBandFault::of(&f.spec)), State::Injected)
                        }
                    };
                    if matches!(next, State::Injected) {
                        f.ended_s = Some(now_s);
                    }
                    f.state = next;
                    actions.push(Action { service, act });
                }
                State::Stopped { until_s } if now_s >= until_s => {
                    let f = &mut self.faults[i];
                    f.state = State::Injected;
                    f.ended_s = Some(now_s);
                    actions.push(Action {
                        service: f.service,
                        act: Act::Signal(Signal::CONT),
                    });
                }
                _ => {}
            }
        }
        actions
    }

    /// Supervision noticed `service` (`how`: "exit", "heartbeat deadline") at `now_s`.
    pub fn detected(&mut self, service: ServiceId, how: &'static str, now_s: f64) {
        // Supervision notices what ends or hangs a process; a drop or a corruption injected
        // into the same service is counted, not noticed.
        let noticed = |f: &&mut Fault| f.service == service && supervised(f.spec.kind);
        for f in self.faults.iter_mut().filter(noticed) {
            if f.injected_s.is_some() && f.detected_s.is_none() && f.state != State::Done {
                f.detected_s = Some(now_s);
                f.detected_by = Some(how);
            }
        }
    }

    /// What `service`'s latest heartbeat says: a stop is recovered once the service is heard
    /// from after its SIGCONT; a delay is over once the service says so, and recovered once
    /// it has taken every input that had arrived by then.
    pub fn heard_from(&mut self, service: ServiceId, heard: Heard) {
        match self.furthest.iter_mut().find(|(s, _)| *s == service) {
            Some((_, p)) => *p = (*p).max(heard.progress).max(heard.done),
            None => self
                .furthest
                .push((service, heard.progress.max(heard.done))),
        }
        for f in self.faults.iter_mut().filter(|f| f.service == service) {
            match f.state {
                State::Injected
                    if f.spec.kind == FaultKind::Stop
                        && f.ended_s.is_some_and(|e| heard.at_s >= e) =>
                {
                    f.recovered_s = Some(heard.at_s);
                    f.state = State::Done;
                }
                State::Delaying { order } if heard.faults_obeyed >= order && !heard.delaying => {
                    f.ended_s = Some(heard.at_s);
                    f.catch_up_from_s = Some(heard.at_s);
                    f.state = State::CatchingUp { to: heard.carried };
                }
                _ => {}
            }
            if let State::CatchingUp { to } = f.state {
                let since = f.catch_up_from_s.is_none_or(|t| heard.at_s >= t);
                if since && heard.progress >= to {
                    f.recovered_s = Some(heard.at_s);
                    f.catch_up_s = f.catch_up_from_s.map(|e| heard.at_s - e);
                    f.state = State::Done;
                }
            }
        }
    }

    /// The run ended at `now_s`: each fault whose verdict was not reached says why, and the
    /// faults that never fired are returned (a run that did not test what it was asked to
    /// fails).
    pub fn finish(&mut self) -> Vec<String> {
        let mut never = vec![];
        for f in &mut self.faults {
            let why = match f.state {
                State::Armed => {
                    never.push(format!(
                        "fault {} never fired: the run ended first",
                        f.label()
                    ));
                    Some("never fired: the run ended first")
                }
                State::Delaying { .. } => {
                    Some("the run ended while the delay still slowed the service")
                }
                State::CatchingUp { .. } => Some("the run ended before the service had caught up"),
                State::Stopped { .. } => Some("the run ended while the service was stopped"),
                State::Injected | State::Done => None,
            };
            f.not_reached = why.map(str::to_string);
        }
        never
    }

    /// Supervision restarted `service`, and its new incarnation was resumed at `now_s`: the
    /// faults it had been injected with are recovered from (a stop that supervision ended by
    /// killing the process ends when it was detected).
    /// Recovered once the new incarnation has taken the input the fault found the service at;
    /// it resumed at `resumed_at` (its restored checkpoint's, or 0), so it is replayed the
    /// inputs between.
    pub fn restarted(&mut self, service: ServiceId, now_s: f64, resumed_at: u64) {
        self.orders.retain(|(s, _)| *s != service);
        let found_at = (self.furthest.iter())
            .find(|(s, _)| *s == service)
            .map_or(0, |(_, p)| *p);
        // The restart is the latest fault's that supervision acts on (noticed, or not yet
        // over): on a long run, the earlier faults into the service are over.
        let latest = (self.faults.iter().enumerate())
            .filter(|(_, f)| f.service == service && supervised(f.spec.kind))
            .filter(|(_, f)| {
                f.injected_s.is_some()
                    && (f.state != State::Done || (f.detected_s.is_some() && f.restarts == 0))
            })
            .max_by(|a, b| {
                let at = |f: &Fault| f.injected_s.unwrap_or(0.0);
                at(a.1).total_cmp(&at(b.1))
            })
            .map(|(i, _)| i);
        if let Some(f) = latest.and_then(|i| self.faults.get_mut(i)) {
            f.restarts += 1;
            f.replayed = Some(found_at.saturating_sub(resumed_at));
            f.recovered_s = None;
            f.catch_up_from_s = Some(now_s);
            if f.ended_s.is_none() {
                f.ended_s = f.detected_s.or(Some(now_s));
            }
            f.state = State::CatchingUp { to: found_at };
        }
    }

    /// The drop and corrupt faults injected and not yet seen counted.
    pub fn awaiting_count(&self) -> Vec<Awaiting> {
        self.faults
            .iter()
            .enumerate()
            .filter(|(_, f)| {
                matches!(f.spec.kind, FaultKind::Drop | FaultKind::Corrupt)
                    && f.state == State::Injected
            })
            .map(|(i, f)| Awaiting {
                index: i,
                output: f.output,
                kind: f.spec.kind,
                base: f.tamper_base.unwrap_or((0, 0)),
            })
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
                actions.push(Action {
                    service: f.service,
                    act: Act::Signal(Signal::CONT),
                });
            }
        }
        actions
    }
}

/// Faults supervision may notice and restart the service for: those that end or hang its
/// process, and a delay (long enough, it misses the heartbeat deadline).
fn supervised(kind: FaultKind) -> bool {
    kind.ends_a_process() || kind == FaultKind::Delay
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
        let host = (self.spec.host.as_ref()).map_or(String::new(), |h| format!(",host={h}"));
        let bandwidth = (self.spec.bandwidth_mbit_s)
            .map_or(String::new(), |r| format!(",bandwidth_mbit_s={r}"));
        format!(
            "{}:{}@{at}{d}{bandwidth}{host}",
            self.service.name(),
            self.spec.kind.name()
        )
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
            count: self.spec.count,
            delay_ms: self.spec.delay_ms,
            bandwidth_mbit_s: self.spec.bandwidth_mbit_s,
            injected_s: self.injected_s,
            ended_s: self.ended_s,
            detected_s: self.detected_s,
            detected_by: self.detected_by.map(str::to_string),
            recovered_s: self.recovered_s,
            catch_up_s: self.catch_up_s,
            replayed: self.replayed,
            not_reached: self.not_reached.clone(),
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
#[path = "faults_tests.rs"]
mod tests;
