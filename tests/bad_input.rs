//! Bad input gets a clear error and exit code 2, never a panic.

mod common;

use common::*;

fn write(dir: &std::path::Path, name: &str, text: &str) -> std::path::PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn base() -> String {
    std::fs::read_to_string(scenario("debris-geo.toml")).unwrap()
}

fn spectra_base() -> String {
    std::fs::read_to_string(scenario("geo-hover-yspin.toml")).unwrap()
}

#[test]
fn malformed_scenarios_exit_2_naming_file_and_field() {
    let dir = temp_dir("bad");
    let cases = [
        (
            "unknown.toml",
            base().replace("fov_deg = 10.0", "fov_deg = 10.0\nfocal = 3"),
            "camera.focal",
        ),
        (
            "type.toml",
            base().replace("frames = 50", "frames = \"many\""),
            "camera.frames",
        ),
        (
            "range.toml",
            base().replace("psf_sigma_px = 0.8", "psf_sigma_px = 50.0"),
            "camera.psf_sigma_px",
        ),
        (
            "nan.toml",
            base().replace("fov_deg = 10.0", "fov_deg = nan"),
            "camera.fov_deg",
        ),
        (
            "syntax.toml",
            "name = \"x\"\n[camera\n".to_string(),
            "camera",
        ),
        // Messages point to the right place: a missing field names its table and itself,
        // a bad frame count is one error (not also one per false target), and a huge value
        // prints in exponent form.
        (
            "missing-fov.toml",
            base().replace("fov_deg = 10.0\n", ""),
            "missing-fov.toml:13: field `camera.fov_deg`: missing field `fov_deg`",
        ),
        (
            "missing-band.toml",
            spectra_base().replace("band_start_nm = 400.0\n", ""),
            "field `spectra.band_start_nm`: missing field `band_start_nm`",
        ),
        (
            "huge.toml",
            base().replace("psf_sigma_px = 0.8", "psf_sigma_px = 1e308"),
            "`camera.psf_sigma_px`: 1e308 is out of range; allowed 0.2..=5\n",
        ),
        // Band centres outside the sensor's material tables: refused before any work (the
        // sensor died at run time with a Debug dump of WavelengthOutOfRange).
        (
            "band-start.toml",
            spectra_base().replace("band_start_nm = 400.0", "band_start_nm = 390.0"),
            "`spectra.band_start_nm`: 390 is out of range; allowed 400..=750",
        ),
        (
            "band-stop.toml",
            spectra_base().replace("band_stop_nm = 750.0", "band_stop_nm = 760.0"),
            "`spectra.band_stop_nm`: 760 is out of range; allowed 400..=750",
        ),
    ];
    for (name, text, field) in cases {
        let file = write(&dir, name, &text);
        for sub in ["validate", "run"] {
            let mut cmd = glint();
            cmd.arg(sub).arg(&file);
            if sub == "run" {
                cmd.arg("--out").arg(dir.join("never"));
            }
            let out = cmd.output().unwrap();
            let err = String::from_utf8_lossy(&out.stderr);
            assert_eq!(out.status.code(), Some(2), "{sub} {name}: {err}");
            assert!(
                err.contains(name),
                "{sub} {name}: error does not name the file: {err}"
            );
            assert!(
                err.contains(field),
                "{sub} {name}: error does not name {field}: {err}"
            );
            assert!(!err.contains("panicked"), "{err}");
        }
    }
    assert!(
        !dir.join("never").exists(),
        "a bad scenario must not start a run"
    );
    let zero = write(
        &dir,
        "zero.toml",
        &base().replace("frames = 50", "frames = 0"),
    );
    let out = glint().arg("validate").arg(&zero).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("`camera.frames`: 0 is out of range"), "{err}");
    assert!(
        !err.contains("false_targets"),
        "one error, not one per false target: {err}"
    );
    let missing = glint()
        .arg("validate")
        .arg(dir.join("nope.toml"))
        .output()
        .unwrap();
    assert_eq!(missing.status.code(), Some(2));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn shipped_scenarios_validate() {
    for name in [
        "default.toml",
        "debris-geo.toml",
        "geo-hover-yspin.toml",
        "geo-hover-zspin.toml",
    ] {
        let out = glint()
            .arg("validate")
            .arg(scenario(name))
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
}

#[test]
fn campaigns_run_through_glint_lab_and_plain_runs_through_glint_run() {
    // A campaign is lab work: `glint run` says where it belongs, with exit code 2.
    let campaign = scenario("campaign-axis.toml");
    let out = glint().arg("run").arg(&campaign).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("glint lab campaign"), "{err}");
    // And a plain scenario is no campaign.
    let plain = scenario("geo-hover-yspin.toml");
    let out = glint()
        .args(["lab", "campaign"])
        .arg(&plain)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("no [campaign] section"), "{err}");
}

/// Solver settings outside their documented ranges are refused before any work, naming the
/// file, the field, the value and the range (a 1000-point grid per axis asked for 32 GB and
/// aborted the process).
#[test]
fn unbounded_solver_settings_exit_2_before_any_work() {
    let dir = temp_dir("bad-config");
    let observations =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/y-snr50-seed7-400nm.csv");
    let cases = [
        (
            "[stage3.start]\npoints_per_axis = 1000\n",
            "stage3.start.points_per_axis: 1000 is out of range; allowed 1..=41",
        ),
        (
            "[stage3.start]\nscreen_starts = 4000000000\n",
            "stage3.start.screen_starts: 4000000000 is out of range; allowed 1..=1000",
        ),
        (
            "[stage3.start]\npolish_starts = 4000000000\n",
            "stage3.start.polish_starts: 4000000000 is out of range; allowed 1..=100",
        ),
        (
            "[stage3.start]\nhalf_width_deg_per_frame = 1e9\n",
            "stage3.start.half_width_deg_per_frame: 1000000000 is out of range; allowed (0, 10]",
        ),
        (
            "[stage3.lm]\nmax_iterations = 0\n",
            "stage3.lm.max_iterations: 0 is out of range; allowed 1..=10000",
        ),
    ];
    for (i, (text, want)) in cases.iter().enumerate() {
        let config = write(&dir, &format!("c{i}.toml"), text);
        let out = glint()
            .arg("invert")
            .arg(&observations)
            .arg("--config")
            .arg(&config)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{text}: {err}");
        assert!(err.contains(&format!("c{i}.toml")), "{text}: {err}");
        assert!(err.contains(want), "{text}: {err}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A file that never ends (`/dev/zero`) is refused after a documented number of bytes, with
/// exit 2, by every command that reads a user's file; before, they read until memory ran out.
#[test]
fn endless_input_files_are_refused_at_their_size_limit() {
    for (args, limit) in [
        (&["validate", "/dev/zero"][..], "1 MiB"),
        (&["tool", "detect", "/dev/zero"][..], "128 MiB"),
        (&["invert", "/dev/zero"][..], "256 MiB"),
    ] {
        let out = glint().args(args).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(
            err.contains("/dev/zero") && err.contains(limit),
            "{args:?}: {err}"
        );
    }
}
