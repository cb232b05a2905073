//! Request/response with event wake-ups both ways (request/response ports are not waitable):
//! the laser rangefinder (tracker → sensor) and the solve calls (orchestrator → inversion).
//! Clients always wait with a timeout and clean up dead nodes while waiting, so a crashed
//! server ends the wait instead of hanging it.

use std::time::{Duration, Instant};

use anyhow::{anyhow, Result};
use iceoryx2::port::client::Client;
use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::server::Server;
use iceoryx2::service::port_factory::request_response::PortFactory;
use shared_types::topics::{calls, event_service, Ipc, IpcNode, EVENT_DATA};
use shared_types::{
    DropReason, Message, Meta, RangeRequest, RangeResponse, ServiceId, SolveRequest, SolveResponse,
    TopicId,
};

use crate::clock::mono_ns;
use crate::stats::TopicStats;
use crate::tamper::{Tamper, Verdict};

/// How long a caller waits in silence before it checks whether its server died.
const DEAD_SERVER_CHECK: Duration = Duration::from_millis(50);

/// The iceoryx2 service of a request/response pair.
pub type RpcService<Req, Resp> = PortFactory<Ipc, Req, (), Resp, ()>;

/// A request type and its response type on one topic.
pub trait Rpc {
    type Req: Message + Default;
    type Resp: Message + Default;
    const TOPIC: TopicId;
    fn service(node: &IpcNode) -> Result<RpcService<Self::Req, Self::Resp>>;
    /// The id a request carries (echoed in its response).
    fn set_request_id(req: &mut Self::Req, id: u64);
    /// The id of the request a response answers.
    fn response_id(resp: &Self::Resp) -> u64;
    /// The answer to a request that failed validation.
    fn rejected(req: &Self::Req) -> Self::Resp;
}

/// The laser rangefinder.
pub struct Range;
impl Rpc for Range {
    type Req = RangeRequest;
    type Resp = RangeResponse;
    const TOPIC: TopicId = TopicId::Range;
    fn service(node: &IpcNode) -> Result<RpcService<RangeRequest, RangeResponse>> {
        Ok(calls(node, TopicId::Range)?)
    }
    fn set_request_id(req: &mut RangeRequest, id: u64) {
        req.request_id = id;
    }
    fn response_id(resp: &RangeResponse) -> u64 {
        resp.request_id
    }
    fn rejected(req: &RangeRequest) -> RangeResponse {
        RangeResponse {
            request_id: req.request_id,
            status: shared_types::RangeStatus::Rejected as u32,
            track_id: req.track_id,
            ..Default::default()
        }
    }
}

/// The inversion's solve calls.
pub struct Solve;
impl Rpc for Solve {
    type Req = SolveRequest;
    type Resp = SolveResponse;
    const TOPIC: TopicId = TopicId::Solve;
    fn service(node: &IpcNode) -> Result<RpcService<SolveRequest, SolveResponse>> {
        Ok(calls(node, TopicId::Solve)?)
    }
    fn set_request_id(req: &mut SolveRequest, id: u64) {
        req.request_id = id;
    }
    fn response_id(resp: &SolveResponse) -> u64 {
        resp.request_id
    }
    fn rejected(req: &SolveRequest) -> SolveResponse {
        SolveResponse {
            request_id: req.request_id,
            stage: req.stage,
            status: shared_types::SolveStatus::Rejected as u32,
            ..Default::default()
        }
    }
}

pub struct RpcServer<R: Rpc> {
    server: Server<Ipc, R::Req, (), R::Resp, ()>,
    reply: Notifier<Ipc>,
    producer: ServiceId,
    /// `received`/`dropped` count requests; `published` counts responses (an injected drop
    /// or corruption of a response is counted as `dropped[injected]` / `dropped[malformed]`).
    pub stats: TopicStats,
    /// Injected drops and corruptions of responses still to apply.
    pub tamper: Tamper,
    /// Per client (producer id): the highest request id answered. A request at or below it
    /// is a retry (its answer was slow, or lost with a restart): answered again, counted as a
    /// duplicate, so `received` counts distinct requests whatever the timing.
    answered: Vec<(u32, u64)>,
}

