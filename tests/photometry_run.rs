//! [001] deployed: the sensor's light curve and the photometry service as separate processes
//! over iceoryx2, every sample accounted for, the identification and the UKF scored against
//! the sensor's truth (the shape it rendered, its spin, its attitude at every sample).

mod common;

use common::*;

/// The shipped scenario's library, absolute, for a variant written elsewhere.
fn shapes_absolute() -> (&'static str, String) {
    let lib = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("shapes/shapes.toml");
    (
        "shapes = \"../shapes/shapes.toml\"",
        format!("shapes = \"{}\"", lib.display()),
    )
}

#[test]
fn the_photometry_chain_deployed_identifies_the_satellite_and_tracks_its_attitude() {
    let dir = temp_dir("photometry-run");
    let file = scenario("photometry-geo.toml");
    let r = run_ok(Some(&file), &dir.join("a"), &[]);
    let rep = &r.typed;
    assert!(rep.results.success, "{rep:?}");
    assert!(rep.results.accounting.invariant_held);
    // 20 minutes at 2 s, both ends included
    let samples = 601;
    for topic in ["photometry", "photometry_estimate"] {
        let t = &rep.results.topics[topic];
        assert_eq!(t.expected, samples, "{topic}: {t:?}");
        assert_eq!(t.published, Some(samples), "{topic}: {t:?}");
        for (name, c) in &t.consumers {
            assert_eq!(c.received, Some(samples), "{topic} → {name}: {c:?}");
            assert_eq!(c.dropped, Some(0), "{topic} → {name}: {c:?}");
        }
    }
    let ph = rep
        .results
        .photometry
        .as_ref()
        .expect("no photometry section");
    assert_eq!(ph.samples.total, samples);
    assert_eq!(ph.samples.seen, samples, "a lit arc above the horizon");
    let id = &ph.identification;
    // the truth is what the sensor rendered; glint's answer comes from the light curve alone
    assert_eq!(id.truth_geometry, "box-wing");
    assert_eq!(id.geometry.as_deref(), Some("box-wing"), "{id:?}");
    assert!(id.correct);
    assert_eq!(id.at_s, 600.0, "identified once 10 minutes were gathered");
    let spin_err = (id.spin_rad_s / id.truth_spin_rad_s - 1.0).abs();
    assert!(spin_err < 0.005, "spin {spin_err:e}: {id:?}");
    assert!((id.truth_spin_rad_s - std::f64::consts::TAU / 120.0).abs() < 1e-12);
    let area_err = (id.area_m2 / id.truth_area_m2 - 1.0).abs();
    assert!(area_err < 0.05, "area {area_err}: {id:?}");
    assert!(id.axis_error_deg < 5.0, "{id:?}");
    assert_eq!(id.matching.len(), 6, "every geometry's best");
    assert!(id.matching.windows(2).all(|w| w[0].score <= w[1].score));
    let u = &ph.ukf;
    // every sample from the identification on is answered by the filter
    assert_eq!(u.samples_tracked, samples - 300, "{u:?}");
    assert!(u.attitude_err_deg_final < 2.0, "{u:?}");
    assert!(
        u.attitude_err_deg_final < u.attitude_3sigma_deg_final * 1.5,
        "{u:?}"
    );
    assert!(
        (u.nees_95[0]..=u.nees_95[1]).contains(&u.nees_mean),
        "NEES {} outside {:?}",
        u.nees_mean,
        u.nees_95
    );
    for f in ["photometry-lightcurve.svg", "photometry-attitude.svg"] {
        assert!(r.dir.join(f).exists(), "{f}");
    }
    let summary = std::fs::read_to_string(r.dir.join("summary.md")).unwrap();
    assert!(summary.contains("[001] Ground photometry"), "{summary}");
    assert!(
        summary.contains("Identified **box-wing**, the true geometry"),
        "{summary}"
    );
    // the same scenario and seed give the same science
    let r2 = run_ok(Some(&file), &dir.join("b"), &[]);
    assert_eq!(
        rep.results.science.digest_xxh3,
        r2.typed.results.science.digest_xxh3
    );
    assert_eq!(rep.results.photometry, r2.typed.results.photometry);
}

