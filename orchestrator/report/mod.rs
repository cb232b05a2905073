//! The run report: `report.json` (machine-readable) and `summary.md` (what a person reads).
//!
//! Everything outside the `run` and `timing` objects, the `pid` fields and the Earth methods'
//! `time_us_per_frame` is a function of the scenario and the seed alone, so two runs of the same scenario and seed give byte-identical
//! reports once those are removed (keys are sorted; serde_json's map is a BTreeMap).

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Context, Result};
use serde_json::{json, Value};
use shared_types::{deployment, DropReason, Scenario, ServiceId, TopicCounters, TopicId};

pub mod debris;
pub mod earth;
mod earth_frame;
pub mod faults;
pub mod fit;
pub mod inversion;
mod science;

use crate::consume::Consumer;
use crate::deploy::{Ending, ServiceProcess};

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

/// What the debris pictures need besides the score.
pub struct DebrisFacts {
    pub score: crate::score_debris::DebrisScore,
    pub camera: glint_physics::camera::PinholeCamera,
    pub snapshot: Option<(u64, u32, u32, Vec<u16>)>,
    pub detections: Vec<shared_types::Detections>,
    pub truths: Vec<shared_types::Truth>,
}

/// What the Earth sensor's section and pictures need.
pub struct EarthFacts {
    pub score: earth::EarthScore,
    pub snapshot: Option<(u64, u32, u32, Vec<u16>)>,
    pub answers: Vec<shared_types::EarthAttitude>,
    pub truths: Vec<shared_types::Truth>,
}

pub struct RunFacts {
    pub debris: Option<DebrisFacts>,
    pub earth: Option<EarthFacts>,
    pub solve: Vec<shared_types::SolveResponse>,
    pub spectra: Vec<shared_types::Spectrum>,
    pub services: Vec<ServiceFact>,
    pub topics: BTreeMap<TopicId, TopicFact>,
    pub failure: Option<String>,
    pub outcome: Outcome,
    pub frame_latency_ns: Vec<u64>,
    pub spectrum_latency_ns: Vec<u64>,
    /// Per pipeline stage, its latency per frame from the messages' send times ([`stages`]).
    pub stage_latency_ns: Vec<(&'static str, Vec<u64>)>,
    /// The orchestrator's own CPU time at the end of the run [s].
    pub orchestrator_cpu_s: Option<f64>,
    pub light_curve: Vec<(u64, [f64; 3], [f64; 3])>,
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
    pub faults: Vec<crate::faults::Fault>,
    /// Solve answers the inversion dropped and sent invalid on purpose, and those the
    /// sequencer noticed as unanswered and rejected as malformed.
    pub solve_tampered: [u64; 4],
    /// Nodes under the prefix that were not the deployment's ([`crate::membership`]).
    pub membership: Value,
}

/// The service that publishes a topic.
pub(super) use shared_types::deployment::producer as producer_of;

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
        faults: Vec<crate::faults::Fault>,
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
            })
            .collect();
        let digests = consumer.digests();
        let science = science::digest(&digests, &solve);
        let mut topics = BTreeMap::new();
        for t in [
            TopicId::Frame,
            TopicId::Detections,
            TopicId::Tracks,
            TopicId::Spectrum,
            TopicId::EarthFrame,
            TopicId::EarthAttitude,
            TopicId::Truth,
        ] {
            if deployment::expected_messages(scenario, t) == 0 {
                continue;
            }
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
            let reported = consumer.reported(producer_of(t), t).map(|c| c.published);
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
                    producer_dropped: consumer
                        .reported(producer_of(t), t)
                        .map_or([0; shared_types::DROP_REASONS], |c| c.dropped),
                    digest: digests.get(&t).copied(),
                    consumers,
                },
            );
        }
        let debris = scenario.camera.as_ref().map(|cam| {
            let camera = glint_detector::service_core::camera(cam);
            let a_m = cam.orbit_semi_major_axis_km * 1e3;
            let n_rad_s = (glint_physics::orbit::MU_EARTH_M3_S2 / (a_m * a_m * a_m)).sqrt();
            let frame_truths: Vec<shared_types::Truth> = consumer
                .truths
                .iter()
                .filter(|t| t.kind == shared_types::Truth::KIND_FRAME)
                .copied()
                .collect();
            DebrisFacts {
                score: crate::score_debris::score(
                    &camera,
                    n_rad_s,
                    &frame_truths,
                    &consumer.detection_msgs,
                    &consumer.track_msgs,
                ),
                camera,
                snapshot: consumer.snapshot.clone(),
                detections: consumer.detection_msgs.clone(),
                truths: frame_truths,
            }
        });
        let earth = scenario.earth.as_ref().map(|_| {
            let truths: Vec<shared_types::Truth> = (consumer.truths.iter())
                .filter(|t| t.kind == shared_types::Truth::KIND_EARTH)
                .copied()
                .collect();
            EarthFacts {
                score: earth::score(&truths, &consumer.earth_msgs),
                snapshot: consumer.earth_snapshot.clone(),
                answers: consumer.earth_msgs.clone(),
                truths,
            }
        });
        RunFacts {
            debris,
            earth,
            solve,
            spectra: consumer.spectra_msgs.clone(),
            services,
            topics,
            failure,
            outcome,
            frame_latency_ns: consumer.frame_latency_ns.clone(),
            stage_latency_ns: stages(consumer),
            orchestrator_cpu_s: crate::deploy::cpu_seconds("self"),
            spectrum_latency_ns: consumer.spectrum_latency_ns.clone(),
            light_curve: consumer.light_curve.clone(),
            range_requests: consumer
                .reported(ServiceId::Sensor, TopicId::Range)
                .map_or(0, |c| c.received + c.dropped.iter().sum::<u64>()),
            laser_shots: consumer
                .track_msgs
                .iter()
                .flat_map(|m| m.items[..(m.n as usize).min(m.items.len())].iter())
                .filter(|e| e.range_status != u32::MAX)
                .count() as u64,
            science_digest: science,
            wall_s: 0.0,
            prefix: String::new(),
            scenario_file: String::new(),
            shm_removed: 0,
            shm_leftover: vec![],
            shm_held_by: vec![],
            faults,
            solve_tampered: [0; 4],
            membership: Value::Null,
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
            && self.shm_leftover.is_empty()
            && self.services.iter().all(|s| s.ending == Ending::Shutdown)
    }
}

