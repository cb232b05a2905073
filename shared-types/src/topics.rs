//! Topic names, quality of service, and the one place services are opened.
//!
//! The first process to create an iceoryx2 service fixes its QoS, and any setting an opener
//! passes is checked as a minimum; so every process opens every service through the functions
//! here, with the same numbers. The orchestrator creates all services before it spawns children.
//!
//! Each data topic has an event service of the same name: the producer notifies after `send`,
//! consumers block on the listener in a WaitSet (pub/sub ports are not waitable).
//!
//! Every service carries the attribute `glint.contract = CONTRACT_VERSION`; opening a service
//! created by another contract version fails with a clear error instead of exchanging garbage.

use iceoryx2::port::event_id::EventId;
use iceoryx2::prelude::*;
use iceoryx2::service::attribute::{AttributeKey, AttributeValue};
use iceoryx2::service::port_factory::{event, publish_subscribe, request_response};

use crate::messages::{FrameHeader, Message};
use crate::CONTRACT_VERSION;

use crate::table::{visit, Pattern, PayloadVisitor, TopicSpec};
pub use crate::table::{ServiceId, TopicId};

/// Frames queued per subscriber at most, and at least: 16 frames ride out a consumer's
/// millisecond wake-up tails at 1000 frames/s (with 4, the sensor of a 1024² chain waited for
/// credit a third of the time).
const FRAME_WINDOW_MAX: usize = 16;
const FRAME_WINDOW_MIN: usize = 4;
/// Pixels one subscriber's frame queue may hold, 32 MiB: large frames get fewer slots, so a
/// 4096² deployment does not take gigabytes of shared memory.
const FRAME_QUEUE_BYTES: usize = 32 << 20;

/// A frame topic's subscriber buffer, history (a restarted consumer catches up from it) and
/// sim-clock credit window, for frames of `frame_px` u16 pixels.
pub fn frame_window(frame_px: usize) -> usize {
    (FRAME_QUEUE_BYTES / (2 * frame_px).max(1)).clamp(FRAME_WINDOW_MIN, FRAME_WINDOW_MAX)
}

/// A topic's per-subscriber buffer — for a produced data topic also its sim-clock credit
/// window: a producer never has more than this many unacknowledged messages in flight per
/// consumer, so nothing overflows — for the frame sizes of `scenario`. Calls: one in flight.
pub fn credit_window(topic: TopicId, scenario: &crate::Scenario) -> usize {
    match topic.spec().pattern {
        Pattern::Frames { pixels } => frame_window(pixels(scenario)),
        Pattern::Messages { buffer, .. } => buffer,
        Pattern::Calls { .. } => 1,
    }
}

const MAX_NODES: usize = 24;
/// Notifiers and listeners per event: every service, plus restarts.
const MAX_PEERS: usize = 16;

/// Event id a producer notifies with after a send.
pub const EVENT_DATA: EventId = EventId::new(1);
/// Event id the iceoryx2 cleanup emits when a notifier's node died.
pub const EVENT_NOTIFIER_DEAD: EventId = EventId::new(2);

#[derive(Debug, thiserror::Error)]
pub enum OpenError {
    #[error("opening service '{service}': {detail}")]
    Open { service: String, detail: String },
}

fn err(topic: TopicId, e: impl std::fmt::Debug) -> OpenError {
    OpenError::Open {
        service: topic.service_name(),
        detail: format!("{e:?}"),
    }
}

fn name(topic: TopicId) -> Result<ServiceName, OpenError> {
    ServiceName::new(&topic.service_name()).map_err(|e| err(topic, e))
}

fn contract_verifier(topic: TopicId) -> Result<AttributeVerifier, OpenError> {
    let key = AttributeKey::try_from("glint.contract").map_err(|e| err(topic, e))?;
    let value = AttributeValue::try_from(CONTRACT_VERSION.to_string().as_str())
        .map_err(|e| err(topic, e))?;
    AttributeVerifier::new()
        .require(&key, &value)
        .map_err(|e| err(topic, e))
}

pub type Ipc = ipc::Service;
pub type IpcNode = Node<Ipc>;
pub type FrameService = publish_subscribe::PortFactory<Ipc, [u16], FrameHeader>;
pub type PubSubService<T> = publish_subscribe::PortFactory<Ipc, T, ()>;
pub type EventService = event::PortFactory<Ipc>;
pub type CallService<Req, Resp> = request_response::PortFactory<Ipc, Req, (), Resp, ()>;

/// Opens (or creates) a frame topic (`[u16]` pixels with a [`FrameHeader`]) for frames of
/// `frame_px` pixels (every process of a deployment derives it from the same scenario:
/// [`frames`]).
pub fn frames_sized(
    node: &IpcNode,
    t: TopicId,
    frame_px: usize,
) -> Result<FrameService, OpenError> {
    if !matches!(t.spec().pattern, Pattern::Frames { .. }) {
        return Err(mismatch(t, "frames"));
    }
    let window = frame_window(frame_px);
    node.service_builder(&name(t)?)
        .publish_subscribe::<[u16]>()
        .user_header::<FrameHeader>()
        .max_publishers(2)
        .max_subscribers(4)
        .max_nodes(MAX_NODES)
        .subscriber_max_buffer_size(window)
        .subscriber_max_borrowed_samples(2)
        .history_size(window)
        .enable_safe_overflow(true)
        .open_or_create_with_attributes(&contract_verifier(t)?)
        .map_err(|e| err(t, e))
}

