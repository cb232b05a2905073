//! A soak's part of the report: its verdict (every fault detected and recovered, nothing lost
//! where nothing may be, every process's memory flat after its warm-up), the figures behind
//! it, and the memory figure every run draws (`memory.svg`).

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use anyhow::Result;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use shared_types::scenario::FaultKind;
use shared_types::{Scenario, ServiceId};

use super::{FaultReport, RunFacts};
use crate::plots::{line_chart, Series, BLUE, GREEN, GREY, ORANGE, PURPLE, RED};
use crate::run::memory::MemoryTrace;

/// A process's resident memory may grow this much after its warm-up [%].
pub const MEMORY_GROWTH_MAX_PCT: f64 = 10.0;

/// A soak's verdict and figures.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct SoakReport {
    /// Every fault held the matrix's invariants, and every process's memory stayed flat.
    pub passed: bool,
    /// What broke the verdict.
    pub misses: Vec<String>,
    /// The soak's time [s].
    pub duration_s: f64,
    /// When the camera's stream was ended [s after the start], and after how many frames.
    pub ended_s: Option<f64>,
    pub frames: Option<u64>,
    pub faults: usize,
    pub detected: usize,
    pub recovered: usize,
    /// Messages never processed, over the faults whose kind loses nothing (kill, stop, panic,
    /// delay).
    pub lost: u64,
    /// The longest catch-up of a restarted service [s].
    pub catch_up_s_max: Option<f64>,
    /// The most inputs a restarted service was fed again.
    pub replayed_max: Option<u64>,
    /// Each process's growth after its warm-up [%] (`timing.memory` has the traces).
    pub memory_growth_pct: BTreeMap<String, f64>,
    /// Faults whose time targets were missed on this machine (a figure, not the verdict).
    pub late: Vec<String>,
}

impl SoakReport {
    pub fn new(scenario: &Scenario, facts: &RunFacts, faults: &[FaultReport]) -> Option<Self> {
        let soak = scenario.soak.as_ref()?;
        let deadline_s = scenario.run.heartbeat_deadline_ms as f64 * 1e-3;
        let mut misses = vec![];
        let mut late = vec![];
        let (mut detected, mut recovered, mut lost) = (0, 0, 0);
        for (i, f) in faults.iter().enumerate() {
            let (Some(service), Some(kind)) = (
                ServiceId::from_name(&f.service),
                FaultKind::from_name(&f.kind),
            ) else {
                continue;
            };
            let (m, l) = crate::run::matrix::fault_verdict(service, kind, f, deadline_s);
            let name = format!(
                "fault {} ({} {} at {:.0} s)",
                i + 1,
                f.service,
                f.kind,
                f.at_s.unwrap_or(0.0)
            );
            misses.extend(m.into_iter().map(|m| format!("{name}: {m}")));
            late.extend(l.into_iter().map(|l| format!("{name}: {l}")));
            detected += usize::from(f.detected_s.is_some() || kind == FaultKind::Delay);
            recovered += usize::from(f.recovered_s.is_some());
            if !matches!(kind, FaultKind::Drop | FaultKind::Corrupt) {
                lost += f.lost.unwrap_or(0);
            }
        }
        let memory_growth_pct: BTreeMap<String, f64> = (facts.memory.iter())
            .map(|(name, t)| (name.clone(), t.growth_pct))
            .collect();
        for (name, g) in &memory_growth_pct {
            if g.is_nan() || *g > MEMORY_GROWTH_MAX_PCT {
                misses.push(format!(
                    "{name}'s memory grew {g:.1} % after its warm-up (at most {MEMORY_GROWTH_MAX_PCT} %)"
                ));
            }
        }
        if facts.soak_end.is_none() {
            misses.push("the run ended before the soak's time was up".into());
        }
        let max_f = |v: Vec<f64>| v.into_iter().reduce(f64::max);
        Some(SoakReport {
            passed: misses.is_empty(),
            misses,
            duration_s: soak.duration_s,
            ended_s: facts.soak_end.map(|e| e.at_s),
            frames: facts.soak_end.map(|e| e.frames),
            faults: faults.len(),
            detected,
            recovered,
            lost,
            catch_up_s_max: max_f(faults.iter().filter_map(|f| f.catch_up_s).collect()),
            replayed_max: faults.iter().filter_map(|f| f.replayed).max(),
            memory_growth_pct,
            late,
        })
    }

    /// summary.md's soak section (the verdict first).
    pub fn markdown(&self) -> String {
        let mut s = String::new();
        let verdict = if self.passed { "PASS" } else { "FAIL" };
        let _ = writeln!(
            s,
            "## Soak — {verdict}\n\n{} s, {} frames; {} faults: {} detected, {} recovered, lost {}; \
             longest catch-up {}, most inputs replayed {}.\n",
            self.ended_s.map_or("—".into(), |t| format!("{t:.0}")),
            self.frames.map_or("—".into(), |n| n.to_string()),
            self.faults,
            self.detected,
            self.recovered,
            self.lost,
            self.catch_up_s_max.map_or("—".into(), |t| format!("{t:.3} s")),
            self.replayed_max.map_or("—".into(), |n| n.to_string()),
        );
        let growth: Vec<String> = (self.memory_growth_pct.iter())
            .map(|(n, g)| format!("{n} {g:+.1} %"))
            .collect();
        let _ = writeln!(
            s,
            "Resident memory, the run's last tenth against the tenth after its warm-up \
             (medians): {} (at most {MEMORY_GROWTH_MAX_PCT} %).\n\n![memory](memory.svg)\n",
            growth.join(", ")
        );
        for m in &self.misses {
            let _ = writeln!(s, "- ✗ {m}");
        }
        if !self.late.is_empty() {
            let _ = writeln!(
                s,
                "\nTime targets missed on this machine (figures, not the verdict):\n"
            );
            for l in &self.late {
                let _ = writeln!(s, "- {l}");
            }
        }
        s
    }
}

/// `memory.svg`: every process's resident memory over the run.
pub fn memory_plot(dir: &Path, memory: &BTreeMap<String, MemoryTrace>) -> Result<()> {
    if memory.values().all(|t| t.t_s.len() < 2) {
        return Ok(());
    }
    let colors = [BLUE, GREEN, RED, ORANGE, PURPLE, GREY];
    let series: Vec<Series> = (memory.iter().enumerate())
        .map(|(i, (name, t))| Series {
            label: name,
            points: t
                .t_s
                .iter()
                .copied()
                .zip(t.rss_mb.iter().copied())
                .collect(),
            color: colors[i % colors.len()],
            markers: false,
        })
        .collect();
    line_chart(
        &dir.join("memory.svg"),
        "Resident memory of each process",
        "time since the start [s]",
        "resident set [MB]",
        &series,
    )
}
