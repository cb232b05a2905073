//! The rows of the table: every topic and every service of glint, each declared once
//! (docs/architecture.md, "Adding a service").

use super::*;

const DATA_PUBLISHERS: usize = 2;
/// Subscribers per data topic: orchestrator, one consumer service, one restart replacement, one tool.
const DATA_SUBSCRIBERS: usize = 4;
/// Publishers per many-to-one topic, subscribers per one-to-many topic: every service, plus restarts.
const PEERS: usize = 16;

/// A data topic: `buffer` per subscriber, and the last `buffer` messages kept for a late
/// joiner — a restarted consumer, or a restarted bridge that must put on the wire again what
/// its dead incarnation took and never delivered (even a topic only the orchestrator reads
/// crosses hosts when its producer runs elsewhere).
const fn data(buffer: usize) -> Pattern {
    Pattern::Messages {
        publishers: DATA_PUBLISHERS,
        subscribers: DATA_SUBSCRIBERS,
        buffer,
        history: true,
    }
}

/// Every topic, in [`TopicId`] order.
pub const TOPICS: [TopicSpec; 16] = [
    TopicSpec {
        id: TopicId::Frame,
        name: "frame",
        pattern: Pattern::Frames {
            pixels: Scenario::frame_px,
        },
        section: Section::Camera,
        from: From::One(ServiceId::Sensor),
        count: Count::Stream {
            messages: |sc| sc.camera.as_ref().map_or(0, |c| c.frames),
            period_ns: |sc| sc.camera.as_ref().map(|c| c.frame_period_ns().max(1)),
        },
        replay: Replay::Remade,
        truth: Some(Truth::KIND_FRAME),
        about: "debris camera frames ([u16] in place)",
    },
    TopicSpec {
        id: TopicId::Spectrum,
        name: "spectrum",
        pattern: data(32),
        section: Section::Spectra,
        from: From::One(ServiceId::Sensor),
        count: Count::Stream {
            messages: |sc| (sc.spectra.as_ref()).map_or(0, |s| s.stable_samples + s.motion_frames),
            period_ns: |_| None,
        },
        replay: Replay::Remade,
        truth: Some(Truth::KIND_SPECTRUM),
        about: "the satellite's spectrum, one per sample of the stable and motion windows",
    },
    TopicSpec {
        id: TopicId::Truth,
        name: "truth",
        pattern: data(32),
        section: Section::Always,
        from: From::One(ServiceId::Sensor),
        count: Count::Truth,
        replay: Replay::OrchestratorOnly,
        truth: None,
        about: "what the sensor rendered, for scoring (never read by a service)",
    },
    TopicSpec {
        id: TopicId::Heartbeat,
        name: "heartbeat",
        pattern: Pattern::Messages {
            publishers: PEERS,
            subscribers: 4,
            buffer: 64,
            history: false,
        },
        section: Section::Always,
        from: From::Every,
        count: Count::Open,
        replay: Replay::Never,
        truth: None,
        about: "each service's state and counters",
    },
    TopicSpec {
        id: TopicId::Control,
        name: "control",
        pattern: Pattern::Messages {
            publishers: DATA_PUBLISHERS,
            subscribers: PEERS,
            buffer: 16,
            history: false,
        },
        section: Section::Always,
        from: From::One(ServiceId::Orchestrator),
        count: Count::Open,
        replay: Replay::Never,
        truth: None,
        about: "start, pause, shutdown, replay orders, in-band faults",
    },
    TopicSpec {
        id: TopicId::Ack,
        name: "ack",
        pattern: Pattern::Messages {
            publishers: PEERS,
            // Every producer reads the acks of its consumers (the credit).
            subscribers: PEERS,
            buffer: 256,
            history: false,
        },
        section: Section::Always,
        from: From::Every,
        count: Count::Open,
        replay: Replay::Never,
        truth: None,
        about: "what each consumer has taken: the producers' sim-clock credit",
    },
    TopicSpec {
        id: TopicId::Range,
        name: "range",
        pattern: Pattern::Calls {
            clients: 4,
            in_flight: 8,
            responses: 4,
        },
        section: Section::Camera,
        from: From::One(ServiceId::Sensor),
        count: Count::Open,
        replay: Replay::Never,
        truth: None,
        about: "the laser rangefinder: a shot and its echo",
    },
    TopicSpec {
        id: TopicId::Detections,
        name: "detections",
        pattern: data(16),
        section: Section::Camera,
        from: From::One(ServiceId::Detector),
        count: Count::PerInput(TopicId::Frame),
        replay: Replay::Logged,
        truth: None,
        about: "each frame's detections: ellipse features, matched ids, angles",
    },
    TopicSpec {
        id: TopicId::Tracks,
        name: "tracks",
        pattern: data(16),
        section: Section::Camera,
        from: From::One(ServiceId::Tracker),
        count: Count::PerInput(TopicId::Detections),
        replay: Replay::OrchestratorOnly,
        truth: None,
        about: "each frame's tracks: angle filter and CW EKF states",
    },
    TopicSpec {
        id: TopicId::Solve,
        name: "solve",
        pattern: Pattern::Calls {
            clients: 2,
            in_flight: 2,
            responses: 2,
        },
        section: Section::Spectra,
        from: From::One(ServiceId::Inversion),
        count: Count::Open,
        replay: Replay::Never,
        truth: None,
        about: "the three-stage attitude solve, one call per stage",
    },
    TopicSpec {
        id: TopicId::EarthFrame,
        name: "earth_frame",
        pattern: Pattern::Frames {
            pixels: Scenario::earth_px,
        },
        section: Section::Earth,
        from: From::One(ServiceId::Sensor),
        count: Count::Stream {
            messages: |sc| sc.earth.as_ref().map_or(0, |e| e.frames()),
            period_ns: |sc| sc.earth.as_ref().map(|e| e.exposure_end_ns(0).max(1)),
        },
        replay: Replay::Remade,
        truth: Some(Truth::KIND_EARTH),
        about: "fisheye infrared Earth frames ([u16] in place)",
    },
    TopicSpec {
        id: TopicId::EarthAttitude,
        name: "earth_attitude",
        pattern: data(16),
        section: Section::Earth,
        from: From::One(ServiceId::Earth),
        count: Count::PerInput(TopicId::EarthFrame),
        replay: Replay::Logged,
        truth: None,
        about: "each Earth frame's attitude angle β and tilt, per method",
    },
    TopicSpec {
        id: TopicId::Stereo,
        name: "stereo",
        pattern: data(32),
        section: Section::Stereo,
        from: From::One(ServiceId::Sensor),
        count: Count::Stream {
            messages: |sc| sc.stereo.as_ref().map_or(0, |s| s.epochs()),
            period_ns: |sc| {
                (sc.stereo.as_ref()).map(|s| ((s.epoch_period_s * 1e9).round() as u64).max(1))
            },
        },
        replay: Replay::Remade,
        truth: Some(Truth::KIND_STEREO),
        about: "the stereo rig's epochs: every feature seen, normalised image coordinates",
    },
    TopicSpec {
        id: TopicId::RelNav,
        name: "relnav",
        pattern: data(16),
        section: Section::Stereo,
        from: From::One(ServiceId::RelNav),
        count: Count::PerInput(TopicId::Stereo),
        replay: Replay::OrchestratorOnly,
        truth: None,
        about: "each epoch's relative pose, rates, inertia ratios and covariance",
    },
    TopicSpec {
        id: TopicId::Photometry,
        name: "photometry",
        pattern: data(64),
        section: Section::Photometry,
        from: From::One(ServiceId::Sensor),
        count: Count::Stream {
            messages: |sc| sc.photometry.as_ref().map_or(0, |p| p.samples()),
            period_ns: |sc| {
                (sc.photometry.as_ref()).map(|p| ((p.cadence_s * 1e9).round() as u64).max(1))
            },
        },
        replay: Replay::Remade,
        truth: Some(Truth::KIND_PHOTOMETRY),
        about: "the telescope's light curve: magnitude, σ, Sun and observer, range (or a gap)",
    },
    TopicSpec {
        id: TopicId::PhotometryEstimate,
        name: "photometry_estimate",
        pattern: data(16),
        section: Section::Photometry,
        from: From::One(ServiceId::Photometry),
        count: Count::PerInput(TopicId::Photometry),
        replay: Replay::OrchestratorOnly,
        truth: None,
        about: "each sample's identification (geometry, axis, spin, size) and UKF attitude",
    },
];

