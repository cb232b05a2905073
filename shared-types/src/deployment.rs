//! Who runs and who consumes what, derived from the scenario alone, so the orchestrator and
//! every producer agree without passing lists around.

use crate::scenario::Scenario;
use crate::topics::{ServiceId, TopicId};

/// Services the orchestrator spawns for a scenario, in start order.
pub fn services(scenario: &Scenario) -> Vec<ServiceId> {
    let _ = scenario;
    vec![ServiceId::Sensor]
}

/// Consumers whose acknowledgement a producer waits for in sim-clock mode (and whose counters
/// the report checks).
pub fn consumers(scenario: &Scenario, topic: TopicId) -> Vec<ServiceId> {
    match topic {
        TopicId::Frame if scenario.camera.is_some() => vec![ServiceId::Orchestrator],
        TopicId::Spectrum if scenario.spectra.is_some() => vec![ServiceId::Orchestrator],
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
    match topic {
        TopicId::Frame => frames,
        TopicId::Spectrum => spectra,
        TopicId::Truth => frames + spectra,
        _ => 0,
    }
}
