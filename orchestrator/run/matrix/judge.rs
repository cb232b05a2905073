//! A case's verdict: its fault's timeline against the targets (detected, recovered, took
//! effect) and, end to end, what it lost and whether the science equals the baseline's.

use shared_types::scenario::{FaultKind, MatrixCase};
use shared_types::{deployment, Scenario, ServiceId, TopicId};

use std::collections::BTreeMap;

use super::{Case, CaseRun, DETECT_S, RECOVER_S, STOP_MARGIN_S};
use crate::report::{FaultReport, Report, TopicReport};

/// A case against the targets: detected in time, recovered in time, nothing lost and the
/// science equal (kill, stop, panic, delay), or exact counts (drop, corrupt). A verdict the
/// run ended before reaching is a miss that says so.
pub(super) fn judge(
    name: &str,
    service: ServiceId,
    kind: FaultKind,
    run: CaseRun,
    deadline_s: f64,
) -> Case {
    let CaseRun {
        success,
        failure,
        science_equal: equal,
        fault,
    } = run;
    let mut misses = vec![];
    if !success {
        misses.push(format!(
            "the run failed: {}",
            failure.as_deref().unwrap_or("invariant")
        ));
    }
    let f = fault.as_ref();
    let (timeline_misses, late) = timeline(kind, f, deadline_s);
    misses.extend(timeline_misses);
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
            whole(equal, f.and_then(|f| f.lost), &mut misses);
            Some(equal)
        }
    };
    Case {
        name: name.to_string(),
        service,
        host: None,
        judged_here: true,
        kind,
        success,
        lost: f.and_then(|f| f.lost),
        fault,
        science_equal,
        misses,
        late,
    }
}

/// A fault that loses nothing: the science equal to the baseline's, lost 0.
pub(super) fn whole(science_equal: bool, lost: Option<u64>, misses: &mut Vec<String>) {
    if !science_equal {
        misses.push("science differs from the baseline".into());
    }
    if lost != Some(0) {
        misses.push(format!(
            "lost {}",
            lost.map_or("unknown".to_string(), |n| n.to_string())
        ));
    }
}

/// A fault's timeline against the targets: detected (all but a delay), recovered, and a
/// delay took effect. The invariants it broke, and the time targets it missed.
pub(super) fn timeline(
    kind: FaultKind,
    f: Option<&FaultReport>,
    deadline_s: f64,
) -> (Vec<String>, Vec<String>) {
    let mut misses = vec![];
    let mut late = vec![];
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
    (misses, late)
}

/// A case whose fault another host's part fired (its bridge): judged here end to end — the
/// run succeeded, every message accounted for, nothing lost, the science equal to the
/// baseline's. Its detection and recovery are that host's to judge (its matrix summary).
pub(super) fn judge_elsewhere(
    case: &MatrixCase,
    host: &str,
    report: &Report,
    science_equal: bool,
    lost: Option<u64>,
) -> Case {
    let r = &report.results;
    let mut misses = vec![];
    if !r.success {
        misses.push(format!(
            "the run failed: {}",
            r.failure.as_deref().unwrap_or("invariant")
        ));
    }
    if !r.accounting.invariant_held {
        misses.push("accounting invariant broken".into());
    }
    whole(science_equal, lost, &mut misses);
    Case {
        name: case.name.clone(),
        service: case.service,
        host: Some(host.to_string()),
        judged_here: false,
        kind: case.kind,
        success: r.success,
        fault: None,
        lost,
        science_equal: Some(science_equal),
        misses,
        late: vec![],
    }
}

/// What a bridge's fault cost: of every topic that crosses hosts, what its consumers on
/// another host than its producer's did not receive, beyond what they did not receive in the
/// fault-free `baseline` (`None`: a consumer reported no count).
pub(crate) fn crossing_lost(
    scenario: &Scenario,
    report: &Report,
    baseline: &Report,
) -> Option<u64> {
    let missing = |r: &Report| crossing_missing(scenario, &r.results.topics);
    Some(missing(report)?.saturating_sub(missing(baseline)?))
}

/// Of every topic that crosses hosts, what its consumers on another host than its producer's
/// did not receive (`None`: one reported no count).
fn crossing_missing(scenario: &Scenario, topics: &BTreeMap<String, TopicReport>) -> Option<u64> {
    let mut sum = 0;
    for (name, t) in topics {
        let Some(topic) = TopicId::from_name(name) else {
            continue;
        };
        let from = deployment::producer(topic).and_then(|p| scenario.host_of(p));
        for (consumer, c) in &t.consumers {
            let on = ServiceId::from_name(consumer).and_then(|s| scenario.host_of(s));
            if on.is_some() && on != from {
                sum += t.expected.saturating_sub(c.received?);
            }
        }
    }
    Some(sum)
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
            bandwidth_mbit_s: None,
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

    /// What a bridge's fault cost in the split debris chain: what crossed hosts and did not
    /// arrive (frames to ground's detector, tracks back to the orchestrator), not what stayed
    /// on one host (detections, ground to ground).
    #[test]
    fn a_bridge_fault_costs_what_did_not_cross() {
        let text = include_str!("../../../scenarios/debris-split.toml");
        let sc = Scenario::from_toml_str(text, "debris-split.toml").unwrap();
        let consumer = |received: Option<u64>| crate::report::ConsumerReport {
            received,
            duplicates: None,
            dropped: Some(0),
            dropped_by_reason: None,
            accounted: true,
        };
        let topic = |consumers: &[(&str, Option<u64>)]| TopicReport {
            expected: 50,
            published: Some(50),
            digest_xxh3: None,
            consumers: (consumers.iter())
                .map(|(n, r)| (n.to_string(), consumer(*r)))
                .collect(),
        };
        let topics = |frame: u64, detections: u64, tracks: Option<u64>| -> BTreeMap<_, _> {
            [
                (
                    "frame",
                    topic(&[("detector", Some(frame)), ("orchestrator", Some(50))]),
                ),
                ("detections", topic(&[("tracker", Some(detections))])),
                ("tracks", topic(&[("orchestrator", tracks)])),
            ]
            .into_iter()
            .map(|(n, t)| (n.to_string(), t))
            .collect()
        };
        assert_eq!(crossing_missing(&sc, &topics(50, 50, Some(50))), Some(0));
        // 2 frames and 1 track did not cross; the detections never had to
        assert_eq!(crossing_missing(&sc, &topics(48, 40, Some(49))), Some(3));
        // a consumer that reported no count: unknown
        assert_eq!(crossing_missing(&sc, &topics(50, 50, None)), None);
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
