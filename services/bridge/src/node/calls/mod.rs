//! Calls across hosts: a call made on one host and answered on another (the tracker's laser
//! shots, the sensor on the other host). On the caller's host the bridge is the call's server:
//! it takes each request, puts it on Zenoh (`glint/<deployment>/<call>/request`) and holds it
//! until the response comes back (`…/<call>/response`), which it passes on as the server made
//! it (seq, times, producer unchanged). On the server's host the bridge is a client: it asks
//! the server each request that comes off the wire, under the request's own id, and puts the
//! answer back. Nothing is retried here: a request or an answer that a restart or the link
//! lost is asked again by its caller under the same id, as on one host, and the server counts
//! the repeat as a duplicate.

use std::sync::atomic::Ordering;
use std::time::Duration;

use anyhow::{anyhow, Result};
use glint_runtime::rpc::{Range, Rpc, RpcClient, RpcServer, Solve};
use glint_runtime::TopicStats;
use iceoryx2::prelude::ZeroCopySend;
use shared_types::topics::IpcNode;
use shared_types::{DropReason, Message, ServiceId, TopicId};
use zenoh::qos::{CongestionControl, Priority};
use zenoh::sample::Locality;
use zenoh::Wait;

mod ends;

use super::{key, Env};
use crate::envelope::{digest_of, Envelope, Refusal};
use ends::{Answer, Serve};

/// How long the loop waits while this host's server has a call to answer: the most an answer
/// waits here beyond the server's own time.
const POLL: Duration = Duration::from_millis(1);
/// How long the loop waits otherwise: a request from a caller here, or anything off the wire,
/// wakes it at once; this only bounds how late it sees the stop flag.
const IDLE: Duration = Duration::from_millis(50);

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

/// What one end of a call counted. Every request taken ends answered or abandoned (or is still
/// held): `taken == answered + abandoned + held`.
#[derive(Debug, Default, Clone, Copy, PartialEq)]
struct Counts {
    /// Requests taken: from a caller on this host (serve), or valid off the wire (answer).
    taken: u64,
    /// Answers passed on: to the caller here (serve), or onto the wire (answer).
    answered: u64,
    /// Requests given up here: asked again by their caller, their caller gone, their server
    /// gone or its answer invalid, over the in-flight limit (their caller asks again).
    abandoned: u64,
    /// Off the wire and refused: not this contract's, or failed validation.
    refused: u64,
    /// Answers off the wire for no request held: a first attempt's, after its caller asked
    /// again (the retry's answer is the same).
    late: u64,
}

impl Counts {
    /// The call's row in the bridge's per-hop counters: *taken* the requests, *passed on* the
    /// answers, *lost* the calls that got no answer through this bridge (their caller asked
    /// again), *refused* what came off the wire and was not this contract's.
    fn hop(&self, topic: TopicId) -> TopicStats {
        let mut s = TopicStats::new(topic);
        s.received = self.taken;
        s.published = self.answered;
        s.dropped[DropReason::Link as usize] = self.abandoned;
        s.dropped[DropReason::Malformed as usize] = self.refused;
        s
    }
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
    /// Whether it holds a call not yet answered.
    fn busy(&self) -> bool;
    /// The leg it puts on.
    fn wire(&self) -> &Wire;
    /// Waits up to `timeout` for a request from a caller on this host (serve side only; the
    /// answer side has nothing to wait for here and returns at once).
    fn wait_for_caller(&self, timeout: Duration) -> Result<()>;
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
    /// Whether the other host's bridge takes this leg.
    fn matched(&self) -> Result<bool> {
        Ok((self.publisher.matching_status().wait())
            .map_err(|e| anyhow!("zenoh matching status: {e}"))?
            .matching())
    }

