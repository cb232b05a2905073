//! The run report: `report.json` (machine-readable) and `summary.md` (what a person reads).
//!
//! Everything outside the `run` and `timing` objects, the `pid` fields and the Earth methods'
//! `time_us_per_frame` is a function of the scenario and the seed alone, so two runs of the same scenario and seed give byte-identical
//! reports once those are removed (keys are sorted; serde_json's map is a BTreeMap).

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Context, Result};
use serde_json::{json, Value};
use shared_types::{DropReason, Scenario, TopicId};

pub mod debris;
pub mod earth;
mod earth_frame;
mod facts;
pub mod faults;
pub mod fit;
pub mod inversion;
mod science;

pub use facts::*;

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
            "time_s": f.services.iter()
                .filter_map(|s| Some((s.name.clone(), time_json(&s.time?))))
                .collect::<serde_json::Map<_, _>>(),
        },
    })
}

/// The share of a service's time it was working [%]: awake and not waiting for an RPC answer.
pub fn busy_percent(t: &shared_types::ServiceTime) -> f64 {
    let total = t.busy_ns + t.credit_wait_ns + t.idle_ns;
    100.0 * t.busy_ns.saturating_sub(t.rpc_wait_ns) as f64 / total.max(1) as f64
}

/// Where a service's time went [s]: asleep (`credit_wait`, `idle`) or `busy`, and busy's
/// parts (`work` is the rest: its own computation and housekeeping).
fn time_json(t: &shared_types::ServiceTime) -> Value {
    let s = |ns: u64| ns as f64 * 1e-9;
    let parts = t.publish_ns + t.checksum_ns + t.rpc_wait_ns;
    json!({
        "busy_s": s(t.busy_ns),
        "credit_wait_s": s(t.credit_wait_ns),
        "idle_s": s(t.idle_ns),
        "work_s": s(t.busy_ns.saturating_sub(parts)),
        "checksum_s": s(t.checksum_ns),
        "publish_s": s(t.publish_ns),
        "rpc_wait_s": s(t.rpc_wait_ns),
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
    if !f.spectra.is_empty() {
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
    let light_curve = light_curve(&facts.spectra);
    if let Some((_, bands, _)) = light_curve.first() {
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
    if let Some(snap) = &e.snapshot {
        earth_frame::annotated(dir, section, snap, &e.answers, &e.truths)?;
    }
    Ok(())
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

/// The frames whose pixels the report draws, per frame topic: the debris section's frame 1,
/// the Earth section's first frame at the angle nearest 20° (a ring clear of the blind zone
/// and of the image circle's edge).
pub fn snapshots(scenario: &Scenario) -> Vec<(TopicId, u64)> {
    let mut v = vec![];
    if scenario.camera.is_some() {
        v.push((TopicId::Frame, 1));
    }
    if let Some(e) = &scenario.earth {
        let angles = e.angles_deg();
        let near_20 = |a: f64| (a.abs() - 20.0).abs();
        let best = (0..angles.len())
            .min_by(|&a, &b| near_20(angles[a]).total_cmp(&near_20(angles[b])))
            .unwrap_or(0);
        v.push((TopicId::EarthFrame, best as u64 * e.images_per_angle as u64));
    }
    v
}
