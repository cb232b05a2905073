//! Sequencing of the three-stage solve ([000]): stage 1 once the inversion holds the complete
//! stable window, then stage 2, then stage 3 once it holds the motion window. Each stage is a
//! request/response call with a request id and a timeout; `NotReady` and lost calls are retried
//! on a later tick, up to a limit.

use std::time::Duration;

use anyhow::Result;
use glint_runtime::rpc::{CallOutcome, RpcClient, Solve};
use shared_types::topics::IpcNode;
use shared_types::{Scenario, ServiceId, SolveRequest, SolveResponse, SolveStatus, TopicId};

use crate::consume::Consumer;

/// Attempts per stage before the run is declared failed.
const MAX_ATTEMPTS: u32 = 200;

pub struct Sequencer {
    client: RpcClient<Solve>,
    stable_samples: u64,
    total_samples: u64,
    timeout: Duration,
    next_stage: u32,
    attempts: u32,
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
            responses: vec![],
            failure: None,
        }))
    }

    pub fn done(&self) -> bool {
        self.next_stage > 3 || self.failure.is_some()
    }

    /// Makes progress if the inversion holds what the next stage needs (judged from its
    /// acknowledged spectra in its heartbeat; a premature call just answers `NotReady`).
    pub fn step(&mut self, node: &IpcNode, consumer: &Consumer) -> Result<()> {
        while !self.done() {
            let have = consumer
                .reported(ServiceId::Inversion, TopicId::Spectrum)
                .map_or(0, |c| c.next_seq);
            let need = if self.next_stage == 3 {
                self.total_samples
            } else {
                self.stable_samples
            };
            if have < need {
                return Ok(());
            }
            let req = SolveRequest {
                stage: self.next_stage,
                flags: SolveRequest::FLAG_JOINT,
                ..Default::default()
            };
            self.attempts += 1;
            match self.client.call(node, req, 0, self.timeout)? {
                CallOutcome::Answered(resp) if resp.status == SolveStatus::NotReady as u32 => {
                    if self.attempts >= MAX_ATTEMPTS {
                        self.failure = Some(format!(
                            "solve stage {} never became ready",
                            self.next_stage
                        ));
                    }
                    return Ok(());
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
                }
                other => {
                    tracing::warn!(stage = self.next_stage, ?other, "solve call lost; retrying");
                    if self.attempts >= 3 {
                        self.failure = Some(format!("solve stage {}: {other:?}", self.next_stage));
                    }
                    return Ok(());
                }
            }
        }
        Ok(())
    }
}
