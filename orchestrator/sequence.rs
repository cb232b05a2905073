//! Sequencing of the three-stage solve ([000]): stage 1 once the inversion holds the complete
//! stable window, then stage 2, then stage 3 once it holds the motion window. Each stage is a
//! request/response call with a request id and a timeout, polled from the run loop (which goes
//! on supervising while a stage solves). `NotReady` is asked again on a later tick; a call lost
//! with its server (the inversion restarted) is sent again with the same request id once the
//! inversion is back.

use std::time::Duration;

use anyhow::Result;
use glint_runtime::rpc::{CallOutcome, Pending, RpcClient, Solve};
use shared_types::topics::IpcNode;
use shared_types::{Scenario, ServiceId, SolveRequest, SolveResponse, SolveStatus, TopicId};

use crate::consume::Consumer;

/// `NotReady` answers per stage before the run is declared failed.
const MAX_ATTEMPTS: u32 = 200;
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
            responses: vec![],
            failure: None,
        }))
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
            if !inversion_up || have < need {
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

    /// Takes the outcome of call `id`; `true` when the next stage may be asked at once.
    fn answered(&mut self, id: u64, outcome: CallOutcome<SolveResponse>) -> bool {
        match outcome {
            CallOutcome::Answered(resp) if resp.status == SolveStatus::NotReady as u32 => {
                self.attempts += 1;
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
            CallOutcome::Disconnected => {
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
