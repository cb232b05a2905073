//! [003] offline tools on files, as a user brings samples from a real sensor.

mod common;

use common::{glint, scenario, temp_dir};

/// Runs a glint command, asserts success, parses its JSON output.
fn glint_json(cmd: &mut std::process::Command) -> serde_json::Value {
    let out = cmd.output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

/// `glint tool tfit` on the 20 samples of docs/math.md §7.4 prints the high-precision MLE.
#[test]
fn tool_tfit_prints_the_mle_of_a_sample_file() {
    let dir = temp_dir("tfit");
    let file = dir.join("beta_k.txt");
    let sample = "10.12 9.87 10.05 9.96 10.31 9.74 10.02 10.08 9.91 10.44 9.99 10.15 9.82 10.01 \
                  9.58 10.06 9.95 10.23 9.89 10.97";
    let text: String = std::iter::once("# β_k samples [deg]\n".to_string())
        .chain(
            sample
                .split_whitespace()
                .map(|v| format!("{v}   # one sample\n")),
        )
        .collect();
    std::fs::write(&file, text).unwrap();
    let v = glint_json(glint().args(["tool", "tfit"]).arg(&file));
    let f = |k: &str| v[k].as_f64().unwrap();
    assert_eq!(v["n"], 20);
    assert!((f("mu") - 10.0087229834).abs() < 1e-8, "{v}");
    assert!((f("sigma") - 0.142487934787).abs() < 1e-9, "{v}");
    assert!((f("nu") - 2.03295355610).abs() < 1e-7, "{v}");
    assert!((f("nll") - 0.0524515737191).abs() < 1e-10, "{v}");
    assert!(v["iterations"].as_u64().unwrap() >= 1);
    let _ = std::fs::remove_dir_all(&dir);
}

/// scipy's `t.fit` of a file in tests/data/tfit-scipy, from its header comment.
fn scipy_fit(path: &std::path::Path) -> [f64; 4] {
    let text = std::fs::read_to_string(path).unwrap();
    let line = text.lines().find(|l| l.contains("t.fit:")).unwrap();
    let words: Vec<&str> = line.split_whitespace().collect();
    let after = |key: &str| -> f64 {
        let i = words.iter().position(|w| *w == key).unwrap();
        words[i + 1].parse().unwrap()
    };
    [after("nu"), after("mu"), after("sigma"), after("nll")]
}

/// Against an independent implementation: on 1000 t draws in degrees and in radians glint's
/// MLE is scipy's (scipy.stats.t.fit 1.17, values in the files' headers) and no worse in
/// likelihood; at a scale of 3e-5 scipy stops at ν ≈ 2 and glint finds a likelihood higher by
/// more than 30 (the fit does not depend on the data's units).
#[test]
fn tool_tfit_agrees_with_scipy_where_scipy_converges_and_beats_it_where_it_does_not() {
    let data = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/tfit-scipy");
    for name in ["deg", "rad"] {
        let file = data.join(format!("{name}.txt"));
        let [nu, mu, sigma, nll] = scipy_fit(&file);
        let g = glint_json(glint().args(["tool", "tfit"]).arg(&file));
        let get = |k: &str| g[k].as_f64().unwrap();
        assert!(
            (get("nu") / nu - 1.0).abs() < 1e-4,
            "{name}: ν {} vs {nu}",
            get("nu")
        );
        assert!(
            (get("mu") - mu).abs() < 1e-5 * sigma,
            "{name}: μ {} vs {mu}",
            get("mu")
        );
        assert!(
            (get("sigma") / sigma - 1.0).abs() < 1e-5,
            "{name}: σ {}",
            get("sigma")
        );
        assert!(
            get("nll") <= nll + 1e-9 * nll.abs(),
            "{name}: nll {} vs {nll}",
            get("nll")
        );
    }
    let file = data.join("tiny.txt");
    let [nu, _, _, nll] = scipy_fit(&file);
    assert!(nu < 2.5, "scipy's own answer there: ν {nu}");
    let g = glint_json(glint().args(["tool", "tfit"]).arg(&file));
    let (g_nu, g_nll) = (g["nu"].as_f64().unwrap(), g["nll"].as_f64().unwrap());
    assert!((4.0..40.0).contains(&g_nu), "ν {g_nu}");
    assert!(g_nll < nll - 30.0, "nll {g_nll} vs scipy's {nll}");
}

#[test]
fn tool_tfit_rejects_a_bad_file_with_line_and_column() {
    let dir = temp_dir("tfit-bad");
    let file = dir.join("bad.txt");
    std::fs::write(&file, "1.0\n2.0\n  three\n").unwrap();
    let out = glint().args(["tool", "tfit"]).arg(&file).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("bad.txt:3:3: `three` is not a number"),
        "{err}"
    );
    std::fs::write(&file, "1.0\n1.0\n1.0\n").unwrap();
    let out = glint().args(["tool", "tfit"]).arg(&file).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("all 3 samples are equal"));
    let missing = glint()
        .args(["tool", "tfit", "/nonexistent/x.txt"])
        .output()
        .unwrap();
    assert_eq!(missing.status.code(), Some(2));
    let _ = std::fs::remove_dir_all(&dir);
}