/// A killed photometry service is restarted from its checkpoint — while gathering (the
/// samples so far) and while tracking (the identification and the filter) — and its answers
/// are byte for byte those of the run without the fault.
#[test]
fn a_killed_photometry_resumes_from_its_checkpoint_with_the_same_answers() {
    let dir = temp_dir("photometry-kill");
    let file = scenario("photometry-geo.toml");
    let clean = run_ok(Some(&file), &dir.join("clean"), &[]);
    let digest = |r: &RunResult, topic: &str| r.typed.results.topics[topic].digest_xxh3.clone();
    // checkpoints every 256 inputs (or every second): before the identification at sample 300
    // one holds the gathered samples, after it the identification and the filter (the core's
    // restore from either is checked sample by sample in services/photometry/tests). A kill
    // fires when the orchestrator has seen sample `at` go by; the service is then at most the
    // topic's credit window (64) behind it, past the checkpoint at 256 or at 512.
    for at in [400, 590] {
        let out = dir.join(format!("kill-{at}"));
        let r = run_ok(
            Some(&file),
            &out,
            &["--fault", &format!("photometry:kill@{at}")],
        );
        let faults = &r.typed.faults;
        assert_eq!(faults.len(), 1, "{faults:?}");
        let f = &faults[0];
        assert_eq!(f.detected_by.as_deref(), Some("exit"), "{f:?}");
        assert_eq!(f.restarts, 1, "{f:?}");
        assert_eq!(f.lost, Some(0), "{f:?}");
        let log = std::fs::read_to_string(out.join("logs").join("photometry.log")).unwrap();
        let restored = log
            .lines()
            .find_map(|l| l.split("restored its checkpoint input_seq=").nth(1))
            .and_then(|s| s.trim().parse::<u64>().ok())
            .unwrap_or_else(|| panic!("no checkpoint restored:\n{log}"));
        assert!(
            restored > 0 && restored <= at,
            "kill at {at}: restored at {restored}"
        );
        assert_eq!(
            digest(&r, "photometry_estimate"),
            digest(&clean, "photometry_estimate"),
            "kill at {at}"
        );
        assert_eq!(r.typed.results.photometry, clean.typed.results.photometry);
    }
}

/// An arc that runs into the Earth's shadow (near the equinox, towards the satellite's local
/// midnight): the samples in shadow carry no magnitude and say why, every one is still
/// answered, and the identification is made from the lit part.
#[test]
fn an_arc_into_the_earths_shadow_has_counted_gaps_and_every_sample_answered() {
    let dir = temp_dir("photometry-shadow");
    let (from, to) = shapes_absolute();
    let file = scenario_variant(
        "photometry-geo.toml",
        &[
            (from, &to),
            (
                "start_utc = \"2026-03-10T12:00:00Z\"",
                "start_utc = \"2026-03-10T13:50:00Z\"",
            ),
            ("duration_s = 1200.0", "duration_s = 2400.0"),
        ],
        &dir,
    );
    let r = run_ok(Some(&file), &dir.join("out"), &[]);
    assert!(r.typed.results.success);
    let samples = 1201;
    let t = &r.typed.results.topics["photometry_estimate"];
    assert_eq!(t.published, Some(samples), "{t:?}");
    let ph = r
        .typed
        .results
        .photometry
        .as_ref()
        .expect("no photometry section");
    let c = &ph.samples;
    assert_eq!(c.total, samples);
    assert!(c.shadow > 100 && c.seen > 300, "{c:?}");
    assert_eq!(c.seen + c.shadow + c.below_horizon + c.no_flux, samples);
    // identified from the lit part, and answered through the shadow
    assert!(ph.identification.geometry.is_some(), "{ph:?}");
    assert_eq!(ph.ukf.samples_tracked + 300, samples, "{ph:?}");
    assert_eq!(ph.ukf.updates, ph.ukf.samples_tracked - c.shadow, "{ph:?}");
}

/// An arc shorter than the identification window: every sample is answered `GATHERING`, the
/// report says nothing was identified (its figures NaN, written null and read back as NaN),
/// and the run still passes: nothing was lost.
#[test]
fn an_arc_too_short_to_identify_reports_no_identification() {
    let dir = temp_dir("photometry-short");
    let (from, to) = shapes_absolute();
    let file = scenario_variant(
        "photometry-geo.toml",
        &[(from, &to), ("duration_s = 1200.0", "duration_s = 300.0")],
        &dir,
    );
    let r = run_ok(Some(&file), &dir.join("out"), &[]);
    assert!(r.typed.results.success);
    let ph = r
        .typed
        .results
        .photometry
        .as_ref()
        .expect("no photometry section");
    let id = &ph.identification;
    assert_eq!(id.geometry, None, "{id:?}");
    assert!(
        !id.correct && id.spin_rad_s.is_nan() && id.matching.is_empty(),
        "{id:?}"
    );
    assert_eq!(ph.ukf.samples_tracked, 0);
    assert!(ph.ukf.nees_mean.is_nan());
    assert_eq!(
        r.typed.results.topics["photometry_estimate"].published,
        Some(151)
    );
    let summary = std::fs::read_to_string(r.dir.join("summary.md")).unwrap();
    assert!(summary.contains("Identified nothing"), "{summary}");
}
