//! `glint run` of a `[matrix]` scenario: the fault-free baseline, then one deployment per
//! (service × kind) with that one fault, each in `DIR/<service>-<kind>` (a split deployment:
//! also every host's bridge, `DIR/bridge-<host>-<kind>`; every host runs its part, follow.rs). `DIR/report.json`
//! lists every case's `faults[]` entries with its `case` name and whether its science equals
//! the baseline's; `DIR/summary.md` leads with the verdict and shows the matrix. The verdict
//! (and `glint run`'s exit code) is the invariants'; the time targets are figures beside it.

use std::fmt::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use shared_types::scenario::{FaultKind, FaultMatrix};
use shared_types::{Scenario, ServiceId};

use crate::report::{FaultReport, Report, Science};
use crate::run::{self, RunOptions};

mod follow;
mod judge;

use judge::{crossing_lost, judge, judge_elsewhere};

/// The matrix's `report.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct MatrixReport {
    pub scenario: String,
    /// Every case held every invariant, and the baseline passed.
    pub success: bool,
    pub baseline: MatrixBaseline,
    pub cases: Vec<CaseReport>,
    /// Each case's fault entry, with its case name and science compared to the baseline's.
    pub faults: Vec<CaseFault>,
}

/// The `report.json` of another host's matrix (`glint run --host` of a split `[matrix]`
/// scenario): its part of each case, and the faults it fired on its own bridge, judged on
/// detection and recovery (their `lost` and `invariant_held` are the orchestrator's report's).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct HostMatrixReport {
    pub scenario: String,
    pub host: String,
    /// Its part of every case ended well, and every fault it fired was detected and
    /// recovered from.
    pub success: bool,
    pub baseline_success: bool,
    pub cases: Vec<CaseReport>,
    pub faults: Vec<CaseFault>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct MatrixBaseline {
    pub success: bool,
    pub science: Science,
}

/// One case's verdict.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct CaseReport {
    /// `<service>-<kind>`, or `bridge-<host>-<kind>`.
    pub case: String,
    /// The host whose part fired the fault (a split deployment's bridge).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub host: Option<String>,
    /// Its run succeeded.
    pub success: bool,
    pub science_equal: Option<bool>,
    /// Every invariant held.
    pub passed: bool,
    /// The invariants it broke.
    pub misses: Vec<String>,
    /// Within the time targets on this machine (a figure, not an invariant).
    pub within_targets: bool,
    pub late: Vec<String>,
}

/// A case's fault entry.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct CaseFault {
    pub case: String,
    #[serde(flatten)]
    pub fault: FaultReport,
}

/// Detection within this long of the injection (a stop: the heartbeat deadline and this).
const DETECT_S: f64 = 0.5;
const STOP_MARGIN_S: f64 = 0.1;
/// Recovery within this long of the fault's end.
const RECOVER_S: f64 = 2.0;

/// One case's outcome, as the matrix shows it.
struct Case {
    name: String,
    service: ServiceId,
    /// The host whose part fired it (`None`: not split, or one of the orchestrator's host's
    /// services).
    host: Option<String>,
    /// Its fault's detection and recovery were judged here (the host that fired it).
    judged_here: bool,
    kind: FaultKind,
    success: bool,
    fault: Option<FaultReport>,
    /// What it lost (its fault's entry's, or counted end to end for another host's fault).
    lost: Option<u64>,
    science_equal: Option<bool>,
    /// Invariants it broke (empty: held): not detected, not recovered, lost, science unequal,
    /// counts unequal, the run failed.
    misses: Vec<String>,
    /// Time targets it missed (a figure of this machine, not an invariant).
    late: Vec<String>,
}