/// A 16-bit binary PGM (P5, big-endian samples).
fn write_pgm16(path: &std::path::Path, w: usize, h: usize, px: &[u16]) {
    let mut bytes = format!("P5\n{w} {h}\n65535\n").into_bytes();
    for v in px {
        bytes.extend_from_slice(&v.to_be_bytes());
    }
    std::fs::write(path, bytes).unwrap();
}

/// An Earth of angular radius ρ seen through r = f θ with its nadir `tilt_deg` from the axis
/// about Y, the limb blurred by a Gaussian of 1.2 px: written here from the geometry alone.
fn earth_frame(w: usize, h: usize, f_px: f64, c: (f64, f64), tilt_deg: f64) -> Vec<u16> {
    let rho = (6371.0f64 / (6371.0 + 950.0)).asin();
    let t = tilt_deg.to_radians();
    let e = [t.sin(), 0.0, t.cos()];
    (0..w * h)
        .map(|i| {
            let (dx, dy) = ((i % w) as f64 - c.0, (i / w) as f64 - c.1);
            let r = dx.hypot(dy);
            let theta = r / f_px;
            let u = if r == 0.0 {
                [0.0, 0.0, 1.0]
            } else {
                [theta.sin() * dx / r, theta.sin() * dy / r, theta.cos()]
            };
            let angle = (u[0] * e[0] + u[1] * e[1] + u[2] * e[2])
                .clamp(-1.0, 1.0)
                .acos();
            let d_px = (angle - rho) * f_px;
            (20.0 + 3000.0 * 0.5 * libm::erfc(d_px / (1.2 * std::f64::consts::SQRT_2))) as u16
        })
        .collect()
}

/// `glint tool earth` on a frame written from the geometry: every method within 0.1° of the
/// truth (the Hough baseline of its model value, math.md §4.7: 12° → 12.006), the tilt's sign
/// right, and a time per method.
#[test]
fn tool_earth_reads_beta_from_a_fisheye_frame() {
    let dir = temp_dir("tool-earth");
    let file = dir.join("earth.pgm");
    let (w, h, f, c) = (512, 512, 130.0, (255.5, 255.5));
    write_pgm16(&file, w, h, &earth_frame(w, h, f, c, -12.0));
    let v = glint_json(glint().args(["tool", "earth"]).arg(&file).args([
        "--f-px",
        "130",
        "--center",
        "255.5,255.5",
        "--altitude-km",
        "950",
    ]));
    let b = |m: &str| v["beta_deg"][m].as_f64().unwrap();
    assert!((b("cross_product") - 12.0).abs() < 0.02, "{v}");
    assert!((b("lookup") - 12.0).abs() < 0.05, "{v}");
    assert!((b("hough") - 12.0).abs() < 0.1, "{v}");
    assert!((v["tilt_deg"].as_f64().unwrap() + 12.0).abs() < 0.02, "{v}");
    assert!(v["edge_points"].as_u64().unwrap() > 300, "{v}");
    for m in ["edges", "cross_product", "lookup", "hough"] {
        assert!(v["time_us"][m].as_f64().unwrap() > 0.0, "{v}");
    }
    let bad = glint()
        .args(["tool", "earth"])
        .arg(&file)
        .args(["--f-px", "0", "--center", "255.5,255.5"])
        .output()
        .unwrap();
    assert_eq!(bad.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("allowed 1 to 100000"));
    let _ = std::fs::remove_dir_all(&dir);
}

