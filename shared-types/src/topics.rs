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

use crate::messages::*;
use crate::CONTRACT_VERSION;

/// Services of a deployment. The numeric value travels in [`Meta::producer`] and [`Ack::consumer`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[repr(u32)]
pub enum ServiceId {
    Orchestrator = 0,
    Sensor = 1,
    Detector = 2,
    Tracker = 3,
    Inversion = 4,
    Earth = 5,
}

impl ServiceId {
    pub const SPAWNABLE: [ServiceId; 5] = [
        ServiceId::Sensor,
        ServiceId::Detector,
        ServiceId::Tracker,
        ServiceId::Inversion,
        ServiceId::Earth,
    ];

    pub fn name(self) -> &'static str {
        match self {
            ServiceId::Orchestrator => "orchestrator",
            ServiceId::Sensor => "sensor",
            ServiceId::Detector => "detector",
            ServiceId::Tracker => "tracker",
            ServiceId::Inversion => "inversion",
            ServiceId::Earth => "earth",
        }
    }

    pub fn from_name(name: &str) -> Option<Self> {
        [ServiceId::Orchestrator]
            .into_iter()
            .chain(Self::SPAWNABLE)
            .find(|s| s.name() == name)
    }

    pub fn from_u32(v: u32) -> Option<Self> {
        [ServiceId::Orchestrator]
            .into_iter()
            .chain(Self::SPAWNABLE)
            .find(|s| *s as u32 == v)
    }
}

/// Topics of the chain.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[repr(u32)]
pub enum TopicId {
    Frame = 0,
    Spectrum = 1,
    Truth = 2,
    Heartbeat = 3,
    Control = 4,
    Ack = 5,
    Range = 6,
    Detections = 7,
    Tracks = 8,
    Solve = 9,
    EarthFrame = 10,
    EarthAttitude = 11,
}

impl TopicId {
    pub const ALL: [TopicId; 12] = [
        TopicId::Frame,
        TopicId::Spectrum,
        TopicId::Truth,
        TopicId::Heartbeat,
        TopicId::Control,
        TopicId::Ack,
        TopicId::Range,
        TopicId::Detections,
        TopicId::Tracks,
        TopicId::Solve,
        TopicId::EarthFrame,
        TopicId::EarthAttitude,
    ];

    /// Short name used in reports (`topics.<name>`).
    pub fn name(self) -> &'static str {
        match self {
            TopicId::Frame => "frame",
            TopicId::Spectrum => "spectrum",
            TopicId::Truth => "truth",
            TopicId::Heartbeat => "heartbeat",
            TopicId::Control => "control",
            TopicId::Ack => "ack",
            TopicId::Range => "range",
            TopicId::Detections => "detections",
            TopicId::Tracks => "tracks",
            TopicId::Solve => "solve",
            TopicId::EarthFrame => "earth_frame",
            TopicId::EarthAttitude => "earth_attitude",
        }
    }

    /// iceoryx2 service name (the run prefix lives in the iceoryx2 config, not here).
    pub fn service_name(self) -> String {
        format!("glint/{}", self.name())
    }

    pub fn from_u32(v: u32) -> Option<Self> {
        Self::ALL.into_iter().find(|t| *t as u32 == v)
    }
}

/// Per-subscriber buffer of the data topics; also the sim-clock credit window: a producer never
/// has more than this many unacknowledged messages in flight per consumer, so nothing overflows.
/// The frame topic's is [`frame_window`].
pub const SPECTRUM_BUFFER: usize = 32;
pub const TRUTH_BUFFER: usize = 32;
const HEARTBEAT_BUFFER: usize = 64;
const CONTROL_BUFFER: usize = 16;
const ACK_BUFFER: usize = 256;
/// Frames queued per subscriber at most, and at least: 16 frames ride out a consumer's
/// millisecond wake-up tails at 1000 frames/s (with 4, the sensor of a 1024² chain waited for
/// credit a third of the time).
const FRAME_WINDOW_MAX: usize = 16;
const FRAME_WINDOW_MIN: usize = 4;
/// Pixels one subscriber's frame queue may hold, 32 MiB: large frames get fewer slots, so a
/// 4096² deployment does not take gigabytes of shared memory.
const FRAME_QUEUE_BYTES: usize = 32 << 20;

/// The frame topic's subscriber buffer, history (a restarted consumer catches up from it) and
/// sim-clock credit window, for frames of `frame_px` u16 pixels.
pub fn frame_window(frame_px: usize) -> usize {
    (FRAME_QUEUE_BYTES / (2 * frame_px).max(1)).clamp(FRAME_WINDOW_MIN, FRAME_WINDOW_MAX)
}

