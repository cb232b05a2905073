//! A deployment split across hosts (`[hosts]`, ADR 0038): which part `glint run --host` runs,
//! and the part of every host but the orchestrator's — its services and its bridge, run until
//! the orchestrator of record ends the run over the bridge (its `Shutdown` arrives like any
//! control message), then stopped with the ladder, the bridge last so that the services' last
//! heartbeats reach the orchestrator. The bridge is supervised here as `[supervision]` says
//! (once it was first ready): killed or hung, it is restarted, and the other hosts' bridges put
//! again what it may have lost; a service of this host that fails ends the part (its restart
//! needs replay orders only the orchestrator's host gives).

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use glint_runtime::ports::Inbox;
use glint_runtime::{open_node, remove_shm, run_loop, Step};
use shared_types::{deployment, Command, Control, Heartbeat, Scenario, ServiceId, TopicId};

use crate::report::FaultReport;
use crate::run::deploy::{stop_ladder, Ending, ServiceProcess};
use crate::run::keeper::Keeper;

/// What `glint run --host` says when glint was built without the bridge.
pub const WITHOUT_HOSTS: &str = "this glint was built without the `hosts` feature, which a \
     deployment split across hosts needs: cargo build --release --features hosts";

/// The host `glint run` runs the part of: `None` for a scenario on one host; else `--host`,
/// or the orchestrator's host. An error (exit 2) for a `--host` the scenario does not name.
pub fn resolve(scenario: &Scenario, host: Option<&str>) -> Result<Option<String>, String> {
    if !scenario.split() {
        return match host {
            Some(h) => Err(format!(
                "--host {h}: the scenario has no [hosts.<name>] sections (it runs on one host)"
            )),
            None => Ok(None),
        };
    }
    if !cfg!(feature = "hosts") {
        return Err(WITHOUT_HOSTS.to_string());
    }
    let host = host.or(scenario.orchestrator_host()).unwrap_or_default();
    if !scenario.hosts.contains_key(host) {
        let names: Vec<&str> = scenario.hosts.keys().map(|s| s.as_str()).collect();
        return Err(format!(
            "--host {host}: not a host of the scenario; allowed: {}",
            names.join(", ")
        ));
    }
    Ok(Some(host.to_string()))
}

/// Services `glint run --host <host>` spawns: those placed there, and the bridge.
pub fn local_services(scenario: &Scenario, host: Option<&str>) -> Vec<ServiceId> {
    let mut here: Vec<ServiceId> = (deployment::services(scenario).into_iter())
        .filter(|s| *s == ServiceId::Bridge || scenario.runs_on(*s, host))
        .collect();
    // The bridge last: it is stopped after the services it carries for.
    here.sort_by_key(|s| *s == ServiceId::Bridge);
    here
}

/// Services of the deployment that run on another host than `host`.
pub fn remote_services(scenario: &Scenario, host: Option<&str>) -> Vec<ServiceId> {
    (deployment::services(scenario).into_iter())
        .filter(|s| *s != ServiceId::Bridge && !scenario.runs_on(*s, host))
        .collect()
}

/// Runs the part of `host` (not the orchestrator's) until the orchestrator of record ends the
/// run. Returns the host's directory and whether every process of it ended well.
pub fn run_host(opts: &super::RunOptions, host: &str) -> Result<(PathBuf, bool)> {
    let (dir, part) = part(opts, host)?;
    Ok((dir, part.ok))
}

/// [`run_host`] for a matrix: whether every process ended well, and the faults this host fired
/// (their timelines; what they lost is the orchestrator's to count).
pub fn run_part(opts: &super::RunOptions, host: &str) -> Result<Part> {
    let (_, part) = part(opts, host)?;
    Ok(part)
}

/// How a host's part of a run ended.
pub struct Part {
    /// Every process of it ended well.
    pub ok: bool,
    /// The orchestrator of record started the run (the two parts met).
    pub met: bool,
    /// The faults this host fired (their timelines; what they lost is the orchestrator's to
    /// count).
    pub fired: Vec<FaultReport>,
}

