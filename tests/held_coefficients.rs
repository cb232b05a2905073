//! The opt-in held coefficients (docs/adr/0030) across processes: the scenario's setting reaches
//! the inversion service, the report names the fits that used it, and `glint invert` reproduces
//! the service's answer with the same setting.

mod common;

use common::*;

/// `spectra.held_coefficients` reaches the inversion service (docs/adr/0030). With λ* held and
/// both windows noisy, the report says which fit held stage 1's coefficients, and the service's
/// λ* is `glint invert`'s with the same setting on the exported observations, to the bit. Not
/// vacuous: the default setting answers differently.
#[test]
fn held_coefficients_reach_the_service_and_are_reproduced_offline() {
    let dir = temp_dir("held");
    let file = scenario_variant(
        "geo-hover-zspin.toml",
        &[
            ("stable_samples = 720", "stable_samples = 360"),
            ("motion_frames = 720", "motion_frames = 240"),
            (
                "attitude_convention = \"verbatim\"",
                "attitude_convention = \"verbatim\"\nsnr = 20.0\nheld_coefficients = \"single-band\"",
            ),
        ],
        &dir,
    );
    let r = run_ok(Some(&file), &dir.join("out"), &[]);
    let s3 = &r.report["inversion"]["stage3"];
    assert_eq!(s3["status"], "ok", "{s3}");
    assert_eq!(s3["held_coefficients"], true, "{s3}");
    assert_eq!(s3["joint"]["held_coefficients"], false, "{s3}");
    let summary = std::fs::read_to_string(r.dir.join("summary.md")).unwrap();
    assert!(
        summary.contains("held by their stable-window prior"),
        "{summary}"
    );

    let observations = r.dir.join("observations.csv");
    let config = dir.join("held.toml");
    std::fs::write(&config, "[stage3]\nheld_coefficients = \"single-band\"\n").unwrap();
    let config = config.to_str().unwrap();
    let held = invert_ok(&observations, &dir.join("held"), &["--config", config]);
    assert_eq!(held["rate"]["refit"]["held_coefficients"], true, "{held}");
    assert_eq!(s3["p_deg_per_frame"], held["rate"]["rate_deg_per_frame"]);
    let plain = invert_ok(&observations, &dir.join("plain"), &[]);
    assert_eq!(
        plain["rate"]["refit"]["held_coefficients"], false,
        "{plain}"
    );
    assert_ne!(s3["p_deg_per_frame"], plain["rate"]["rate_deg_per_frame"]);
    let _ = std::fs::remove_dir_all(&dir);
}