/// History kept for late joiners (a restarted consumer catches up from it).
pub const SPECTRUM_HISTORY: usize = SPECTRUM_BUFFER;
pub const DETECTIONS_BUFFER: usize = 16;
pub const TRACKS_BUFFER: usize = 16;
pub const EARTH_ATTITUDE_BUFFER: usize = 16;

/// The sim-clock credit window of a produced data topic (its subscriber buffer), for the
/// frame sizes of `scenario`.
pub fn credit_window(topic: TopicId, scenario: &crate::Scenario) -> usize {
    match topic {
        TopicId::Frame => frame_window(scenario.frame_px()),
        TopicId::EarthFrame => frame_window(scenario.earth_px()),
        TopicId::EarthAttitude => EARTH_ATTITUDE_BUFFER,
        TopicId::Spectrum => SPECTRUM_BUFFER,
        TopicId::Truth => TRUTH_BUFFER,
        TopicId::Detections => DETECTIONS_BUFFER,
        TopicId::Tracks => TRACKS_BUFFER,
        TopicId::Heartbeat => HEARTBEAT_BUFFER,
        TopicId::Control => CONTROL_BUFFER,
        TopicId::Ack => ACK_BUFFER,
        // Request/response services: one request in flight per client.
        TopicId::Range | TopicId::Solve => 1,
    }
}

/// Subscribers per data topic: orchestrator, one consumer service, one restart replacement, one tool.
const MAX_DATA_SUBSCRIBERS: usize = 4;
/// Publishers/nodes per many-to-one topic: every service, plus restarts.
const MAX_PEERS: usize = 16;
const MAX_NODES: usize = 24;

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
pub type RangeService = request_response::PortFactory<Ipc, RangeRequest, (), RangeResponse, ()>;
pub type SolveService = request_response::PortFactory<Ipc, SolveRequest, (), SolveResponse, ()>;

/// Opens (or creates) the debris camera's frame topic: `[u16]` pixels with a [`FrameHeader`],
/// frames of `frame_px` pixels (every process of a deployment derives it from the same
/// scenario).
pub fn frame_service(node: &IpcNode, frame_px: usize) -> Result<FrameService, OpenError> {
    frame_service_on(node, TopicId::Frame, frame_px)
}

/// Opens (or creates) the Earth sensor's frame topic, frames of `frame_px` pixels.
pub fn earth_frame_service(node: &IpcNode, frame_px: usize) -> Result<FrameService, OpenError> {
    frame_service_on(node, TopicId::EarthFrame, frame_px)
}

fn frame_service_on(
    node: &IpcNode,
    t: TopicId,
    frame_px: usize,
) -> Result<FrameService, OpenError> {
    let window = frame_window(frame_px);
    node.service_builder(&name(t)?)
        .publish_subscribe::<[u16]>()
        .user_header::<FrameHeader>()
        .max_publishers(2)
        .max_subscribers(MAX_DATA_SUBSCRIBERS)
        .max_nodes(MAX_NODES)
        .subscriber_max_buffer_size(window)
        .subscriber_max_borrowed_samples(2)
        .history_size(window)
        .enable_safe_overflow(true)
        .open_or_create_with_attributes(&contract_verifier(t)?)
        .map_err(|e| err(t, e))
}

fn pubsub<T: std::fmt::Debug + ZeroCopySend>(
    node: &IpcNode,
    t: TopicId,
    publishers: usize,
    subscribers: usize,
    buffer: usize,
    history: usize,
) -> Result<PubSubService<T>, OpenError> {
    node.service_builder(&name(t)?)
        .publish_subscribe::<T>()
        .max_publishers(publishers)
        .max_subscribers(subscribers)
        .max_nodes(MAX_NODES)
        .subscriber_max_buffer_size(buffer)
        .subscriber_max_borrowed_samples(2)
        .history_size(history)
        .enable_safe_overflow(true)
        .open_or_create_with_attributes(&contract_verifier(t)?)
        .map_err(|e| err(t, e))
}

pub fn spectrum_service(node: &IpcNode) -> Result<PubSubService<Spectrum>, OpenError> {
    pubsub(
        node,
        TopicId::Spectrum,
        2,
        MAX_DATA_SUBSCRIBERS,
        SPECTRUM_BUFFER,
        SPECTRUM_HISTORY,
    )
}

