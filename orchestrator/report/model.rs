//! `report.json` as types: [`Report`] is what a run writes and what every reader — summary.md,
//! the console, the fault matrix, `glint lab`, the system tests, other tools through the
//! published schema (`glint report --schema`) — reads back by deserialising, never by keys.
//!
//! Its deterministic part is a type: [`Results`] is a function of the scenario and the seed
//! alone (two runs of the same scenario and seed give equal `Results`); what this run did
//! besides — its identity and process ids ([`RunInfo`]), its timings ([`Timing`]), the faults
//! injected into it and the strangers seen ([`Report::faults`], [`Report::membership`]) — lives
//! beside it.

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::{Context, Result};
use schemars::JsonSchema;
use serde::{Deserialize, Deserializer, Serialize};

use super::earth::EarthReport;
use super::inversion::InversionReport;
use crate::report::score_debris::{DetectionScore, TargetScore};

/// `report.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct Report {
    /// What the run found: a function of the scenario and the seed alone.
    #[serde(flatten)]
    pub results: Results,
    /// Every injected fault and what supervision saw of it (times in seconds after the
    /// services were started).
    pub faults: Vec<FaultReport>,
    /// Nodes under the deployment's prefix that were not the deployment's.
    pub membership: MembershipReport,
    /// A soak's verdict and figures (`[soak]`, `glint run --soak`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub soak: Option<super::soak::SoakReport>,
    /// This run's identity: its prefix, files, process ids.
    pub run: RunInfo,
    /// Where the time went, on this machine.
    pub timing: Timing,
}

