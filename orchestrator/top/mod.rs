//! `glint top [PREFIX]`: a live view of a running deployment. It joins the deployment's shared
//! memory as an observer (node `glint-top`: reported by the run, never its failure), reads
//! every service's heartbeats and each process's /proc entries, and shows per service its
//! state, pid, restarts, input and output rates, latency percentiles, drops by reason, CPU and
//! resident memory ([`model`]); `--once --json` prints one snapshot for scripts.

pub mod model;
mod view;

use std::process::ExitCode;
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail, Result};
use glint_runtime::{live_nodes, mono_ns, open_node, Inbox};
use serde::Serialize;
use shared_types::{Heartbeat, TopicId};

use crate::run::deploy::cpu_seconds;
use crate::run::memory::rss_bytes;
use model::{Model, ServiceRow};

/// How long `--once` watches before its snapshot: enough heartbeats for rates and CPU.
const ONCE_WATCH: Duration = Duration::from_millis(1500);
/// How often the screen is redrawn and /proc read.
const REFRESH: Duration = Duration::from_millis(250);
/// A service not heard from for this long shows as silent.
const SILENT_AFTER: Duration = Duration::from_secs(2);

/// `glint top --once --json`.
#[derive(Debug, Serialize)]
pub struct Snapshot {
    pub prefix: String,
    /// The deployment's live nodes (services, the orchestrator, observers such as this one).
    pub nodes: Vec<String>,
    pub services: Vec<ServiceRow>,
}

/// The deployments running now: prefixes with a live node, with their nodes' names.
fn running() -> Vec<(String, Vec<String>)> {
    glint_runtime::glint_prefixes()
        .into_iter()
        .filter_map(|p| {
            let nodes: Vec<String> = live_nodes(&p).into_iter().map(|(n, _)| n).collect();
            (!nodes.is_empty()).then_some((p, nodes))
        })
        .collect()
}

/// `prefix`, or the one deployment running; an error names what there is to choose from.
fn choose(prefix: Option<String>) -> Result<String> {
    if let Some(p) = prefix {
        if !glint_runtime::is_deployment_prefix(&p) {
            bail!("`{p}` is not a deployment prefix (glint_<hex>_: `run.prefix` in report.json)");
        }
        if live_nodes(&p).is_empty() {
            bail!("no deployment is running under {p}");
        }
        return Ok(p);
    }
    match running().as_slice() {
        [] => bail!("no glint deployment is running (start one with `glint run`)"),
        [(p, _)] => Ok(p.clone()),
        many => {
            let list: Vec<String> = (many.iter())
                .map(|(p, nodes)| format!("{p} ({})", nodes.join(", ")))
                .collect();
            bail!(
                "several deployments are running; name one: {}",
                list.join("; ")
            )
        }
    }
}

/// An observer of one deployment: its heartbeats and its processes.
struct Watch {
    prefix: String,
    // Declared before the node it was opened on: dropped first.
    heartbeats: Inbox<Heartbeat>,
    _node: shared_types::topics::IpcNode,
    model: Model,
}

impl Watch {
    fn open(prefix: &str) -> Result<Watch> {
        let node = open_node(prefix, "glint-top")?;
        let (mut heartbeats, _listener) = Inbox::open(&node, TopicId::Heartbeat)?;
        heartbeats.stats.peers_restart();
        Ok(Watch {
            prefix: prefix.to_string(),
            heartbeats,
            _node: node,
            model: Model::default(),
        })
    }

    /// Takes every heartbeat queued and samples each process.
    fn poll(&mut self) -> Result<()> {
        let now = mono_ns();
        let model = &mut self.model;
        self.heartbeats.drain(|r| {
            model.heartbeat(r.msg, now);
            Ok(())
        })?;
        for (id, pid) in self.model.pids() {
            self.model
                .process(id, now, cpu_seconds(pid), rss_bytes(pid));
        }
        Ok(())
    }

    fn snapshot(&self) -> Snapshot {
        let mut nodes: Vec<String> = (live_nodes(&self.prefix).into_iter())
            .map(|(n, _)| n)
            .collect();
        nodes.sort();
        Snapshot {
            prefix: self.prefix.clone(),
            nodes,
            services: self.model.rows(mono_ns(), SILENT_AFTER.as_nanos() as u64),
        }
    }
}

/// `glint top`.
pub(crate) fn command(prefix: Option<String>, once: bool, json: bool) -> ExitCode {
    let prefix = match choose(prefix) {
        Ok(p) => p,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    let result = if once {
        watch_once(&prefix).map(|s| {
            if json {
                println!("{}", serde_json::to_string_pretty(&s).unwrap_or_default());
            } else {
                print!("{}", view::text(&s));
            }
        })
    } else {
        view::interactive(&prefix)
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(1)
        }
    }
}

/// Watches for [`ONCE_WATCH`]; one snapshot.
fn watch_once(prefix: &str) -> Result<Snapshot> {
    let mut w = Watch::open(prefix)?;
    let t0 = Instant::now();
    while t0.elapsed() < ONCE_WATCH {
        w.poll()?;
        std::thread::sleep(Duration::from_millis(100));
    }
    w.poll()?;
    let s = w.snapshot();
    if s.services.is_empty() {
        return Err(anyhow!("no heartbeat from {prefix} in {ONCE_WATCH:?}"));
    }
    Ok(s)
}