pub fn truth_service(node: &IpcNode) -> Result<PubSubService<Truth>, OpenError> {
    pubsub(
        node,
        TopicId::Truth,
        2,
        MAX_DATA_SUBSCRIBERS,
        TRUTH_BUFFER,
        0,
    )
}

pub fn detections_service(node: &IpcNode) -> Result<PubSubService<Detections>, OpenError> {
    pubsub(
        node,
        TopicId::Detections,
        2,
        MAX_DATA_SUBSCRIBERS,
        DETECTIONS_BUFFER,
        DETECTIONS_BUFFER,
    )
}

pub fn tracks_service(node: &IpcNode) -> Result<PubSubService<Tracks>, OpenError> {
    pubsub(
        node,
        TopicId::Tracks,
        2,
        MAX_DATA_SUBSCRIBERS,
        TRACKS_BUFFER,
        0,
    )
}

pub fn earth_attitude_service(node: &IpcNode) -> Result<PubSubService<EarthAttitude>, OpenError> {
    pubsub(
        node,
        TopicId::EarthAttitude,
        2,
        MAX_DATA_SUBSCRIBERS,
        EARTH_ATTITUDE_BUFFER,
        EARTH_ATTITUDE_BUFFER,
    )
}

pub fn heartbeat_service(node: &IpcNode) -> Result<PubSubService<Heartbeat>, OpenError> {
    pubsub(node, TopicId::Heartbeat, MAX_PEERS, 4, HEARTBEAT_BUFFER, 0)
}

pub fn control_service(node: &IpcNode) -> Result<PubSubService<Control>, OpenError> {
    pubsub(node, TopicId::Control, 2, MAX_PEERS, CONTROL_BUFFER, 0)
}

pub fn ack_service(node: &IpcNode) -> Result<PubSubService<Ack>, OpenError> {
    pubsub(node, TopicId::Ack, MAX_PEERS, 4, ACK_BUFFER, 0)
}

/// The laser rangefinder: request/response, served by the sensor.
pub fn range_service(node: &IpcNode) -> Result<RangeService, OpenError> {
    let t = TopicId::Range;
    node.service_builder(&name(t)?)
        .request_response::<RangeRequest, RangeResponse>()
        .max_servers(2)
        .max_clients(4)
        .max_nodes(MAX_NODES)
        .max_active_requests_per_client(8)
        .max_response_buffer_size(4)
        .enable_safe_overflow_for_requests(false)
        .enable_safe_overflow_for_responses(false)
        .open_or_create_with_attributes(&contract_verifier(t)?)
        .map_err(|e| err(t, e))
}

/// The inversion's solve calls: request/response, served by the inversion.
pub fn solve_service(node: &IpcNode) -> Result<SolveService, OpenError> {
    let t = TopicId::Solve;
    node.service_builder(&name(t)?)
        .request_response::<SolveRequest, SolveResponse>()
        .max_servers(2)
        .max_clients(2)
        .max_nodes(MAX_NODES)
        .max_active_requests_per_client(2)
        .max_response_buffer_size(2)
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

/// Creates every service of the contract (the orchestrator does this before spawning children),
/// with the frame sizes of `scenario`.
pub fn create_all(
    node: &IpcNode,
    scenario: &crate::Scenario,
) -> Result<Vec<Box<dyn std::any::Any>>, OpenError> {
    create_all_sized(node, scenario.frame_px(), scenario.earth_px())
}

/// [`create_all`] for camera frames of `frame_px` and Earth frames of `earth_px` pixels.
pub fn create_all_sized(
    node: &IpcNode,
    frame_px: usize,
    earth_px: usize,
) -> Result<Vec<Box<dyn std::any::Any>>, OpenError> {
    let mut keep: Vec<Box<dyn std::any::Any>> = vec![
        Box::new(frame_service(node, frame_px)?),
        Box::new(earth_frame_service(node, earth_px)?),
        Box::new(earth_attitude_service(node)?),
        Box::new(spectrum_service(node)?),
        Box::new(truth_service(node)?),
        Box::new(heartbeat_service(node)?),
        Box::new(control_service(node)?),
        Box::new(ack_service(node)?),
        Box::new(range_service(node)?),
        Box::new(detections_service(node)?),
        Box::new(tracks_service(node)?),
    ];
    for t in TopicId::ALL {
        keep.push(Box::new(event_service(node, t, false)?));
    }
    keep.push(Box::new(solve_service(node)?));
    keep.push(Box::new(event_service(node, TopicId::Range, true)?));
    keep.push(Box::new(event_service(node, TopicId::Solve, true)?));
    Ok(keep)
}
