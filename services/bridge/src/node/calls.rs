//! Calls across hosts: a call made on one host and answered on another (the tracker's laser
//! shots, the sensor on the other host). On the caller's host the bridge is the call's server:
//! it takes each request, puts it on Zenoh (`glint/<deployment>/<call>/request`) and holds it
//! until the response comes back (`…/<call>/response`), which it passes on as the server made
//! it (seq, times, producer unchanged). On the server's host the bridge is a client: it asks
//! the server each request that comes off the wire, under the request's own id, and puts the
//! answer back. Nothing is retried here: a request or an answer that a restart or the link
//! lost is asked again by its caller under the same id, as on one host, and the server counts
//! the repeat as a duplicate.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use anyhow::{anyhow, Result};
use glint_runtime::rpc::{Pending, Range, Request, Rpc, RpcClient, RpcServer, Solve};
use iceoryx2::port::listener::Listener;
use iceoryx2::prelude::ZeroCopySend;
use shared_types::topics::{Ipc, IpcNode};
use shared_types::{Message, Scenario, ServiceId, TopicId};
use zenoh::qos::{CongestionControl, Priority};
use zenoh::sample::Locality;
use zenoh::Wait;

use super::key;
use crate::envelope::{digest_of, Envelope, Refusal};
use crate::routes::Routes;

/// How long the loop waits for the wire before it looks at its iceoryx2 side again: the most a
/// call waits here beyond its round trip.
const POLL: Duration = Duration::from_millis(1);

/// Which side of a call this bridge is on its host.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Side {
    /// The caller is here: the bridge serves the call and asks across.
    Serve,
    /// The server is here: the bridge asks it what comes across.
    Answer,
}

impl Side {
    /// The leg this side puts on the wire, and the one it takes off it.
    fn legs(self) -> (&'static str, &'static str) {
        match self {
            Side::Serve => ("request", "response"),
            Side::Answer => ("response", "request"),
        }
    }
}

/// What one end of a call counted.
#[derive(Debug, Default, Clone, Copy)]
struct Counts {
    /// Put on the wire.
    put: u64,
    /// Taken off the wire and passed on.
    passed_on: u64,
    /// Off the wire and refused: not this contract's, or failed validation.
    refused: u64,
    /// Given up here: an answer nobody waits for any more, a request its caller asked again, a
    /// call its server did not answer (its caller asks again).
    abandoned: u64,
}

/// One call this bridge carries, on its side.
trait CallEnd {
    fn topic(&self) -> TopicId;
    fn side(&self) -> Side;
    /// Serves the iceoryx2 side: requests to put (serve), answers to put back (answer).
    fn step(&mut self) -> Result<()>;
    /// A message off the wire for this end.
    fn take(&mut self, payload: &[u8], attachment: Option<&[u8]>);
    fn counts(&self) -> Counts;
}

/// The publisher of one leg and its envelopes.
struct Wire {
    topic: TopicId,
    publisher: zenoh::pubsub::Publisher<'static>,
    host: u16,
    link_seq: u64,
    /// The fingerprint of what this leg puts, and of what it takes.
    put_digest: u64,
    take_digest: u64,
}

impl Wire {
    fn put(&mut self, bytes: &[u8]) -> Result<()> {
        let envelope = Envelope::new(self.topic, self.host, self.link_seq, self.put_digest);
        self.link_seq += 1;
        (self.publisher.put(bytes.to_vec()))
            .attachment(envelope.to_bytes().to_vec())
            .wait()
            .map_err(|e| anyhow!("zenoh put on {}: {e}", self.topic.name()))
    }

    /// The message of type `T` in a payload off the wire, or why it is refused.
    fn read<T: Message>(&self, payload: &[u8], attachment: Option<&[u8]>) -> Result<T, String> {
        Envelope::read(attachment, self.topic, self.take_digest).map_err(|e| e.to_string())?;
        if payload.len() != std::mem::size_of::<T>() {
            return Err(Refusal::Size.to_string());
        }
        let m: T = bytemuck::pod_read_unaligned(payload);
        m.check().map_err(|e| e.to_string())?;
        Ok(m)
    }
}

/// The fingerprints of a call's request and response types.
fn digests<R: Rpc>() -> (u64, u64) {
    // SAFETY: `type_name` only returns the `#[type_name]` string.
    let (req, resp) = unsafe {
        (
            <R::Req as ZeroCopySend>::type_name(),
            <R::Resp as ZeroCopySend>::type_name(),
        )
    };
    (
        digest_of(req, std::mem::size_of::<R::Req>(), 0),
        digest_of(resp, std::mem::size_of::<R::Resp>(), 0),
    )
}

/// The caller's host: the bridge serves the call here.
struct Serve<R: Rpc> {
    server: RpcServer<R>,
    requests: Listener<Ipc>,
    wire: Wire,
    /// Requests put across and not yet answered, by id.
    waiting: Vec<(u64, Request<R>)>,
    counts: Counts,
}

