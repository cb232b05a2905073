//! Out of this host: every exported topic's messages taken from shared memory (the bridge is
//! one more subscriber on its host) and put on Zenoh, each with its envelope. A put under
//! `Block` waits for the link: what cannot go yet stays in the subscriber's queue, which the
//! sim-clock credit keeps from overflowing; in realtime mode a gap is counted by seq.
//!
//! A host whose bridge left (killed, restarted) misses what was put while it was dying. The
//! egress holds while any host is away, and when one comes back puts again the last messages
//! of each data topic, as many as the topic's credit window: in sim clock no producer is further
//! ahead of its slowest consumer than that, so whatever the dead bridge lost is among them.
//! They go marked [`Envelope::RESENT`]; consumers skip those they already had (`duplicates`).

use std::collections::VecDeque;
use std::sync::atomic::Ordering;
use std::time::Duration;

use anyhow::{anyhow, Result};
use glint_runtime::stats::SeqVerdict;
use glint_runtime::{run_loop, Step, TopicStats};
use shared_types::Scenario;
use zenoh::bytes::ZBytes;
use zenoh::qos::{CongestionControl, Priority};
use zenoh::sample::Locality;
use zenoh::Wait;

use super::ports::{taker, TakeBytes};
use super::{key, Env};
use crate::envelope::Envelope;
use crate::link::LinkSeqs;
use crate::routes::{exported_by, Routes};

/// How often the loop looks at the stop flag when nothing arrives.
const TICK: Duration = Duration::from_millis(50);
/// Messages one topic may put on the wire per round: a topic that always has more (frames on
/// a slow link) does not hold back the others (heartbeats, control, acks go first each round).
const BATCH: usize = 8;

struct Route {
    port: Box<dyn TakeBytes>,
    publisher: zenoh::pubsub::Publisher<'static>,
    /// This hop's accounting of a data topic: taken from shared memory, put on the wire.
    stats: Option<TopicStats>,
    /// The last messages put (their bytes, shared with Zenoh's buffers, not copied), at most
    /// `keep`: put again when a host comes back.
    sent: VecDeque<ZBytes>,
    keep: usize,
}

/// The egress thread's body: runs until `stop` is set or a termination signal arrives;
/// `ready` is called once every port is open.
pub fn run(env: &Env, ready: impl FnOnce()) -> Result<()> {
    let Env {
        prefix,
        scenario,
        routes,
        session,
        shared,
        stop,
    } = *env;
    let node = glint_runtime::open_node(prefix, "bridge-out")?;
    let deployment = scenario.deployment_key();
    let mut out = vec![];
    let mut listeners = vec![];
    // Housekeeping first: each round serves heartbeats, control and acks before data.
    let mut exports = routes.exports.clone();
    exports.sort_by_key(|t| t.spec().is_data());
    for &t in &exports {
        let data = t.spec().is_data();
        let priority = if data {
            Priority::Data
        } else {
            Priority::RealTime
        };
        let publisher = (session.declare_publisher(key(&deployment, t)))
            .congestion_control(CongestionControl::Block)
            .priority(priority)
            .express(!data)
            .allowed_destination(Locality::Remote)
            .wait()
            .map_err(|e| anyhow!("zenoh publisher for {}: {e}", t.name()))?;
        let (port, listener) = taker(&node, scenario, t)?;
        listeners.push(listener);
        out.push(Route {
            port,
            publisher,
            stats: data.then(|| TopicStats::new(t)),
            sent: VecDeque::new(),
            // Data only: heartbeats are periodic, acks go again with every heartbeat, and a
            // control order obeyed twice would act twice (its readers take a seq that goes
            // back as a new incarnation of the orchestrator, not as a duplicate).
            keep: match data {
                true => shared_types::topics::credit_window(t, scenario),
                false => 0,
            },
        });
    }
    // Ready once the other hosts' bridges take every exported topic: nothing put before that
    // (the run's `Start` among it) would reach them.
    for r in &out {
        while !(r.publisher.matching_status().wait())
            .map_err(|e| anyhow!("zenoh matching status: {e}"))?
            .matching()
        {
            if stop.load(Ordering::SeqCst) || glint_runtime::lifeline::end_requested().is_some() {
                return Ok(());
            }
            std::thread::sleep(Duration::from_millis(10));
        }
    }
    ready();
    let inputs: Vec<_> = listeners.iter().map(|l| (l, None)).collect();
    let mut links = LinkSeqs::default();
    let mut rejoins = shared.rejoins.load(Ordering::SeqCst);
    run_loop(&inputs, TICK, |_| {
        if shared.away.load(Ordering::SeqCst) > 0 {
            // Hold: nothing leaves while a host is away (its bridge would not take it).
            return Ok(if stop.load(Ordering::SeqCst) {
                Step::Stop
            } else {
                Step::WaitAtMost(TICK)
            });
        }
        let now = shared.rejoins.load(Ordering::SeqCst);
        if now != rejoins {
            rejoins = now;
            for r in out.iter_mut() {
                resend(r, routes, &mut links)?;
                if let Some(s) = &r.stats {
                    shared.set(s);
                }
            }
        }
        let mut more = false;
        for r in out.iter_mut() {
            if stop.load(Ordering::SeqCst) {
                return Ok(Step::Stop);
            }
            more |= forward(r, scenario, routes, &mut links, &shared.pace, || {
                shared.away.load(Ordering::SeqCst) > 0
                    || shared.rejoins.load(Ordering::SeqCst) != rejoins
            })?;
            if let Some(s) = &r.stats {
                shared.set(s);
            }
        }
        // A topic left with messages is served again at once, after the others.
        Ok(if more {
            Step::WaitAtMost(Duration::ZERO)
        } else {
            Step::Wait
        })
    })?;
    Ok(())
}