/// `glint tool earth-calibrate` fits σ per calibration frame and writes the table that
/// `glint tool earth --sigma-table` then uses for the lookup version.
#[test]
fn tool_earth_calibrate_writes_the_table_the_lookup_version_reads() {
    let dir = temp_dir("earth-calibrate");
    let (w, h, f, c) = (512, 512, 130.0, (255.5, 255.5));
    let frames: Vec<std::path::PathBuf> = [5.0, 12.0, -20.0]
        .iter()
        .map(|&t| {
            let p = dir.join(format!("cal{t}.pgm"));
            write_pgm16(&p, w, h, &earth_frame(w, h, f, c, t));
            p
        })
        .collect();
    let table = dir.join("sigma.csv");
    glint_json(
        glint()
            .args(["tool", "earth-calibrate"])
            .args(&frames)
            .args(["--f-px", "130", "--center", "255.5,255.5", "--out"])
            .arg(&table),
    );
    let csv = std::fs::read_to_string(&table).unwrap();
    let rows: Vec<&str> = csv.lines().collect();
    assert_eq!(rows[0], "mu_deg,sigma_deg");
    assert_eq!(rows.len(), 4, "{csv}");
    let mus: Vec<f64> = rows[1..]
        .iter()
        .map(|r| r.split(',').next().unwrap().parse().unwrap())
        .collect();
    for (mu, want) in mus.iter().zip([5.0, 12.0, 20.0]) {
        assert!((mu - want).abs() < 0.05, "{csv}");
    }
    let frame = dir.join("x.pgm");
    write_pgm16(&frame, w, h, &earth_frame(w, h, f, c, 9.0));
    let v = glint_json(
        glint()
            .args(["tool", "earth"])
            .arg(&frame)
            .args(["--f-px", "130", "--center", "255.5,255.5", "--sigma-table"])
            .arg(&table),
    );
    assert_eq!(v["lookup_sigma"], "the calibrated table");
    // Its answer is within the 0.05° budget, or it says its mode is too far from the
    // samples' fitted location to promise that.
    match v["beta_deg"]["lookup"].as_f64() {
        Some(b) => assert!((b - 9.0).abs() <= 0.05, "{v}"),
        None => assert!(
            (v["not_determined"]["lookup"].as_str().unwrap())
                .contains("from their fitted location"),
            "{v}"
        ),
    }
    std::fs::write(&table, "mu_deg,sigma_deg\n5,0.1\n7\n").unwrap();
    let bad = glint()
        .args(["tool", "earth"])
        .arg(&frame)
        .args(["--f-px", "130", "--center", "255.5,255.5", "--sigma-table"])
        .arg(&table)
        .output()
        .unwrap();
    assert_eq!(bad.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&bad.stderr).contains("sigma.csv:3: expected `mu_deg,sigma_deg`")
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// The shipped σ table is what `earth-calibrate --scenario` makes of the shipped scenario: one
/// row per degree 0°…60°, each the mean σ of its 4 frames.
#[test]
fn the_shipped_sigma_table_is_the_calibration_of_the_shipped_scenario() {
    let dir = temp_dir("earth-calibrate-scenario");
    let out = dir.join("table.csv");
    let v = glint_json(
        glint()
            .args(["tool", "earth-calibrate", "--scenario"])
            .arg(scenario("earth-sensor-turntable.toml"))
            .arg("--out")
            .arg(&out),
    );
    assert_eq!(v["angles"], 61, "{v}");
    assert_eq!(v["frames"], 61 * 4, "{v}");
    let made = std::fs::read_to_string(&out).unwrap();
    let shipped = std::fs::read_to_string(scenario("earth-sensor-sigma.csv")).unwrap();
    assert_eq!(made, shipped);
    let first: Vec<&str> = made.lines().take(2).collect();
    assert_eq!(first[0], "mu_deg,sigma_deg");
    assert!(first[1].starts_with("0,"), "{}", first[1]);
    let _ = std::fs::remove_dir_all(&dir);
}

/// `glint tool earth` on frames from an independent renderer (tests/data/earth-fisheye,
/// `sim_fisheye.py`: WGS 84 Earth, a 180° ideal fisheye whose image circle cuts the disk from
/// β ≈ 35° on, black outside the lens): every number it prints is within 0.05° of the file's
/// truth, and a method that gives none says why. The cut disk is answered by the cross product
/// (the lens's boundary is not taken for the limb); the circle baseline says its model is off.
#[test]
fn tool_earth_on_another_renderers_frames_is_right_or_says_not_determined() {
    let data = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/earth-fisheye");
    let truth = std::fs::read_to_string(data.join("TRUTH.csv")).unwrap();
    let mut answered = std::collections::BTreeMap::<&str, Vec<f64>>::new();
    for row in truth.lines().skip(1) {
        let c: Vec<&str> = row.split(',').collect();
        let (file, beta, f_px, center) = (c[0], c[1], c[2], format!("{},{}", c[3], c[4]));
        let beta: f64 = beta.parse().unwrap();
        let v = glint_json(
            glint()
                .args(["tool", "earth"])
                .arg(data.join(file))
                .args(["--f-px", f_px, "--center", &center]),
        );
        let valid: Vec<&str> = (v["valid_methods"].as_array().unwrap().iter())
            .map(|m| m.as_str().unwrap())
            .collect();
        for m in ["cross_product", "lookup", "hough"] {
            match v["beta_deg"][m].as_f64() {
                Some(b) => {
                    assert!(
                        (b - beta).abs() <= 0.05,
                        "{file} {m}: {b} against {beta}: {v}"
                    );
                    assert!(valid.contains(&m), "{file} {m}: {v}");
                    answered.entry(m).or_default().push(beta);
                }
                None => {
                    let why = v["not_determined"][m].as_str().unwrap_or("");
                    assert!(why.starts_with("not determined: "), "{file} {m}: {v}");
                    assert!(!valid.contains(&m), "{file} {m}: {v}");
                }
            }
        }
        if beta == 45.0 {
            // The disk is cut by the lens's circle; the baseline's circle is off by degrees.
            let why = v["not_determined"]["hough"].as_str().unwrap();
            assert!(why.contains("departs from a circle"), "{v}");
            assert!(v["beta_deg"]["cross_product"].is_f64(), "{v}");
        }
    }
    // The cross product answers the cut disk up to 65°; the baseline stops by 20°.
    let cross = &answered["cross_product"];
    assert!(
        [0.0, 10.0, 40.0, 45.0, 50.0, 60.0]
            .iter()
            .all(|b| cross.contains(b)),
        "{cross:?}"
    );
    let hough = &answered["hough"];
    assert!(hough.contains(&0.0) && hough.contains(&10.0), "{hough:?}");
    assert!(hough.iter().all(|&b| b <= 20.0), "{hough:?}");
}

/// `glint tool earth --lens LENS.toml` on frames through a distorted lens from the independent
/// renderer (Kannala–Brandt k₁ = 0.05, k₂ = −0.01: at the limb's ~60° the ideal `r = f θ` is
/// off by 5 %): with the calibration every number is within 0.05° of the truth, the baseline
/// fitting its circle in the undistorted image; without it (the ideal lens assumed) the answers
/// are ~5 % of β off, or not determined.
#[test]
fn tool_earth_undistorts_a_users_lens_calibration() {
    let data = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/earth-fisheye-kb");
    let lens = data.join("lens.toml");
    let truth = std::fs::read_to_string(data.join("TRUTH.csv")).unwrap();
    for row in truth.lines().skip(1) {
        let c: Vec<&str> = row.split(',').collect();
        let (file, beta) = (data.join(c[0]), c[1].parse::<f64>().unwrap());
        let v = glint_json(
            glint()
                .args(["tool", "earth"])
                .arg(&file)
                .arg("--lens")
                .arg(&lens),
        );
        for m in ["cross_product", "lookup", "hough"] {
            if let Some(b) = v["beta_deg"][m].as_f64() {
                assert!(
                    (b - beta).abs() <= 0.05,
                    "{} {m}: {b} against {beta}: {v}",
                    c[0]
                );
            }
        }
        assert!(v["beta_deg"]["cross_product"].is_f64(), "{v}");
        if beta <= 10.0 {
            assert!(v["beta_deg"]["hough"].is_f64(), "{v}");
        }
        // The same frame without the calibration.
        let ideal = glint_json(glint().args(["tool", "earth"]).arg(&file).args([
            "--f-px",
            c[2],
            "--center",
            &format!("{},{}", c[3], c[4]),
        ]));
        if let Some(b) = ideal["beta_deg"]["cross_product"].as_f64() {
            assert!((b - beta).abs() > 0.02 * beta, "{ideal}");
        }
    }
    // A calibration glint cannot use is refused with the field and the reason.
    let dir = temp_dir("lens");
    let bad = dir.join("bad.toml");
    std::fs::write(
        &bad,
        "fx = 160\nfy = 160\ncx = 255.5\ncy = 255.5\nD = [-0.6, 0, 0, 0]\n",
    )
    .unwrap();
    let out = glint()
        .args(["tool", "earth"])
        .arg(data.join("kb-b5.pgm"))
        .arg("--lens")
        .arg(&bad)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("bad.toml: field `D`: θ_d stops growing at θ = 42"),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
