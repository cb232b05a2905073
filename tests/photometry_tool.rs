//! `glint tool photometry` on a light curve written by an independent simulator
//! (tests/data/photometry/sim_lightcurve.py: its own BRDF code, each face cut into 3 × 3 for
//! shadowing, Earth rotation moving the observer, 0.05 mag noise) and glint's shipped shapes.

mod common;

use common::*;

#[test]
fn another_simulators_light_curve_gives_its_geometry_and_spin() {
    let dir = temp_dir("photometry-tool");
    let data = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/photometry");
    let out = glint()
        .args(["tool", "photometry"])
        .arg(data.join("LC.csv"))
        .arg("--shapes")
        .arg(std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("shapes/shapes.toml"))
        .arg("--out")
        .arg(&dir)
        .output()
        .unwrap();
    assert_success(&out);
    let truth = read_json(&data.join("TRUTH.json"));
    let id = read_json(&dir.join("identification.json"));
    assert_eq!(id["geometry"], truth["geometry"], "{id:#}");
    let (w, w_true) = (
        id["spin_rad_s"].as_f64().unwrap(),
        truth["spin_rad_s"].as_f64().unwrap(),
    );
    assert!((w / w_true - 1.0).abs() < 0.005, "spin {w} vs {w_true}");
    let matching = id["matching"].as_array().unwrap();
    assert_eq!(matching.len(), 6);
    let scores: Vec<f64> = matching
        .iter()
        .map(|m| m["score"].as_f64().unwrap())
        .collect();
    assert!(scores.windows(2).all(|s| s[0] <= s[1]), "{scores:?}");
    let csv = std::fs::read_to_string(dir.join("attitude.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(
        lines.next(),
        Some("t_s,qw,qx,qy,qz,wx,wy,wz,sig_th_x,sig_th_y,sig_th_z,sig_w_x,sig_w_y,sig_w_z")
    );
    assert_eq!(lines.count(), 600, "one row per sample");
}

#[test]
fn bad_light_curves_and_shapes_are_named_by_file_line_and_field() {
    let dir = temp_dir("photometry-bad");
    let shapes = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("shapes/shapes.toml");
    let run = |lc: &str, shapes: &std::path::Path| {
        let file = dir.join("LC.csv");
        std::fs::write(&file, lc).unwrap();
        let out = glint()
            .args(["tool", "photometry"])
            .arg(&file)
            .arg("--shapes")
            .arg(shapes)
            .arg("--out")
            .arg(dir.join("out"))
            .output()
            .unwrap();
        (
            out.status.code(),
            String::from_utf8_lossy(&out.stderr).to_string(),
        )
    };
    let header = "t_s,mag,sigma_mag,sun_x,sun_y,sun_z,obs_x,obs_y,obs_z,range_m\n";
    let (code, err) = run(
        &format!("{header}0,12.5,0.05,1,0,0,0,1,0,3.6e7\n1,abc,0.05,1,0,0,0,1,0,3.6e7\n"),
        &shapes,
    );
    assert_eq!(code, Some(2));
    assert!(
        err.contains("line 3, column `mag`: `abc` is not a number"),
        "{err}"
    );
    let (code, err) = run(
        &format!("{header}0,12.5,0.05,1,0,0,0,0.5,0,3.6e7\n"),
        &shapes,
    );
    assert_eq!(code, Some(2));
    assert!(
        err.contains("line 2") && err.contains("observer direction has length 0.5"),
        "{err}"
    );
    // A user's shapes file naming an OBJ with a bad face.
    std::fs::write(dir.join("bad.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n").unwrap();
    let mine = dir.join("mine.toml");
    std::fs::write(
        &mine,
        "[[shape]]\nname = \"mine\"\nobj = \"bad.obj\"\nmaterial = { r_diff = 0.3, r_spec = 0.5, n_u = 10.0, n_v = 10.0 }\n",
    )
    .unwrap();
    let lc = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/photometry/LC.csv"),
    )
    .unwrap();
    let (code, err) = run(&lc, &mine);
    assert_eq!(code, Some(2));
    assert!(
        err.contains("bad.obj: line 4, column 7: vertex index 4 out of range"),
        "{err}"
    );
    std::fs::write(
        &mine,
        "[[shape]]\nname = \"mine\"\nobj = \"bad.obj\"\nmaterial = { r_diff = 1.5, r_spec = 0.5, n_u = 10.0, n_v = 10.0 }\n",
    )
    .unwrap();
    let (code, err) = run(&lc, &mine);
    assert_eq!(code, Some(2));
    assert!(
        err.contains("field `shape[0].material.r_diff`: 1.5 is out of range; allowed 0..=1"),
        "{err}"
    );
}