/// Percentiles of a latency sample [µs].
fn percentiles_us(ns: &[u64]) -> Value {
    if ns.is_empty() {
        return Value::Null;
    }
    let mut v = ns.to_vec();
    v.sort_unstable();
    let p = |q: f64| v[((v.len() - 1) as f64 * q).round() as usize] as f64 / 1e3;
    json!({ "count": v.len(), "p50": p(0.5), "p90": p(0.9), "p99": p(0.99), "max": p(1.0) })
}

fn report_json(scenario: &Scenario, f: &RunFacts) -> Value {
    let mut topics = serde_json::Map::new();
    for (t, tf) in &f.topics {
        let mut consumers = serde_json::Map::new();
        for (name, c) in &tf.consumers {
            let v = match c {
                Some(c) => {
                    let by_reason: serde_json::Map<String, Value> = DropReason::ALL
                        .iter()
                        .map(|r| (r.name().to_string(), json!(c.dropped[*r as usize])))
                        .collect();
                    json!({
                        "received": c.received,
                        "duplicates": c.duplicates,
                        "dropped": c.dropped.iter().sum::<u64>(),
                        "dropped_by_reason": by_reason,
                        "accounted": c.received + c.dropped.iter().sum::<u64>() == tf.expected,
                    })
                }
                None => json!({ "received": null, "dropped": null, "accounted": false }),
            };
            consumers.insert(name.clone(), v);
        }
        topics.insert(
            t.name().to_string(),
            json!({
                "expected": tf.expected,
                "published": tf.published,
                "digest_xxh3": tf.digest.map(|d| format!("{d:016x}")),
                "consumers": consumers,
            }),
        );
    }
    // What was produced: the expected count on a complete run, fewer on a failed one.
    let produced = |id| {
        f.topics
            .get(&id)
            .map_or(0, |t: &TopicFact| t.published.unwrap_or(t.expected))
    };
    let (frames, spectra) = (produced(TopicId::Frame), produced(TopicId::Spectrum));
    let earth_frames = produced(TopicId::EarthFrame);
    let rate = |n: u64| {
        if f.outcome.production_s > 0.0 {
            n as f64 / f.outcome.production_s
        } else {
            0.0
        }
    };
    let (detection, tracking) = match &f.debris {
        Some(d) => debris::json(&d.score),
        None => (Value::Null, Value::Null),
    };
    let inversion = match &scenario.spectra {
        Some(sp) => serde_json::to_value(inversion::InversionReport::new(sp, &f.solve))
            .unwrap_or(Value::Null),
        None => Value::Null,
    };
    let earth = f.earth.as_ref().map_or(Value::Null, |e| e.score.json());
    json!({
        "inversion": inversion,
        "earth": earth,
        "detection": detection,
        "tracking": tracking,
        "glint_version": env!("CARGO_PKG_VERSION"),
        "contract_version": shared_types::CONTRACT_VERSION,
        "scenario": {
            "name": scenario.name,
            "clock": format!("{:?}", scenario.clock).to_lowercase(),
            "frames": frames,
            "spectra": spectra,
            "earth_frames": earth_frames,
        },
        "seed": scenario.seed,
        "success": f.success(),
        "failure": f.failure,
        "accounting": { "invariant_held": f.invariant_held() },
        "faults": faults::json(f),
        "services": f.services.iter().map(|s| json!({
            "name": s.name, "pid": s.pid, "restarts": s.restarts, "ending": s.ending.label(),
        })).collect::<Vec<_>>(),
        "topics": topics,
        "science": { "digest_xxh3": format!("{:016x}", f.science_digest) },
        "membership": f.membership,
        "laser": { "shots": f.laser_shots, "served": f.range_requests },
        "shared_memory": { "leftover": f.shm_leftover, "held_by": f.shm_held_by },
        "run": {
            "prefix": f.prefix,
            "scenario_file": f.scenario_file,
            "shm_entries_removed": f.shm_removed,
        },
        "timing": {
            "wall_s": f.wall_s,
            "startup_s": f.outcome.startup_s,
            "production_s": f.outcome.production_s,
            "frames_per_s": rate(frames),
            "spectra_per_s": rate(spectra),
            "earth_frames_per_s": rate(earth_frames),
            "frame_latency_us": percentiles_us(&f.frame_latency_ns),
            "spectrum_latency_us": percentiles_us(&f.spectrum_latency_ns),
            "stage_latency_us": f.stage_latency_ns.iter()
                .map(|(name, ns)| (name.to_string(), percentiles_us(ns)))
                .collect::<serde_json::Map<_, _>>(),
            "cpu_s": f.services.iter().map(|s| (s.name.clone(), json!(s.cpu_s)))
                .chain([("orchestrator".to_string(), json!(f.orchestrator_cpu_s))])
                .collect::<serde_json::Map<_, _>>(),
        },
    })
}