impl<R: Rpc> RpcServer<R> {
    /// Opens the server; the returned listener wakes the loop on new requests.
    pub fn open(node: &IpcNode, producer: ServiceId) -> Result<(Self, Listener<Ipc>)> {
        let name = R::TOPIC.name();
        let server = R::service(node)?
            .server_builder()
            .create()
            .map_err(|e| anyhow!("{name} server: {e:?}"))?;
        let reply = event_service(node, R::TOPIC, true)?
            .notifier_builder()
            .create()
            .map_err(|e| anyhow!("{name} reply notifier: {e:?}"))?;
        let listener = event_service(node, R::TOPIC, false)?
            .listener_builder()
            .create()
            .map_err(|e| anyhow!("{name} request listener: {e:?}"))?;
        Ok((
            RpcServer {
                server,
                reply,
                producer,
                stats: TopicStats::new(R::TOPIC),
                tamper: Tamper::default(),
                answered: Vec::new(),
            },
            listener,
        ))
    }

    /// Answers every pending request with `answer(request) -> (response, t_ns)`. Malformed
    /// requests are counted and answered with the rejection response.
    pub fn serve(&mut self, mut answer: impl FnMut(&R::Req) -> (R::Resp, u64)) -> Result<usize> {
        let mut n = 0;
        while let Some(req) = self.take_request()? {
            n += 1;
            let (resp, t_ns) = answer(&req.payload);
            self.respond(req, resp, t_ns)?;
        }
        Ok(n)
    }

    /// The next valid request, to be answered later with [`RpcServer::respond`] (a long
    /// computation need not block the loop). Malformed requests are counted and answered with
    /// the rejection response on the way.
    pub fn take_request(&mut self) -> Result<Option<Request<R>>> {
        loop {
            let Some(active) = self
                .server
                .receive()
                .map_err(|e| anyhow!("{} receive: {e:?}", R::TOPIC.name()))?
            else {
                return Ok(None);
            };
            let payload = *active.payload();
            let req = Request { active, payload };
            match payload.check() {
                Ok(()) => {
                    let (client, id) = (payload.meta().producer, payload.meta().seq);
                    match self.answered.iter_mut().find(|(c, _)| *c == client) {
                        Some((_, last)) if id <= *last => self.stats.duplicates += 1,
                        Some((_, last)) => {
                            *last = id;
                            self.stats.accept();
                        }
                        None => {
                            self.answered.push((client, id));
                            self.stats.accept();
                        }
                    }
                    return Ok(Some(req));
                }
                Err(_) => {
                    self.stats.drop_for(DropReason::Malformed);
                    let t_ns = payload.meta().t_ns;
                    self.send_response(req, R::rejected(&payload), t_ns)?;
                }
            }
        }
    }

    /// Answers a request taken with [`RpcServer::take_request`] (or drops or corrupts the answer,
    /// as an injected fault says).
    pub fn respond(&mut self, req: Request<R>, resp: R::Resp, t_ns: u64) -> Result<()> {
        match self.tamper.verdict() {
            Verdict::Send => self.send_response(req, resp, t_ns),
            Verdict::Drop => {
                tracing::info!(topic = R::TOPIC.name(), "injected drop of a response");
                self.stats.drop_for(DropReason::Injected);
                self.stats.published += 1;
                Ok(())
            }
            Verdict::Corrupt(how) => {
                tracing::info!(topic = R::TOPIC.name(), "injected corruption of a response");
                self.stats.drop_for(DropReason::Malformed);
                let mut resp = resp;
                self.stamp(&mut resp, t_ns);
                resp.corrupt(how);
                self.send_stamped(req, resp)
            }
        }
    }

