//! The faults section of the report: one entry per injected fault (what, when, noticed when
//! and how, heard from again when, what it cost), the table in summary.md and the timeline.

use std::fmt::Write;
use std::path::Path;

use anyhow::{anyhow, Result};
use plotters::prelude::*;
use shared_types::scenario::FaultKind;
use shared_types::table::Count;
use shared_types::{deployment, DropReason, ServiceId, TopicId};

use super::{FaultReport, RunFacts, TopicFact};
use crate::plots::{BLUE, GREEN, ORANGE, RED};

/// What the fault cost: for a consumer, the messages published on its inputs that it never
/// processed — missed while it was down or behind (realtime: counted as gaps, late or stale)
/// or never taken at all — less what other faults account for (inputs an upstream `corrupt`
/// sent invalid, gaps an upstream `drop` made); for the sensor, the messages of its streams it
/// never produced (realtime: those that came due while it was down). `None` where nothing was reported.
fn lost(f: &RunFacts, service: ServiceId) -> Option<u64> {
    let name = service.name();
    let inputs: Vec<&TopicFact> = f
        .topics
        .values()
        .filter(|t| t.consumers.contains_key(name))
        .collect();
    if service == ServiceId::Sensor || inputs.is_empty() {
        return Some(
            f.topics
                .iter()
                .filter(|(t, _)| deployment::producer(**t) == Some(ServiceId::Sensor))
                .filter(|(t, _)| matches!(t.spec().count, Count::Stream { .. }))
                .map(|(_, t)| {
                    let made = t.published.unwrap_or(0).min(t.expected);
                    t.expected - made + t.producer_dropped[DropReason::Overflow as usize]
                })
                .sum(),
        );
    }
    let mut sum = 0;
    for t in inputs {
        let published = t.published?;
        let c = t.consumers.get(name)?.as_ref();
        let explained = c.map_or(0, |c| {
            let gaps = c.dropped[DropReason::Overflow as usize];
            c.received
                + c.dropped[DropReason::Malformed as usize]
                + gaps.min(t.producer_dropped[DropReason::Injected as usize])
        });
        sum += published.saturating_sub(explained);
    }
    Some(sum)
}

/// A drop or corrupt fault's accounting: (outputs the service dropped or sent invalid on
/// purpose, the fewest of them any consumer counted as a gap or as malformed).
fn tampered(f: &RunFacts, fault: &crate::run::faults::Fault) -> (u64, u64) {
    let drop = fault.spec.kind == FaultKind::Drop;
    if fault.output == Some(TopicId::Solve) {
        // The answers' one client is the orchestrator's sequencer.
        let t = &f.solve_tampered;
        return if drop { (t[0], t[2]) } else { (t[1], t[3]) };
    }
    let (theirs, ours) = if drop {
        (DropReason::Injected, DropReason::Overflow)
    } else {
        (DropReason::Malformed, DropReason::Malformed)
    };
    let Some(t) = fault.output.and_then(|o| f.topics.get(&o)) else {
        return (0, 0);
    };
    let injected = t.producer_dropped[theirs as usize];
    let counted = t
        .consumers
        .values()
        .map(|c| c.as_ref().map_or(0, |c| c.dropped[ours as usize]))
        .min()
        .unwrap_or(0);
    // On a long run with several of them on one output, each is what came after its own
    // injection and before the next's.
    let base = fault.tamper_base.unwrap_or((0, 0));
    let next = (f.faults.iter())
        .filter(|g| g.output == fault.output && g.spec.kind == fault.spec.kind)
        .filter(|g| g.injected_s > fault.injected_s)
        .min_by(|a, b| {
            let at = |g: &crate::run::faults::Fault| g.injected_s.unwrap_or(f64::INFINITY);
            at(a).total_cmp(&at(b))
        })
        .and_then(|g| g.tamper_base);
    let (end_made, end_counted) = next.unwrap_or((injected, counted));
    (
        end_made.saturating_sub(base.0),
        end_counted.saturating_sub(base.1),
    )
}

/// The report's entry per injected fault.
pub fn reports(f: &RunFacts) -> Vec<FaultReport> {
    f.faults
        .iter()
        .map(|fault| match fault.spec.kind {
            FaultKind::Drop | FaultKind::Corrupt => {
                // Lost by design; the invariant is that every one of them was counted.
                let (injected, counted) = tampered(f, fault);
                let mut r = fault.report(Some(injected), f.invariant_held() && injected == counted);
                r.injected = Some(injected);
                r.counted = Some(counted);
                r
            }
            _ => fault.report(lost(f, fault.service), f.invariant_held()),
        })
        .collect()
}