/// A text histogram of latencies (log-spaced bins) for the summary.
fn latency_histogram(ns: &[u64]) -> String {
    if ns.is_empty() {
        return String::new();
    }
    let edges_us = [
        5.0,
        10.0,
        20.0,
        50.0,
        100.0,
        200.0,
        500.0,
        1000.0,
        2000.0,
        5000.0,
        f64::INFINITY,
    ];
    let mut counts = vec![0usize; edges_us.len()];
    for &v in ns {
        let us = v as f64 / 1e3;
        let i = edges_us
            .iter()
            .position(|e| us < *e)
            .unwrap_or(edges_us.len() - 1);
        counts[i] += 1;
    }
    let max = *counts.iter().max().unwrap_or(&1).max(&1);
    let mut s = String::from("```\n");
    let mut lo = 0.0;
    for (e, c) in edges_us.iter().zip(&counts) {
        let label = if e.is_finite() {
            format!("{lo:>6.0}–{e:<6.0} µs")
        } else {
            format!("{lo:>6.0}+        µs")
        };
        let bar = "█".repeat((c * 40).div_ceil(max));
        let _ = writeln!(s, "{label} {bar} {c}");
        lo = *e;
    }
    s.push_str("```\n");
    s
}

fn summary_md(scenario: &Scenario, f: &RunFacts, j: &Value) -> String {
    let mut s = String::new();
    let verdict = if f.success() { "PASS" } else { "FAIL" };
    let _ = writeln!(s, "# glint run: {} — {verdict}\n", scenario.name);
    if !scenario.description.is_empty() {
        let _ = writeln!(s, "{}\n", scenario.description.trim());
    }
    let _ = writeln!(
        s,
        "Seed {}, clock `{}`, scenario file `{}`.\n",
        scenario.seed,
        j["scenario"]["clock"].as_str().unwrap_or("?"),
        f.scenario_file
    );
    if let Some(fail) = &f.failure {
        let _ = writeln!(s, "**Failure:** {fail}\n");
    }
    // The answer first: the attitude solve's rate and its uncertainty, then the run's record.
    if let Some(sp) = &scenario.spectra {
        let report = inversion::InversionReport::new(sp, &f.solve);
        s.push_str(&report.markdown(sp.wavelengths_nm().len()));
    }
    if let Some(e) = &f.earth {
        s.push_str(&e.score.markdown());
    }
    let _ = writeln!(
        s,
        "\n## Services\n\n| service | pid | restarts | ended by | CPU [s] |\n|---|---|---|---|---|"
    );
    for sv in &f.services {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} |",
            sv.name,
            sv.pid,
            sv.restarts,
            sv.ending.label(),
            sv.cpu_s.map_or("—".into(), |c| format!("{c:.2}"))
        );
    }
    s.push_str(&faults::markdown(f));
    let _ = writeln!(
        s,
        "\n## Message accounting\n\nEvery message published must be received or dropped with a counted reason.\n\n| topic | published | consumer | received | dropped | accounted | digest |\n|---|---|---|---|---|---|---|"
    );
    for (t, tf) in &f.topics {
        for (name, c) in &tf.consumers {
            let (r, d, ok) = match c {
                Some(c) => {
                    let d: u64 = c.dropped.iter().sum();
                    (
                        c.received.to_string(),
                        d.to_string(),
                        c.received + d == tf.expected,
                    )
                }
                None => ("—".into(), "—".into(), false),
            };
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {} | `{}` |",
                t.name(),
                tf.published.map_or("—".into(), |p| p.to_string()),
                name,
                r,
                d,
                if ok { "yes" } else { "**NO**" },
                tf.digest.map_or(String::new(), |d| format!("{d:016x}"))
            );
        }
    }
    let tm = &j["timing"];
    let _ = writeln!(
        s,
        "\n## Timing (this machine; not part of the deterministic results)\n\n- wall time {:.3} s (startup {:.3} s, production {:.3} s)\n- frames/s {:.1}, spectra/s {:.1}, Earth frames/s {:.1}\n- laser requests served: {}\n- shared memory: {} entries removed, {} left over",
        f.wall_s,
        f.outcome.startup_s,
        f.outcome.production_s,
        tm["frames_per_s"].as_f64().unwrap_or(0.0),
        tm["spectra_per_s"].as_f64().unwrap_or(0.0),
        tm["earth_frames_per_s"].as_f64().unwrap_or(0.0),
        f.range_requests,
        f.shm_removed,
        f.shm_leftover.len()
    );
    if let Some(d) = &f.debris {
        s.push_str(&debris::markdown(&d.score));
    }
    if !f.light_curve.is_empty() {
        let _ = writeln!(s, "\n## Light curve\n\n![light curve](light-curve.svg)");
    }
    for (label, ns) in [
        ("Frame", &f.frame_latency_ns),
        ("Spectrum", &f.spectrum_latency_ns),
    ] {
        if ns.is_empty() {
            continue;
        }
        let p = percentiles_us(ns);
        let _ = writeln!(
            s,
            "\n### {label} latency, sensor send → orchestrator receive\n\np50 {:.1} µs, p90 {:.1} µs, p99 {:.1} µs, max {:.1} µs over {} messages.\n",
            p["p50"].as_f64().unwrap_or(0.0),
            p["p90"].as_f64().unwrap_or(0.0),
            p["p99"].as_f64().unwrap_or(0.0),
            p["max"].as_f64().unwrap_or(0.0),
            ns.len()
        );
        s.push_str(&latency_histogram(ns));
        let _ = writeln!(
            s,
            "\n![{label} latency](latency-{}.svg)",
            label.to_lowercase()
        );
    }
    s
}

