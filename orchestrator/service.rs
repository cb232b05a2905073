//! `glint service NAME`: one service of the table in this process, on the service skeleton.

use anyhow::{bail, Result};
use glint_runtime::{run_service, ServiceArgs};
use shared_types::ServiceId;

/// Runs service `id` until `Shutdown` or a termination signal: the one place a service of the
/// table is bound to the node type of its crate.
pub fn run(id: ServiceId, args: ServiceArgs<'_>) -> Result<()> {
    match id {
        ServiceId::Sensor => run_service::<glint_sensor::node::SensorNode>(args),
        ServiceId::Detector => run_service::<glint_detector::node::DetectorNode>(args),
        ServiceId::Tracker => run_service::<glint_tracker::node::TrackerNode>(args),
        ServiceId::Inversion => run_service::<glint_inversion::node::InversionNode>(args),
        ServiceId::Earth => run_service::<glint_earth::node::EarthNode>(args),
        ServiceId::Orchestrator => bail!("the orchestrator is `glint run`, not a service"),
    }
}