fn part(opts: &super::RunOptions, host: &str) -> Result<(PathBuf, Part)> {
    let scenario = &opts.scenario;
    let prefix = super::run_prefix();
    let id = prefix.trim_start_matches("glint_").trim_end_matches('_');
    let name = format!("{}-{host}", scenario.name);
    let dir = super::run_dir::prepare(opts.out_dir.as_deref(), &name, id, opts.replace)?;
    let out_dir = dir.path.clone();
    let resolved = out_dir.join("scenario.toml");
    std::fs::write(&resolved, scenario.to_toml())
        .with_context(|| format!("writing {}", resolved.display()))?;
    let exe = std::env::current_exe().context("locating the glint executable")?;
    let result = serve(scenario, host, &prefix, &exe, &resolved, &out_dir);
    let (removed, held_by) = remove_shm(&prefix);
    tracing::info!(removed, ?held_by, "shared memory removed");
    let summary = result?;
    let text = summary.text(host, scenario);
    std::fs::write(out_dir.join("summary.md"), &text)?;
    eprint!("{text}");
    drop(dir);
    let part = Part {
        ok: summary.ok,
        met: summary.met,
        fired: summary.fired,
    };
    Ok((out_dir, part))
}

/// How a host's part ended.
struct HostSummary {
    ok: bool,
    why: Option<String>,
    /// Each process: name, pid, how it ended.
    processes: Vec<(String, u32, String)>,
    /// The bridge's last heartbeat: its per-hop counters.
    bridge: Option<Heartbeat>,
    /// Times the bridge was restarted.
    bridge_restarts: u32,
    /// The faults this host fired, as a table (empty: none), and their entries.
    faults: String,
    fired: Vec<FaultReport>,
    /// The orchestrator of record started the run.
    met: bool,
}

impl HostSummary {
    fn text(&self, host: &str, scenario: &Scenario) -> String {
        let mut t = format!(
            "# {} — host `{host}`: {}\n\n",
            scenario.name,
            match (&self.why, self.ok) {
                (_, true) => "ended by the orchestrator of record".to_string(),
                (Some(w), false) => format!("FAILED: {w}"),
                (None, false) => "FAILED".to_string(),
            }
        );
        t += "| process | pid | ended |\n|---|---|---|\n";
        for (n, pid, e) in &self.processes {
            t += &format!("| {n} | {pid} | {e} |\n");
        }
        t += &self.faults;
        if self.bridge_restarts > 0 {
            t += &format!(
                "\nThe bridge was restarted {} time(s); its counters below are its last \
                 incarnation's (the report of the orchestrator's host accounts end to end).\n",
                self.bridge_restarts
            );
        }
        if let Some(hb) = &self.bridge {
            t += "\nThe bridge, per hop (its side of each topic that crosses):\n\n";
            t += "| topic | taken | passed on | lost on the link | refused |\n|---|---|---|---|---|\n";
            for c in hb.topics.iter().filter(|c| c.topic != u32::MAX) {
                let name = TopicId::from_u32(c.topic).map_or("?", |t| t.name());
                t += &format!(
                    "| {name} | {} | {} | {} | {} |\n",
                    c.received,
                    c.published,
                    c.dropped[shared_types::DropReason::Link as usize],
                    c.dropped[shared_types::DropReason::Malformed as usize]
                );
            }
        }
        t
    }
}

