//! The matrix on another host than the orchestrator's: its part of every case.

use anyhow::Result;
use shared_types::scenario::FaultMatrix;
use shared_types::Scenario;

use super::judge::timeline;
use super::{case_options, Case, CaseFault, HostMatrixReport, DETECT_S, STOP_MARGIN_S};
use crate::run::hosts::Part;
use crate::run::{self, RunOptions};
use std::path::PathBuf;

/// The matrix on `host`, another host than the orchestrator's: its part of the baseline and
/// of every case, in the orchestrator's order (each case a deployment of its own: the two
/// meet on the case's deployment key). Judges the faults this host fired on its own bridge
/// (detected, recovered, took effect); the orchestrator's report judges every case end to
/// end. `DIR/summary.md` leads with the verdict; each part's directory is `DIR/<case>/`.
pub(super) fn follow(
    opts: RunOptions,
    matrix: &FaultMatrix,
    host: &str,
) -> Result<(PathBuf, bool)> {
    let scenario = opts.scenario.clone();
    let id = format!("{:08x}", std::process::id());
    let name = format!("{}-{host}", scenario.name);
    let dir = crate::run::run_dir::prepare(opts.out_dir.as_deref(), &name, &id, opts.replace)?;
    let root = dir.path.clone();
    std::fs::write(root.join("scenario.toml"), scenario.to_toml())?;
    let mut base = scenario.clone();
    base.matrix = None;
    let deadline_s = scenario.run.heartbeat_deadline_ms as f64 * 1e-3;
    let part = |sc: Scenario, case: &str| -> Result<Part> {
        let part = crate::run::hosts::run_part(&case_options(&opts, sc, root.join(case)), host)?;
        run::bail_if_interrupted("the fault matrix")?;
        Ok(part)
    };
    eprintln!("fault matrix, host {host}: baseline");
    let baseline = part(base.clone(), "baseline")?;
    let baseline_ok = baseline.ok;
    // A part that never met the orchestrator's stops the matrix: the hosts are out of step.
    let mut stopped = (!baseline.met).then(|| unmet(host, "the baseline"));
    let mut rows: Vec<Case> = vec![];
    for case in matrix.cases(&scenario) {
        if stopped.is_some() {
            break;
        }
        eprintln!("fault matrix, host {host}: {}", case.name);
        let Part { ok, met, fired } = part(FaultMatrix::case_scenario(&base, &case), &case.name)?;
        let mine = case.host.as_deref() == Some(host);
        let fault = fired.into_iter().next();
        let (mut misses, late) = match mine {
            true => timeline(case.kind, fault.as_ref(), deadline_s),
            false => (vec![], vec![]),
        };
        if !ok {
            misses.insert(
                0,
                "this host's part did not end well (its summary says why)".into(),
            );
        }
        if !met {
            stopped = Some(unmet(host, &case.name));
        }
        rows.push(Case {
            name: case.name.clone(),
            service: case.service,
            host: case.host.clone(),
            judged_here: mine,
            kind: case.kind,
            success: ok,
            fault,
            lost: None,
            science_equal: None,
            misses,
            late,
        });
    }
    let passed = baseline_ok && stopped.is_none() && rows.iter().all(|c| c.misses.is_empty());
    let report = HostMatrixReport {
        scenario: scenario.name.clone(),
        host: host.to_string(),
        success: passed,
        baseline_success: baseline_ok,
        cases: rows.iter().map(Case::report).collect(),
        faults: (rows.iter())
            .filter(|c| c.judged_here)
            .filter_map(|c| {
                Some(CaseFault {
                    case: c.name.clone(),
                    fault: c.fault.clone()?,
                })
            })
            .collect(),
    };
    let text = follower_summary(&scenario, host, &rows, baseline_ok, passed);
    super::write(&root, &report, text, stopped)?;
    drop(dir);
    Ok((root, passed))
}

/// Why the matrix stopped: `host`'s part of `case` never met the orchestrator of record.
fn unmet(host: &str, case: &str) -> String {
    format!(
        "The matrix stopped at {case}: the orchestrator of record never started host {host}'s \
         part of it (the hosts are out of step: run every host's `glint run FILE --host NAME` \
         together, with the same file)."
    )
}

/// The summary of another host's matrix: its parts, and the faults it fired.
fn follower_summary(
    scenario: &Scenario,
    host: &str,
    rows: &[Case],
    baseline_ok: bool,
    passed: bool,
) -> String {
    let verdict = if passed { "PASS" } else { "FAIL" };
    let fired = rows.iter().filter(|c| c.judged_here).count();
    let mut s = format!(
        "# {} — fault matrix, host `{host}`: {verdict}\n\nThis host ran its part of the \
         baseline ({}) and of {} cases; it fired {fired} of them on its own bridge and judged \
         their detection and recovery here (detected < {DETECT_S} s after injection, a stop < \
         heartbeat deadline + {STOP_MARGIN_S} s: a time target; detected, recovered: \
         invariants). The orchestrator's matrix judges every case end to end: what was lost, \
         the accounting, the science.\n\n\
         | case | part | detected (by) | recovered | restarts | misses |\n|---|---|---|---|---|---|\n",
        scenario.name,
        if baseline_ok { "ok" } else { "FAILED" },
        rows.len()
    );
    for c in rows {
        let f = c.fault.as_ref().filter(|_| c.judged_here);
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
        let notes = [c.misses.clone(), c.late.clone()].concat().join("; ");
        s += &format!(
            "| {} | {} | {detected} | {} | {} | {} |\n",
            c.name,
            if c.success { "ended well" } else { "FAILED" },
            after(f.and_then(|f| f.recovered_s), f.and_then(|f| f.ended_s)),
            f.map_or("—".into(), |f| f.restarts.to_string()),
            if notes.is_empty() {
                "—".to_string()
            } else {
                notes
            }
        );
    }
    s += "\nEach part's directory is `<case>/` beside this file (its summary and logs).\n";
    s
}
