//! Sequencing of the three-stage solve ([000]): stage 1 once the inversion holds the complete
//! stable window, then stage 2, then stage 3 once it holds the motion window. Each stage is a
//! request/response call with a request id and a timeout, polled from the run loop (which goes
//! on supervising while a stage solves). `NotReady` is asked again on a later tick; a call lost
//! with its server (the inversion restarted) is sent again with the same request id once the
//! inversion is back.

use std::time::Duration;

use anyhow::Result;
use glint_runtime::rpc::{CallOutcome, Pending, RpcClient, Solve};
use shared_types::scenario::FaultKind;
use shared_types::topics::IpcNode;
use shared_types::{Scenario, ServiceId, SolveRequest, SolveResponse, SolveStatus, TopicId};

use crate::run::consume::Consumer;

/// `NotReady` answers per stage before the run is declared failed.
const MAX_ATTEMPTS: u32 = 200;
/// The pause before asking again after `NotReady`.
const NOT_READY_PAUSE: Duration = Duration::from_millis(20);
/// Calls lost per stage (their server gone) before the run is declared failed.
const MAX_LOST: u32 = 10;

pub struct Sequencer {
    client: RpcClient<Solve>,
    stable_samples: u64,
    total_samples: u64,
    timeout: Duration,
    next_stage: u32,
    attempts: u32,
    lost: u32,
    /// The call in flight.
    in_flight: Option<Pending<Solve>>,
    /// The id of a lost call, sent again.
    retry_id: Option<u64>,
    /// After `NotReady`, not asked again before this instant.
    not_before: Option<std::time::Instant>,
    /// Answers rejected as malformed (each asked again).
    pub malformed: u64,
    /// Calls that ended unanswered (the server gone or the request discarded; asked again).
    pub unanswered: u64,
    /// Responses of stages 1, 2, 3 in order.
    pub responses: Vec<SolveResponse>,
    pub failure: Option<String>,
}

impl Sequencer {
    /// `None` when the scenario has no spectra (nothing to solve).
    pub fn open(node: &IpcNode, scenario: &Scenario) -> Result<Option<Self>> {
        let Some(sp) = &scenario.spectra else {
            return Ok(None);
        };
        // A replay that leaves the inversion out has no one to ask.
        if !shared_types::deployment::carries(scenario, shared_types::TopicId::Solve) {
            return Ok(None);
        }
        Ok(Some(Sequencer {
            client: RpcClient::open(node, ServiceId::Orchestrator)?,
            stable_samples: sp.stable_samples,
            total_samples: sp.stable_samples + sp.motion_frames,
            timeout: Duration::from_secs_f64(scenario.run.timeout_s),
            next_stage: 1,
            attempts: 0,
            lost: 0,
            in_flight: None,
            retry_id: None,
            not_before: None,
            malformed: 0,
            unanswered: 0,
            responses: vec![],
            failure: None,
        }))
    }

    /// The inversion restarted: its new incarnation holds no stage, so the solve starts again
    /// from stage 1 (the answers come out the same: the replay gives it the same spectra).
    pub fn server_restarted(&mut self) {
        if self.done() {
            return;
        }
        self.next_stage = 1;
        self.responses.clear();
        self.attempts = 0;
        self.in_flight = None;
    }

    pub fn done(&self) -> bool {
        self.next_stage > 3 || self.failure.is_some()
    }

    /// Makes progress: takes the answer of the call in flight, or — when the inversion is up
    /// and holds what the next stage needs (judged from the acknowledged spectra in its
    /// heartbeat; a premature call just answers `NotReady`) — sends the next call.
    pub fn step(&mut self, consumer: &Consumer, inversion_up: bool) -> Result<()> {
        while !self.done() {
            if let Some(p) = &self.in_flight {
                // A request the inversion discards unanswered (an injected drop) disconnects.
                let outcome = match self.client.poll(p)? {
                    Some(o) => o,
                    None if p.sent.elapsed() > self.timeout => CallOutcome::TimedOut,
                    None => return Ok(()),
                };
                let id = p.id;
                self.in_flight = None;
                if !self.answered(id, outcome) {
                    return Ok(());
                }
                continue;
            }
            let have = consumer
                .reported(ServiceId::Inversion, TopicId::Spectrum)
                .map_or(0, |c| c.next_seq);
            let need = if self.next_stage == 3 {
                self.total_samples
            } else {
                self.stable_samples
            };
            let waiting = self
                .not_before
                .is_some_and(|t| std::time::Instant::now() < t);
            if !inversion_up || have < need || waiting {
                return Ok(());
            }
            let req = SolveRequest {
                stage: self.next_stage,
                flags: SolveRequest::FLAG_JOINT,
                ..Default::default()
            };
            let id = match self.retry_id.take() {
                Some(id) => id,
                None => self.client.new_id(),
            };
            self.in_flight = Some(self.client.send(req, id, 0)?);
        }
        Ok(())
    }

    /// Whether the sequencer noticed the inversion's dropped (`Drop`) or malformed
    /// (`Corrupt`) answers.
    pub fn counted(&self, kind: FaultKind) -> bool {
        match kind {
            FaultKind::Drop => self.unanswered > 0,
            _ => self.malformed > 0,
        }
    }

    /// Takes the outcome of call `id`; `true` when the next stage may be asked at once.
    fn answered(&mut self, id: u64, outcome: CallOutcome<SolveResponse>) -> bool {
        match outcome {
            CallOutcome::Answered(resp) if resp.status == SolveStatus::NotReady as u32 => {
                self.attempts += 1;
                self.not_before = Some(std::time::Instant::now() + NOT_READY_PAUSE);
                if self.attempts >= MAX_ATTEMPTS {
                    self.failure = Some(format!(
                        "solve stage {} never became ready",
                        self.next_stage
                    ));
                }
                false
            }
            CallOutcome::Answered(resp) => {
                tracing::info!(
                    stage = self.next_stage,
                    status = resp.status,
                    "solve answered"
                );
                self.responses.push(resp);
                self.next_stage += 1;
                self.attempts = 0;
                self.lost = 0;
                true
            }
            CallOutcome::Malformed => {
                self.malformed += 1;
                self.retry_id = Some(id);
                self.lost += 1;
                if self.lost >= MAX_LOST {
                    self.failure = Some(format!(
                        "solve stage {}: {} answers malformed or lost",
                        self.next_stage, self.lost
                    ));
                }
                // Asked again at once.
                true
            }
            CallOutcome::Disconnected => {
                // The server gone, or (it still being up) the request discarded unanswered.
                self.unanswered += 1;
                tracing::warn!(
                    stage = self.next_stage,
                    request = id,
                    "solve call lost; retrying"
                );
                self.lost += 1;
                self.retry_id = Some(id);
                if self.lost >= MAX_LOST {
                    self.failure = Some(format!(
                        "solve stage {}: {} calls lost",
                        self.next_stage, self.lost
                    ));
                }
                false
            }
            CallOutcome::TimedOut => {
                self.failure = Some(format!(
                    "solve stage {}: no answer within run.timeout_s = {} s",
                    self.next_stage,
                    self.timeout.as_secs_f64()
                ));
                false
            }
        }
    }
}
