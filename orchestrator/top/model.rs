//! What `glint top` shows, computed from what it observed: each service's heartbeats (state,
//! pid, counters, its last latency) and its process in /proc (CPU time, resident memory). Pure:
//! the caller feeds heartbeats and /proc samples with their times; a test feeds its own.

use std::collections::{BTreeMap, VecDeque};

use serde::Serialize;
use shared_types::{DropReason, Heartbeat, ServiceId, TopicId};

/// Latencies kept per service for the percentiles (one per heartbeat: the last one it saw).
const LATENCY_WINDOW: usize = 256;
/// The window rates are measured over [ns].
const RATE_WINDOW_NS: u64 = 2_000_000_000;

/// One service as `glint top` shows it (`--once --json`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ServiceRow {
    pub name: String,
    /// starting, ready, running, finished, stopping; `silent` once its heartbeats stopped.
    pub state: String,
    pub pid: u32,
    /// Restarts seen while watching (a new pid for the service).
    pub restarts: u32,
    /// Messages it accepted per second, over its inputs [1/s].
    pub inputs_per_s: f64,
    /// Messages it published per second, over its outputs [1/s].
    pub outputs_per_s: f64,
    /// Its input latency (send → processed), over the heartbeats seen [µs]; `None`: none yet.
    pub latency_p50_us: Option<f64>,
    pub latency_p99_us: Option<f64>,
    /// Messages it dropped, by reason (reasons with none left out).
    pub dropped: BTreeMap<String, u64>,
    /// CPU use of its process over the rate window [% of one core].
    pub cpu_percent: Option<f64>,
    /// Resident memory of its process [MiB].
    pub rss_mib: Option<f64>,
}

/// Totals of one heartbeat at a time.
#[derive(Debug, Clone, Copy)]
struct Totals {
    t_ns: u64,
    inputs: u64,
    outputs: u64,
}

#[derive(Debug, Default)]
struct Watched {
    last: Option<Heartbeat>,
    last_seen_ns: u64,
    restarts: u32,
    totals: VecDeque<Totals>,
    latencies_ns: VecDeque<u64>,
    /// (time [ns], CPU time [s]) of the /proc samples over the rate window.
    cpu: VecDeque<(u64, f64)>,
    rss_bytes: Option<u64>,
}

/// Every service seen under one prefix.
#[derive(Debug, Default)]
pub struct Model {
    services: BTreeMap<ServiceId, Watched>,
}

/// The heartbeats' counters summed over inputs (received) and outputs (published).
fn totals(hb: &Heartbeat, id: ServiceId, t_ns: u64) -> Totals {
    let spec = id.spec();
    let (mut inputs, mut outputs) = (0, 0);
    for c in hb.topics.iter().filter(|c| c.topic != u32::MAX) {
        let Some(topic) = TopicId::from_u32(c.topic) else {
            continue;
        };
        if spec.inputs.contains(&topic) {
            inputs += c.received;
        }
        if spec.outputs.contains(&topic) {
            outputs += c.published;
        }
    }
    Totals {
        t_ns,
        inputs,
        outputs,
    }
}

/// The `q`-quantile of `v` (nearest rank).
fn quantile(v: &VecDeque<u64>, q: f64) -> Option<f64> {
    let mut s: Vec<u64> = v.iter().copied().collect();
    if s.is_empty() {
        return None;
    }
    s.sort_unstable();
    let k = ((q * s.len() as f64).ceil() as usize).clamp(1, s.len()) - 1;
    Some(s[k] as f64 * 1e-3)
}

impl Model {
    /// A heartbeat taken at `t_ns` (`CLOCK_MONOTONIC`).
    pub fn heartbeat(&mut self, hb: &Heartbeat, t_ns: u64) {
        let Some(id) = ServiceId::from_u32(hb.meta.producer) else {
            return;
        };
        let w = self.services.entry(id).or_default();
        if let Some(last) = &w.last {
            if last.pid != hb.pid {
                w.restarts += 1;
                // a new process counts from zero again
                w.totals.clear();
                w.cpu.clear();
            }
        }
        w.totals.push_back(totals(hb, id, t_ns));
        while w.totals.len() > 2 && t_ns - w.totals[1].t_ns > RATE_WINDOW_NS {
            w.totals.pop_front();
        }
        if hb.last_latency_ns > 0 {
            w.latencies_ns.push_back(hb.last_latency_ns);
            if w.latencies_ns.len() > LATENCY_WINDOW {
                w.latencies_ns.pop_front();
            }
        }
        w.last = Some(*hb);
        w.last_seen_ns = t_ns;
    }

    /// The pids to sample in /proc.
    pub fn pids(&self) -> Vec<(ServiceId, u32)> {
        (self.services.iter())
            .filter_map(|(id, w)| w.last.map(|hb| (*id, hb.pid)))
            .collect()
    }

    /// A /proc sample of `id`'s process at `t_ns`: its CPU time [s] and resident memory.
    pub fn process(&mut self, id: ServiceId, t_ns: u64, cpu_s: Option<f64>, rss: Option<u64>) {
        let Some(w) = self.services.get_mut(&id) else {
            return;
        };
        if let Some(c) = cpu_s {
            w.cpu.push_back((t_ns, c));
            // over the rate window: /proc counts CPU time in ticks of 10 ms
            while w.cpu.len() > 2 && t_ns - w.cpu[1].0 > RATE_WINDOW_NS {
                w.cpu.pop_front();
            }
        }
        w.rss_bytes = rss;
    }

