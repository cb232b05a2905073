//! The laser rangefinder over request/response, with event wake-ups both ways (request/response
//! ports are not waitable). Clients always wait with a timeout and clean up dead nodes while
//! waiting, so a crashed server ends the wait instead of hanging it.

use std::time::{Duration, Instant};

use anyhow::{anyhow, Result};
use iceoryx2::port::client::Client;
use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::server::Server;
use shared_types::topics::{event_service, range_service, Ipc, IpcNode, EVENT_DATA};
use shared_types::{Message, Meta, RangeRequest, RangeResponse, RangeStatus, ServiceId, TopicId};

use crate::clock::mono_ns;
use crate::stats::TopicStats;

pub struct RangeServer {
    server: Server<Ipc, RangeRequest, (), RangeResponse, ()>,
    reply: Notifier<Ipc>,
    producer: ServiceId,
    /// `received`/`dropped` count requests; `published` counts responses.
    pub stats: TopicStats,
}

impl RangeServer {
    /// Opens the server; the returned listener wakes the loop on new requests.
    pub fn open(node: &IpcNode, producer: ServiceId) -> Result<(Self, Listener<Ipc>)> {
        let svc = range_service(node)?;
        let server = svc
            .server_builder()
            .create()
            .map_err(|e| anyhow!("range server: {e:?}"))?;
        let reply = event_service(node, TopicId::Range, true)?
            .notifier_builder()
            .create()
            .map_err(|e| anyhow!("range reply notifier: {e:?}"))?;
        let listener = event_service(node, TopicId::Range, false)?
            .listener_builder()
            .create()
            .map_err(|e| anyhow!("range request listener: {e:?}"))?;
        Ok((
            RangeServer {
                server,
                reply,
                producer,
                stats: TopicStats::new(TopicId::Range),
            },
            listener,
        ))
    }

    /// Answers every pending request with `answer(request) -> (response, t_ns)`. Malformed
    /// requests are counted and answered with `RangeStatus::Rejected`.
    pub fn serve(
        &mut self,
        mut answer: impl FnMut(&RangeRequest) -> (RangeResponse, u64),
    ) -> Result<usize> {
        let mut n = 0;
        while let Some(active) = self
            .server
            .receive()
            .map_err(|e| anyhow!("range receive: {e:?}"))?
        {
            n += 1;
            let req = *active.payload();
            let (mut resp, t_ns) = match req.check() {
                Ok(()) => {
                    self.stats.accept();
                    answer(&req)
                }
                Err(_) => {
                    self.stats.drop_for(shared_types::DropReason::Malformed);
                    let r = RangeResponse {
                        request_id: req.request_id,
                        status: RangeStatus::Rejected as u32,
                        track_id: req.track_id,
                        ..Default::default()
                    };
                    (r, req.meta.t_ns)
                }
            };
            resp.meta = Meta::new(self.stats.published, t_ns, mono_ns(), self.producer);
            active
                .send_copy(resp)
                .map_err(|e| anyhow!("range respond: {e:?}"))?;
            self.stats.published += 1;
            self.reply
                .notify_with_custom_event_id(EVENT_DATA)
                .map_err(|e| anyhow!("range reply notify: {e:?}"))?;
        }
        Ok(n)
    }
}

pub struct RangeClient {
    client: Client<Ipc, RangeRequest, (), RangeResponse, ()>,
    request: Notifier<Ipc>,
    reply: Listener<Ipc>,
    producer: ServiceId,
    next_id: u64,
}

/// Outcome of [`RangeClient::call`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CallOutcome {
    Answered(RangeResponse),
    /// No answer within the timeout.
    TimedOut,
    /// The server disappeared (dead-node cleanup disconnected the request).
    Disconnected,
}

impl RangeClient {
    pub fn open(node: &IpcNode, producer: ServiceId) -> Result<Self> {
        let svc = range_service(node)?;
        let client = svc
            .client_builder()
            .create()
            .map_err(|e| anyhow!("range client: {e:?}"))?;
        let request = event_service(node, TopicId::Range, false)?
            .notifier_builder()
            .create()
            .map_err(|e| anyhow!("range request notifier: {e:?}"))?;
        let reply = event_service(node, TopicId::Range, true)?
            .listener_builder()
            .create()
            .map_err(|e| anyhow!("range reply listener: {e:?}"))?;
        Ok(RangeClient {
            client,
            request,
            reply,
            producer,
            next_id: 0,
        })
    }

    /// Sends a request for simulated time `t_ns` and blocks until the answer, the timeout, or
    /// the server's death.
    pub fn call(
        &mut self,
        node: &IpcNode,
        mut req: RangeRequest,
        t_ns: u64,
        timeout: Duration,
    ) -> Result<CallOutcome> {
        req.request_id = self.next_id;
        req.meta = Meta::new(self.next_id, t_ns, mono_ns(), self.producer);
        self.next_id += 1;
        let pending = self
            .client
            .send_copy(req)
            .map_err(|e| anyhow!("range request: {e:?}"))?;
        self.request
            .notify_with_custom_event_id(EVENT_DATA)
            .map_err(|e| anyhow!("range request notify: {e:?}"))?;
        let t0 = Instant::now();
        loop {
            if let Some(r) = pending
                .receive()
                .map_err(|e| anyhow!("range reply: {e:?}"))?
            {
                return Ok(CallOutcome::Answered(*r.payload()));
            }
            if !pending.is_connected() {
                return Ok(CallOutcome::Disconnected);
            }
            let left = timeout.saturating_sub(t0.elapsed());
            if left.is_zero() {
                return Ok(CallOutcome::TimedOut);
            }
            let woke = self
                .reply
                .timed_wait(|_| {}, left.min(Duration::from_millis(50)))
                .map_err(|e| anyhow!("range reply wait: {e:?}"))?;
            let _ = woke;
            node.try_cleanup_dead_nodes();
        }
    }
}
