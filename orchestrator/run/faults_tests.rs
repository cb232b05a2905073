//! Unit tests of fault injection's state machine ([`super`]).

use super::*;

fn injector(specs: &[&str]) -> Injector {
    let mut sc = Scenario::from_toml_str(
        include_str!("../../scenarios/debris-geo.toml"),
        "debris-geo.toml",
    )
    .unwrap();
    sc.fault = specs.iter().map(|s| FaultSpec::parse(s).unwrap()).collect();
    sc.faults.enabled = true;
    sc.validate().unwrap();
    Injector::new(&sc, None)
}

/// A heartbeat at `at_s` from a service that has taken `progress` inputs, no fault order
/// obeyed, and the orchestrator at the same point.
fn heard(at_s: f64, progress: u64) -> Heard {
    Heard {
        at_s,
        faults_obeyed: 0,
        delaying: false,
        progress,
        carried: progress,
        done: 0,
    }
}

#[test]
fn a_delay_by_messages_ends_when_the_service_says_so_and_recovers_once_caught_up() {
    let mut inj = injector(&["detector:delay@10,delay_ms=5,count=8"]);
    let a = inj.step(0.5, |_| 11, |_, _| (0, 0));
    assert!(matches!(a[0].act, Act::Order(f) if f.count == 8 && f.duration_ms == 0));
    // Before the service obeyed: a heartbeat saying it is not slowed ends nothing.
    inj.heard_from(ServiceId::Detector, heard(0.52, 11));
    assert_eq!(inj.faults[0].ended_s, None, "the order had not arrived");
    let slowed = Heard {
        faults_obeyed: 1,
        delaying: true,
        ..heard(0.6, 14)
    };
    inj.heard_from(ServiceId::Detector, slowed);
    assert_eq!(inj.faults[0].ended_s, None, "still slowed");
    // Over, with a backlog: 30 frames had arrived, it had taken 19.
    let over = Heard {
        faults_obeyed: 1,
        carried: 30,
        ..heard(0.7, 19)
    };
    inj.heard_from(ServiceId::Detector, over);
    assert_eq!(inj.faults[0].ended_s, Some(0.7));
    assert_eq!(inj.faults[0].recovered_s, None, "a backlog left");
    let caught_up = Heard {
        faults_obeyed: 1,
        carried: 34,
        ..heard(0.75, 30)
    };
    inj.heard_from(ServiceId::Detector, caught_up);
    let f = &inj.faults[0];
    assert_eq!(f.recovered_s, Some(0.75));
    assert!((f.catch_up_s.unwrap() - 0.05).abs() < 1e-12);
    assert!(inj.finish().is_empty());
    assert_eq!(inj.faults[0].not_reached, None);
}

#[test]
fn a_delay_the_run_outlasted_is_not_reached_and_a_fault_that_never_fired_fails_the_run() {
    let mut inj = injector(&["detector:delay@10,delay_ms=5,count=8", "tracker:kill@40"]);
    inj.step(0.5, |_| 11, |_, _| (0, 0));
    let slowed = Heard {
        faults_obeyed: 1,
        delaying: true,
        ..heard(0.6, 14)
    };
    inj.heard_from(ServiceId::Detector, slowed);
    let never = inj.finish();
    assert_eq!(never.len(), 1, "{never:?}");
    assert!(
        never[0].contains("tracker:kill@40 never fired"),
        "{never:?}"
    );
    assert!(inj.faults[0]
        .not_reached
        .as_deref()
        .unwrap()
        .contains("still slowed"));
    assert_eq!(inj.faults[0].recovered_s, None);
}

#[test]
fn a_restarted_service_recovers_once_it_has_taken_the_input_the_kill_found_it_at() {
    let mut inj = injector(&["detector:kill@20"]);
    inj.heard_from(ServiceId::Detector, heard(0.4, 21));
    assert_eq!(
        inj.step(0.45, |_| 21, |_, _| (0, 0))[0].act,
        Act::Signal(Signal::KILL)
    );
    inj.detected(ServiceId::Detector, "exit", 0.46);
    inj.restarted(ServiceId::Detector, 0.6, 16);
    assert_eq!(inj.faults[0].recovered_s, None, "resumed is not recovered");
    inj.heard_from(ServiceId::Detector, heard(0.62, 5));
    assert_eq!(inj.faults[0].recovered_s, None, "replaying");
    inj.heard_from(ServiceId::Detector, heard(0.7, 21));
    let f = &inj.faults[0];
    assert_eq!(
        (f.recovered_s, f.restarts, f.replayed),
        (Some(0.7), 1, Some(5))
    );
    assert!((f.catch_up_s.unwrap() - 0.1).abs() < 1e-12);
}