pub fn run_matrix(opts: RunOptions) -> Result<(PathBuf, bool)> {
    let scenario = opts.scenario.clone();
    let matrix = scenario.matrix.clone().context("no [matrix] section")?;
    // Another host than the orchestrator's runs its part of every case, in the same order.
    if let Some(host) =
        (opts.host.clone()).filter(|h| Some(h.as_str()) != scenario.orchestrator_host())
    {
        return follow::follow(opts, &matrix, &host);
    }
    let id = format!("{:08x}", std::process::id());
    let dir =
        crate::run::run_dir::prepare(opts.out_dir.as_deref(), &scenario.name, &id, opts.replace)?;
    let root = dir.path.clone();
    std::fs::write(root.join("scenario.toml"), scenario.to_toml())?;
    let mut base = scenario.clone();
    base.matrix = None;

    let deploy = |sc: Scenario, case: &str| -> Result<Report> {
        let (sub, _) = run::run(case_options(&opts, sc, root.join(case)))?;
        run::bail_if_interrupted("the fault matrix")?;
        Report::read(&sub.join("report.json")).with_context(|| format!("{case}'s report"))
    };
    eprintln!("fault matrix: baseline");
    let baseline = deploy(base.clone(), "baseline")?;
    let deadline_s = scenario.run.heartbeat_deadline_ms as f64 * 1e-3;

    let mut cases = vec![];
    // A host that never joined a case stops the matrix: the hosts are out of step.
    let mut stopped = unheard(&baseline, "the baseline");
    for case in matrix.cases(&scenario) {
        if stopped.is_some() {
            break;
        }
        eprintln!("fault matrix: {}", case.name);
        let report = deploy(FaultMatrix::case_scenario(&base, &case), &case.name)?;
        let science_equal = report.results.science == baseline.results.science;
        // A bridge's fault costs what the topics that cross hosts did not deliver.
        let lost = (case.service == ServiceId::Bridge)
            .then(|| crossing_lost(&base, &report, &baseline))
            .flatten();
        let elsewhere = (case.host.as_deref()).filter(|h| opts.host.as_deref() != Some(*h));
        cases.push(match elsewhere {
            // Fired by the other host's part: judged here end to end, and there (its
            // summary) on detection and recovery.
            Some(host) => judge_elsewhere(&case, host, &report, science_equal, lost),
            None => {
                let mut fault = report.faults.first().cloned();
                if let Some(f) = fault.as_mut().filter(|_| case.service == ServiceId::Bridge) {
                    f.lost = lost;
                }
                let run = CaseRun {
                    success: report.results.success,
                    failure: report.results.failure.clone(),
                    science_equal,
                    fault,
                };
                Case {
                    host: case.host.clone(),
                    ..judge(&case.name, case.service, case.kind, run, deadline_s)
                }
            }
        });
        stopped = unheard(&report, &case.name);
    }
    let baseline_ok = baseline.results.success;
    let passed = baseline_ok && stopped.is_none() && cases.iter().all(|c| c.misses.is_empty());
    let report = MatrixReport {
        scenario: scenario.name.clone(),
        success: passed,
        baseline: MatrixBaseline {
            success: baseline.results.success,
            science: baseline.results.science.clone(),
        },
        cases: cases.iter().map(Case::report).collect(),
        faults: (cases.iter())
            .filter_map(|c| {
                let mut fault = c.fault.clone()?;
                fault.science_equal = c.science_equal;
                Some(CaseFault {
                    case: c.name.clone(),
                    fault,
                })
            })
            .collect(),
    };
    let text = summary(&scenario, &cases, baseline_ok, passed) + &left_out(&scenario, &matrix);
    write(&root, &report, text, stopped)?;
    drop(dir);
    Ok((root, passed))
}

/// Writes a matrix's `report.json` and `summary.md` (`stopped`: why it stopped early, last).
fn write(
    root: &Path,
    report: &impl Serialize,
    summary: String,
    stopped: Option<String>,
) -> Result<()> {
    std::fs::write(
        root.join("report.json"),
        serde_json::to_string_pretty(report)? + "\n",
    )?;
    let stopped = stopped.map_or(String::new(), |why| format!("\n{why}\n"));
    std::fs::write(root.join("summary.md"), summary + &stopped)?;
    Ok(())
}

impl Case {
    /// Its verdict as `report.json` gives it.
    fn report(&self) -> CaseReport {
        CaseReport {
            case: self.name.clone(),
            host: self.host.clone(),
            success: self.success,
            science_equal: self.science_equal,
            passed: self.misses.is_empty(),
            misses: self.misses.clone(),
            within_targets: self.late.is_empty(),
            late: self.late.clone(),
        }
    }
}