/// Opens (or creates) frame topic `t` with the frame size of `scenario`.
pub fn frames(
    node: &IpcNode,
    t: TopicId,
    scenario: &crate::Scenario,
) -> Result<FrameService, OpenError> {
    frames_sized(node, t, frame_pixels(t, scenario))
}

/// Pixels of one frame of topic `t` in `scenario` (0 for a topic that carries no frames).
pub fn frame_pixels(t: TopicId, scenario: &crate::Scenario) -> usize {
    match t.spec().pattern {
        Pattern::Frames { pixels } => pixels(scenario),
        Pattern::Messages { .. } | Pattern::Calls { .. } => 0,
    }
}

fn mismatch(t: TopicId, asked: &str) -> OpenError {
    OpenError::Open {
        service: t.service_name(),
        detail: format!(
            "opened as {asked}, but the topic carries {}",
            crate::table::payload_type_name(t)
        ),
    }
}

/// Opens (or creates) message topic `t`, with the QoS of its row in the table.
pub fn messages<T: Message>(node: &IpcNode, t: TopicId) -> Result<PubSubService<T>, OpenError> {
    // SAFETY: `type_name` only returns the `#[type_name]` string.
    let asked = unsafe { <T as ZeroCopySend>::type_name() };
    let Pattern::Messages {
        publishers,
        subscribers,
        buffer,
        history,
    } = t.spec().pattern
    else {
        return Err(mismatch(t, asked));
    };
    if asked != crate::table::payload_type_name(t) {
        return Err(mismatch(t, asked));
    }
    node.service_builder(&name(t)?)
        .publish_subscribe::<T>()
        .max_publishers(publishers)
        .max_subscribers(subscribers)
        .max_nodes(MAX_NODES)
        .subscriber_max_buffer_size(buffer)
        .subscriber_max_borrowed_samples(2)
        .history_size(if history { buffer } else { 0 })
        .enable_safe_overflow(true)
        .open_or_create_with_attributes(&contract_verifier(t)?)
        .map_err(|e| err(t, e))
}

/// Opens (or creates) call topic `t` (request/response), served by its producer.
pub fn calls<Req: Message, Resp: Message>(
    node: &IpcNode,
    t: TopicId,
) -> Result<CallService<Req, Resp>, OpenError> {
    // SAFETY: as above.
    let asked = unsafe { <Req as ZeroCopySend>::type_name() };
    let Pattern::Calls {
        clients,
        in_flight,
        responses,
    } = t.spec().pattern
    else {
        return Err(mismatch(t, asked));
    };
    if asked != crate::table::payload_type_name(t) {
        return Err(mismatch(t, asked));
    }
    node.service_builder(&name(t)?)
        .request_response::<Req, Resp>()
        .max_servers(2)
        .max_clients(clients)
        .max_nodes(MAX_NODES)
        .max_active_requests_per_client(in_flight)
        .max_response_buffer_size(responses)
        .enable_safe_overflow_for_requests(false)
        .enable_safe_overflow_for_responses(false)
        .open_or_create_with_attributes(&contract_verifier(t)?)
        .map_err(|e| err(t, e))
}

/// The wake-up event paired with a topic. For request/response topics, `reply = true` names the
/// server→client direction.
pub fn event_service(node: &IpcNode, t: TopicId, reply: bool) -> Result<EventService, OpenError> {
    let n = if reply {
        format!("{}/reply", t.service_name())
    } else {
        t.service_name()
    };
    let service_name = ServiceName::new(&n).map_err(|e| err(t, e))?;
    node.service_builder(&service_name)
        .event()
        .max_notifiers(MAX_PEERS)
        .max_listeners(MAX_PEERS)
        .max_nodes(MAX_NODES)
        .notifier_dead_event(EVENT_NOTIFIER_DEAD)
        .open_or_create_with_attributes(&contract_verifier(t)?)
        .map_err(|e| err(t, e))
}

/// Creates every service of the table, with the frame sizes of `scenario` (the orchestrator
/// does this before spawning children): each topic and its wake-up event, and a call's reply
/// event.
pub fn create_all(
    node: &IpcNode,
    scenario: &crate::Scenario,
) -> Result<Vec<Box<dyn std::any::Any>>, OpenError> {
    struct Create<'a> {
        node: &'a IpcNode,
        scenario: &'a crate::Scenario,
    }
    type Kept = Result<Vec<Box<dyn std::any::Any>>, OpenError>;
    impl PayloadVisitor for Create<'_> {
        type Out = Kept;
        fn frames(self, spec: &'static TopicSpec) -> Kept {
            let service = frames(self.node, spec.id, self.scenario)?;
            let event = event_service(self.node, spec.id, false)?;
            Ok(vec![Box::new(service), Box::new(event)])
        }
        fn messages<T: Message>(self, spec: &'static TopicSpec) -> Kept {
            let service = messages::<T>(self.node, spec.id)?;
            let event = event_service(self.node, spec.id, false)?;
            Ok(vec![Box::new(service), Box::new(event)])
        }
        fn calls<Req: Message, Resp: Message>(self, spec: &'static TopicSpec) -> Kept {
            let service = calls::<Req, Resp>(self.node, spec.id)?;
            let request = event_service(self.node, spec.id, false)?;
            let reply = event_service(self.node, spec.id, true)?;
            Ok(vec![Box::new(service), Box::new(request), Box::new(reply)])
        }
    }
    let mut keep = vec![];
    for t in TopicId::ALL {
        keep.extend(visit(t, Create { node, scenario })?);
    }
    Ok(keep)
}
