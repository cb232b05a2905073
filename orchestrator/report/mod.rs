//! The run report: `report.json` (machine-readable, the types of [`model`]) and `summary.md`
//! (what a person reads), both made from one [`Report`] value; the pictures from the run's
//! facts.
//!
//! [`Results`] is a function of the scenario and the seed alone, so two runs of the same
//! scenario and seed give equal results; the run's identity, its timings, its faults and the
//! strangers it saw are beside them.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Context, Result};
use shared_types::{DropReason, Scenario, ServiceId, TopicId};

pub mod debris;
mod debris_scorer;
pub mod earth;
mod earth_frame;
mod facts;
pub mod faults;
pub mod fit;
pub mod inversion;
pub mod model;
mod science;
pub mod score_debris;
pub mod sections;
pub mod soak;

pub use facts::*;
pub use model::*;
pub use sections::{folds, snapshots};

/// The report of a finished run.
pub fn build(scenario: &Scenario, f: &RunFacts) -> Report {
    let mut topics = BTreeMap::new();
    for (t, tf) in &f.topics {
        let mut consumers = BTreeMap::new();
        for (name, c) in &tf.consumers {
            let v = match c {
                Some(c) => {
                    let dropped: u64 = c.dropped.iter().sum();
                    ConsumerReport {
                        received: Some(c.received),
                        duplicates: Some(c.duplicates),
                        dropped: Some(dropped),
                        dropped_by_reason: Some(
                            (DropReason::ALL.iter())
                                .map(|r| (r.name().to_string(), c.dropped[*r as usize]))
                                .collect(),
                        ),
                        accounted: c.received + dropped == tf.expected,
                    }
                }
                None => ConsumerReport {
                    received: None,
                    duplicates: None,
                    dropped: None,
                    dropped_by_reason: None,
                    accounted: false,
                },
            };
            consumers.insert(name.clone(), v);
        }
        topics.insert(
            t.name().to_string(),
            TopicReport {
                expected: tf.expected,
                published: tf.published,
                digest_xxh3: tf.digest.map(|d| format!("{d:016x}")),
                consumers,
            },
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
    let results = Results {
        glint_version: env!("CARGO_PKG_VERSION").to_string(),
        contract_version: shared_types::CONTRACT_VERSION,
        scenario: ScenarioInfo {
            name: scenario.name.clone(),
            clock: format!("{:?}", scenario.clock).to_lowercase(),
            frames,
            spectra,
            earth_frames,
        },
        seed: scenario.seed,
        success: f.success(),
        failure: f.failure.clone(),
        accounting: Accounting {
            invariant_held: f.invariant_held(),
        },
        services: (f.services.iter())
            .map(|s| ServiceReport {
                name: s.name.clone(),
                restarts: s.restarts,
                ending: s.ending.label(),
            })
            .collect(),
        topics,
        science: Science {
            digest_xxh3: format!("{:016x}", f.science_digest),
        },
        laser: LaserReport {
            shots: f.laser_shots,
            served: f.range_requests,
        },
        shared_memory: SharedMemory {
            leftover: f.shm_leftover.clone(),
            held_by: f.shm_held_by.clone(),
        },
        inversion: None,
        earth: None,
        detection: None,
        tracking: None,
        relnav: None,
        photometry: None,
    };
    let faults = faults::reports(f);
    let mut report = Report {
        results,
        soak: soak::SoakReport::new(scenario, f, &faults),
        faults,
        membership: f.membership.clone(),
        run: RunInfo {
            prefix: f.prefix.clone(),
            scenario_file: f.scenario_file.clone(),
            shm_entries_removed: f.shm_removed,
            pids: (f.services.iter())
                .map(|s| (s.name.clone(), s.pid))
                .collect(),
            recording: f.recording.clone(),
            hosts: f.hosts.clone(),
        },
        timing: Timing {
            wall_s: f.wall_s,
            startup_s: f.outcome.startup_s,
            production_s: f.outcome.production_s,
            frames_per_s: rate(frames),
            spectra_per_s: rate(spectra),
            earth_frames_per_s: rate(earth_frames),
            frame_latency_us: f.frame_latency.percentiles(),
            spectrum_latency_us: f.spectrum_latency.percentiles(),
            stage_latency_us: (f.stage_latency.iter())
                .map(|(name, l)| (name.to_string(), l.percentiles()))
                .collect(),
            cpu_s: (f.services.iter())
                .map(|s| (s.name.clone(), s.cpu_s))
                .chain([("orchestrator".to_string(), f.orchestrator_cpu_s)])
                .collect(),
            time_s: (f.services.iter())
                .filter_map(|s| Some((s.name.clone(), service_timing(&s.time?))))
                .collect(),
            earth_us_per_frame: BTreeMap::new(),
            memory: f.memory.clone(),
        },
    };
    for section in &f.sections {
        section.report(&mut report.results, &mut report.timing);
    }
    report
}

/// The share of a service's time it was working [%]: awake and not waiting for an RPC answer.
pub fn busy_percent(t: &shared_types::ServiceTime) -> f64 {
    let total = t.busy_ns + t.credit_wait_ns + t.idle_ns;
    100.0 * t.busy_ns.saturating_sub(t.rpc_wait_ns) as f64 / total.max(1) as f64
}

/// Where a service's time went [s]: asleep (`credit_wait`, `idle`) or `busy`, and busy's
/// parts (`work` is the rest: its own computation and housekeeping).
fn service_timing(t: &shared_types::ServiceTime) -> ServiceTiming {
    let s = |ns: u64| ns as f64 * 1e-9;
    let parts = t.publish_ns + t.checksum_ns + t.rpc_wait_ns;
    ServiceTiming {
        busy_s: s(t.busy_ns),
        credit_wait_s: s(t.credit_wait_ns),
        idle_s: s(t.idle_ns),
        work_s: s(t.busy_ns.saturating_sub(parts)),
        checksum_s: s(t.checksum_ns),
        publish_s: s(t.publish_ns),
        rpc_wait_s: s(t.rpc_wait_ns),
    }
}

/// A text histogram of latencies (log-spaced bins) for the summary.
fn latency_histogram(latency: &crate::run::latency::Latency) -> String {
    if latency.is_empty() {
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
    for (us, n) in latency.counts_us() {
        let i = edges_us
            .iter()
            .position(|e| us < *e)
            .unwrap_or(edges_us.len() - 1);
        counts[i] += n as usize;
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

fn summary_md(scenario: &Scenario, f: &RunFacts, r: &Report) -> String {
    let mut s = String::new();
    let passed = f.success() && r.soak.as_ref().is_none_or(|s| s.passed);
    let verdict = if passed { "PASS" } else { "FAIL" };
    let _ = writeln!(s, "# glint run: {} — {verdict}\n", scenario.name);
    if !scenario.description.is_empty() {
        let _ = writeln!(s, "{}\n", scenario.description.trim());
    }
    let _ = writeln!(
        s,
        "Seed {}, clock `{}`, scenario file `{}`.\n",
        scenario.seed, r.results.scenario.clock, f.scenario_file
    );
    if let Some(fail) = &f.failure {
        let _ = writeln!(s, "**Failure:** {fail}\n");
    }
    if let Some(soak) = &r.soak {
        s.push_str(&soak.markdown());
    }
    // The answers first (each mission's result and its uncertainty), then the run's record.
    for section in &f.sections {
        s.push_str(&section.markdown());
    }
    let _ = writeln!(
        s,
        "\n## Services\n\nbusy: the share of its time a service was working (the one near 100 % is the \
         bottleneck); the rest it waited: for input, for a consumer, for an RPC answer.\n\n\
         | service | pid | restarts | ended by | CPU [s] | busy |\n|---|---|---|---|---|---|"
    );
    for sv in &f.services {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} |",
            sv.name,
            sv.pid,
            sv.restarts,
            sv.ending.label(),
            sv.cpu_s.map_or("—".into(), |c| format!("{c:.2}")),
            sv.time
                .map_or("—".into(), |t| format!("{:.0} %", busy_percent(&t)))
        );
    }
    s.push_str(&crate::run::links::markdown(&f.hosts));
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
    let tm = &r.timing;
    // The sensor's streams that carried messages, each per second of production (the table
    // names them; truth rides beside every one of them).
    let rates: Vec<String> = (f.topics.iter())
        .filter(|(t, _)| t.spec().producer() == Some(ServiceId::Sensor) && **t != TopicId::Truth)
        .filter_map(|(t, tf)| Some((t, tf.published.filter(|&n| n > 0)?)))
        .map(|(t, n)| {
            let per_s = n as f64 / f.outcome.production_s.max(1e-9);
            format!("`{}` {per_s:.1}/s", t.name())
        })
        .collect();
    let _ = writeln!(
        s,
        "\n## Timing (this machine; not part of the deterministic results)\n\n- wall time {:.3} s (startup {:.3} s, production {:.3} s)\n- sensor output: {}\n- laser requests served: {}\n- shared memory: {} entries removed, {} left over",
        f.wall_s,
        f.outcome.startup_s,
        f.outcome.production_s,
        if rates.is_empty() { "none".to_string() } else { rates.join(", ") },
        f.range_requests,
        f.shm_removed,
        f.shm_leftover.len()
    );
    if !f.shm_held_by.is_empty() {
        let _ = writeln!(
            s,
            "- the left-over entries are held by node(s) {} outside the deployment (observers, \
             not a failure); `glint clean --prefix {}` removes them once those end",
            f.shm_held_by.join(", "),
            f.prefix
        );
    }
    for (label, latency, p) in [
        ("Frame", &f.frame_latency, &tm.frame_latency_us),
        ("Spectrum", &f.spectrum_latency, &tm.spectrum_latency_us),
    ] {
        let Some(p) = p else {
            continue;
        };
        let _ = writeln!(
            s,
            "\n### {label} latency, sensor send → orchestrator receive\n\np50 {:.1} µs, p90 {:.1} µs, p99 {:.1} µs, max {:.1} µs over {} messages.\n",
            p.p50,
            p.p90,
            p.p99,
            p.max,
            p.count
        );
        s.push_str(&latency_histogram(latency));
        let _ = writeln!(
            s,
            "\n![{label} latency](latency-{}.svg)",
            label.to_lowercase()
        );
    }
    s
}

/// Writes `report` again as `dir/report.json` (a verdict changed after it was written).
pub fn rewrite(dir: &Path, report: &Report) -> Result<()> {
    let text = serde_json::to_string_pretty(report)? + "\n";
    std::fs::write(dir.join("report.json"), text).context("writing report.json")
}

/// Writes `report.json`, `summary.md` and the pictures; returns the report.
pub fn write(dir: &Path, scenario: &Scenario, facts: &RunFacts) -> Result<Report> {
    let report = build(scenario, facts);
    let text = serde_json::to_string_pretty(&report)? + "\n";
    std::fs::write(dir.join("report.json"), text).context("writing report.json")?;
    std::fs::write(dir.join("summary.md"), summary_md(scenario, facts, &report))
        .context("writing summary.md")?;
    for (name, latency) in [
        ("frame", &facts.frame_latency),
        ("spectrum", &facts.spectrum_latency),
    ] {
        if latency.is_empty() {
            continue;
        }
        let us = latency.counts_us();
        crate::plots::log_histogram(
            &dir.join(format!("latency-{name}.svg")),
            &format!("{name} latency, sensor send → orchestrator receive"),
            "latency [µs] (log scale)",
            &us,
        )?;
    }
    if !facts.faults.is_empty() {
        faults::timeline(&dir.join("faults.svg"), facts)?;
    }
    soak::memory_plot(dir, &facts.memory)?;
    for section in &facts.sections {
        section.plots(dir)?;
    }
    Ok(report)
}

/// `light-curve.svg`: the band-integrated flux of the first, middle and last band of every
/// received spectrum.
pub(crate) fn light_curve_plot(dir: &Path, spectra: &[shared_types::Spectrum]) -> Result<()> {
    let light_curve = light_curve(spectra);
    let Some((_, bands, _)) = light_curve.first() else {
        return Ok(());
    };
    let colors = [crate::plots::BLUE, crate::plots::GREEN, crate::plots::RED];
    let labels: Vec<String> = bands.iter().map(|b| format!("{b:.0} nm")).collect();
    let series: Vec<crate::plots::Series> = (0..3)
        .map(|i| crate::plots::Series {
            label: &labels[i],
            points: light_curve
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
    )
}

/// The received spectra reduced for the light-curve plot: (stream index, the first, middle
/// and last band's centre, their flux).
fn light_curve(spectra: &[shared_types::Spectrum]) -> Vec<(u64, [f64; 3], [f64; 3])> {
    spectra
        .iter()
        .filter(|m| m.n_bands > 0)
        .map(|m| {
            let n = m.n_bands as usize;
            let pick = [0, n / 2, n - 1];
            (
                m.meta.seq,
                pick.map(|i| m.wavelength_nm[i]),
                pick.map(|i| m.flux_w[i]),
            )
        })
        .collect()
}

/// `glint report --schema`.
pub fn command(schema: bool) -> std::process::ExitCode {
    use std::process::ExitCode;
    if !schema {
        eprintln!("error: `glint report` needs --schema");
        return ExitCode::from(2);
    }
    let text = serde_json::to_string_pretty(&Report::schema()).unwrap_or_default();
    println!("{text}");
    ExitCode::SUCCESS
}