/// The services of the matrix no case faults, and why (empty: none): those of another host
/// than the orchestrator's (only its bridge is faulted there).
fn left_out(scenario: &Scenario, matrix: &FaultMatrix) -> String {
    let cases = matrix.cases(scenario);
    let mut out: Vec<String> = (matrix.services_of(scenario).into_iter())
        .filter(|s| *s != ServiceId::Bridge && !cases.iter().any(|c| c.service == *s))
        .map(|s| format!("{} (on {})", s.name(), scenario.host_of(s).unwrap_or("?")))
        .collect();
    // A bridge the first topic that crosses hosts does not pass (its `at_seq` would count
    // nothing there).
    if matrix.services_of(scenario).contains(&ServiceId::Bridge) {
        out.extend(
            (scenario.hosts.keys())
                .filter(|h| !cases.iter().any(|c| c.host.as_deref() == Some(h.as_str())))
                .map(|h| {
                    format!("bridge (on {h}: the first topic that crosses hosts does not pass it)")
                }),
        );
    }
    match out.is_empty() {
        true => String::new(),
        false => format!(
            "\nNot faulted: {} — a matrix faults the orchestrator's host's services and every \
             host's bridge.\n",
            out.join(", ")
        ),
    }
}

/// Why the matrix stops after `case` (`None`: it goes on): another host's services were never
/// heard in it, so that host's part never joined.
fn unheard(report: &Report, case: &str) -> Option<String> {
    let host = report.run.hosts.iter().find(|h| !h.heard)?;
    Some(format!(
        "The matrix stopped at {case}: host {} never joined it (the hosts are out of step: run \
         every host's `glint run FILE --host NAME` together, with the same file).",
        host.name
    ))
}

/// What the matrix reads of one case's run.
#[derive(Debug, Clone)]
struct CaseRun {
    success: bool,
    failure: Option<String>,
    /// Its science equals the baseline's.
    science_equal: bool,
    /// Its one fault's entry.
    fault: Option<FaultReport>,
}

/// One fault of a longer run (a soak) against the matrix's targets, its science not compared
/// (no baseline): what it broke, and the time targets it missed on this machine.
pub(crate) fn fault_verdict(
    service: ServiceId,
    kind: FaultKind,
    fault: &FaultReport,
    deadline_s: f64,
) -> (Vec<String>, Vec<String>) {
    let run = CaseRun {
        success: true,
        failure: None,
        science_equal: true,
        fault: Some(fault.clone()),
    };
    let case = judge("", service, kind, run, deadline_s);
    (case.misses, case.late)
}

/// The options of one case's run: `opts` with the case's scenario, its directory, no
/// progress bar.
pub(super) fn case_options(opts: &RunOptions, scenario: Scenario, out_dir: PathBuf) -> RunOptions {
    RunOptions {
        scenario,
        scenario_file: opts.scenario_file.clone(),
        out_dir: Some(out_dir),
        replace: opts.replace,
        progress: false,
        record: opts.record,
        host: opts.host.clone(),
    }
}

