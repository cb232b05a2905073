//! Supervision's side of a live deployment: one step of the [`Supervisor`] over the children
//! (their exits, their heartbeats), and what each of its actions asks of the run — signal,
//! respawn, resume (replay orders in sim clock, continue orders in realtime), or give up.

use std::time::Instant;

use anyhow::Result;
use glint_runtime::Step;
use shared_types::scenario::Clock;
use shared_types::table::Count;
use shared_types::{deployment, Command, Replay, ServiceId, TopicId};

use super::Live;
use crate::run::faults::Injector;
use crate::run::supervise::{Action, Noticed, Observation};

impl Live<'_> {
    /// Realtime mode replays nothing to a restarted service: it resumes at the newest input.
    /// Each of its inputs whose output counts one message per input continues its accounting
    /// where the last incarnation left it, as the orchestrator saw it — that output's messages
    /// are the inputs it processed, its last heartbeat's drops the rest — so the gap it
    /// missed while down is counted as dropped, and the output continues at its next seq, so
    /// that no new message takes the seq of one already sent. The main input's seq it resumes
    /// at, if any was continued.
    fn continue_in_realtime(&mut self, id: ServiceId) -> Result<Option<u64>> {
        let mut main = None;
        let outputs = deployment::outputs(self.scenario, id);
        for input in deployment::inputs(self.scenario, id) {
            let per_input =
                |o: &&TopicId| matches!(o.spec().count, Count::PerInput(t) if t == input);
            let Some(output) = outputs.iter().find(per_input).copied() else {
                continue;
            };
            let processed = self.consumer.carried(output);
            let dropped = (self.last_heard.get(&id))
                .and_then(|hb| hb.topics.iter().find(|c| c.topic == input as u32))
                .map_or(0, |c| c.dropped.iter().sum::<u64>());
            let next = processed + dropped;
            self.consumer.continue_at(id, input, next, processed)?;
            self.consumer
                .continue_at(id, output, processed, processed)?;
            main.get_or_insert(next);
        }
        if main.is_none() {
            main = self.continue_streams(id)?;
        }
        Ok(main)
    }

    /// A source restarted in realtime mode continues each stream where the run's clock has
    /// come to: a paced stream at the message due now (those that came due while it was down
    /// were never made: its consumers count the gap, its fault counts them lost), one paced by
    /// its consumers where it stopped; its truth (one per message of every stream) continues
    /// at their sum. The first stream's seq it resumes at, if it has any.
    fn continue_streams(&mut self, id: ServiceId) -> Result<Option<u64>> {
        let elapsed_ns = (self.since_start(Instant::now()) * 1e9) as u64;
        let (mut main, mut made) = (None, 0);
        let outputs = deployment::outputs(self.scenario, id);
        for &topic in &outputs {
            let Count::Stream { .. } = topic.spec().count else {
                continue;
            };
            let sent = self.consumer.carried(topic);
            let end = deployment::expected_messages(self.scenario, topic).max(sent);
            let due = deployment::realtime_period_ns(self.scenario, topic)
                .map_or(sent, |period| elapsed_ns.div_ceil(period).clamp(sent, end));
            made += due;
            self.consumer.continue_at(id, topic, due, sent)?;
            main.get_or_insert(due);
        }
        for &topic in outputs
            .iter()
            .filter(|t| matches!(t.spec().count, Count::Truth))
        {
            let sent = self.consumer.carried(topic);
            self.consumer.continue_at(id, topic, made.max(sent), sent)?;
        }
        Ok(main)
    }

    /// One step of supervision, and what its actions ask of the run.
    pub(super) fn supervise(&mut self, now: Instant, now_s: f64) -> Result<Option<Step>> {
        let seen = &self.consumer.seen;
        let observed: Vec<Observation> = (self.children.iter_mut())
            .map(|c| Observation {
                id: c.id,
                exited: (!c.is_running()).then(|| c.exit_ok.unwrap_or(false)),
                heartbeat: (seen.get(&c.id))
                    .filter(|s| s.heartbeat.pid == c.pid)
                    .map(|s| (s.at, s.heartbeat.state)),
            })
            .collect();
        for action in self.supervisor.step(now, &observed) {
            if let Some(stop) = self.act(action, now_s)? {
                return Ok(Some(stop));
            }
        }
        Ok(None)
    }

    fn act(&mut self, action: Action, now_s: f64) -> Result<Option<Step>> {
        let Some(i) = self.children.iter().position(|c| c.id == action.service()) else {
            return Ok(None);
        };
        match action {
            Action::Noticed { id, how } => {
                tracing::warn!(service = id.name(), how = how.label(), "service failed");
                self.injector.detected(id, how.label(), now_s);
            }
            Action::Kill(_) => self.children[i].signal(rustix::process::Signal::KILL),
            Action::Respawn(id) => {
                // What the dead incarnation last said of itself (a realtime restart continues
                // its accounting).
                if let Some(seen) = self.consumer.seen.get(&id) {
                    self.last_heard.insert(id, seen.heartbeat);
                }
                // The dead process's ports go before the new one opens its own.
                self.node.try_cleanup_dead_nodes();
                let n = self.supervisor.restarts(id);
                tracing::info!(service = id.name(), restart = n, "restarting");
                self.children[i] = self.spawner.spawn(id, n)?;
            }
            Action::Resume(id) => {
                let continued = match self.scenario.clock {
                    Clock::Realtime => self.continue_in_realtime(id)?,
                    Clock::Sim => None,
                };
                if self.scenario.clock == Clock::Sim {
                    for topic in deployment::inputs(self.scenario, id) {
                        // From where its restored checkpoint left it (its ready heartbeat
                        // says), or from the first message without one.
                        let from_seq = self.consumer.reported(id, topic).map_or(0, |c| c.next_seq);
                        let order = Replay {
                            consumer: id,
                            topic,
                            from_seq,
                        };
                        if let Some(producer) = deployment::producer(topic) {
                            self.consumer.replay(producer, order)?;
                        }
                    }
                }
                self.consumer.command(Command::Start, id as u32)?;
                let resumed_at = continued
                    .unwrap_or_else(|| self.progress(id, &self.consumer.seen[&id].heartbeat));
                self.injector.restarted(id, now_s, resumed_at);
                let serves_solve = deployment::producer(TopicId::Solve) == Some(id);
                if let (true, Some(seq)) = (serves_solve, self.sequencer.as_mut()) {
                    seq.server_restarted();
                }
                tracing::info!(service = id.name(), "restarted service resumed");
            }
            Action::GiveUp { id, how, why } => {
                let limits = &self.scenario.run;
                let c = &self.children[i];
                let what = match how {
                    Noticed::Exit => format!("exited unexpectedly: {}", c.ending.label()),
                    Noticed::HeartbeatDeadline => format!(
                        "sent no heartbeat for run.heartbeat_deadline_ms = {} ms",
                        limits.heartbeat_deadline_ms
                    ),
                    Noticed::RestartTimeout => format!(
                        "was not ready again within run.startup_timeout_ms = {} ms",
                        limits.startup_timeout_ms
                    ),
                };
                let why = format!(
                    "service {} {what}{}; not restarted: {why}\n{}",
                    id.name(),
                    injected_note(&self.injector, id),
                    c.log_tail(8)
                );
                return Ok(Some(self.fail(why)));
            }
        }
        Ok(None)
    }
}

/// " (injected fault: …)" when faults were injected into `id`.
fn injected_note(injector: &Injector, id: ServiceId) -> String {
    let faults = injector.injected_into(id);
    if faults.is_empty() {
        String::new()
    } else {
        format!(" (injected fault: {})", faults.join(", "))
    }
}