/// Writes `report.json` and `summary.md`; returns whether the run succeeded.
pub fn write(dir: &Path, scenario: &Scenario, facts: &RunFacts) -> Result<bool> {
    let j = report_json(scenario, facts);
    let text = serde_json::to_string_pretty(&j)? + "\n";
    std::fs::write(dir.join("report.json"), text).context("writing report.json")?;
    std::fs::write(dir.join("summary.md"), summary_md(scenario, facts, &j))
        .context("writing summary.md")?;
    for (name, ns) in [
        ("frame", &facts.frame_latency_ns),
        ("spectrum", &facts.spectrum_latency_ns),
    ] {
        if ns.is_empty() {
            continue;
        }
        let us: Vec<f64> = ns.iter().map(|v| *v as f64 / 1e3).collect();
        crate::plots::log_histogram(
            &dir.join(format!("latency-{name}.svg")),
            &format!("{name} latency, sensor send → orchestrator receive"),
            "latency [µs] (log scale)",
            &us,
        )?;
    }
    if let Some(sp) = &scenario.spectra {
        inversion::InversionReport::new(sp, &facts.solve).plots(dir)?;
        crate::observations::write(
            &dir.join("observations.csv"),
            &facts.spectra,
            Some(sp.rate_deg_per_frame),
        )?;
        // Fit plots need complete windows (a run cut short has none to solve).
        if facts.solve.iter().any(|r| r.stage == 3) {
            if let Err(e) = fit::plots(dir, sp, &facts.solve) {
                tracing::warn!(error = %e, "fit plots skipped");
            }
        }
    }
    if !facts.faults.is_empty() {
        faults::timeline(&dir.join("faults.svg"), facts)?;
    }
    if let Some(d) = &facts.debris {
        debris::plots(
            dir,
            &d.score,
            &d.camera,
            d.snapshot.as_ref(),
            &d.detections,
            &d.truths,
        )?;
    }
    if let (Some(e), Some(section)) = (&facts.earth, &scenario.earth) {
        earth_plots(dir, scenario.seed, section, e)?;
    }
    if let Some((_, bands, _)) = facts.light_curve.first() {
        let colors = [crate::plots::BLUE, crate::plots::GREEN, crate::plots::RED];
        let labels: Vec<String> = bands.iter().map(|b| format!("{b:.0} nm")).collect();
        let series: Vec<crate::plots::Series> = (0..3)
            .map(|i| crate::plots::Series {
                label: &labels[i],
                points: facts
                    .light_curve
                    .iter()
                    .map(|(k, _, f)| (*k as f64, f[i]))
                    .collect(),
                color: colors[i],
                markers: false,
            })
            .collect();
        crate::plots::line_chart(
            &dir.join("light-curve.svg"),
            "Received spectra: band-integrated flux (stable window, then motion)",
            "sample (stream order)",
            "flux [W]",
            &series,
        )?;
    }
    Ok(facts.success())
}