    /// Answers with a response its server already stamped and sealed (a bridge passing on the
    /// answer of a server on another host: its seq, times and producer stay the server's).
    pub fn forward(&mut self, req: Request<R>, resp: R::Resp) -> Result<()> {
        self.send_stamped(req, resp)
    }

    fn stamp(&self, resp: &mut R::Resp, t_ns: u64) {
        *resp.meta_mut() = Meta::new(self.stats.published, t_ns, mono_ns(), self.producer);
        resp.seal();
    }

    fn send_response(&mut self, req: Request<R>, mut resp: R::Resp, t_ns: u64) -> Result<()> {
        self.stamp(&mut resp, t_ns);
        self.send_stamped(req, resp)
    }

    fn send_stamped(&mut self, req: Request<R>, resp: R::Resp) -> Result<()> {
        req.active
            .send_copy(resp)
            .map_err(|e| anyhow!("{} respond: {e:?}", R::TOPIC.name()))?;
        self.stats.published += 1;
        self.reply
            .notify_with_custom_event_id(EVENT_DATA)
            .map_err(|e| anyhow!("{} reply notify: {e:?}", R::TOPIC.name()))?;
        Ok(())
    }
}

/// A request taken and not yet answered ([`RpcServer::take_request`]); dropping it unanswered
/// disconnects its client's pending call.
pub struct Request<R: Rpc> {
    active: iceoryx2::active_request::ActiveRequest<Ipc, R::Req, (), R::Resp, ()>,
    /// The request, validated.
    pub payload: R::Req,
}

impl<R: Rpc> Request<R> {
    /// Whether its client still waits for the answer (it may have timed out, or ended).
    pub fn is_connected(&self) -> bool {
        self.active.is_connected()
    }
}

pub struct RpcClient<R: Rpc> {
    client: Client<Ipc, R::Req, (), R::Resp, ()>,
    request: Notifier<Ipc>,
    reply: Listener<Ipc>,
    producer: ServiceId,
    next_id: u64,
    /// Time spent waiting in calls [ns].
    wait_ns: u64,
}

/// Outcome of [`RpcClient::call`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CallOutcome<T> {
    Answered(T),
    /// No answer within the timeout.
    TimedOut,
    /// The server disappeared (dead-node cleanup disconnected the request).
    Disconnected,
    /// The answer failed validation: not trusted (the caller may ask again).
    Malformed,
}

impl<R: Rpc> RpcClient<R> {
    pub fn open(node: &IpcNode, producer: ServiceId) -> Result<Self> {
        let name = R::TOPIC.name();
        let client = R::service(node)?
            .client_builder()
            .create()
            .map_err(|e| anyhow!("{name} client: {e:?}"))?;
        let request = event_service(node, R::TOPIC, false)?
            .notifier_builder()
            .create()
            .map_err(|e| anyhow!("{name} request notifier: {e:?}"))?;
        let reply = event_service(node, R::TOPIC, true)?
            .listener_builder()
            .create()
            .map_err(|e| anyhow!("{name} reply listener: {e:?}"))?;
        Ok(RpcClient {
            client,
            request,
            reply,
            producer,
            next_id: 0,
            wait_ns: 0,
        })
    }

    /// Sends a request for simulated time `t_ns` and blocks until the answer, the timeout, or
    /// the server's death.
    pub fn call(
        &mut self,
        node: &IpcNode,
        req: R::Req,
        t_ns: u64,
        timeout: Duration,
    ) -> Result<CallOutcome<R::Resp>> {
        let id = self.new_id();
        self.call_with_id(node, req, id, t_ns, timeout)
    }

    /// The id the next fresh request gets (a checkpoint keeps it).
    pub fn next_id(&self) -> u64 {
        self.next_id
    }

    /// Fresh ids go on from `id` (a restored checkpoint): the requests a replay makes get the
    /// ids they first had.
    pub fn resume_ids_at(&mut self, id: u64) {
        self.next_id = id;
    }

    /// A fresh request id, for [`RpcClient::call_with_id`].
    pub fn new_id(&mut self) -> u64 {
        self.next_id += 1;
        self.next_id - 1
    }

