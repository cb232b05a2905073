//! What a run leaves to report: its services, every topic's accounting, the science each
//! section scores, collected once from the orchestrator's consumer and the children.

use std::collections::BTreeMap;

use shared_types::{deployment, Scenario, ServiceId, TopicCounters, TopicId};

use super::science;
use crate::run::consume::Consumer;
use crate::run::deploy::{Ending, ServiceProcess};
use crate::run::latency::Latency;

pub struct Outcome {
    pub startup_s: f64,
    pub production_s: f64,
}

pub struct ServiceFact {
    pub name: String,
    pub pid: u32,
    pub restarts: u32,
    pub ending: Ending,
    /// CPU time of its last incarnation [s] (none if it did not exit).
    pub cpu_s: Option<f64>,
    /// Where its last incarnation's time went, from its last heartbeat.
    pub time: Option<shared_types::ServiceTime>,
}

pub struct ConsumerFact {
    pub received: u64,
    pub dropped: [u64; shared_types::DROP_REASONS],
    /// Copies skipped because they were already accounted for (replays after a restart).
    pub duplicates: u64,
}

pub struct TopicFact {
    /// What the run had to carry: the scenario's count less what was dropped upstream with a
    /// counted reason.
    pub expected: u64,
    pub published: Option<u64>,
    /// The producer's own counts of what it dropped (`injected`) or sent invalid
    /// (`malformed`) on purpose: in-band faults.
    pub producer_dropped: [u64; shared_types::DROP_REASONS],
    pub digest: Option<u64>,
    pub consumers: BTreeMap<String, Option<ConsumerFact>>,
}