/// Puts up to [`BATCH`] queued messages of one route on the wire (one copy, from shared
/// memory into the buffer Zenoh sends); whether it stopped before the queue was empty. It
/// stops as soon as `changed()` says a host left or came back (a put can block on a stopped
/// peer until its link closes): the round starts again, holding or putting again first.
fn forward(
    r: &mut Route,
    scenario: &Scenario,
    routes: &Routes,
    links: &mut LinkSeqs,
    pace: &super::pace::Pace,
    changed: impl Fn() -> bool,
) -> Result<bool> {
    let topic = r.port.topic();
    for _ in 0..BATCH {
        if changed() {
            return Ok(true);
        }
        let mut bytes = Vec::new();
        let Some(taken) = r.port.take(&mut bytes)? else {
            return Ok(false);
        };
        // Only what was written on this host leaves it (an import stays home: no loops).
        if !exported_by(scenario, &routes.host, taken.producer) {
            continue;
        }
        // A replay's copies (a consumer restarted) cross too; they count as duplicates here.
        if let Some(s) = r.stats.as_mut() {
            if s.observe(taken.producer, taken.seq) == SeqVerdict::Accept {
                s.accept();
            }
        }
        // An injected slow link paces the data (housekeeping is never slowed).
        if r.stats.is_some() {
            pace.keep(bytes.len());
        }
        let seq = links.stamp(topic, routes.host_index);
        let envelope = Envelope::new(topic, routes.host_index, seq, r.port.digest());
        let bytes = ZBytes::from(bytes);
        put(r, bytes.clone(), envelope)?;
        if r.keep > 0 {
            if r.sent.len() == r.keep {
                r.sent.pop_front();
            }
            r.sent.push_back(bytes);
        }
        if let Some(s) = r.stats.as_mut() {
            s.published += 1;
        }
    }
    Ok(true)
}

/// Puts the route's last messages on the wire again, in their order, marked resent (counted
/// as `duplicates` on both sides of the hop).
fn resend(r: &mut Route, routes: &Routes, links: &mut LinkSeqs) -> Result<()> {
    let topic = r.port.topic();
    for bytes in r.sent.clone() {
        let seq = links.stamp(topic, routes.host_index);
        let envelope = Envelope::new(topic, routes.host_index, seq, r.port.digest()).resent();
        put(r, bytes, envelope)?;
        if let Some(s) = r.stats.as_mut() {
            s.duplicates += 1;
        }
    }
    if !r.sent.is_empty() {
        tracing::info!(
            topic = topic.name(),
            n = r.sent.len(),
            "put again: a host came back"
        );
    }
    Ok(())
}

fn put(r: &Route, bytes: ZBytes, envelope: Envelope) -> Result<()> {
    (r.publisher.put(bytes))
        .attachment(envelope.to_bytes().to_vec())
        .wait()
        .map_err(|e| anyhow!("zenoh put on {}: {e}", r.port.topic().name()))
}