fn serve(
    scenario: &Scenario,
    host: &str,
    prefix: &str,
    exe: &std::path::Path,
    resolved: &std::path::Path,
    out_dir: &std::path::Path,
) -> Result<HostSummary> {
    let node = open_node(prefix, &format!("host-{host}"))?;
    let _services = shared_types::topics::create_all(&node, scenario)?;
    let (mut control, control_l) = Inbox::<Control>::open(&node, TopicId::Control)?;
    control.stats.peers_restart();
    let (mut heartbeats, heartbeat_l) = Inbox::<Heartbeat>::open(&node, TopicId::Heartbeat)?;
    heartbeats.stats.peers_restart();
    let log_dir = out_dir.join("logs");
    let mut children = (local_services(scenario, Some(host)).into_iter())
        .map(|id| ServiceProcess::spawn(exe, id, prefix, resolved, &log_dir, 0, Some(host)))
        .collect::<Result<Vec<_>>>()?;
    tracing::info!(prefix, host, services = children.len(), "deployed");
    let limits = &scenario.run;
    let t0 = Instant::now();
    let deadline = t0
        + Duration::from_secs_f64(limits.timeout_s)
        + Duration::from_millis(limits.startup_timeout_ms);
    // The orchestrator's host waits this long for this part (its startup limit and the host
    // silence limit); this part waits as long again before it gives up on ever starting.
    let unmet =
        2 * (Duration::from_millis(limits.startup_timeout_ms) + scenario.host_silence_limit());
    let mut keeper = Keeper::new(scenario, host);
    let mut why: Option<String> = None;
    let mut shutdown = false;
    let inputs = [(&control_l, None), (&heartbeat_l, None)];
    let exit = run_loop(&inputs, Duration::from_millis(20), |_| {
        control.drain(|r| {
            let to_all = r.msg.target == Control::ALL;
            match Command::from_u32(r.msg.command) {
                Some(Command::Shutdown) if to_all => shutdown = true,
                Some(Command::Start) if to_all => keeper.start(),
                _ => {}
            }
            Ok(())
        })?;
        heartbeats.drain(|r| {
            if r.msg.meta.producer == ServiceId::Bridge as u32 {
                keeper.heard(*r.msg);
            }
            Ok(())
        })?;
        if shutdown {
            return Ok(Step::Stop);
        }
        // The bridge, last of the children, is the keeper's once it was ready.
        let b = children.len() - 1;
        let respawn = |n| {
            node.try_cleanup_dead_nodes();
            ServiceProcess::spawn(
                exe,
                ServiceId::Bridge,
                prefix,
                resolved,
                &log_dir,
                n,
                Some(host),
            )
        };
        if let Some(w) = keeper.step(&mut children[b], respawn)? {
            why = Some(w);
            return Ok(Step::Stop);
        }
        let kept = usize::from(keeper.supervising());
        let exited = (children.iter_mut().take(b + 1 - kept).enumerate())
            .find_map(|(i, c)| c.poll_exit().then_some(i));
        if let Some(c) = exited.map(|i| &children[i]) {
            why = Some(format!(
                "{} exited before the run ended: {}\n{}",
                c.id.name(),
                c.ending.label(),
                c.log_tail(8)
            ));
            return Ok(Step::Stop);
        }
        if !keeper.met() && t0.elapsed() > unmet {
            why = Some(format!(
                "the orchestrator of record never started the run within {} ms (is its \
                 host's part running, with the same scenario file, --seed and --fault?)",
                unmet.as_millis()
            ));
            return Ok(Step::Stop);
        }
        if Instant::now() > deadline {
            why =
                Some("the orchestrator of record did not end the run within run.timeout_s".into());
            return Ok(Step::Stop);
        }
        Ok(Step::Wait)
    })?;
    if exit == glint_runtime::Exit::Terminated && why.is_none() {
        why = Some("interrupted by a signal".into());
    }
    // The services first (they obey the orchestrator's Shutdown, forwarded by the bridge; the
    // ladder makes sure), then, once their last heartbeats had time to cross, the bridge.
    let grace = Duration::from_millis(limits.shutdown_grace_ms);
    let bridges = children
        .iter()
        .filter(|c| c.id == ServiceId::Bridge)
        .count();
    let split_at = children.len() - bridges;
    let (services, bridge) = children.split_at_mut(split_at);
    stop_ladder(services, grace, &mut || {}, &mut || {});
    let linger = Duration::from_millis(3 * limits.heartbeat_period_ms);
    std::thread::sleep(linger);
    for b in bridge.iter() {
        b.signal(rustix::process::Signal::TERM);
    }
    stop_ladder(bridge, grace, &mut || {}, &mut || {});
    let _ = heartbeats.drain(|r| {
        if r.msg.meta.producer == ServiceId::Bridge as u32 {
            keeper.heard(*r.msg);
        }
        Ok(())
    });
    let never = keeper.finish();
    if why.is_none() && !never.is_empty() {
        why = Some(never.join("; "));
    }
    // A service ends on the orchestrator's Shutdown, the bridge by its own exit status.
    let ended_well = |c: &ServiceProcess| {
        c.exit_ok == Some(true) || (c.id != ServiceId::Bridge && c.ending == Ending::Shutdown)
    };
    let ok = why.is_none() && children.iter().all(ended_well);
    if why.is_none() && !ok {
        why = Some("a process of this host did not end well (see the table)".into());
    }
    let processes = (children.iter())
        .map(|c| (c.id.name().to_string(), c.pid, c.ending.label()))
        .collect();
    Ok(HostSummary {
        ok,
        why,
        processes,
        bridge: keeper.last_beat(),
        bridge_restarts: keeper.restarts(),
        faults: keeper.faults_table(),
        fired: keeper.fault_reports(),
        met: keeper.met(),
    })
}
