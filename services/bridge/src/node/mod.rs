//! `glint service bridge --host NAME`: one host's bridge. Threads, each with its own iceoryx2
//! node (ports are not `Send`) around one Zenoh session: *egress* takes the exported topics
//! from shared memory and puts them on Zenoh; *ingress* takes the imported ones off Zenoh and
//! publishes them here; *calls* (when a call crosses hosts) carries requests and responses
//! ([`calls`]); the main thread obeys control and sends the bridge's heartbeat, which carries
//! each bridged data topic's per-hop counters.

mod calls;
mod egress;
mod ingress;
mod pace;
mod ports;

use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{mpsc, Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::{anyhow, Context, Result};
use glint_runtime::{run_loop, Housekeeping, Step, TopicStats};
use shared_types::{Heartbeat, Scenario, ServiceId, TopicId};
use zenoh::Wait;

use crate::routes::{routes, Routes};

/// The Zenoh key of a topic of a deployment: `glint/<deployment>/<topic>`.
pub fn key(deployment: &str, topic: TopicId) -> String {
    format!("glint/{deployment}/{}", topic.name())
}

/// Exit status of `glint service bridge` when it ended for [`OrchestratorLost`]: its host's
/// part does not restart it, but ends.
pub const EXIT_ORCHESTRATOR_LOST: u8 = 3;

/// The orchestrator's host was away past the heartbeat deadline: the run is over for this
/// host (nothing of glint outlives its orchestrator).
#[derive(Debug)]
pub struct OrchestratorLost(pub String);

impl std::fmt::Display for OrchestratorLost {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for OrchestratorLost {}

/// What each of the bridge's threads works with.
#[derive(Clone, Copy)]
pub struct Env<'a> {
    /// The deployment's shared-memory prefix on this host.
    pub prefix: &'a str,
    pub scenario: &'a Scenario,
    pub routes: &'a Routes,
    pub session: &'a zenoh::Session,
    pub shared: &'a Shared,
    /// Set when the bridge stops; each thread ends at it.
    pub stop: &'a AtomicBool,
}

/// The per-hop counters the threads keep and the heartbeat carries.
#[derive(Default)]
pub struct Shared {
    stats: Mutex<Vec<TopicStats>>,
    /// A thread's error: the bridge stops with it.
    failed: Mutex<Option<String>>,
    /// Other hosts whose bridge is away: the egress holds (what it has not put stays queued
    /// in shared memory, where sim-clock credit holds the producers).
    away: AtomicUsize,
    /// Hosts come back so far: the egress puts again what it last sent, which may have been
    /// in flight to the dead bridge (its consumers skip what they already have).
    rejoins: AtomicU64,
    /// An injected slow link, kept by the egress.
    pace: pace::Pace,
}

impl Shared {
    fn set(&self, s: &TopicStats) {
        let mut all = self.stats.lock().unwrap_or_else(|p| p.into_inner());
        match all.iter_mut().find(|x| x.topic == s.topic) {
            Some(x) => *x = s.clone(),
            None => all.push(s.clone()),
        }
    }

    fn snapshot(&self) -> Vec<TopicStats> {
        self.stats.lock().unwrap_or_else(|p| p.into_inner()).clone()
    }

    fn fail(&self, why: String) {
        let mut f = self.failed.lock().unwrap_or_else(|p| p.into_inner());
        f.get_or_insert(why);
    }

    fn failure(&self) -> Option<String> {
        self.failed
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .clone()
    }
}

/// The Zenoh session of `host`: a peer that listens on its own endpoint and connects to every
/// other host's, with no multicast scouting (it meets only the hosts the scenario names), its
/// lease and blocking limit the scenario's host silence limit.
fn session(scenario: &Scenario, host: &str) -> Result<zenoh::Session> {
    let own = (scenario.hosts.get(host))
        .ok_or_else(|| anyhow!("`{host}` is not a host of the scenario's [hosts]"))?;
    let others: Vec<&str> = (scenario.hosts.iter())
        .filter(|(n, _)| n.as_str() != host)
        .map(|(_, h)| h.endpoint.as_str())
        .collect();
    let json = |v: serde_json::Value| v.to_string();
    // Zenoh keeps a silent link (its lease) and a put blocked on it (before closing the
    // session) as long as glint waits for a silent host: a partition or a stopped bridge
    // shorter than that loses nothing in Zenoh either.
    let limit = scenario.host_silence_limit();
    let mut config = zenoh::Config::default();
    for (k, v) in [
        ("mode", json("peer".into())),
        ("listen/endpoints", json(vec![own.endpoint.as_str()].into())),
        ("connect/endpoints", json(others.into())),
        ("scouting/multicast/enabled", "false".to_string()),
        ("scouting/gossip/enabled", "false".to_string()),
        ("transport/link/tx/lease", limit.as_millis().to_string()),
        (
            "transport/link/tx/queue/congestion_control/block/wait_before_close",
            limit.as_micros().to_string(),
        ),
    ] {
        (config.insert_json5(k, &v)).map_err(|e| anyhow!("zenoh config {k} = {v}: {e}"))?;
    }
    zenoh::open(config)
        .wait()
        .map_err(|e| anyhow!("opening the zenoh session on {}: {e}", own.endpoint))
}

/// Runs `host`'s bridge of the deployment under `prefix` until a termination signal.
pub fn run(prefix: &str, scenario: &Scenario, host: &str) -> Result<()> {
    let routes = routes(scenario, host);
    tracing::info!(
        host,
        deployment = scenario.deployment_key(),
        exports = ?names(&routes.exports),
        imports = ?names(&routes.imports),
        "bridge routes"
    );
    let session = session(scenario, host)?;
    let node = glint_runtime::open_node(prefix, "bridge")?;
    let (mut hk, control) = Housekeeping::open(&node, ServiceId::Bridge)?;
    let period = Duration::from_millis(scenario.run.heartbeat_period_ms);
    hk.heartbeat_period = period;
    let shared = Arc::new(Shared::default());
    let stop = Arc::new(AtomicBool::new(false));
    let (ready_tx, ready_rx) = mpsc::channel();
    let mut directions = vec![Direction::Egress, Direction::Ingress];
    if !routes.serves.is_empty() || !routes.answers.is_empty() {
        directions.push(Direction::Calls);
    }
    let threads = directions.into_iter().map(|dir| {
        let (prefix, scenario, routes) = (prefix.to_string(), scenario.clone(), routes.clone());
        let (session, shared, stop, ready) = (
            session.clone(),
            shared.clone(),
            stop.clone(),
            ready_tx.clone(),
        );
        std::thread::Builder::new()
            .name(format!("bridge-{}", dir.name()))
            .spawn(move || {
                let env = Env {
                    prefix: &prefix,
                    scenario: &scenario,
                    routes: &routes,
                    session: &session,
                    shared: &shared,
                    stop: &stop,
                };
                let r = dir.run(&env, || {
                    let _ = ready.send(dir);
                });
                if let Err(e) = r {
                    shared.fail(format!("{}: {e:#}", dir.name()));
                }
                // Whatever ended this thread ends the bridge.
                stop.store(true, Ordering::SeqCst);
            })
    });
    let threads = threads.into_iter().collect::<std::io::Result<Vec<_>>>()?;
    drop(ready_tx);
    for _ in 0..threads.len() {
        ready_rx
            .recv()
            .map_err(|_| anyhow!("{}", shared.failure().unwrap_or_default()))
            .context("opening the bridge's ports")?;
    }
    // Presence: every bridge holds a liveliness token; a host whose token goes (its bridge
    // ended, or its link was silent for Zenoh's lease) is away until it comes back.
    let deployment = scenario.deployment_key();
    // One token per incarnation (`…/@bridge/<host>/<pid>`): a restarted bridge's token may be
    // seen before its dead predecessor's goes.
    let incarnation = std::process::id();
    let _token = (session.liveliness())
        .declare_token(format!("glint/{deployment}/@bridge/{host}/{incarnation}"))
        .wait()
        .map_err(|e| anyhow!("zenoh liveliness token: {e}"))?;
    let peers = Arc::new(Mutex::new(Peers::default()));
    let _presence = {
        let (peers, shared, host) = (peers.clone(), shared.clone(), host.to_string());
        (session.liveliness())
            .declare_subscriber(format!("glint/{deployment}/@bridge/*/*"))
            .history(true)
            .callback(move |s| {
                let mut key = s.key_expr().as_str().rsplit('/');
                let (id, peer) = (key.next().unwrap_or(""), key.next().unwrap_or(""));
                let here = s.kind() == zenoh::sample::SampleKind::Put;
                let mut p = peers.lock().unwrap_or_else(|p| p.into_inner());
                p.saw(&host, peer, id, here, &shared);
            })
            .wait()
            .map_err(|e| anyhow!("zenoh liveliness subscriber: {e}"))?
    };
    // The orchestrator's host away this long is lost: its supervision had the time to bring
    // its bridge back (the limit the orchestrator gives every other host).
    let lost_after = scenario.host_silence_limit();
    hk.state = Heartbeat::READY;
    tracing::info!(host, "bridge ready");
    let beat = |hk: &mut Housekeeping| -> Result<()> {
        let stats = shared.snapshot();
        hk.beat(0, &stats.iter().collect::<Vec<_>>())
    };
    beat(&mut hk)?;
    // The bridge stops on a `Shutdown` addressed to it, which the orchestrator sends once the
    // services it carries for have stopped and their last heartbeats crossed (a `Shutdown` to
    // all is theirs), or on SIGTERM.
    let mut orchestrator_lost = None;
    let mut delays = pace::Delays::new(scenario, host);
    let exit = run_loop(&[(&control, None)], period, |_| {
        if hk.poll_control()?.contains(&shared_types::Command::Start) {
            hk.state = Heartbeat::RUNNING;
            delays.start();
        }
        let trigger = delays.trigger().map(|t| t as u32);
        let passed_on = (shared.snapshot().iter())
            .find(|s| Some(s.topic as u32) == trigger)
            .map_or(0, |s| s.published);
        if delays.step(passed_on, &shared.pace) {
            hk.faults_obeyed += 1;
        }
        hk.delaying_elsewhere = shared.pace.on();
        if stop.load(Ordering::SeqCst) || hk.shutdown_addressed {
            return Ok(Step::Stop);
        }
        let orchestrator = scenario.orchestrator_host().unwrap_or_default();
        let lost = (peers.lock().unwrap_or_else(|p| p.into_inner())).away_for(orchestrator);
        if let Some(t) = lost.filter(|t| *t >= lost_after) {
            // After the run's Shutdown, the orchestrator's host leaving is the run's end.
            if !hk.shutdown_requested {
                orchestrator_lost = Some(format!(
                    "lost the orchestrator's host `{orchestrator}`: its bridge was away for \
                     {} ms (run.heartbeat_deadline_ms + supervision.backoff_max_ms + \
                     run.startup_timeout_ms = {} ms; it ended, or the link was silent past \
                     Zenoh's lease)",
                    t.as_millis(),
                    lost_after.as_millis()
                ));
            }
            return Ok(Step::Stop);
        }
        beat(&mut hk)?;
        Ok(Step::Wait)
    });
    stop.store(true, Ordering::SeqCst);
    for t in threads {
        let _ = t.join();
    }
    hk.state = Heartbeat::STOPPING;
    beat(&mut hk)?;
    if let Some(why) = orchestrator_lost {
        return Err(OrchestratorLost(format!("bridge of host {host}: {why}")).into());
    }
    if let Some(f) = shared.failure() {
        return Err(anyhow!("bridge of host {host}: {f}"));
    }
    exit?;
    let _ = session.close().wait();
    Ok(())
}

/// The other hosts' bridges this one has seen come and go, by incarnation.
#[derive(Default)]
struct Peers {
    /// Each incarnation's token present: (host, incarnation).
    tokens: Vec<(String, String)>,
    /// Hosts with no token, and since when.
    away: Vec<(String, Instant)>,
}

impl Peers {
    /// Incarnation `id` of `peer`'s bridge appeared (`here`) or went. A host with no token is
    /// away: the egress holds. A new incarnation of a host seen before (it rejoined, or its
    /// restarted bridge is seen before its dead one goes) makes the egress put again what it
    /// last sent ([`Shared::rejoins`]).
    fn saw(&mut self, host: &str, peer: &str, id: &str, here: bool, shared: &Shared) {
        if peer == host {
            return;
        }
        let token = (peer.to_string(), id.to_string());
        let known =
            self.tokens.iter().any(|(p, _)| p == peer) || self.away.iter().any(|(p, _)| p == peer);
        if here {
            if known {
                tracing::info!(
                    peer,
                    incarnation = id,
                    "host's bridge back, a new incarnation"
                );
                shared.rejoins.fetch_add(1, Ordering::SeqCst);
            } else {
                tracing::info!(peer, "host joined");
            }
            self.away.retain(|(p, _)| p != peer);
            self.tokens.push(token);
        } else {
            self.tokens.retain(|t| *t != token);
            let gone = !self.tokens.iter().any(|(p, _)| p == peer);
            if gone && !self.away.iter().any(|(p, _)| p == peer) {
                tracing::warn!(peer, "host away: its bridge left");
                self.away.push((peer.to_string(), Instant::now()));
            }
        }
        shared.away.store(self.away.len(), Ordering::SeqCst);
    }

    /// How long `peer` has been away, if it is.
    fn away_for(&self, peer: &str) -> Option<Duration> {
        (self.away.iter().find(|(p, _)| p == peer)).map(|(_, t)| t.elapsed())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_host_is_away_without_a_token_and_a_new_incarnation_is_a_rejoin() {
        let shared = Shared::default();
        let mut p = Peers::default();
        let state = |s: &Shared| {
            (
                s.away.load(Ordering::SeqCst),
                s.rejoins.load(Ordering::SeqCst),
            )
        };
        p.saw("a", "a", "1", true, &shared); // itself: ignored
        p.saw("a", "b", "10", true, &shared);
        assert_eq!(state(&shared), (0, 0), "a first join is no rejoin");
        p.saw("a", "b", "10", false, &shared);
        assert_eq!(state(&shared), (1, 0));
        assert!(p.away_for("b").is_some());
        p.saw("a", "b", "11", true, &shared);
        assert_eq!(state(&shared), (0, 1), "back: put again");
        // the restarted bridge seen before its dead predecessor goes
        p.saw("a", "b", "12", true, &shared);
        assert_eq!(state(&shared), (0, 2));
        p.saw("a", "b", "11", false, &shared);
        assert_eq!(state(&shared), (0, 2), "still one incarnation present");
        assert!(p.away_for("b").is_none());
    }
}

#[derive(Debug, Clone, Copy)]
enum Direction {
    Egress,
    Ingress,
    /// Calls made on one host and answered on another ([`calls`]).
    Calls,
}

impl Direction {
    fn name(self) -> &'static str {
        match self {
            Direction::Egress => "egress",
            Direction::Ingress => "ingress",
            Direction::Calls => "calls",
        }
    }

    fn run(self, env: &Env, ready: impl FnOnce()) -> Result<()> {
        match self {
            Direction::Egress => egress::run(env, ready),
            Direction::Ingress => ingress::run(env, ready),
            Direction::Calls => calls::run(env, ready),
        }
    }
}

fn names(topics: &[TopicId]) -> Vec<&'static str> {
    topics.iter().map(|t| t.name()).collect()
}