fn secs(v: Option<f64>) -> String {
    v.map_or("—".into(), |s| format!("{s:.3}"))
}

/// The summary's faults table (empty without faults).
pub fn markdown(f: &RunFacts) -> String {
    let mut s = String::new();
    if f.faults.is_empty() {
        return s;
    }
    let _ = writeln!(
        s,
        "\n## Faults\n\nTimes in seconds after the services were started. ![fault timeline](faults.svg)\n\n| service | fault | injected | detected (by) | recovered | lost |\n|---|---|---|---|---|---|"
    );
    for fault in &f.faults {
        let what = match (fault.spec.at_seq, fault.spec.at_s, fault.spec.duration_s) {
            (Some(seq), _, d) => format!("{}@{seq}{}", fault.spec.kind.name(), dur(d)),
            (_, Some(at), d) => format!("{}@{at}s{}", fault.spec.kind.name(), dur(d)),
            _ => fault.spec.kind.name().into(),
        };
        let detected = match (fault.detected_s, fault.detected_by) {
            (Some(t), Some(by)) => format!("{t:.3} ({by})"),
            _ => "not detected".into(),
        };
        let _ = writeln!(
            s,
            "| {} | {what} | {} | {detected} | {} | {} |",
            fault.service.name(),
            secs(fault.injected_s),
            fault.recovered_s.map_or("no".into(), |t| format!("{t:.3}")),
            lost(f, fault.service).map_or("?".into(), |n| n.to_string())
        );
    }
    s
}

fn dur(d: Option<f64>) -> String {
    d.map_or(String::new(), |d| format!(" for {d} s"))
}

/// `faults.svg`: one row per service; each fault a red span from injection to its end (a
/// kill: a red cross), an orange mark where supervision noticed it, a green one where the
/// service was heard from again.
pub fn timeline(path: &Path, f: &RunFacts) -> Result<()> {
    let rows: Vec<&str> = f.services.iter().map(|s| s.name.as_str()).collect();
    let row = |id: ServiceId| rows.iter().position(|r| *r == id.name()).unwrap_or(0) as f64;
    let end_s = f.outcome.production_s.max(
        f.faults
            .iter()
            .flat_map(|x| [x.injected_s, x.ended_s, x.detected_s, x.recovered_s])
            .flatten()
            .fold(0.0, f64::max),
    );
    let root = SVGBackend::new(path, (900, 120 + 60 * rows.len() as u32)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| anyhow!("{e:?}"))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "Faults: injected (red), detected (orange), recovered (green)",
            ("sans-serif", 18),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(90)
        .build_cartesian_2d(
            0.0..(end_s * 1.05).max(0.1),
            -0.5..(rows.len() as f64 - 0.5),
        )
        .map_err(|e| anyhow!("{e:?}"))?;
    chart
        .configure_mesh()
        .x_desc("time after start [s]")
        .y_labels(rows.len())
        .y_label_formatter(&|v| {
            let i = v.round();
            if (v - i).abs() < 1e-6 && i >= 0.0 {
                rows.get(i as usize)
                    .map_or(String::new(), |r| r.to_string())
            } else {
                String::new()
            }
        })
        .disable_y_mesh()
        .draw()
        .map_err(|e| anyhow!("{e:?}"))?;
    // The run itself, per service, as a thin line.
    for (i, _) in rows.iter().enumerate() {
        let y = i as f64;
        chart
            .draw_series(LineSeries::new(
                [(0.0, y), (f.outcome.production_s, y)],
                BLUE.mix(0.4).stroke_width(2),
            ))
            .map_err(|e| anyhow!("{e:?}"))?;
    }
    for fault in &f.faults {
        let y = row(fault.service);
        let Some(t0) = fault.injected_s else { continue };
        let t1 = fault.ended_s.unwrap_or(t0);
        if t1 > t0 {
            chart
                .draw_series(std::iter::once(Rectangle::new(
                    [(t0, y - 0.15), (t1, y + 0.15)],
                    RED.mix(0.6).filled(),
                )))
                .map_err(|e| anyhow!("{e:?}"))?;
        } else {
            chart
                .draw_series(std::iter::once(Cross::new((t0, y), 7, RED.stroke_width(3))))
                .map_err(|e| anyhow!("{e:?}"))?;
        }
        for (t, color) in [(fault.detected_s, ORANGE), (fault.recovered_s, GREEN)] {
            if let Some(t) = t {
                chart
                    .draw_series(std::iter::once(TriangleMarker::new(
                        (t, y + 0.3),
                        7,
                        color.filled(),
                    )))
                    .map_err(|e| anyhow!("{e:?}"))?;
            }
        }
    }
    root.present().map_err(|e| anyhow!("{e:?}"))?;
    Ok(())
}