/// Every service, in [`ServiceId`] order (also the order they are started in).
pub const SERVICES: [ServiceSpec; 9] = [
    ServiceSpec {
        id: ServiceId::Orchestrator,
        name: "orchestrator",
        section: Section::Always,
        // It reads every data topic: accounting, digests, and what the report scores.
        inputs: &[
            TopicId::Frame,
            TopicId::Spectrum,
            TopicId::Truth,
            TopicId::Detections,
            TopicId::Tracks,
            TopicId::EarthFrame,
            TopicId::EarthAttitude,
            TopicId::Stereo,
            TopicId::RelNav,
            TopicId::Photometry,
            TopicId::PhotometryEstimate,
        ],
        outputs: &[TopicId::Control],
        calls: &[TopicId::Solve],
        code: "glint (orchestrator/)",
        about: "deploys, supervises, sequences the solve, injects faults, reports",
    },
    ServiceSpec {
        id: ServiceId::Sensor,
        name: "sensor",
        section: Section::Always,
        inputs: &[],
        outputs: &[
            TopicId::Frame,
            TopicId::Spectrum,
            TopicId::EarthFrame,
            TopicId::Stereo,
            TopicId::Photometry,
            TopicId::Truth,
            TopicId::Range,
        ],
        calls: &[],
        code: "glint-sensor",
        about: "renders every stream of the scenario into shared memory; the laser",
    },
    ServiceSpec {
        id: ServiceId::Detector,
        name: "detector",
        section: Section::Camera,
        inputs: &[TopicId::Frame],
        outputs: &[TopicId::Detections],
        calls: &[],
        code: "glint-detector",
        about: "[002] streak detection, second-moment features, inter-frame matching",
    },
    ServiceSpec {
        id: ServiceId::Tracker,
        name: "tracker",
        section: Section::Camera,
        inputs: &[TopicId::Detections],
        outputs: &[TopicId::Tracks],
        calls: &[TopicId::Range],
        code: "glint-tracker",
        about: "[002] angle filter, laser pointing, CW EKF",
    },
    ServiceSpec {
        id: ServiceId::Inversion,
        name: "inversion",
        section: Section::Spectra,
        inputs: &[TopicId::Spectrum],
        outputs: &[TopicId::Solve],
        calls: &[],
        code: "glint-inversion",
        about: "[000] three-stage attitude solve from spectra",
    },
    ServiceSpec {
        id: ServiceId::Earth,
        name: "earth",
        section: Section::Earth,
        inputs: &[TopicId::EarthFrame],
        outputs: &[TopicId::EarthAttitude],
        calls: &[],
        code: "glint-earth",
        about: "[003] attitude angle from infrared Earth frames",
    },
    ServiceSpec {
        id: ServiceId::RelNav,
        name: "relnav",
        section: Section::Stereo,
        inputs: &[TopicId::Stereo],
        outputs: &[TopicId::RelNav],
        calls: &[],
        code: "glint-relnav",
        about: "[004] relative pose, rates and inertia ratios of a tumbling target",
    },
    ServiceSpec {
        id: ServiceId::Photometry,
        name: "photometry",
        section: Section::Photometry,
        inputs: &[TopicId::Photometry],
        outputs: &[TopicId::PhotometryEstimate],
        calls: &[],
        code: "glint-photometry",
        about: "[001] geometry, spin and size from a light curve; attitude by a UKF",
    },
    ServiceSpec {
        id: ServiceId::Bridge,
        name: "bridge",
        section: Section::Hosts,
        // What it carries is not its own: the topics whose producer and consumers the scenario
        // places on different hosts (glint-bridge's routes), each counted per hop.
        inputs: &[],
        outputs: &[],
        calls: &[],
        code: "glint-bridge",
        about: "carries the topics that cross hosts over Zenoh, every message counted per hop",
    },
];