impl<R: Rpc> CallEnd for Serve<R> {
    fn topic(&self) -> TopicId {
        R::TOPIC
    }
    fn side(&self) -> Side {
        Side::Serve
    }

    fn step(&mut self) -> Result<()> {
        let _ = self.requests.try_wait(|_| {});
        while let Some(req) = self.server.take_request()? {
            let id = req.payload.meta().seq;
            // Asked again (its answer was late, or lost): the caller gave up the first one.
            let before = self.waiting.len();
            self.waiting.retain(|(w, _)| *w != id);
            self.counts.abandoned += (before - self.waiting.len()) as u64;
            self.wire.put(bytemuck::bytes_of(&req.payload))?;
            self.counts.put += 1;
            self.waiting.push((id, req));
        }
        Ok(())
    }

    fn take(&mut self, payload: &[u8], attachment: Option<&[u8]>) {
        let resp: R::Resp = match self.wire.read(payload, attachment) {
            Ok(r) => r,
            Err(why) => return refused(&mut self.counts, R::TOPIC, &why),
        };
        let id = R::response_id(&resp);
        let Some(at) = self.waiting.iter().position(|(w, _)| *w == id) else {
            // Its caller asked again and this is the first attempt's answer, or a repeat.
            self.counts.abandoned += 1;
            return;
        };
        let (_, req) = self.waiting.swap_remove(at);
        match self.server.forward(req, resp) {
            Ok(()) => self.counts.passed_on += 1,
            // The caller stopped waiting (timed out, restarted): it asks again.
            Err(e) => {
                tracing::debug!(topic = R::TOPIC.name(), "answer not passed on: {e:#}");
                self.counts.abandoned += 1;
            }
        }
    }

    fn counts(&self) -> Counts {
        self.counts
    }
}

/// The server's host: the bridge asks the server what comes across.
struct Answer<R: Rpc> {
    client: RpcClient<R>,
    wire: Wire,
    pending: Vec<Pending<R>>,
    /// The most requests the call keeps in flight per client (the table's `in_flight`).
    in_flight: usize,
    counts: Counts,
}

impl<R: Rpc> CallEnd for Answer<R> {
    fn topic(&self) -> TopicId {
        R::TOPIC
    }
    fn side(&self) -> Side {
        Side::Answer
    }

    fn step(&mut self) -> Result<()> {
        let mut i = 0;
        while i < self.pending.len() {
            match self.client.poll(&self.pending[i])? {
                None => i += 1,
                Some(glint_runtime::rpc::CallOutcome::Answered(resp)) => {
                    self.pending.swap_remove(i);
                    self.wire.put(bytemuck::bytes_of(&resp))?;
                    self.counts.put += 1;
                }
                // The server died or answered what does not validate: the caller asks again.
                Some(outcome) => {
                    tracing::warn!(topic = R::TOPIC.name(), ?outcome, "call not answered");
                    self.pending.swap_remove(i);
                    self.counts.abandoned += 1;
                }
            }
        }
        Ok(())
    }

    fn take(&mut self, payload: &[u8], attachment: Option<&[u8]>) {
        let req: R::Req = match self.wire.read(payload, attachment) {
            Ok(r) => r,
            Err(why) => return refused(&mut self.counts, R::TOPIC, &why),
        };
        let (id, t_ns) = (req.meta().seq, req.meta().t_ns);
        // Asked again: the caller gave up the first attempt; so does this bridge. At the
        // in-flight limit the oldest goes (its caller has long asked again).
        let before = self.pending.len();
        self.pending.retain(|p| p.id != id);
        if self.pending.len() >= self.in_flight {
            self.pending.remove(0);
        }
        self.counts.abandoned += (before - self.pending.len()) as u64;
        match self.client.send(req, id, t_ns) {
            Ok(p) => {
                self.pending.push(p);
                self.counts.passed_on += 1;
            }
            Err(e) => {
                tracing::warn!(topic = R::TOPIC.name(), "request not passed on: {e:#}");
                self.counts.abandoned += 1;
            }
        }
    }

    fn counts(&self) -> Counts {
        self.counts
    }
}

fn refused(counts: &mut Counts, topic: TopicId, why: &str) {
    counts.refused += 1;
    if counts.refused == 1 || counts.refused.is_power_of_two() {
        tracing::warn!(
            topic = topic.name(),
            refused = counts.refused,
            "call refused off the wire: {why}"
        );
    }
}

