//! The table of glint's services and topics: the one place each is declared.
//!
//! A topic row ([`TopicSpec`]) says what it carries, who produces it, how many messages a run
//! carries, how deep its queues are, and how a restarted consumer gets its messages again. A
//! service row ([`ServiceSpec`]) says which scenario section deploys it, what it consumes and
//! what it produces. Everything else reads these rows: the openers and their QoS
//! ([`crate::topics`]), who consumes what and how many messages to expect
//! ([`crate::deployment`]), the sim-clock credit, the replay orders after a restart, the fault
//! triggers and targets, the orchestrator's taps, the report's accounting, validation's
//! messages, the CLI's list of services.
//!
//! [`visit`] is the one place a topic is bound to its Rust payload type; code that must handle
//! every topic generically (create every service, tap every topic, record every topic) is a
//! [`PayloadVisitor`].
//!
//! Adding a service or a topic: docs/architecture.md, "Adding a service".

use crate::messages::*;
use crate::scenario::Scenario;

mod check;
mod rows;
pub use check::check;
pub use rows::{SERVICES, TOPICS};

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
    RelNav = 6,
    Photometry = 7,
    /// One per host of a split deployment: carries the topics that cross hosts (ADR 0038).
    Bridge = 8,
}

/// Topics of the chain. The numeric value travels in [`Ack::topic`] and the heartbeats' counters.
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
    Stereo = 12,
    RelNav = 13,
    Photometry = 14,
    PhotometryEstimate = 15,
}

/// The scenario section a service or topic exists with.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Section {
    /// Every deployment.
    Always,
    /// `[camera]`: the debris camera ([002]).
    Camera,
    /// `[spectra]`: the satellite's spectra ([000]).
    Spectra,
    /// `[earth]`: the infrared Earth sensor ([003]).
    Earth,
    /// `[stereo]`: the stereo rig and the tumbling target ([004]).
    Stereo,
    /// `[photometry]`: the ground telescope's light curve ([001]).
    Photometry,
    /// `[hosts]`: a deployment split across machines.
    Hosts,
}

impl Section {
    /// Whether `scenario` has this section.
    pub fn present(self, scenario: &Scenario) -> bool {
        match self {
            Section::Always => true,
            Section::Camera => scenario.camera.is_some(),
            Section::Spectra => scenario.spectra.is_some(),
            Section::Earth => scenario.earth.is_some(),
            Section::Stereo => scenario.stereo.is_some(),
            Section::Photometry => scenario.photometry.is_some(),
            Section::Hosts => scenario.split(),
        }
    }

    /// How a scenario file names it.
    pub fn name(self) -> &'static str {
        match self {
            Section::Always => "(always)",
            Section::Camera => "[camera]",
            Section::Spectra => "[spectra]",
            Section::Earth => "[earth]",
            Section::Stereo => "[stereo]",
            Section::Photometry => "[photometry]",
            Section::Hosts => "[hosts]",
        }
    }
}

/// How a topic moves its messages, and the sizes of its ports.
#[derive(Debug, Clone, Copy)]
pub enum Pattern {
    /// `[u16]` pixels with a [`FrameHeader`], rendered into the loaned sample and read in
    /// place. Its queue, history and credit window are sized from the frame
    /// ([`crate::topics::frame_window`]).
    Frames {
        /// Pixels of one frame in a scenario (0 without the section).
        pixels: fn(&Scenario) -> usize,
    },
    /// One fixed-size message per sample.
    Messages {
        publishers: usize,
        subscribers: usize,
        /// Per-subscriber queue, and the sim-clock credit window of a produced data topic.
        buffer: usize,
        /// Kept for late joiners: a restarted consumer (or bridge) finds the last `buffer`
        /// messages.
        history: bool,
    },
    /// Request/response with a reply event: the producer serves, `clients` call.
    Calls {
        clients: usize,
        /// Requests one client may have in flight.
        in_flight: usize,
        /// Responses queued per client.
        responses: usize,
    },
}

