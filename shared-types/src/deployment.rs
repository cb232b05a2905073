//! Who runs and who consumes what, derived from the scenario and the table
//! ([`crate::table`]) alone, so the orchestrator and every producer agree without passing
//! lists around.

use crate::scenario::Scenario;
use crate::table::{Count, TopicSpec, SERVICES, TOPICS};
use crate::topics::{ServiceId, TopicId};

/// Whether `scenario` deploys `service`.
/// A replay (`[replay]`) deploys the consumers it names.
pub fn deploys(scenario: &Scenario, service: ServiceId) -> bool {
    service.spec().section.present(scenario)
        && scenario.replay.as_ref().is_none_or(|r| r.runs(service))
}

/// Whether the call `call` is made in `scenario`: it is carried and its client calls it (the
/// tracker's laser only when `camera.tracker.laser` is on).
pub fn calls_made(scenario: &Scenario, call: TopicId) -> bool {
    let made = match call {
        TopicId::Range => (scenario.camera.as_ref()).is_some_and(|c| c.tracker.laser),
        TopicId::Solve => true,
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
        | TopicId::PhotometryEstimate => false,
    };
    made && carries(scenario, call)
}

/// The services that call `call` in `scenario` (its clients; the orchestrator calls `solve`).
pub fn callers(scenario: &Scenario, call: TopicId) -> Vec<ServiceId> {
    if !calls_made(scenario, call) {
        return vec![];
    }
    std::iter::once(ServiceId::Orchestrator)
        .chain(services(scenario))
        .filter(|s| s.spec().calls.contains(&call))
        .collect()
}

/// Whether `topic` exists in `scenario` (its section is there).
/// A topic whose producer a replay leaves out is not carried.
pub fn carries(scenario: &Scenario, topic: TopicId) -> bool {
    let spec = topic.spec();
    spec.section.present(scenario)
        && spec.producer().is_none_or(|p| {
            p == ServiceId::Orchestrator || p == ServiceId::Sensor || deploys(scenario, p)
        })
}

/// Services the orchestrator spawns for a scenario, in start order.
pub fn services(scenario: &Scenario) -> Vec<ServiceId> {
    ServiceId::spawnable()
        .filter(|s| deploys(scenario, *s))
        .collect()
}

/// Consumers whose acknowledgement a producer waits for in sim-clock mode (and whose counters
/// the report checks): every deployed service that lists `topic` among its inputs.
pub fn consumers(scenario: &Scenario, topic: TopicId) -> Vec<ServiceId> {
    if !carries(scenario, topic) {
        return vec![];
    }
    SERVICES
        .iter()
        .filter(|s| s.inputs.contains(&topic) && deploys(scenario, s.id))
        .map(|s| s.id)
        .collect()
}

/// Messages a topic carries over the whole run (0 for housekeeping and calls).
pub fn expected_messages(scenario: &Scenario, topic: TopicId) -> u64 {
    let spec = topic.spec();
    if !carries(scenario, topic) {
        return 0;
    }
    match spec.count {
        Count::Stream { messages, .. } => messages(scenario),
        Count::PerInput(input) => expected_messages(scenario, input),
        Count::Truth => TOPICS
            .iter()
            .filter(|t| t.truth.is_some())
            .map(|t| expected_messages(scenario, t.id))
            .sum(),
        Count::Open => 0,
    }
}

/// In realtime mode, how often the sensor sends message `k + 1` of `topic` after message `k`
/// [ns]: message `k` is due `k · period` after `Start`. `None`: a stream paced by its
/// consumers alone, or not a stream.
pub fn realtime_period_ns(scenario: &Scenario, topic: TopicId) -> Option<u64> {
    match topic.spec().count {
        Count::Stream { period_ns, .. } => period_ns(scenario),
        Count::PerInput(_) | Count::Truth | Count::Open => None,
    }
}

/// The service that publishes a data topic (or serves a call).
pub fn producer(topic: TopicId) -> Option<ServiceId> {
    topic.spec().producer()
}

/// The data topics `service` consumes in this scenario.
pub fn inputs(scenario: &Scenario, service: ServiceId) -> Vec<TopicId> {
    if !deploys(scenario, service) {
        return vec![];
    }
    (service.spec().inputs.iter())
        .copied()
        .filter(|t| carries(scenario, *t))
        .collect()
}

