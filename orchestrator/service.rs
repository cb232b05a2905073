//! `glint service NAME`: one service of the table in this process, on the service skeleton.

use anyhow::{bail, Result};
use glint_runtime::{run_service, ServiceArgs};
use shared_types::ServiceId;

/// Runs service `id` until `Shutdown` or a termination signal: the one place a service of the
/// table is bound to the node type of its crate.
pub fn run(id: ServiceId, args: ServiceArgs<'_>, host: Option<&str>) -> Result<()> {
    match id {
        ServiceId::Sensor => run_service::<glint_sensor::node::SensorNode>(args),
        ServiceId::Detector => run_service::<glint_detector::node::DetectorNode>(args),
        ServiceId::Tracker => run_service::<glint_tracker::node::TrackerNode>(args),
        ServiceId::Inversion => run_service::<glint_inversion::node::InversionNode>(args),
        ServiceId::Earth => run_service::<glint_earth::node::EarthNode>(args),
        ServiceId::RelNav => run_service::<glint_relnav::node::RelNavNode>(args),
        ServiceId::Photometry => run_service::<glint_photometry::node::PhotometryNode>(args),
        ServiceId::Bridge => bridge(args, host),
        ServiceId::Orchestrator => bail!("the orchestrator is `glint run`, not a service"),
    }
}

/// One host's bridge of a deployment split across hosts.
#[cfg(feature = "hosts")]
fn bridge(args: ServiceArgs<'_>, host: Option<&str>) -> Result<()> {
    let Some(host) = host else {
        bail!("the bridge runs with --host NAME (a host of the scenario's [hosts])");
    };
    glint_bridge::node::run(args.prefix, args.scenario, host)
}

#[cfg(not(feature = "hosts"))]
fn bridge(_: ServiceArgs<'_>, _: Option<&str>) -> Result<()> {
    bail!("{}", crate::run::hosts::WITHOUT_HOSTS)
}

/// `glint service NAME --prefix P --scenario FILE [--restarted] [--host NAME]`.
pub(crate) fn command(args: crate::cli::ServiceArgs) -> std::process::ExitCode {
    use std::process::ExitCode;
    let crate::cli::ServiceArgs {
        name,
        prefix,
        scenario,
        restarted,
        host,
    } = args;
    glint_runtime::init_tracing(&name);
    // A service ends with the process that started it (see glint_runtime::lifeline).
    glint_runtime::lifeline::watch_parent();
    let sc = match shared_types::Scenario::from_file(&scenario) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    let args = glint_runtime::ServiceArgs {
        prefix: &prefix,
        scenario: &sc,
        restarted,
    };
    let Some(id) = ServiceId::from_name(&name) else {
        eprintln!(
            "error: unknown service '{name}' (available: {})",
            ServiceId::names()
        );
        return ExitCode::from(2);
    };
    let result = run(id, args, host.as_deref());
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            tracing::error!("{e:#}");
            eprintln!("error: {e:#}");
            ExitCode::from(exit_status(&e))
        }
    }
}

/// 1 for a failed service; the bridge's own status when the orchestrator's host was lost.
fn exit_status(e: &anyhow::Error) -> u8 {
    #[cfg(feature = "hosts")]
    if e.is::<glint_bridge::node::OrchestratorLost>() {
        return glint_bridge::node::EXIT_ORCHESTRATOR_LOST;
    }
    let _ = e;
    1
}