/// One end of call `R` on `side`, its leg's publisher open.
fn open_end<R: Rpc + 'static>(
    node: &IpcNode,
    side: Side,
    publisher: zenoh::pubsub::Publisher<'static>,
    host: u16,
) -> Result<Box<dyn CallEnd>> {
    let (request, response) = digests::<R>();
    let wire = |put_digest, take_digest| Wire {
        topic: R::TOPIC,
        publisher,
        host,
        link_seq: 0,
        put_digest,
        take_digest,
    };
    Ok(match side {
        Side::Serve => {
            let (server, requests) = RpcServer::<R>::open(node, ServiceId::Bridge)?;
            Box::new(Serve {
                server,
                requests,
                wire: wire(request, response),
                waiting: vec![],
                counts: Counts::default(),
            })
        }
        Side::Answer => {
            let in_flight = match R::TOPIC.spec().pattern {
                shared_types::table::Pattern::Calls { in_flight, .. } => in_flight,
                shared_types::table::Pattern::Frames { .. }
                | shared_types::table::Pattern::Messages { .. } => 1,
            };
            Box::new(Answer {
                client: RpcClient::<R>::open(node, ServiceId::Bridge)?,
                wire: wire(response, request),
                pending: vec![],
                in_flight,
                counts: Counts::default(),
            })
        }
    })
}

/// The end of `call` on `side`.
fn end(
    node: &IpcNode,
    call: TopicId,
    side: Side,
    publisher: zenoh::pubsub::Publisher<'static>,
    host: u16,
) -> Result<Box<dyn CallEnd>> {
    match call {
        TopicId::Range => open_end::<Range>(node, side, publisher, host),
        TopicId::Solve => open_end::<Solve>(node, side, publisher, host),
        TopicId::Frame
        | TopicId::Spectrum
        | TopicId::Truth
        | TopicId::Heartbeat
        | TopicId::Control
        | TopicId::Ack
        | TopicId::Detections
        | TopicId::Tracks
        | TopicId::EarthFrame
        | TopicId::EarthAttitude
        | TopicId::Stereo
        | TopicId::RelNav
        | TopicId::Photometry
        | TopicId::PhotometryEstimate => Err(anyhow!("`{}` is not a call", call.name())),
    }
}

/// The calls thread's body: runs until `stop` is set or a termination signal arrives; `ready`
/// is called once every port and subscriber is open.
pub fn run(
    prefix: &str,
    scenario: &Scenario,
    routes: &Routes,
    session: &zenoh::Session,
    stop: &AtomicBool,
    ready: impl FnOnce(),
) -> Result<()> {
    let node = glint_runtime::open_node(prefix, "bridge-calls")?;
    let deployment = scenario.deployment_key();
    let sides = (routes.serves.iter().map(|t| (*t, Side::Serve)))
        .chain(routes.answers.iter().map(|t| (*t, Side::Answer)));
    let (tx, inbox) = std::sync::mpsc::channel::<(usize, zenoh::sample::Sample)>();
    let mut ends = vec![];
    let mut subscribers = vec![];
    for (i, (call, side)) in sides.enumerate() {
        let (out, into) = side.legs();
        let base = key(&deployment, call);
        let publisher = (session.declare_publisher(format!("{base}/{out}")))
            .congestion_control(CongestionControl::Block)
            .priority(Priority::InteractiveHigh)
            .express(true)
            .allowed_destination(Locality::Remote)
            .wait()
            .map_err(|e| anyhow!("zenoh publisher for {base}/{out}: {e}"))?;
        ends.push(end(&node, call, side, publisher, routes.host_index)?);
        let tx = tx.clone();
        let subscriber = (session.declare_subscriber(format!("{base}/{into}")))
            .allowed_origin(Locality::Remote)
            .callback(move |sample| {
                let _ = tx.send((i, sample));
            })
            .wait()
            .map_err(|e| anyhow!("zenoh subscriber on {base}/{into}: {e}"))?;
        subscribers.push(subscriber);
    }
    drop(tx);
    ready();
    while !stop.load(Ordering::SeqCst) && glint_runtime::lifeline::end_requested().is_none() {
        let mut next = inbox.recv_timeout(POLL).map_err(|e| match e {
            std::sync::mpsc::RecvTimeoutError::Timeout => None,
            std::sync::mpsc::RecvTimeoutError::Disconnected => Some(()),
        });
        loop {
            match next {
                Ok((i, sample)) => {
                    let attachment = sample.attachment().map(|a| a.to_bytes());
                    let payload = sample.payload().to_bytes();
                    ends[i].take(&payload, attachment.as_deref());
                }
                Err(None) => break,
                Err(Some(())) => return Err(anyhow!("the zenoh subscribers closed")),
            }
            next = inbox.try_recv().map_err(|e| match e {
                std::sync::mpsc::TryRecvError::Empty => None,
                std::sync::mpsc::TryRecvError::Disconnected => Some(()),
            });
        }
        for e in &mut ends {
            e.step()?;
        }
    }
    for e in &ends {
        let c = e.counts();
        tracing::info!(
            call = e.topic().name(),
            side = ?e.side(),
            put = c.put,
            passed_on = c.passed_on,
            refused = c.refused,
            abandoned = c.abandoned,
            "calls across hosts"
        );
    }
    drop(subscribers);
    Ok(())
}
