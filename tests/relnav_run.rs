//! [004] deployed: the sensor's stereo stream and the relnav service as separate processes over
//! iceoryx2, every epoch accounted for, the filter's answers scored against the sensor's truth
//! (an independent integration of the target) and held to the paper's figures.

mod common;

use common::*;

#[test]
fn the_stereo_chain_deployed_accounts_for_every_epoch_and_converges() {
    let dir = temp_dir("relnav-run");
    // The shipped 100 minutes (6001 epochs, a few seconds even in a debug build): the score's
    // window is the last 50 minutes, as the paper's.
    let file = scenario("stereo-tumbling.toml");
    let r = run_ok(Some(&file), &dir.join("a"), &[]);
    let rep = &r.typed;
    assert!(rep.results.success, "{rep:?}");
    assert!(rep.results.accounting.invariant_held);
    let epochs = 6001;
    for topic in ["stereo", "relnav"] {
        let t = &rep.results.topics[topic];
        assert_eq!(t.expected, epochs, "{topic}: {t:?}");
        assert_eq!(t.published, Some(epochs), "{topic}: {t:?}");
        for (name, c) in &t.consumers {
            assert_eq!(c.received, Some(epochs), "{topic} → {name}: {c:?}");
            assert_eq!(c.dropped, Some(0), "{topic} → {name}: {c:?}");
        }
    }
    let nav = rep.results.relnav.as_ref().expect("no relnav section");
    // every epoch but the start's is answered (the start fits five epochs, answers at the
    // fifth); the last 50 minutes at 1 s, both ends included, are scored
    assert_eq!(nav.filter.estimates, epochs - 4, "{nav:?}");
    assert_eq!(nav.window_s, [3000.0, 6000.0], "{nav:?}");
    assert_eq!(nav.epochs_scored, 3001, "{nav:?}");
    assert_eq!(nav.filter.starts, 1, "{nav:?}");
    assert_eq!(
        nav.filter.diverged + nav.filter.numerical_failures,
        0,
        "{nav:?}"
    );
    let e = &nav.rtmse;
    assert!(e.attitude_deg < 0.1, "{e:?}");
    assert!(e.rate_rad_s < 6e-5, "{e:?}");
    assert!(e.position_m < 0.010, "{e:?}");
    assert!(e.velocity_m_s < 10e-6, "{e:?}");
    assert!(e.inertia_k < 0.02, "{e:?}");
    assert!(
        (0.95..=1.0).contains(&nav.within_3sigma.attitude),
        "{nav:?}"
    );
    for g in [
        "attitude",
        "rate",
        "inertia-k",
        "position",
        "velocity",
        "inertia",
    ] {
        assert!(
            r.dir.join(format!("relnav-{g}.svg")).exists(),
            "relnav-{g}.svg"
        );
    }
    let summary = std::fs::read_to_string(r.dir.join("summary.md")).unwrap();
    assert!(summary.contains("[004] Relative navigation"), "{summary}");
    // the same scenario and seed give the same science
    let r2 = run_ok(Some(&file), &dir.join("b"), &[]);
    assert_eq!(
        rep.results.science.digest_xxh3,
        r2.typed.results.science.digest_xxh3
    );
    assert_eq!(rep.results.relnav, r2.typed.results.relnav);
}

/// A killed relnav is restarted from its last checkpoint (the filter's state, not a rerun from
/// epoch 0) and its estimates are byte for byte those of the run without the fault.
#[test]
fn a_killed_relnav_resumes_from_its_checkpoint_with_the_same_estimates() {
    let dir = temp_dir("relnav-kill");
    let file = scenario_variant(
        "stereo-tumbling.toml",
        &[("duration_s = 6000.0", "duration_s = 1200.0")],
        &dir,
    );
    let clean = run_ok(Some(&file), &dir.join("clean"), &[]);
    let out = dir.join("kill");
    let r = run_ok(Some(&file), &out, &["--fault", "relnav:kill@600"]);
    let faults = &r.typed.faults;
    assert_eq!(faults.len(), 1, "{faults:?}");
    let f = &faults[0];
    assert_eq!(f.detected_by.as_deref(), Some("exit"), "{f:?}");
    assert_eq!(f.restarts, 1, "{f:?}");
    assert_eq!(f.lost, Some(0), "{f:?}");
    assert!(f.recovered_s.is_some(), "{f:?}");
    let relnav = (r.typed.results.services.iter())
        .find(|s| s.name == "relnav")
        .unwrap();
    assert_eq!(relnav.restarts, 1);
    let log = std::fs::read_to_string(out.join("logs").join("relnav.log")).unwrap();
    let restored = log
        .lines()
        .find_map(|l| l.split("restored its checkpoint input_seq=").nth(1))
        .and_then(|s| s.trim().parse::<u64>().ok())
        .unwrap_or_else(|| panic!("no checkpoint restored:\n{log}"));
    assert!(restored > 0 && restored <= 600, "restored at {restored}");
    let digest = |r: &RunResult, topic: &str| r.typed.results.topics[topic].digest_xxh3.clone();
    assert_eq!(digest(&r, "relnav"), digest(&clean, "relnav"));
    assert_eq!(
        r.typed.results.science.digest_xxh3,
        clean.typed.results.science.digest_xxh3
    );
    assert_eq!(r.typed.results.relnav, clean.typed.results.relnav);
}

/// The paper's Table 1 start (truth with its stated offsets, k̂₀ = 0) as a scenario option:
/// the filter answers from the first epoch, with no start from the measurements, and meets the
/// paper's figures over the last 50 minutes.
#[test]
fn the_papers_table1_start_answers_from_the_first_epoch() {
    let dir = temp_dir("relnav-table1");
    let file = scenario_variant(
        "stereo-tumbling.toml",
        &[("start = \"measurements\"", "start = \"table1\"")],
        &dir,
    );
    let r = run_ok(Some(&file), &dir.join("out"), &[]);
    let nav = r.typed.results.relnav.as_ref().expect("no relnav section");
    assert_eq!(nav.filter.starts, 0, "{nav:?}");
    assert_eq!(nav.filter.starting_epochs, 0, "{nav:?}");
    assert_eq!(nav.filter.estimates, 6001, "{nav:?}");
    let (e, p) = (&nav.rtmse, &nav.paper);
    assert!(
        e.attitude_deg < p.attitude_deg && e.rate_rad_s < p.rate_rad_s,
        "{e:?}"
    );
    assert!(
        e.inertia_k <= p.inertia_k && e.position_m <= p.position_m,
        "{e:?}"
    );
    assert!(e.velocity_m_s < p.velocity_m_s, "{e:?}");
}