/// The topics `service` publishes or serves in this scenario, main first.
pub fn outputs(scenario: &Scenario, service: ServiceId) -> Vec<TopicId> {
    if !deploys(scenario, service) {
        return vec![];
    }
    (service.spec().outputs.iter())
        .copied()
        .filter(|t| carries(scenario, *t))
        .collect()
}

/// The topic whose progress triggers an `at_seq` fault of `service`: its main input; for a
/// source (the sensor), its main output; for the bridge, the first data topic that crosses
/// hosts.
pub fn trigger_topic(scenario: &Scenario, service: ServiceId) -> Option<TopicId> {
    let mut inputs = inputs(scenario, service).into_iter();
    inputs
        .next()
        .or_else(|| outputs(scenario, service).into_iter().next())
        .or_else(|| crossing(scenario))
}

/// The first data topic whose producer and a consumer run on different hosts: what a service
/// with no topics of its own (the bridge) is counted by.
fn crossing(scenario: &Scenario) -> Option<TopicId> {
    let home = |s: ServiceId| scenario.host_of(s);
    (data_topics(scenario).into_iter())
        .find(|t| {
            let from = producer(t.id).map(home);
            consumers(scenario, t.id)
                .into_iter()
                .any(|c| Some(home(c)) != from)
        })
        .map(|t| t.id)
}

/// The output an in-band `drop` or `corrupt` fault of `service` hits: its main output.
pub fn fault_output(scenario: &Scenario, service: ServiceId) -> Option<TopicId> {
    outputs(scenario, service).into_iter().next()
}

/// The data topics of the scenario (those it accounts for), in table order.
pub fn data_topics(scenario: &Scenario) -> Vec<&'static TopicSpec> {
    TOPICS
        .iter()
        .filter(|t| t.is_data() && expected_messages(scenario, t.id) > 0)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scenario(file: &str) -> Scenario {
        let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios/");
        let text = std::fs::read_to_string(format!("{dir}{file}")).unwrap();
        Scenario::from_toml_str(&text, file).unwrap()
    }

    #[test]
    fn the_debris_chain_is_derived_from_the_table() {
        let sc = scenario("debris-geo.toml");
        let frames = sc.camera.as_ref().unwrap().frames;
        assert_eq!(
            services(&sc),
            [ServiceId::Sensor, ServiceId::Detector, ServiceId::Tracker]
        );
        assert_eq!(
            consumers(&sc, TopicId::Frame),
            [ServiceId::Orchestrator, ServiceId::Detector]
        );
        assert_eq!(consumers(&sc, TopicId::Tracks), [ServiceId::Orchestrator]);
        assert_eq!(consumers(&sc, TopicId::Spectrum), []);
        for t in [
            TopicId::Frame,
            TopicId::Detections,
            TopicId::Tracks,
            TopicId::Truth,
        ] {
            assert_eq!(expected_messages(&sc, t), frames, "{t:?}");
        }
        assert_eq!(expected_messages(&sc, TopicId::Heartbeat), 0);
        assert_eq!(producer(TopicId::Detections), Some(ServiceId::Detector));
        assert_eq!(producer(TopicId::Heartbeat), None);
        assert_eq!(inputs(&sc, ServiceId::Tracker), [TopicId::Detections]);
        assert_eq!(
            trigger_topic(&sc, ServiceId::Sensor),
            Some(TopicId::Frame),
            "a source's trigger is its main output"
        );
        assert_eq!(fault_output(&sc, ServiceId::Tracker), Some(TopicId::Tracks));
        assert_eq!(trigger_topic(&sc, ServiceId::Earth), None, "not deployed");
    }

    #[test]
    fn the_sensor_main_output_follows_the_sections() {
        let sc = scenario("geo-hover-yspin.toml");
        assert!(sc.camera.is_none() && sc.spectra.is_some());
        assert_eq!(
            trigger_topic(&sc, ServiceId::Sensor),
            Some(TopicId::Spectrum)
        );
        assert_eq!(
            fault_output(&sc, ServiceId::Inversion),
            Some(TopicId::Solve)
        );
        let sp = sc.spectra.as_ref().unwrap();
        assert_eq!(
            expected_messages(&sc, TopicId::Truth),
            sp.stable_samples + sp.motion_frames
        );
        let earth = scenario("earth-sensor-turntable.toml");
        assert_eq!(
            trigger_topic(&earth, ServiceId::Sensor),
            Some(TopicId::EarthFrame)
        );
        assert_eq!(
            consumers(&earth, TopicId::EarthAttitude),
            [ServiceId::Orchestrator]
        );
    }
}