/// The deterministic part of a report.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct Results {
    pub glint_version: String,
    pub contract_version: u32,
    pub scenario: ScenarioInfo,
    pub seed: u64,
    /// The run passed: no failure, every message accounted for, nothing left in shared
    /// memory, every service ended by `Shutdown`.
    pub success: bool,
    /// Why it failed.
    pub failure: Option<String>,
    pub accounting: Accounting,
    pub services: Vec<ServiceReport>,
    /// Per data topic, by name.
    pub topics: BTreeMap<String, TopicReport>,
    pub science: Science,
    pub laser: LaserReport,
    pub shared_memory: SharedMemory,
    /// [000] the attitude solve.
    pub inversion: Option<InversionReport>,
    /// [003] the infrared Earth sensor.
    pub earth: Option<EarthReport>,
    /// [002] detections against truth.
    pub detection: Option<DetectionScore>,
    /// [002] tracks against truth.
    pub tracking: Option<TrackingReport>,
    /// [004] relative navigation against truth.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub relnav: Option<super::sections::RelNavReport>,
    /// [001] ground photometry against truth.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub photometry: Option<super::sections::PhotometryReport>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct ScenarioInfo {
    pub name: String,
    /// `sim` or `realtime`.
    pub clock: String,
    /// Messages produced per sensor stream (the expected count on a complete run).
    pub frames: u64,
    pub spectra: u64,
    pub earth_frames: u64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct Accounting {
    /// received + dropped == published == expected, for every topic and consumer.
    pub invariant_held: bool,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct ServiceReport {
    pub name: String,
    pub restarts: u32,
    /// `shutdown`, `sigterm`, `sigkill`, `exited (…)`, `running`.
    pub ending: String,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct TopicReport {
    /// What the run had to carry: the scenario's count less what was dropped upstream with a
    /// counted reason.
    pub expected: u64,
    pub published: Option<u64>,
    /// xxh3 of the content the orchestrator received (16 hex digits).
    pub digest_xxh3: Option<String>,
    /// Per consumer (the orchestrator among them), by service name.
    pub consumers: BTreeMap<String, ConsumerReport>,
}

/// One consumer's counts on a topic (`received`, `dropped` absent: it reported none).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct ConsumerReport {
    pub received: Option<u64>,
    /// Copies skipped because they were already accounted for (replays after a restart).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub duplicates: Option<u64>,
    pub dropped: Option<u64>,
    /// By reason: overflow, malformed, injected, late, stale.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dropped_by_reason: Option<BTreeMap<String, u64>>,
    /// received + dropped == expected.
    pub accounted: bool,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct Science {
    /// One digest of every result the run produced (every topic's content and the solve's
    /// answers): equal digests, equal science.
    pub digest_xxh3: String,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct LaserReport {
    /// Shots the tracker fired.
    pub shots: u64,
    /// Requests the sensor served.
    pub served: u64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct SharedMemory {
    /// Entries of the deployment's prefix still there after it ended: a failure of the run,
    /// unless live nodes outside the deployment hold them (`held_by`: observers such as a
    /// Python client, whose files they are).
    pub leftover: Vec<String>,
    /// Live nodes outside the deployment that held them.
    pub held_by: Vec<String>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct TrackingReport {
    pub targets: Vec<TargetScore>,
}

/// One injected fault.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct FaultReport {
    pub service: String,
    /// kill, stop, panic, delay, drop, corrupt.
    pub kind: String,
    pub at_seq: Option<u64>,
    pub at_s: Option<f64>,
    pub duration_s: Option<f64>,
    /// A delay by messages, a drop's or a corruption's outputs: how many.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub count: Option<u32>,
    /// A delay: added before each message [ms].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub delay_ms: Option<u64>,
    /// A bridge's delay (a slow link): the link's bandwidth while it lasted [Mbit/s].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bandwidth_mbit_s: Option<f64>,
    pub injected_s: Option<f64>,
    pub ended_s: Option<f64>,
    pub detected_s: Option<f64>,
    /// `exit`, `heartbeat deadline`, `sequence gap`, `validation`.
    pub detected_by: Option<String>,
    /// Recovered: a restarted service has taken again the input the fault found it at; a
    /// stop's service is heard from after SIGCONT; a delay's service has taken every input
    /// that had arrived when the delay ended; a drop or corruption is counted downstream.
    pub recovered_s: Option<f64>,
    /// From the restarted service's resume (a delay: its end) to recovered [s].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub catch_up_s: Option<f64>,
    /// A restart: inputs fed again, from its restored checkpoint (or the first) to where the
    /// fault found it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub replayed: Option<u64>,
    /// Why the run ended before this fault's verdict could be reached (absent: reached).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub not_reached: Option<String>,
    pub restarts: u32,
    /// What it cost: messages the service's inputs carried that it never processed (the
    /// sensor: that it never produced); a drop or corruption: how many it made.
    pub lost: Option<u64>,
    pub invariant_held: bool,
    /// Against a fault-free run of the same seed (the fault matrix).
    pub science_equal: Option<bool>,
    /// A drop or corruption: outputs dropped or sent invalid on purpose.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub injected: Option<u64>,
    /// A drop or corruption: the fewest of them any consumer counted.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub counted: Option<u64>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema, Default)]
pub struct MembershipReport {
    pub strangers: Vec<StrangerReport>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct StrangerReport {
    pub name: String,
    pub pid: Option<u32>,
    /// `impostor` (named as a glint service: fails the run) or `observer`.
    pub role: String,
    pub seen_s: f64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct RunInfo {
    /// The deployment's shared-memory prefix (`glint clean --prefix`).
    pub prefix: String,
    pub scenario_file: String,
    pub shm_entries_removed: usize,
    /// Each service's last process id.
    pub pids: BTreeMap<String, u32>,
    /// What `glint run --record` wrote.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub recording: Option<crate::run::record::RecordingReport>,
    /// A deployment split across hosts: each host, its services, the times it was cut off,
    /// and the orchestrator's host's bridge per hop (docs/hosts.md).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub hosts: Vec<crate::run::links::HostReport>,
}

/// Percentiles of a latency sample [µs].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct Percentiles {
    pub count: usize,
    pub p50: f64,
    pub p90: f64,
    pub p99: f64,
    pub max: f64,
}

impl Percentiles {
    pub fn of_ns(ns: &[u64]) -> Option<Percentiles> {
        if ns.is_empty() {
            return None;
        }
        let mut v = ns.to_vec();
        v.sort_unstable();
        let p = |q: f64| v[((v.len() - 1) as f64 * q).round() as usize] as f64 / 1e3;
        Some(Percentiles {
            count: v.len(),
            p50: p(0.5),
            p90: p(0.9),
            p99: p(0.99),
            max: p(1.0),
        })
    }
}

/// Where a service's time went [s].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct ServiceTiming {
    pub busy_s: f64,
    pub credit_wait_s: f64,
    pub idle_s: f64,
    /// Of busy: its own computation and housekeeping.
    pub work_s: f64,
    pub checksum_s: f64,
    pub publish_s: f64,
    pub rpc_wait_s: f64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct Timing {
    pub wall_s: f64,
    pub startup_s: f64,
    pub production_s: f64,
    pub frames_per_s: f64,
    pub spectra_per_s: f64,
    pub earth_frames_per_s: f64,
    /// Sensor send → orchestrator receive.
    pub frame_latency_us: Option<Percentiles>,
    pub spectrum_latency_us: Option<Percentiles>,
    /// [002] per stage, from the messages' send times: detect, track, end_to_end.
    pub stage_latency_us: BTreeMap<String, Option<Percentiles>>,
    /// CPU time of each process [s] (the services' last incarnations, the orchestrator).
    pub cpu_s: BTreeMap<String, Option<f64>>,
    pub time_s: BTreeMap<String, ServiceTiming>,
    /// [003] each method's compute time per answered frame, the shared edges included [µs].
    #[serde(default)]
    pub earth_us_per_frame: BTreeMap<String, Option<f64>>,
    /// Each process's resident memory over the run, sampled about once a second.
    #[serde(default)]
    pub memory: BTreeMap<String, crate::run::memory::MemoryTrace>,
}

impl Report {
    /// Reads `report.json`.
    pub fn read(path: &Path) -> Result<Report> {
        let text =
            std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
        serde_json::from_str(&text).with_context(|| format!("parsing {}", path.display()))
    }

    /// The JSON Schema of `report.json` (`glint report --schema`).
    pub fn schema() -> serde_json::Value {
        serde_json::to_value(schemars::schema_for!(Report)).unwrap_or_default()
    }
}

/// A number that JSON carries as `null` when it is not finite (serde_json writes NaN as
/// `null`): read back as NaN.
pub fn f64_or_nan<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
}

/// [`f64_or_nan`] for a triple.
pub fn triple_or_nan<'de, D: Deserializer<'de>>(d: D) -> Result<[f64; 3], D::Error> {
    let v = <[Option<f64>; 3]>::deserialize(d)?;
    Ok(v.map(|x| x.unwrap_or(f64::NAN)))
}

/// [`f64_or_nan`] for a pair.
pub fn pair_or_nan<'de, D: Deserializer<'de>>(d: D) -> Result<[f64; 2], D::Error> {
    let v = <[Option<f64>; 2]>::deserialize(d)?;
    Ok(v.map(|x| x.unwrap_or(f64::NAN)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_published_schema_is_the_types_schema() {
        let published: serde_json::Value =
            serde_json::from_str(include_str!("../../docs/report.schema.json")).unwrap();
        assert_eq!(
            published,
            Report::schema(),
            "docs/report.schema.json is stale: `glint report --schema > docs/report.schema.json`"
        );
    }

    #[test]
    fn a_failed_solve_reads_back() {
        // A failed stage 3 answers with every number NaN: written as nulls, read back as NaN.
        let sp = crate::run::command::default_scenario().spectra.unwrap();
        let failed = shared_types::SolveResponse {
            stage: 3,
            ..Default::default()
        };
        let report = super::super::inversion::InversionReport::new(&sp, &[failed]);
        let text = serde_json::to_string(&report).unwrap();
        let back: super::super::inversion::InversionReport =
            serde_json::from_str(&text).unwrap_or_else(|e| panic!("{e}: {text}"));
        assert_eq!(
            serde_json::to_string(&back).unwrap(),
            text,
            "the same report once read back"
        );
    }

    #[test]
    fn a_non_finite_score_reads_back_as_nan() {
        #[derive(Deserialize)]
        struct S {
            #[serde(deserialize_with = "f64_or_nan")]
            x: f64,
            #[serde(deserialize_with = "pair_or_nan")]
            p: [f64; 2],
        }
        let s: S = serde_json::from_str(r#"{"x": null, "p": [1.5, null]}"#).unwrap();
        assert!(s.x.is_nan() && s.p[0] == 1.5 && s.p[1].is_nan());
    }
}
