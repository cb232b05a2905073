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