/// A long run: a kill, then a drop, then a kill again, all into the detector. Each restart
/// is the latest kill's; the drop is counted from its own injection, never restarted, and
/// the first kill's recovery stands.
#[test]
fn on_a_long_run_each_restart_and_count_is_its_own_faults() {
    let mut inj = injector(&[
        "detector:kill@1s",
        "detector:drop@2s,count=2",
        "detector:kill@3s",
    ]);
    let tampered = |made: u64| move |_: TopicId, _: FaultKind| (made, made);
    inj.heard_from(ServiceId::Detector, heard(0.9, 40));
    assert_eq!(inj.step(1.0, |_| 40, tampered(0)).len(), 1);
    inj.detected(ServiceId::Detector, "exit", 1.01);
    inj.restarted(ServiceId::Detector, 1.2, 32);
    inj.heard_from(ServiceId::Detector, heard(1.3, 41));
    assert_eq!(inj.faults[0].recovered_s, Some(1.3));
    // The drop: 3 drops were made (and counted) before it, by an earlier fault.
    assert_eq!(inj.step(2.0, |_| 80, tampered(3)).len(), 1);
    assert_eq!(inj.faults[1].tamper_base, Some((3, 3)));
    let awaiting = inj.awaiting_count();
    assert_eq!(awaiting.len(), 1);
    assert_eq!(awaiting[0].base, (3, 3));
    inj.counted(1, 2.1);
    // The second kill: its restart is its own.
    inj.heard_from(ServiceId::Detector, heard(2.9, 120));
    assert_eq!(inj.step(3.0, |_| 120, tampered(5)).len(), 1);
    inj.detected(ServiceId::Detector, "exit", 3.01);
    inj.restarted(ServiceId::Detector, 3.2, 112);
    inj.heard_from(ServiceId::Detector, heard(3.4, 121));
    let [first, drop, second] = &inj.faults[..] else {
        unreachable!()
    };
    assert_eq!((first.restarts, first.recovered_s), (1, Some(1.3)));
    assert_eq!((first.detected_s, first.replayed), (Some(1.01), Some(8)));
    assert_eq!((drop.restarts, drop.recovered_s), (0, Some(2.1)));
    assert_eq!(drop.detected_by, Some("sequence gap"));
    assert_eq!((second.restarts, second.recovered_s), (1, Some(3.4)));
    assert_eq!((second.detected_s, second.replayed), (Some(3.01), Some(8)));
    assert!(inj.finish().is_empty());
}

#[test]
fn a_stop_fires_at_its_message_and_continues_after_its_duration() {
    let mut inj = injector(&["detector:stop@5,duration_s=0.5"]);
    assert!(
        inj.step(1.0, |_| 5, |_, _| (0, 0)).is_empty(),
        "message 5 not yet carried"
    );
    let a = inj.step(1.1, |_| 6, |_, _| (0, 0));
    assert_eq!(
        a,
        [Action {
            service: ServiceId::Detector,
            act: Act::Signal(Signal::STOP)
        }]
    );
    assert!(inj.step(1.5, |_| 6, |_, _| (0, 0)).is_empty());
    let a = inj.step(1.6, |_| 6, |_, _| (0, 0));
    assert_eq!(
        a,
        [Action {
            service: ServiceId::Detector,
            act: Act::Signal(Signal::CONT)
        }]
    );
    inj.heard_from(ServiceId::Detector, heard(1.55, 0));
    assert_eq!(
        inj.faults[0].recovered_s, None,
        "a heartbeat from before SIGCONT"
    );
    inj.heard_from(ServiceId::Tracker, heard(1.7, 0));
    assert_eq!(inj.faults[0].recovered_s, None, "another service");
    inj.heard_from(ServiceId::Detector, heard(1.7, 0));
    let f = &inj.faults[0];
    assert_eq!(
        (f.injected_s, f.ended_s, f.recovered_s),
        (Some(1.1), Some(1.6), Some(1.7))
    );
    assert!(
        inj.step(9.0, |_| 50, |_, _| (0, 0)).is_empty(),
        "fired once"
    );
}

#[test]
fn a_kill_at_a_time_is_detected_once() {
    let mut inj = injector(&["tracker:kill@0.25s"]);
    assert!(inj.step(0.2, |_| 100, |_, _| (0, 0)).is_empty());
    assert_eq!(
        inj.step(0.25, |_| 0, |_, _| (0, 0))[0].act,
        Act::Signal(Signal::KILL)
    );
    inj.detected(ServiceId::Tracker, "exit", 0.27);
    inj.detected(ServiceId::Tracker, "heartbeat deadline", 5.0);
    let f = &inj.faults[0];
    assert_eq!((f.detected_s, f.detected_by), (Some(0.27), Some("exit")));
}
