//! `glint run` of a `[matrix]` scenario: the fault-free baseline, then one deployment per
//! (service × kind) with that one fault, each in `DIR/<service>-<kind>`. `DIR/report.json`
//! lists every case's `faults[]` entries with its `case` name and whether its science equals
//! the baseline's; `DIR/summary.md` leads with the verdict and shows the matrix. The verdict
//! (and `glint run`'s exit code) is the invariants'; the time targets are figures beside it.

use std::fmt::Write;
use std::path::PathBuf;

use anyhow::{Context, Result};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use shared_types::scenario::FaultKind;
use shared_types::{deployment, Scenario, ServiceId};

use crate::report::{FaultReport, Report, Science};
use crate::run::{self, RunOptions};

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

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct MatrixBaseline {
    pub success: bool,
    pub science: Science,
}

/// One case's verdict.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct CaseReport {
    /// `<service>-<kind>`.
    pub case: String,
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
    kind: FaultKind,
    success: bool,
    fault: Option<FaultReport>,
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
    let id = format!("{:08x}", std::process::id());
    let dir =
        crate::run::run_dir::prepare(opts.out_dir.as_deref(), &scenario.name, &id, opts.replace)?;
    let root = dir.path.clone();
    std::fs::write(root.join("scenario.toml"), scenario.to_toml())?;
    let mut base = scenario.clone();
    base.matrix = None;

    let deploy = |sc: Scenario, case: &str| -> Result<Report> {
        let (sub, _) = run::run(RunOptions {
            scenario: sc,
            scenario_file: opts.scenario_file.clone(),
            out_dir: Some(root.join(case)),
            replace: opts.replace,
            progress: false,
            record: opts.record,
            host: None,
        })?;
        run::bail_if_interrupted("the fault matrix")?;
        Report::read(&sub.join("report.json")).with_context(|| format!("{case}'s report"))
    };
    eprintln!("fault matrix: baseline");
    let baseline = deploy(base.clone(), "baseline")?;
    let deadline_s = scenario.run.heartbeat_deadline_ms as f64 * 1e-3;

    let mut cases = vec![];
    for (si, service) in matrix.services_of(&scenario).into_iter().enumerate() {
        let trigger = deployment::trigger_topic(&scenario, service);
        let at_seq = trigger.map_or(0, |t| deployment::expected_messages(&scenario, t)) * 3 / 10;
        for kind in matrix.kinds_of() {
            let name = format!("{}-{}", service.name(), kind.name());
            eprintln!("fault matrix: {name}");
            let mut sc = base.clone();
            sc.fault = vec![matrix.fault(service, si, kind, at_seq)];
            sc.faults.enabled |= kind.in_band();
            let report = deploy(sc, &name)?;
            let run = CaseRun {
                success: report.results.success,
                failure: report.results.failure.clone(),
                science_equal: report.results.science == baseline.results.science,
                fault: report.faults.first().cloned(),
            };
            cases.push(judge(&name, service, kind, run, deadline_s));
        }
    }
    let baseline_ok = baseline.results.success;
    let passed = baseline_ok && cases.iter().all(|c| c.misses.is_empty());
    let report = MatrixReport {
        scenario: scenario.name.clone(),
        success: passed,
        baseline: MatrixBaseline {
            success: baseline.results.success,
            science: baseline.results.science.clone(),
        },
        cases: (cases.iter())
            .map(|c| CaseReport {
                case: c.name.clone(),
                success: c.success,
                science_equal: c.science_equal,
                passed: c.misses.is_empty(),
                misses: c.misses.clone(),
                within_targets: c.late.is_empty(),
                late: c.late.clone(),
            })
            .collect(),
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
    std::fs::write(
        root.join("report.json"),
        serde_json::to_string_pretty(&report)? + "\n",
    )?;
    std::fs::write(
        root.join("summary.md"),
        summary(&scenario, &cases, baseline_ok, passed),
    )?;
    drop(dir);
    Ok((root, passed))
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

/// A case against the targets: detected in time, recovered in time, nothing lost and the
/// science equal (kill, stop, panic, delay), or exact counts (drop, corrupt). A verdict the
/// run ended before reaching is a miss that says so.
fn judge(name: &str, service: ServiceId, kind: FaultKind, run: CaseRun, deadline_s: f64) -> Case {
    let CaseRun {
        success,
        failure,
        science_equal: equal,
        fault,
    } = run;
    let mut misses = vec![];
    let mut late = vec![];
    if !success {
        misses.push(format!(
            "the run failed: {}",
            failure.as_deref().unwrap_or("invariant")
        ));
    }
    let f = fault.as_ref();
    let injected = f.and_then(|f| f.injected_s);
    let detected = f.and_then(|f| f.detected_s);
    let ended = f.and_then(|f| f.ended_s);
    let recovered = f.and_then(|f| f.recovered_s);
    let detect_limit = match kind {
        FaultKind::Stop => deadline_s + STOP_MARGIN_S,
        FaultKind::Kill
        | FaultKind::Panic
        | FaultKind::Delay
        | FaultKind::Drop
        | FaultKind::Corrupt => DETECT_S,
    };
    // A delay is not a failure: nothing to detect, only to recover from.
    if kind != FaultKind::Delay {
        match (injected, detected) {
            (Some(i), Some(d)) if d - i < detect_limit => {}
            (Some(i), Some(d)) => late.push(format!(
                "detected {:.3} s after injection (target < {detect_limit} s)",
                d - i
            )),
            _ => misses.push("not detected".into()),
        }
    }
    match (ended, recovered, f.and_then(|f| f.not_reached.as_deref())) {
        (Some(e), Some(r), _) if r - e < RECOVER_S => {}
        (Some(e), Some(r), _) => late.push(format!(
            "recovered {:.3} s after the fault ended (target < {RECOVER_S} s)",
            r - e
        )),
        (_, _, Some(why)) => misses.push(format!("not reached: {why}")),
        _ => misses.push("not recovered".into()),
    }
    // A delay took effect: the service slept `delay_ms` before each of `count` messages
    // between the order and the heartbeat that said it was over (a lower bound on any host).
    if let Some(f) = f.filter(|_| kind == FaultKind::Delay) {
        let slept_s = match (f.count, f.duration_s) {
            (Some(n), _) => f64::from(n) * f.delay_ms.unwrap_or(0) as f64 * 1e-3,
            (None, Some(d)) => d,
            (None, None) => 0.0,
        };
        if let (Some(i), Some(e)) = (f.injected_s, f.ended_s) {
            if e - i < slept_s {
                misses.push(format!(
                    "the delay took no effect: over {:.3} s after injection, it sleeps {slept_s:.3} s",
                    e - i
                ));
            }
        }
    }
    if !f.is_some_and(|f| f.invariant_held) {
        misses.push("accounting invariant broken".into());
    }
    let science_equal = match kind {
        FaultKind::Drop | FaultKind::Corrupt => {
            let (made, counted) = (f.and_then(|f| f.injected), f.and_then(|f| f.counted));
            if made != counted || made.unwrap_or(0) == 0 {
                let n = |v: Option<u64>| v.map_or("none".to_string(), |v| v.to_string());
                misses.push(format!("{} injected, {} counted", n(made), n(counted)));
            }
            None
        }
        FaultKind::Kill | FaultKind::Stop | FaultKind::Panic | FaultKind::Delay => {
            if !equal {
                misses.push("science differs from the baseline".into());
            }
            let lost = f.and_then(|f| f.lost);
            if lost != Some(0) {
                misses.push(format!(
                    "lost {}",
                    lost.map_or("unknown".to_string(), |n| n.to_string())
                ));
            }
            Some(equal)
        }
    };
    Case {
        name: name.to_string(),
        service,
        kind,
        success,
        fault,
        science_equal,
        misses,
        late,
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
    // The grid: one row per service, one column per kind.
    let mut kinds: Vec<FaultKind> = vec![];
    let mut services: Vec<ServiceId> = vec![];
    for c in cases {
        if !kinds.contains(&c.kind) {
            kinds.push(c.kind);
        }
        if !services.contains(&c.service) {
            services.push(c.service);
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
    for svc in &services {
        let cells: Vec<String> = kinds
            .iter()
            .map(|k| {
                cases
                    .iter()
                    .find(|c| c.service == *svc && c.kind == *k)
                    .map_or("—".into(), |c| {
                        match (c.misses.is_empty(), c.late.is_empty()) {
                            (true, true) => "✓".into(),
                            (true, false) => "✓ late".into(),
                            _ => "✗".into(),
                        }
                    })
            })
            .collect();
        let _ = writeln!(s, "| {} | {} |", svc.name(), cells.join(" | "));
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
        let detected = match f.and_then(|f| f.detected_by.as_deref()) {
            Some(by) => format!(
                "{} ({by})",
                after(f.and_then(|f| f.detected_s), f.and_then(|f| f.injected_s))
            ),
            None => "—".into(),
        };
        let counted = match f.and_then(|f| f.injected.zip(f.counted)) {
            Some((made, counted)) => format!("{counted} of {made}"),
            None => "—".into(),
        };
        let _ = writeln!(
            s,
            "| {} | {detected} | {} | {} | {} | {} | {counted} | {} | {} |",
            c.name,
            after(f.and_then(|f| f.recovered_s), f.and_then(|f| f.ended_s)),
            f.and_then(|f| f.catch_up_s)
                .map_or("—".into(), |s| format!("{s:.3}")),
            f.map_or("—".into(), |f| f.restarts.to_string()),
            f.and_then(|f| f.lost).map_or("—".into(), |n| n.to_string()),
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
         timeline); the baseline's is `baseline/`."
    );
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    const DEADLINE_S: f64 = 0.3;

    /// A fault entry that held everything: injected at 1 s, over at once, noticed 10 ms later,
    /// recovered 0.2 s after, nothing lost.
    fn fault(kind: FaultKind) -> FaultReport {
        FaultReport {
            service: "detector".into(),
            kind: kind.name().into(),
            at_seq: Some(15),
            at_s: None,
            duration_s: None,
            count: None,
            delay_ms: None,
            injected_s: Some(1.0),
            ended_s: Some(1.0),
            detected_s: Some(1.01),
            detected_by: Some("exit".into()),
            recovered_s: Some(1.2),
            catch_up_s: Some(0.05),
            replayed: Some(3),
            not_reached: None,
            restarts: 1,
            lost: Some(0),
            invariant_held: true,
            science_equal: None,
            injected: None,
            counted: None,
        }
    }

    fn run(fault: FaultReport) -> CaseRun {
        CaseRun {
            success: true,
            failure: None,
            science_equal: true,
            fault: Some(fault),
        }
    }

    fn misses(kind: FaultKind, run: CaseRun) -> Vec<String> {
        judge("case", ServiceId::Detector, kind, run, DEADLINE_S).misses
    }

    #[test]
    fn a_case_that_held_everything_passes() {
        for kind in [FaultKind::Kill, FaultKind::Panic, FaultKind::Stop] {
            assert_eq!(misses(kind, run(fault(kind))), Vec::<String>::new());
        }
        let delay = FaultReport {
            detected_s: None,
            detected_by: None,
            restarts: 0,
            count: Some(10),
            delay_ms: Some(5),
            ended_s: Some(1.06),
            ..fault(FaultKind::Delay)
        };
        assert_eq!(
            misses(FaultKind::Delay, run(delay.clone())),
            Vec::<String>::new()
        );
        // Over before it could have slept 10 × 5 ms: it did not take effect.
        let refused = FaultReport {
            ended_s: Some(1.02),
            ..delay
        };
        let m = misses(FaultKind::Delay, run(refused));
        assert!(m[0].starts_with("the delay took no effect"), "{m:?}");
        let drop = FaultReport {
            injected: Some(2),
            counted: Some(2),
            ..fault(FaultKind::Drop)
        };
        assert_eq!(misses(FaultKind::Drop, run(drop)), Vec::<String>::new());
    }

    #[test]
    fn a_delay_that_never_ends_fails_and_says_it_was_not_reached() {
        let never = FaultReport {
            ended_s: None,
            recovered_s: None,
            detected_s: None,
            not_reached: Some("the run ended while the delay still slowed the service".into()),
            ..fault(FaultKind::Delay)
        };
        let m = misses(FaultKind::Delay, run(never));
        assert_eq!(m.len(), 1, "{m:?}");
        assert!(
            m[0].starts_with("not reached: the run ended while"),
            "{m:?}"
        );
    }

    #[test]
    fn a_drop_not_counted_fails() {
        let uncounted = FaultReport {
            injected: Some(2),
            counted: Some(1),
            ..fault(FaultKind::Drop)
        };
        assert_eq!(
            misses(FaultKind::Drop, run(uncounted)),
            ["2 injected, 1 counted"]
        );
        let none_made = FaultReport {
            injected: Some(0),
            counted: Some(0),
            ..fault(FaultKind::Corrupt)
        };
        assert_eq!(misses(FaultKind::Corrupt, run(none_made)).len(), 1);
    }

    #[test]
    fn a_science_digest_that_differs_fails() {
        let differs = CaseRun {
            science_equal: false,
            ..run(fault(FaultKind::Kill))
        };
        assert_eq!(
            misses(FaultKind::Kill, differs),
            ["science differs from the baseline"]
        );
    }

    #[test]
    fn a_loss_an_undetected_kill_and_a_failed_run_fail() {
        let lost = FaultReport {
            lost: Some(3),
            ..fault(FaultKind::Kill)
        };
        assert_eq!(misses(FaultKind::Kill, run(lost)), ["lost 3"]);
        let unseen = FaultReport {
            detected_s: None,
            detected_by: None,
            ..fault(FaultKind::Kill)
        };
        assert_eq!(misses(FaultKind::Kill, run(unseen)), ["not detected"]);
        let failed = CaseRun {
            success: false,
            failure: Some("fault detector:kill@15 never fired: the run ended first".into()),
            ..run(fault(FaultKind::Kill))
        };
        let m = misses(FaultKind::Kill, failed);
        assert!(m[0].contains("never fired"), "{m:?}");
    }

    #[test]
    fn slow_is_late_not_failed() {
        let slow = FaultReport {
            detected_s: Some(1.9),
            recovered_s: Some(4.0),
            ..fault(FaultKind::Kill)
        };
        let case = judge(
            "case",
            ServiceId::Detector,
            FaultKind::Kill,
            run(slow),
            DEADLINE_S,
        );
        assert!(case.misses.is_empty(), "{:?}", case.misses);
        assert_eq!(case.late.len(), 2, "{:?}", case.late);
    }
}
