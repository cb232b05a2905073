//! Into this host: one Zenoh subscriber on the deployment's keys; each message's envelope is
//! checked (contract, topic, type, size: a failure is a counted `malformed` drop), its link
//! sequence accounted (a gap is counted `link` lost), and its bytes copied into a sample loaned
//! from the topic's shared memory here, then sent as the producer sent it (seq, times and
//! producer unchanged), so consumers here account for it end to end as for a local one.

use std::collections::BTreeMap;
use std::sync::atomic::Ordering;
use std::time::Duration;

use anyhow::{anyhow, Result};
use glint_runtime::TopicStats;
use shared_types::{DropReason, TopicId};
use zenoh::sample::Locality;
use zenoh::Wait;

use super::ports::{putter, PutBytes};
use super::Env;
use crate::envelope::{Envelope, Refusal};
use crate::link::{LinkSeqs, LinkVerdict};

/// How long a wait for the wire lasts before the stop flag is looked at again.
const POLL: Duration = Duration::from_millis(50);
/// Messages off the wire waiting for shared memory, at most: when full, Zenoh's receiving
/// thread waits, and with it the link (backpressure to the sending bridge, nothing dropped).
const INBOX: usize = 256;

struct Route {
    port: Box<dyn PutBytes>,
    /// This hop's accounting of a data topic: taken off the wire, published here.
    stats: Option<TopicStats>,
}

/// The ingress thread's body: runs until `stop` is set; `ready` is called once every port and
/// the subscriber are open.
pub fn run(env: &Env, ready: impl FnOnce()) -> Result<()> {
    let Env {
        prefix,
        scenario,
        routes,
        session,
        shared,
        stop,
    } = *env;
    let node = glint_runtime::open_node(prefix, "bridge-in")?;
    let mut inbound: BTreeMap<TopicId, Route> = BTreeMap::new();
    for &t in &routes.imports {
        let route = Route {
            port: putter(&node, scenario, t)?,
            stats: t.spec().is_data().then(|| TopicStats::new(t)),
        };
        inbound.insert(t, route);
    }
    // One subscriber per imported topic (only what this host reads comes to it), all into
    // one bounded inbox.
    let (tx, inbox) = std::sync::mpsc::sync_channel::<(TopicId, zenoh::sample::Sample)>(INBOX);
    let deployment = scenario.deployment_key();
    let mut subscribers = vec![];
    for &t in inbound.keys() {
        let key = super::key(&deployment, t);
        let tx = tx.clone();
        let subscriber = (session.declare_subscriber(&key))
            .allowed_origin(Locality::Remote)
            .callback(move |sample| {
                let _ = tx.send((t, sample));
            })
            .wait()
            .map_err(|e| anyhow!("zenoh subscriber on {key}: {e}"))?;
        subscribers.push(subscriber);
    }
    drop(tx);
    ready();
    let mut links = LinkSeqs::default();
    let mut refused = 0u64;
    while !stop.load(Ordering::SeqCst) && glint_runtime::lifeline::end_requested().is_none() {
        let (topic, sample) = match inbox.recv_timeout(POLL) {
            Ok(x) => x,
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) => continue,
            Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => {
                return Err(anyhow!("the zenoh subscribers closed"));
            }
        };
        let Some(route) = inbound.get_mut(&topic) else {
            continue;
        };
        let topic = route.port.topic();
        let attachment = sample.attachment().map(|a| a.to_bytes());
        let payload = sample.payload();
        let checked =
            Envelope::read(attachment.as_deref(), topic, route.port.digest()).and_then(|e| {
                match payload.len() == route.port.len() {
                    true => Ok(e),
                    false => Err(Refusal::Size),
                }
            });
        let envelope = match checked {
            Ok(e) => e,
            Err(why) => {
                refused += 1;
                if refused == 1 || refused.is_power_of_two() {
                    tracing::warn!(topic = topic.name(), refused, "refused off the wire: {why}");
                }
                if let Some(s) = route.stats.as_mut() {
                    s.malformed();
                    shared.set(s);
                }
                continue;
            }
        };
        match links.observe(topic, envelope.origin_host, envelope.link_seq) {
            LinkVerdict::Repeat => {
                if let Some(s) = route.stats.as_mut() {
                    s.duplicates += 1;
                }
                continue;
            }
            LinkVerdict::Take { lost } => {
                if lost > 0 {
                    tracing::warn!(topic = topic.name(), lost, "lost on the link");
                }
                if let Some(s) = route.stats.as_mut() {
                    s.dropped[DropReason::Link as usize] += lost;
                }
            }
        }
        // Put again after a bridge came back: passed on (its consumers skip what they have),
        // counted as a duplicate of the hop, not as a message.
        let resent = envelope.is_resent();
        route.port.put(&mut payload.slices())?;
        if let Some(s) = route.stats.as_mut() {
            if resent {
                s.duplicates += 1;
            } else {
                s.accept();
                s.published += 1;
            }
            s.next_seq = envelope.link_seq + 1;
            shared.set(s);
        }
    }
    drop(subscribers);
    Ok(())
}
