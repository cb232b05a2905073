//! The inversion on the service skeleton: it keeps the spectra of both windows as they arrive
//! and answers solve calls (request/response with event wake-ups) stage by stage, as the
//! orchestrator sequences them. A stage whose window is incomplete answers `NotReady`, never a
//! guess. A stage solves on a worker thread, so the service goes on beating meanwhile.

use std::thread::JoinHandle;
use std::time::Duration;

use anyhow::{Context, Result};
use glint_runtime::ports::Inbox;
use glint_runtime::rpc::{Request, RpcServer, Solve};
use glint_runtime::waitloop::{Step, Wake};
use glint_runtime::{Io, Output, Service, Setup, TopicStats};
use shared_types::{DropReason, InBandFault, ServiceId, SolveResponse, Spectrum, TopicId, Window};

use crate::service_core::{answer, observation, session};
use crate::session::Session;
use crate::Observation;

/// A stage being solved: its request, and the thread that gives the session back with the
/// answer.
type Solving = (Request<Solve>, JoinHandle<(Session, SolveResponse)>);

/// Stack of the solve thread (the main thread's size: the solves were written for it).
const SOLVE_STACK_BYTES: usize = 8 << 20;
/// How often the loop looks for the end of a solve.
const SOLVE_POLL: Duration = Duration::from_millis(2);

pub struct InversionNode {
    server: RpcServer<Solve>,
    /// The session, or `None` while the solve thread holds it.
    idle: Option<Session>,
    solving: Option<Solving>,
    /// Spectra that arrived while a stage solved: pushed when the session is back.
    held: Vec<(bool, Observation)>,
}

impl Service for InversionNode {
    const ID: ServiceId = ServiceId::Inversion;
    type Input = Inbox<Spectrum>;

    fn open(setup: &mut Setup<'_>) -> Result<(Self, Inbox<Spectrum>)> {
        let sp =
            (setup.scenario.spectra.as_ref()).context("the inversion needs a [spectra] section")?;
        let (spectra, listener) = Inbox::open(setup.node, TopicId::Spectrum)?;
        setup.listen(listener);
        let (server, listener) = RpcServer::<Solve>::open(setup.node, Self::ID)?;
        setup.listen(listener);
        let session = session(sp);
        let node = InversionNode {
            server,
            idle: Some(session),
            solving: None,
            held: vec![],
        };
        Ok((node, spectra))
    }

    fn outputs(&mut self) -> Vec<&mut dyn Output> {
        vec![]
    }

    fn stats(&self) -> Vec<&TopicStats> {
        vec![&self.server.stats]
    }

    /// Drops and corruptions hit the answers.
    fn arm(&mut self, fault: &InBandFault) {
        self.server.tamper.arm(fault);
    }

    fn on_input(&mut self, _io: &mut Io<'_>, sp: &Spectrum) -> Result<Result<(), DropReason>> {
        let (motion, o) = (sp.window == Window::Motion as u32, observation(sp));
        match self.idle.as_mut() {
            Some(session) => session.push(motion, o),
            None => self.held.push((motion, o)),
        }
        Ok(Ok(()))
    }

    fn on_tick(&mut self, _io: &mut Io<'_>, _wakes: &[Wake]) -> Result<Step> {
        if self.solving.as_ref().is_some_and(|(_, h)| h.is_finished()) {
            if let Some((req, h)) = self.solving.take() {
                let (mut session, resp) = h
                    .join()
                    .map_err(|_| anyhow::anyhow!("solve stage {} panicked", req.payload.stage))?;
                for (motion, o) in self.held.drain(..) {
                    session.push(motion, o);
                }
                self.idle = Some(session);
                let t_ns = req.payload.meta.t_ns;
                self.server.respond(req, resp, t_ns)?;
            }
        }
        if self.solving.is_none() {
            if let Some(req) = self.server.take_request()? {
                let mut session = self.idle.take().context("the session is away")?;
                let payload = req.payload;
                let worker = std::thread::Builder::new()
                    .name("solve".into())
                    .stack_size(SOLVE_STACK_BYTES)
                    .spawn(move || {
                        let resp = answer(&mut session, &payload);
                        (session, resp)
                    })
                    .context("starting the solve thread")?;
                self.solving = Some((req, worker));
            }
        }
        // While a stage solves, look for its end often (the worker does not wake the loop).
        Ok(match self.solving {
            Some(_) => Step::WaitAtMost(SOLVE_POLL),
            None => Step::Wait,
        })
    }
}
