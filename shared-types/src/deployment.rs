//! Who runs and who consumes what, derived from the scenario alone, so the orchestrator and
//! every producer agree without passing lists around.

use crate::scenario::Scenario;
use crate::topics::{ServiceId, TopicId};

/// Services the orchestrator spawns for a scenario, in start order.
pub fn services(scenario: &Scenario) -> Vec<ServiceId> {
    let mut v = vec![ServiceId::Sensor];
    if scenario.camera.is_some() {
        v.extend([ServiceId::Detector, ServiceId::Tracker]);
    }
    if scenario.spectra.is_some() {
        v.push(ServiceId::Inversion);
    }
    if scenario.earth.is_some() {
        v.push(ServiceId::Earth);
    }
    v
}

/// Consumers whose acknowledgement a producer waits for in sim-clock mode (and whose counters
/// the report checks).
pub fn consumers(scenario: &Scenario, topic: TopicId) -> Vec<ServiceId> {
    match topic {
        // The orchestrator reads frame headers only (accounting and the digest); the detector
        // reads the pixels.
        TopicId::Frame if scenario.camera.is_some() => {
            vec![ServiceId::Detector, ServiceId::Orchestrator]
        }
        TopicId::Detections if scenario.camera.is_some() => {
            vec![ServiceId::Tracker, ServiceId::Orchestrator]
        }
        TopicId::Tracks if scenario.camera.is_some() => vec![ServiceId::Orchestrator],
        TopicId::Spectrum if scenario.spectra.is_some() => {
            vec![ServiceId::Inversion, ServiceId::Orchestrator]
        }
        // The orchestrator reads Earth frame headers (accounting, the digest, one frame for the
        // annotated picture); the earth service reads the pixels.
        TopicId::EarthFrame if scenario.earth.is_some() => {
            vec![ServiceId::Earth, ServiceId::Orchestrator]
        }
        TopicId::EarthAttitude if scenario.earth.is_some() => vec![ServiceId::Orchestrator],
        TopicId::Truth => vec![ServiceId::Orchestrator],
        _ => vec![],
    }
}

/// Messages the sensor will publish on a topic over the whole run.
pub fn expected_messages(scenario: &Scenario, topic: TopicId) -> u64 {
    let frames = scenario.camera.as_ref().map_or(0, |c| c.frames);
    let spectra = scenario
        .spectra
        .as_ref()
        .map_or(0, |s| s.stable_samples + s.motion_frames);
    let earth = scenario.earth.as_ref().map_or(0, |e| e.frames());
    match topic {
        TopicId::Frame | TopicId::Detections | TopicId::Tracks => frames,
        TopicId::Spectrum => spectra,
        TopicId::EarthFrame | TopicId::EarthAttitude => earth,
        TopicId::Truth => frames + spectra + earth,
        _ => 0,
    }
}

/// The service that publishes a data topic (the sensor publishes frames, Earth frames, spectra
/// and truth).
pub fn producer(topic: TopicId) -> ServiceId {
    match topic {
        TopicId::Detections => ServiceId::Detector,
        TopicId::Tracks => ServiceId::Tracker,
        TopicId::EarthAttitude => ServiceId::Earth,
        _ => ServiceId::Sensor,
    }
}

/// The data topics `service` consumes in this scenario.
pub fn inputs(scenario: &Scenario, service: ServiceId) -> Vec<TopicId> {
    [
        TopicId::Frame,
        TopicId::Spectrum,
        TopicId::Truth,
        TopicId::Detections,
        TopicId::Tracks,
        TopicId::EarthFrame,
        TopicId::EarthAttitude,
    ]
    .into_iter()
    .filter(|t| consumers(scenario, *t).contains(&service))
    .collect()
}