/// Who publishes a topic.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum From {
    /// One service (a data topic's producer, a call's server).
    One(ServiceId),
    /// Every service (heartbeats, acknowledgements).
    Every,
}

/// How many messages a topic carries over a run.
#[derive(Debug, Clone, Copy)]
pub enum Count {
    /// A stream the sensor produces: the scenario says how many messages, and in realtime
    /// mode how often (message `k` is due `k · period` after `Start`; `None`: as fast as
    /// its consumers take them).
    Stream {
        messages: fn(&Scenario) -> u64,
        period_ns: fn(&Scenario) -> Option<u64>,
    },
    /// One message per message of `input` its producer processed (a dropped input makes none).
    PerInput(TopicId),
    /// One per message of every stream that carries truth ([`TopicSpec::truth`]).
    Truth,
    /// Housekeeping and calls: as many as the run needs; not held to a count.
    Open,
}

/// How a topic's messages reach a consumer that restarted (docs/adr/0032).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Replay {
    /// The producer makes them again, byte for byte, from the scenario and the seed.
    Remade,
    /// The producer keeps every message it sent and sends them again.
    Logged,
    /// Not replayed: read only by the orchestrator, which is never restarted.
    OrchestratorOnly,
    /// Not replayed: housekeeping (a restarted service joins at the current seq) or a call
    /// (its client sends it again).
    Never,
}

/// One topic.
#[derive(Debug, Clone, Copy)]
pub struct TopicSpec {
    pub id: TopicId,
    /// Short name: `topics.<name>` in reports, `glint/<name>` in iceoryx2.
    pub name: &'static str,
    pub pattern: Pattern,
    /// The section it exists with.
    pub section: Section,
    pub from: From,
    pub count: Count,
    pub replay: Replay,
    /// The sensor publishes one truth message with each of its messages (scoring), of this
    /// kind ([`Truth::kind`](crate::Truth)).
    pub truth: Option<u32>,
    /// What it carries, for people.
    pub about: &'static str,
}

/// One service (a process of the deployment).
#[derive(Debug, Clone, Copy)]
pub struct ServiceSpec {
    pub id: ServiceId,
    /// `glint service <name>`, `[supervision.services.<name>]`, `--fault <name>:…`.
    pub name: &'static str,
    /// The section that deploys it.
    pub section: Section,
    /// Data topics it consumes and acknowledges (replayed to it after a restart), main first:
    /// an `at_seq` fault fires on the first.
    pub inputs: &'static [TopicId],
    /// Topics it publishes or serves, main first: in-band drops and corruptions hit the first
    /// present; a source's `at_seq` fault fires on it.
    pub outputs: &'static [TopicId],
    /// Calls it makes.
    pub calls: &'static [TopicId],
    /// The crate of its pure core and node.
    pub code: &'static str,
    /// What it does, for people.
    pub about: &'static str,
}

impl ServiceId {
    pub const ALL: [ServiceId; 9] = {
        let mut all = [ServiceId::Orchestrator; 9];
        let mut i = 0;
        while i < SERVICES.len() {
            all[i] = SERVICES[i].id;
            i += 1;
        }
        all
    };

    /// The services `glint run` spawns (every one but the orchestrator).
    pub fn spawnable() -> impl Iterator<Item = ServiceId> {
        Self::ALL
            .into_iter()
            .filter(|s| *s != ServiceId::Orchestrator)
    }

    pub fn spec(self) -> &'static ServiceSpec {
        &SERVICES[self as usize]
    }

    pub fn name(self) -> &'static str {
        self.spec().name
    }

    pub fn from_name(name: &str) -> Option<Self> {
        SERVICES.iter().find(|s| s.name == name).map(|s| s.id)
    }

    pub fn from_u32(v: u32) -> Option<Self> {
        Self::ALL.get(v as usize).copied()
    }

    /// The spawnable services' names, `a, b, c`, for messages.
    pub fn names() -> String {
        Self::spawnable()
            .map(|s| s.name())
            .collect::<Vec<_>>()
            .join(", ")
    }
}