/// The Earth sensor's pictures: error against angle, the β_k samples at the paper's three
/// angles, one annotated frame.
fn earth_plots(
    dir: &Path,
    seed: u64,
    section: &shared_types::scenario::EarthScenario,
    e: &EarthFacts,
) -> Result<()> {
    earth::error_plot(dir, &e.score)?;
    let figures = earth::sample_figures(section, seed, &[5.0, 30.0, 60.0])?;
    earth::samples_plot(dir, &figures)?;
    if let Some((k, w, h, px)) = &e.snapshot {
        earth_frame::annotated(dir, section, *k, *w, *h, px, &e.answers, &e.truths)?;
    }
    Ok(())
}

/// Per-frame latencies of the debris pipeline's stages from the send times the messages carry
/// (one CLOCK_MONOTONIC on this host): `detect` = frame sent → its detections sent (the hop,
/// the checksum and the detection), `track` = detections sent → tracks sent (the hop, the
/// filters and the laser round trip), `end_to_end` = frame sent → tracks sent.
fn stages(c: &Consumer) -> Vec<(&'static str, Vec<u64>)> {
    let frames: BTreeMap<u64, u64> = c.frame_send_ns.iter().copied().collect();
    let dets: BTreeMap<u64, u64> = (c.detection_msgs.iter())
        .map(|d| (d.meta.seq, d.meta.send_mono_ns))
        .collect();
    let gap = |a: &BTreeMap<u64, u64>, b: &BTreeMap<u64, u64>| -> Vec<u64> {
        b.iter()
            .filter_map(|(seq, t1)| a.get(seq).map(|t0| t1.saturating_sub(*t0)))
            .collect()
    };
    if frames.is_empty() || dets.is_empty() {
        return vec![];
    }
    let tracks: BTreeMap<u64, u64> = (c.track_msgs.iter())
        .map(|t| (t.meta.seq, t.meta.send_mono_ns))
        .collect();
    vec![
        ("detect", gap(&frames, &dets)),
        ("track", gap(&dets, &tracks)),
        ("end_to_end", gap(&frames, &tracks)),
    ]
}