    /// Every service seen, in table order, as of `now_ns`; a service whose last heartbeat is
    /// older than `silent_after_ns` shows as `silent`.
    pub fn rows(&self, now_ns: u64, silent_after_ns: u64) -> Vec<ServiceRow> {
        (self.services.iter())
            .filter_map(|(id, w)| {
                let hb = w.last?;
                let rate = |f: fn(&Totals) -> u64| match (w.totals.front(), w.totals.back()) {
                    (Some(a), Some(b)) if b.t_ns > a.t_ns => {
                        (f(b) - f(a).min(f(b))) as f64 / ((b.t_ns - a.t_ns) as f64 * 1e-9)
                    }
                    _ => 0.0,
                };
                let mut dropped = BTreeMap::new();
                for c in hb.topics.iter().filter(|c| c.topic != u32::MAX) {
                    for (r, n) in DropReason::ALL.iter().zip(c.dropped.iter()) {
                        if *n > 0 {
                            *dropped.entry(r.name().to_string()).or_default() += n;
                        }
                    }
                }
                let cpu_percent = match (w.cpu.front(), w.cpu.back()) {
                    (Some(a), Some(b)) if b.0 > a.0 => {
                        Some(100.0 * (b.1 - a.1).max(0.0) / ((b.0 - a.0) as f64 * 1e-9))
                    }
                    _ => None,
                };
                let state = if now_ns.saturating_sub(w.last_seen_ns) > silent_after_ns {
                    "silent"
                } else {
                    state_name(hb.state)
                };
                Some(ServiceRow {
                    name: id.name().to_string(),
                    state: state.to_string(),
                    pid: hb.pid,
                    restarts: w.restarts,
                    inputs_per_s: rate(|t| t.inputs),
                    outputs_per_s: rate(|t| t.outputs),
                    latency_p50_us: quantile(&w.latencies_ns, 0.5),
                    latency_p99_us: quantile(&w.latencies_ns, 0.99),
                    dropped,
                    cpu_percent,
                    rss_mib: w.rss_bytes.map(|b| b as f64 / (1 << 20) as f64),
                })
            })
            .collect()
    }
}

/// A heartbeat's state by name.
pub fn state_name(state: u32) -> &'static str {
    match state {
        Heartbeat::STARTING => "starting",
        Heartbeat::READY => "ready",
        Heartbeat::RUNNING => "running",
        Heartbeat::FINISHED => "finished",
        Heartbeat::STOPPING => "stopping",
        _ => "unknown",
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use shared_types::{Meta, TopicCounters};

    fn beat(service: ServiceId, pid: u32, received: u64, published: u64, lat_ns: u64) -> Heartbeat {
        let mut hb: Heartbeat = bytemuck::Zeroable::zeroed();
        hb.meta = Meta::new(0, 0, 0, service);
        hb.pid = pid;
        hb.state = Heartbeat::RUNNING;
        hb.last_latency_ns = lat_ns;
        for c in hb.topics.iter_mut() {
            c.topic = u32::MAX;
        }
        hb.topics[0] = TopicCounters {
            topic: TopicId::Frame as u32,
            received,
            ..Default::default()
        };
        hb.topics[1] = TopicCounters {
            topic: TopicId::Detections as u32,
            published,
            dropped: [0, 2, 0, 0, 0, 0, 0, 0],
            ..Default::default()
        };
        hb
    }

    /// Rates from the counters over time, percentiles of the latencies seen, drops by reason,
    /// a restart as a new pid, CPU from two /proc samples, silence after the deadline.
    #[test]
    fn rows_follow_the_heartbeats() {
        let mut m = Model::default();
        let s = 1_000_000_000;
        for k in 0..=10u64 {
            // 100 frames/s in, 100 detections/s out; latencies 1..=11 µs
            let hb = beat(ServiceId::Detector, 7, 10 * k, 10 * k, 1000 * (k + 1));
            m.heartbeat(&hb, s + k * 100_000_000);
        }
        m.process(ServiceId::Detector, s, Some(1.0), Some(8 << 20));
        m.process(ServiceId::Detector, 2 * s, Some(1.25), Some(8 << 20));
        let rows = m.rows(2 * s, s);
        assert_eq!(rows.len(), 1);
        let r = &rows[0];
        assert_eq!(
            (r.name.as_str(), r.state.as_str(), r.pid),
            ("detector", "running", 7)
        );
        assert!((r.inputs_per_s - 100.0).abs() < 1e-9, "{r:?}");
        assert!((r.outputs_per_s - 100.0).abs() < 1e-9, "{r:?}");
        assert_eq!(r.latency_p50_us, Some(6.0));
        assert_eq!(r.latency_p99_us, Some(11.0));
        assert_eq!(r.dropped.get("malformed"), Some(&2));
        assert!((r.cpu_percent.unwrap() - 25.0).abs() < 1e-9);
        assert_eq!(r.rss_mib, Some(8.0));
        // a new process: one restart
        m.heartbeat(&beat(ServiceId::Detector, 8, 0, 0, 0), 3 * s);
        assert_eq!(m.rows(3 * s, s)[0].restarts, 1);
        // heard from no more
        assert_eq!(m.rows(5 * s, s)[0].state, "silent");
    }
}