impl TopicId {
    pub const ALL: [TopicId; 16] = {
        let mut all = [TopicId::Frame; 16];
        let mut i = 0;
        while i < TOPICS.len() {
            all[i] = TOPICS[i].id;
            i += 1;
        }
        all
    };

    pub fn spec(self) -> &'static TopicSpec {
        &TOPICS[self as usize]
    }

    /// Short name used in reports (`topics.<name>`).
    pub fn name(self) -> &'static str {
        self.spec().name
    }

    /// iceoryx2 service name (the run prefix lives in the iceoryx2 config, not here).
    pub fn service_name(self) -> String {
        format!("glint/{}", self.name())
    }

    pub fn from_u32(v: u32) -> Option<Self> {
        Self::ALL.get(v as usize).copied()
    }

    pub fn from_name(name: &str) -> Option<Self> {
        TOPICS.iter().find(|t| t.name == name).map(|t| t.id)
    }
}

impl TopicSpec {
    /// The service that publishes or serves it, if one does.
    pub fn producer(&self) -> Option<ServiceId> {
        match self.from {
            From::One(s) => Some(s),
            From::Every => None,
        }
    }

    /// Whether it carries data the run accounts for (a count the scenario fixes).
    pub fn is_data(&self) -> bool {
        !matches!(self.count, Count::Open)
    }
}

/// Code that handles every topic generically, given its payload type.
pub trait PayloadVisitor {
    type Out;
    /// `[u16]` pixels with a [`FrameHeader`].
    fn frames(self, spec: &'static TopicSpec) -> Self::Out;
    /// Messages of type `T`.
    fn messages<T: Message>(self, spec: &'static TopicSpec) -> Self::Out;
    /// Requests of type `Req` answered by `Resp`.
    fn calls<Req: Message, Resp: Message>(self, spec: &'static TopicSpec) -> Self::Out;
}

/// Calls `v` with `topic`'s payload type: the one place a topic is bound to its Rust type.
pub fn visit<V: PayloadVisitor>(topic: TopicId, v: V) -> V::Out {
    let spec = topic.spec();
    match topic {
        TopicId::Frame | TopicId::EarthFrame => v.frames(spec),
        TopicId::Spectrum => v.messages::<Spectrum>(spec),
        TopicId::Truth => v.messages::<Truth>(spec),
        TopicId::Heartbeat => v.messages::<Heartbeat>(spec),
        TopicId::Control => v.messages::<Control>(spec),
        TopicId::Ack => v.messages::<Ack>(spec),
        TopicId::Detections => v.messages::<Detections>(spec),
        TopicId::Tracks => v.messages::<Tracks>(spec),
        TopicId::EarthAttitude => v.messages::<EarthAttitude>(spec),
        TopicId::Stereo => v.messages::<Stereo>(spec),
        TopicId::RelNav => v.messages::<RelNavEstimate>(spec),
        TopicId::Photometry => v.messages::<PhotometrySample>(spec),
        TopicId::PhotometryEstimate => v.messages::<PhotometryEstimate>(spec),
        TopicId::Range => v.calls::<RangeRequest, RangeResponse>(spec),
        TopicId::Solve => v.calls::<SolveRequest, SolveResponse>(spec),
    }
}

/// The contract type name of a topic's payload (a call's request).
pub fn payload_type_name(topic: TopicId) -> &'static str {
    struct Name;
    impl PayloadVisitor for Name {
        type Out = &'static str;
        fn frames(self, _: &'static TopicSpec) -> &'static str {
            // SAFETY: `type_name` only returns the `#[type_name]` string.
            unsafe { <FrameHeader as iceoryx2::prelude::ZeroCopySend>::type_name() }
        }
        fn messages<T: Message>(self, _: &'static TopicSpec) -> &'static str {
            // SAFETY: as above.
            unsafe { <T as iceoryx2::prelude::ZeroCopySend>::type_name() }
        }
        fn calls<Req: Message, Resp: Message>(self, _: &'static TopicSpec) -> &'static str {
            // SAFETY: as above.
            unsafe { <Req as iceoryx2::prelude::ZeroCopySend>::type_name() }
        }
    }
    visit(topic, Name)
}