    /// As [`RpcClient::call`] with the request id given: a retry of a request that was lost (its
    /// server restarted) carries the id of the first attempt, so the answer is the same.
    pub fn call_with_id(
        &mut self,
        node: &IpcNode,
        req: R::Req,
        id: u64,
        t_ns: u64,
        timeout: Duration,
    ) -> Result<CallOutcome<R::Resp>> {
        let t0 = Instant::now();
        let outcome = self.answer_by(node, req, id, t_ns, t0 + timeout);
        self.wait_ns += t0.elapsed().as_nanos() as u64;
        outcome
    }

    /// Time spent in [`RpcClient::call`] so far [ns]: the round trips, answers included.
    pub fn wait_ns(&self) -> u64 {
        self.wait_ns
    }

    /// Sends the request and waits for its outcome until `deadline`.
    fn answer_by(
        &mut self,
        node: &IpcNode,
        req: R::Req,
        id: u64,
        t_ns: u64,
        deadline: Instant,
    ) -> Result<CallOutcome<R::Resp>> {
        let pending = self.send(req, id, t_ns)?;
        loop {
            if let Some(outcome) = self.poll(&pending)? {
                return Ok(outcome);
            }
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Ok(CallOutcome::TimedOut);
            }
            let mut woken = false;
            self.reply
                .timed_wait(|_| woken = true, left.min(DEAD_SERVER_CHECK))
                .map_err(|e| anyhow!("{} reply wait: {e:?}", R::TOPIC.name()))?;
            // A silent slice may mean a dead server: only then scan for dead nodes (a scan
            // opens every node's files — far too costly to run on every answered request).
            if !woken {
                node.try_cleanup_dead_nodes();
            }
        }
    }

    /// Sends request `id` for simulated time `t_ns` without waiting: [`RpcClient::poll`] tells
    /// when it is answered.
    pub fn send(&mut self, mut req: R::Req, id: u64, t_ns: u64) -> Result<Pending<R>> {
        R::set_request_id(&mut req, id);
        *req.meta_mut() = Meta::new(id, t_ns, mono_ns(), self.producer);
        req.seal();
        let name = R::TOPIC.name();
        let inner = self
            .client
            .send_copy(req)
            .map_err(|e| anyhow!("{name} request: {e:?}"))?;
        self.request
            .notify_with_custom_event_id(EVENT_DATA)
            .map_err(|e| anyhow!("{name} request notify: {e:?}"))?;
        Ok(Pending {
            inner,
            id,
            sent: Instant::now(),
        })
    }

    /// The outcome of a sent request, or `None` while it is still unanswered. A server that
    /// died is noticed once dead-node cleanup has run (the caller's, or any other node's).
    pub fn poll(&self, pending: &Pending<R>) -> Result<Option<CallOutcome<R::Resp>>> {
        let _ = self.reply.try_wait(|_| {});
        if let Some(r) = pending
            .inner
            .receive()
            .map_err(|e| anyhow!("{} reply: {e:?}", R::TOPIC.name()))?
        {
            let resp = *r.payload();
            if let Err(e) = resp.check() {
                tracing::warn!(topic = R::TOPIC.name(), "malformed answer rejected: {e}");
                return Ok(Some(CallOutcome::Malformed));
            }
            return Ok(Some(CallOutcome::Answered(resp)));
        }
        if !pending.inner.is_connected() {
            return Ok(Some(CallOutcome::Disconnected));
        }
        Ok(None)
    }
}

/// A request sent and not yet answered ([`RpcClient::send`]).
pub struct Pending<R: Rpc> {
    inner: iceoryx2::pending_response::PendingResponse<Ipc, R::Req, (), R::Resp, ()>,
    /// The request's id.
    pub id: u64,
    /// When it was sent.
    pub sent: Instant,
}

/// The laser's server and client.
pub type RangeServer = RpcServer<Range>;
pub type RangeClient = RpcClient<Range>;
