//! Scenario parsing and validation: every shipped scenario is valid, and every kind of bad
//! input names the file, the field and the allowed range.

use shared_types::scenario::ScenarioError;
use shared_types::Scenario;

fn scenarios_dir() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios")
}

fn base() -> String {
    std::fs::read_to_string(scenarios_dir().join("debris-geo.toml")).unwrap()
}

fn error_of(text: &str) -> String {
    match Scenario::from_toml_str(text, "bad.toml") {
        Ok(_) => panic!("accepted a bad scenario"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn shipped_scenarios_are_valid() {
    let mut n = 0;
    for e in std::fs::read_dir(scenarios_dir()).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "toml") {
            let text = std::fs::read_to_string(&p).unwrap();
            assert!(
                text.starts_with('#'),
                "{} must open with a comment",
                p.display()
            );
            Scenario::from_file(&p).unwrap_or_else(|e| panic!("{e}"));
            n += 1;
        }
    }
    assert!(n >= 4);
}

#[test]
fn unknown_key_is_named() {
    let text = base().replace("fov_deg = 10.0", "fov_deg = 10.0\nfov_degs = 3.0");
    let e = error_of(&text);
    assert!(e.contains("bad.toml"), "{e}");
    assert!(e.contains("camera.fov_degs"), "{e}");
    assert!(e.contains("unknown field"), "{e}");
}

#[test]
fn wrong_type_is_named_with_line() {
    let text = base().replace("frames = 50", "frames = \"fifty\"");
    let err = Scenario::from_toml_str(&text, "bad.toml").unwrap_err();
    match &err {
        ScenarioError::Parse { field, line, .. } => {
            assert_eq!(field, "camera.frames");
            let expected_line = text.lines().position(|l| l.contains("\"fifty\"")).unwrap() + 1;
            assert_eq!(*line, expected_line);
        }
        other => panic!("unexpected {other}"),
    }
}

#[test]
fn out_of_range_reports_the_allowed_range() {
    let e = error_of(&base().replace("fov_deg = 10.0", "fov_deg = 120.0"));
    assert!(
        e.contains("camera.fov_deg") && e.contains("0.1..=90"),
        "{e}"
    );
    let e = error_of(&base().replace("x_m = 6000.0", "x_m = -6000.0"));
    assert!(e.contains("camera.debris[2].x_m"), "{e}");
}

#[test]
fn non_finite_values_are_rejected() {
    let e = error_of(&base().replace("exposure_s = 0.02", "exposure_s = nan"));
    assert!(
        e.contains("camera.exposure_s") && e.contains("not a finite number"),
        "{e}"
    );
    let e = error_of(&base().replace("background_dn = 100.0", "background_dn = inf"));
    assert!(e.contains("camera.background_dn"), "{e}");
}

#[test]
fn all_problems_are_reported_at_once() {
    let text = base()
        .replace("fov_deg = 10.0", "fov_deg = 0.0")
        .replace("frames = 50", "frames = 0");
    let e = error_of(&text);
    assert!(
        e.contains("camera.fov_deg") && e.contains("camera.frames"),
        "{e}"
    );
}

#[test]
fn spectra_band_count_is_bounded() {
    let text = std::fs::read_to_string(scenarios_dir().join("geo-hover-yspin.toml"))
        .unwrap()
        .replace("band_step_nm = 10.0", "band_step_nm = 1.0");
    let e = error_of(&text);
    assert!(
        e.contains("spectra.band_step_nm") && e.contains("64"),
        "{e}"
    );
}

#[test]
fn resolved_scenario_round_trips() {
    let s = Scenario::from_toml_str(&base(), "debris-geo.toml").unwrap();
    let again = Scenario::from_toml_str(&s.to_toml(), "resolved").unwrap();
    assert_eq!(s, again);
}

#[test]
fn campaign_values_are_validated_as_the_scenario_they_make() {
    let text = std::fs::read_to_string(scenarios_dir().join("campaign-phase.toml"))
        .unwrap()
        .replace("values = [3.0, 5.0,", "values = [300.0, 5.0,");
    let e = error_of(&text);
    assert!(
        e.contains("campaign.values[0]") && e.contains("spectra.start_phase_deg"),
        "{e}"
    );
    let text = std::fs::read_to_string(scenarios_dir().join("campaign-axis.toml"))
        .unwrap()
        .replace(
            "parameter = \"spectra.rotation\"",
            "parameter = \"spectra.aperture\"",
        );
    let e = error_of(&text);
    assert!(
        e.contains("campaign.parameter") && e.contains("allowed"),
        "{e}"
    );
}

fn earth_base() -> String {
    std::fs::read_to_string(scenarios_dir().join("earth-sensor-turntable.toml")).unwrap()
}

#[test]
fn the_earth_sweep_is_the_papers() {
    let s = Scenario::from_file(&scenarios_dir().join("earth-sensor-turntable.toml")).unwrap();
    let e = s.earth.as_ref().unwrap();
    let angles = e.angles_deg();
    // −50…−11 and 11…50 in 1° steps (2 × 40), −10…10 in 0.1° steps (201).
    assert_eq!(angles.len(), 281);
    assert_eq!((angles[0], angles[280]), (-50.0, 50.0));
    assert!(angles.windows(2).all(|w| w[1] > w[0]));
    let fine: Vec<f64> = angles.iter().copied().filter(|a| a.abs() <= 10.0).collect();
    assert_eq!(fine.len(), 201);
    assert!(fine.windows(2).all(|w| ((w[1] - w[0]) - 0.1).abs() < 1e-9));
    assert_eq!(e.frames(), 281 * e.images_per_angle as u64);
    // K images per angle: frames k·K … k·K + K − 1 share angle k.
    let k = e.images_per_angle as u64;
    assert_eq!(e.tilt_deg(&angles, 0), -50.0);
    assert_eq!(e.tilt_deg(&angles, k - 1), -50.0);
    assert_eq!(e.tilt_deg(&angles, k), -49.0);
    // The σ table is found beside the scenario file.
    let table = e.sigma_table.as_ref().unwrap();
    assert!(
        table.is_absolute() || table.starts_with(scenarios_dir()),
        "{table:?}"
    );
}

#[test]
fn bad_earth_fields_are_named_with_their_range() {
    let e = error_of(&earth_base().replace("f_px = 130.0", "f_px = 0.5"));
    assert!(e.contains("earth.f_px") && e.contains("10..=10000"), "{e}");
    let e =
        error_of(&earth_base().replace("center_px = [255.5, 255.5]", "center_px = [600.0, 255.5]"));
    assert!(
        e.contains("earth.center_px[0]") && e.contains("0..=511"),
        "{e}"
    );
    let e = error_of(&earth_base().replace("space_dn = 20.0", "space_dn = 5000.0"));
    assert!(
        e.contains("earth.earth_dn") && e.contains("earth.space_dn"),
        "{e}"
    );
    let e = error_of(&earth_base().replace("[earth]", "[earth]\ntrajectory_deg = [0.0, 95.0]"));
    assert!(
        e.contains("earth.trajectory_deg[1]") && e.contains("-80..=80"),
        "{e}"
    );
    let e = error_of(&earth_base().replace("images_per_angle = 2", "images_per_angle = 0"));
    assert!(e.contains("earth.images_per_angle"), "{e}");
    let e = error_of(&earth_base().replace("[earth]", "[earth]\nlens_k = [0.05, 1.5, 0.0, 0.0]"));
    assert!(e.contains("earth.lens_k[1]") && e.contains("-1..=1"), "{e}");
    // θ_d = θ (1 − 0.6 θ²) peaks at θ = 42.7° (f θ_d = 65 px), inside the 255 px circle.
    let e = error_of(
        &earth_base().replace("[earth]", "[earth]\ncalibration_k = [-0.6, 0.0, 0.0, 0.0]"),
    );
    assert!(
        e.contains("earth.calibration_k") && e.contains("stops growing at θ = 42.8°"),
        "{e}"
    );
    let e = error_of(&earth_base().replace("[earth]", "[earth]\nlimb_height_seasonal_km = 80"));
    assert!(
        e.contains("earth.limb_height_seasonal_km") && e.contains("-50..=50"),
        "{e}"
    );
    let e = error_of(&earth_base().replace("noise_dn = 10.0", "noise_dn = 10.0\nnoise = 3"));
    assert!(
        e.contains("earth.noise") && e.contains("unknown field"),
        "{e}"
    );
}

#[test]
fn a_given_trajectory_replaces_the_sweep() {
    let text = earth_base().replace("[earth]", "[earth]\ntrajectory_deg = [1.0, -2.0, 3.5]");
    let s = Scenario::from_toml_str(&text, "t.toml").unwrap();
    let e = s.earth.unwrap();
    assert_eq!(e.angles_deg(), vec![1.0, -2.0, 3.5]);
    assert_eq!(e.frames(), 3 * e.images_per_angle as u64);
}