pub struct RunFacts {
    /// What `--record` wrote.
    pub recording: Option<crate::run::record::RecordingReport>,
    /// The open recording, closed with the report in it once that is written.
    pub recorder: Option<crate::run::record::Recorder>,
    /// The mission sections of the report ([`super::sections`]).
    pub sections: Vec<Box<dyn super::sections::Section>>,
    pub services: Vec<ServiceFact>,
    pub topics: BTreeMap<TopicId, TopicFact>,
    pub failure: Option<String>,
    pub outcome: Outcome,
    pub frame_latency: Latency,
    pub spectrum_latency: Latency,
    /// Per pipeline stage, its latency per frame from the messages' send times
    /// ([`crate::run::taps::Stages`]).
    pub stage_latency: Vec<(&'static str, Latency)>,
    /// The orchestrator's own CPU time at the end of the run [s].
    pub orchestrator_cpu_s: Option<f64>,
    /// Range requests the sensor served (its current incarnation; retries included).
    pub range_requests: u64,
    /// Laser shots the tracker fired (one per confirmed track and frame, from the tracks).
    pub laser_shots: u64,
    /// One digest of every result the run produced: each topic's content digest and the
    /// solve's answers (send times left out). Equal digests, equal science.
    pub science_digest: u64,
    pub wall_s: f64,
    pub prefix: String,
    pub scenario_file: String,
    pub shm_removed: usize,
    pub shm_leftover: Vec<String>,
    /// Live nodes under the prefix once the deployment ended (processes outside it).
    pub shm_held_by: Vec<String>,
    /// The injected faults and what supervision saw of them.
    pub faults: Vec<crate::run::faults::Fault>,
    /// Solve answers the inversion dropped and sent invalid on purpose, and those the
    /// sequencer noticed as unanswered and rejected as malformed.
    pub solve_tampered: [u64; 4],
    /// Nodes under the prefix that were not the deployment's ([`crate::run::membership`]).
    /// Every process's resident memory over the run.
    pub memory: BTreeMap<String, crate::run::memory::MemoryTrace>,
    /// A soak's end ([`crate::run::live::SoakEnd`]).
    pub soak_end: Option<crate::run::live::SoakEnd>,
    pub membership: super::MembershipReport,
    /// A split deployment's hosts ([`crate::run::links`]).
    pub hosts: Vec<crate::run::links::HostReport>,
}

fn consumer_fact(c: TopicCounters) -> ConsumerFact {
    ConsumerFact {
        received: c.received,
        dropped: c.dropped,
        duplicates: u64::from(c.duplicates),
    }
}

impl RunFacts {
    pub fn collect(
        consumer: &Consumer,
        children: &[ServiceProcess],
        scenario: &Scenario,
        solve: Vec<shared_types::SolveResponse>,
        failure: Option<String>,
        faults: Vec<crate::run::faults::Fault>,
        outcome: Outcome,
    ) -> Self {
        let services = children
            .iter()
            .map(|c| ServiceFact {
                name: c.id.name().to_string(),
                pid: c.pid,
                restarts: c.restarts,
                ending: c.ending.clone(),
                cpu_s: c.cpu_s,
                time: consumer.seen.get(&c.id).map(|s| s.heartbeat.time),
            })
            .collect();
        let digests = consumer.digests();
        let taps = &consumer.taps;
        let science = science::digest(&digests, &solve);
        let mut topics = BTreeMap::new();
        for spec in deployment::data_topics(scenario) {
            let t = spec.id;
            let expected = consumer.expected_now(t);
            let mut consumers = BTreeMap::new();
            for c in deployment::consumers(scenario, t) {
                let fact = if c == ServiceId::Orchestrator {
                    consumer
                        .own_stats()
                        .into_iter()
                        .find(|s| s.topic == t)
                        .map(|s| consumer_fact(s.counters()))
                } else {
                    consumer.reported(c, t).map(consumer_fact)
                };
                consumers.insert(c.name().to_string(), fact);
            }
            // A publisher killed between heartbeats reported fewer than it published: what its
            // consumers received (or dropped) it published at least.
            let producer = deployment::producer(t);
            let reported = producer
                .and_then(|p| consumer.reported(p, t))
                .map(|c| c.published);
            let seen = consumers
                .values()
                .flatten()
                .map(|c| c.received + c.dropped.iter().sum::<u64>())
                .max();
            let published = match (reported, seen) {
                (Some(p), Some(s)) => Some(p.max(s)),
                (p, s) => p.or(s),
            };
            topics.insert(
                t,
                TopicFact {
                    expected,
                    published,
                    producer_dropped: producer
                        .and_then(|p| consumer.reported(p, t))
                        .map_or([0; shared_types::DROP_REASONS], |c| c.dropped),
                    digest: digests.get(&t).copied(),
                    consumers,
                },
            );
        }
        let material = super::sections::Material {
            scenario,
            taps,
            solve: &solve,
        };
        let sections = super::sections::collect(&material);
        RunFacts {
            sections,
            services,
            topics,
            failure,
            outcome,
            frame_latency: taps.latency(TopicId::Frame),
            stage_latency: taps.stages(),
            orchestrator_cpu_s: crate::run::deploy::cpu_seconds("self"),
            spectrum_latency: taps.latency(TopicId::Spectrum),
            range_requests: deployment::producer(TopicId::Range)
                .and_then(|p| consumer.reported(p, TopicId::Range))
                .map_or(0, |c| c.received + c.dropped.iter().sum::<u64>()),
            laser_shots: (taps.fold::<super::score_debris::DebrisScorer>())
                .map_or(0, |s| s.laser_shots),
            science_digest: science,
            wall_s: 0.0,
            prefix: String::new(),
            scenario_file: String::new(),
            shm_removed: 0,
            shm_leftover: vec![],
            shm_held_by: vec![],
            faults,
            solve_tampered: [0; 4],
            membership: Default::default(),
            hosts: vec![],
            memory: BTreeMap::new(),
            soak_end: None,
            recording: None,
            recorder: None,
        }
    }

    /// received + dropped == published == expected, for every topic and consumer.
    pub fn invariant_held(&self) -> bool {
        self.topics.values().all(|t| {
            t.published == Some(t.expected)
                && t.consumers.values().all(|c| {
                    c.as_ref()
                        .is_some_and(|c| c.received + c.dropped.iter().sum::<u64>() == t.expected)
                })
        })
    }

    pub fn success(&self) -> bool {
        self.failure.is_none()
            && self.invariant_held()
            && (self.shm_leftover.is_empty() || !self.shm_held_by.is_empty())
            && self.services.iter().all(|s| s.ending == Ending::Shutdown)
    }
}