    /// Puts `bytes` on the leg; false if Zenoh refused it (its caller asks again).
    fn put(&mut self, bytes: &[u8]) -> bool {
        let envelope = Envelope::new(self.topic, self.host, self.link_seq, self.put_digest);
        self.link_seq += 1;
        let put = (self.publisher.put(bytes.to_vec()))
            .attachment(envelope.to_bytes().to_vec())
            .wait();
        if let Err(e) = &put {
            tracing::warn!(topic = self.topic.name(), "call not put on the wire: {e}");
        }
        put.is_ok()
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
    let in_flight = match R::TOPIC.spec().pattern {
        shared_types::table::Pattern::Calls { in_flight, .. } => in_flight,
        shared_types::table::Pattern::Frames { .. }
        | shared_types::table::Pattern::Messages { .. } => 1,
    };
    Ok(match side {
        Side::Serve => {
            let (server, requests) = RpcServer::<R>::open(node, ServiceId::Bridge)?;
            Box::new(Serve {
                server,
                requests,
                wire: wire(request, response),
                waiting: vec![],
                in_flight,
                counts: Counts::default(),
            })
        }
        Side::Answer => Box::new(Answer {
            client: RpcClient::<R>::open(node, ServiceId::Bridge)?,
            wire: wire(response, request),
            pending: vec![],
            in_flight,
            counts: Counts::default(),
        }),
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
pub fn run(env: &Env, ready: impl FnOnce()) -> Result<()> {
    let Env {
        prefix,
        scenario,
        routes,
        session,
        shared,
        stop,
    } = *env;
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
        // Never blocks the thread on a congested or cut link: a call dropped there is asked
        // again by its caller, as one that a killed bridge lost.
        let publisher = (session.declare_publisher(format!("{base}/{out}")))
            .congestion_control(CongestionControl::Drop)
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
    // Ready once the other host's bridge takes what this one puts: a call put before that
    // would wait for its caller's timeout.
    for e in &ends {
        while !e.wire().matched()? {
            if stop.load(Ordering::SeqCst) || glint_runtime::lifeline::end_requested().is_some() {
                return Ok(());
            }
            std::thread::sleep(Duration::from_millis(10));
        }
    }
    ready();
    let mut reported = vec![Counts::default(); ends.len()];
    // Where to wait: on a caller here while no call is held (its request wakes the loop), else
    // on the wire (an answer, or a request from another host, wakes it); a call held by this
    // host's server is looked at every POLL.
    let serves_only = ends.iter().all(|e| e.side() == Side::Serve);
    while !stop.load(Ordering::SeqCst) && glint_runtime::lifeline::end_requested().is_none() {
        let answering = ends.iter().any(|e| e.side() == Side::Answer && e.busy());
        let timeout = if answering { POLL } else { IDLE };
        let mut next = if serves_only && !ends.iter().any(|e| e.busy()) {
            for e in &ends {
                e.wait_for_caller(timeout / ends.len() as u32)?;
            }
            Err(None)
        } else {
            inbox.recv_timeout(timeout).map_err(|e| match e {
                std::sync::mpsc::RecvTimeoutError::Timeout => None,
                std::sync::mpsc::RecvTimeoutError::Disconnected => Some(()),
            })
        };
        if let Err(None) = next {
            next = inbox.try_recv().map_err(|e| match e {
                std::sync::mpsc::TryRecvError::Empty => None,
                std::sync::mpsc::TryRecvError::Disconnected => Some(()),
            });
        }
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
        for (e, last) in ends.iter_mut().zip(&mut reported) {
            e.step()?;
            // Each call's row of this bridge's per-hop counters, in its heartbeat.
            if e.counts() != *last {
                *last = e.counts();
                shared.set(&last.hop(e.topic()));
            }
        }
    }
    for e in &ends {
        let c = e.counts();
        tracing::info!(
            call = e.topic().name(),
            side = ?e.side(),
            taken = c.taken,
            answered = c.answered,
            refused = c.refused,
            abandoned = c.abandoned,
            late = c.late,
            "calls across hosts"
        );
    }
    drop(subscribers);
    Ok(())
}