fn summary(scenario: &Scenario, cases: &[Case], baseline_ok: bool, passed: bool) -> String {
    let mut s = String::new();
    let verdict = if passed { "PASS" } else { "FAIL" };
    let held = cases.iter().filter(|c| c.misses.is_empty()).count();
    let on_time = cases.iter().filter(|c| c.late.is_empty()).count();
    let _ = writeln!(
        s,
        "# {} — fault matrix: {verdict}\n\n{held} of {} faults detected, recovered from and \
         accounted for (lost 0 and the science equal to the baseline for kill, stop, panic and \
         delay; every drop and corruption counted for drop and corrupt). {on_time} of {} within \
         the time targets on this machine (detected < {DETECT_S} s after injection, a stop < \
         heartbeat deadline + {STOP_MARGIN_S} s; recovered < {RECOVER_S} s after the fault \
         ended). Baseline: {}.\n",
        scenario.name,
        cases.len(),
        cases.len(),
        if baseline_ok { "ok" } else { "FAILED" }
    );
    let elsewhere: Vec<&str> = (cases.iter())
        .filter(|c| !c.judged_here)
        .map(|c| c.name.as_str())
        .collect();
    if !elsewhere.is_empty() {
        let _ = writeln!(
            s,
            "{} of them another host fired ({}): judged here end to end (the run, the \
             accounting, lost 0, the science); their detection and recovery by that host's \
             matrix, whose verdict the matrix's also needs.\n",
            elsewhere.len(),
            elsewhere.join(", ")
        );
    }
    // The grid: one row per service, one column per kind.
    let mut kinds: Vec<FaultKind> = vec![];
    let mut services: Vec<(ServiceId, Option<&str>)> = vec![];
    for c in cases {
        if !kinds.contains(&c.kind) {
            kinds.push(c.kind);
        }
        if !services.contains(&(c.service, c.host.as_deref())) {
            services.push((c.service, c.host.as_deref()));
        }
    }
    let _ = writeln!(
        s,
        "| service | {} |\n|---|{}",
        kinds
            .iter()
            .map(|k| k.name())
            .collect::<Vec<_>>()
            .join(" | "),
        "---|".repeat(kinds.len())
    );
    for (svc, host) in &services {
        let cells: Vec<String> = kinds
            .iter()
            .map(|k| {
                cases
                    .iter()
                    .find(|c| c.service == *svc && c.host.as_deref() == *host && c.kind == *k)
                    .map_or("—".into(), |c| {
                        match (c.misses.is_empty(), c.late.is_empty()) {
                            (true, true) => "✓".into(),
                            (true, false) => "✓ late".into(),
                            _ => "✗".into(),
                        }
                    })
            })
            .collect();
        let label = match host {
            Some(h) => format!("{} ({h})", svc.name()),
            None => svc.name().to_string(),
        };
        let _ = writeln!(s, "| {label} | {} |", cells.join(" | "));
    }
    let _ = writeln!(
        s,
        "\n## Cases\n\nTimes in seconds after the fault was injected (detected) or ended (recovered); catch-up from the restarted service's resume (a delay: its end) to recovered.\n\n\
         | case | detected (by) | recovered | catch-up | restarts | lost | counted | science equal | misses |\n\
         |---|---|---|---|---|---|---|---|---|"
    );
    for c in cases {
        let f = c.fault.as_ref();
        let after = |a: Option<f64>, b: Option<f64>| match (a, b) {
            (Some(a), Some(b)) => format!("{:.3}", a - b),
            _ => "—".into(),
        };
        // A fault another host fired: its detection and recovery are in that host's summary.
        let there = (c.host.as_deref()).filter(|_| !c.judged_here);
        let detected = match (f.and_then(|f| f.detected_by.as_deref()), there) {
            (Some(by), _) => format!(
                "{} ({by})",
                after(f.and_then(|f| f.detected_s), f.and_then(|f| f.injected_s))
            ),
            (None, Some(h)) => format!("on {h}"),
            (None, None) => "—".into(),
        };
        let counted = match f.and_then(|f| f.injected.zip(f.counted)) {
            Some((made, counted)) => format!("{counted} of {made}"),
            None => "—".into(),
        };
        let _ = writeln!(
            s,
            "| {} | {detected} | {} | {} | {} | {} | {counted} | {} | {} |",
            c.name,
            match there {
                Some(h) => format!("on {h}"),
                None => after(f.and_then(|f| f.recovered_s), f.and_then(|f| f.ended_s)),
            },
            f.and_then(|f| f.catch_up_s)
                .map_or("—".into(), |s| format!("{s:.3}")),
            f.map_or("—".into(), |f| f.restarts.to_string()),
            c.lost.map_or("—".into(), |n| n.to_string()),
            c.science_equal
                .map_or("—", |e| if e { "yes" } else { "no" }),
            if c.misses.is_empty() && c.late.is_empty() {
                "—".into()
            } else {
                [c.misses.clone(), c.late.clone()].concat().join("; ")
            }
        );
    }
    let _ = writeln!(
        s,
        "\nEach case's run directory is `<case>/` beside this file (its report, summary and fault \
         timeline); the baseline's is `baseline/`. A fault another host fired (its bridge) is \
         judged here end to end, and on its detection and recovery in that host's matrix \
         summary."
    );
    s
}
