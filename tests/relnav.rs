//! [004] `glint tool relnav` on files another simulator wrote (tests/data/relnav: an
//! independent standard-library Python simulator with Shuster quaternions, Euler's equations in
//! the inertia and CW in closed form; its own column order, dropouts, wrong matches, Δt = 5 s),
//! scored against that simulator's truth.

mod common;

use std::path::PathBuf;

use common::{glint, temp_dir};

fn data(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/relnav")
        .join(name)
}

fn read_csv(path: &std::path::Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines().filter(|l| !l.starts_with('#'));
    let header = lines
        .next()
        .unwrap()
        .split(',')
        .map(str::to_string)
        .collect();
    let rows = lines
        .map(|l| l.split(',').map(|c| c.trim().parse().unwrap()).collect())
        .collect();
    (header, rows)
}

/// Quaternion angle between two scalar-first unit quaternions [rad].
fn angle(a: &[f64], b: &[f64]) -> f64 {
    let d: f64 = a.iter().zip(b).map(|(x, y)| x * y).sum();
    2.0 * d.abs().min(1.0).acos()
}

#[test]
fn tool_relnav_on_another_simulators_files_meets_the_papers_figures() {
    let out = temp_dir("relnav-tool");
    let res = glint()
        .args(["tool", "relnav"])
        .arg(data("MEAS.csv"))
        .arg("--rig")
        .arg(data("RIG.toml"))
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        res.status.success(),
        "{}",
        String::from_utf8_lossy(&res.stderr)
    );
    let summary: serde_json::Value = serde_json::from_slice(&res.stdout).unwrap();
    let (header, est) = read_csv(&out.join("relnav.csv"));
    assert_eq!(header.len(), 30);
    assert_eq!(header[..5], ["t_s", "qw", "qx", "qy", "qz"]);
    assert_eq!(header[29], "sig_v_z");
    let (_, truth) = read_csv(&data("TRUTH.csv"));
    let k_line = std::fs::read_to_string(data("TRUTH.csv")).unwrap();
    let k_true: Vec<f64> = k_line.lines().next().unwrap()[1..]
        .split(',')
        .map(|p| p.split('=').nth(1).unwrap().trim().parse().unwrap())
        .collect();
    // RTMSE over the last 50 minutes (eq 40), each estimate against the truth at its t
    let mut sum = [0.0; 5];
    let mut n = 0.0;
    let mut within = 0usize;
    for e in est.iter().filter(|e| e[0] >= 3000.0) {
        let t = truth
            .iter()
            .find(|t| t[0] == e[0])
            .expect("truth at every epoch");
        let errs = [
            angle(&e[1..5], &t[1..5]),
            (0..3)
                .map(|i| (e[5 + i] - t[5 + i]).powi(2))
                .sum::<f64>()
                .sqrt(),
            (0..2)
                .map(|i| (e[8 + i] - k_true[i]).powi(2))
                .sum::<f64>()
                .sqrt(),
            (0..3)
                .map(|i| (e[10 + i] - t[8 + i]).powi(2))
                .sum::<f64>()
                .sqrt(),
            (0..3)
                .map(|i| (e[13 + i] - t[11 + i]).powi(2))
                .sum::<f64>()
                .sqrt(),
        ];
        for g in 0..5 {
            sum[g] += errs[g] * errs[g];
        }
        n += 1.0;
        // position within 3σ per axis
        within += (0..3).all(|i| (e[10 + i] - t[8 + i]).abs() <= 3.0 * e[24 + i]) as usize;
    }
    let r = sum.map(|s| (s / n).sqrt());
    eprintln!(
        "rtmse: att {:.4}°, ω {:.2e} rad/s, k {:.2e}, ρ {:.3} mm, v {:.3} µm/s; {summary}",
        r[0].to_degrees(),
        r[1],
        r[2],
        r[3] * 1e3,
        r[4] * 1e6
    );
    assert!(n >= 590.0, "{n} estimates in the window");
    assert!(r[0].to_degrees() < 0.1 && r[1] < 6e-5 && r[2] < 0.02);
    assert!(r[3] < 0.010 && r[4] < 10e-6);
    assert!(within as f64 >= 0.95 * n, "{within} of {n} within 3σ");
    // the file's wrong matches were refused and counted
    assert!(summary["features_rejected"].as_u64().unwrap() > 0);
}

#[test]
fn tool_relnav_refuses_bad_files_naming_the_field_or_the_line() {
    let dir = temp_dir("relnav-bad");
    let rig = dir.join("RIG.toml");
    let meas = dir.join("MEAS.csv");
    let good_rig = std::fs::read_to_string(data("RIG.toml")).unwrap();
    let run = |rig_text: &str, meas_text: &str| {
        std::fs::write(&rig, rig_text).unwrap();
        std::fs::write(&meas, meas_text).unwrap();
        let out = glint()
            .args(["tool", "relnav"])
            .arg(&meas)
            .arg("--rig")
            .arg(&rig)
            .arg("--out")
            .arg(&dir)
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(2));
        String::from_utf8_lossy(&out.stderr).to_string()
    };
    let meas_ok = "t_s,feature,x_l,y_l,x_r,y_r\n0,0,0.01,0.02,-0.03,0.02\n";
    let e = run(
        &good_rig.replace("baseline_m = 0.5", "baseline_m = -1"),
        meas_ok,
    );
    assert!(
        e.contains("baseline_m") && e.contains("out of range"),
        "{e}"
    );
    let e = run(&good_rig.replace("sigma_norm = 1e-05\n", ""), meas_ok);
    assert!(e.contains("sigma_norm") && e.contains("missing"), "{e}");
    let e = run(&good_rig.replace("[0,1,0]]", "[0,2,0]]"), meas_ok);
    assert!(e.contains("c_co") && e.contains("not a rotation"), "{e}");
    let e = run(&format!("{good_rig}focal = 3\n"), meas_ok);
    assert!(e.contains("unknown field `focal`"), "{e}");
    let e = run(
        &good_rig,
        "t_s,feature,x_l,y_l,x_r,y_r\n0,9,0.01,0.02,-0.03,0.02\n",
    );
    assert!(
        e.contains("line 2") && e.contains("`feature`") && e.contains("0..=4"),
        "{e}"
    );
    let e = run(&good_rig, "t_s,feature,x_l,y_l,x_r\n0,1,0.01,0.02,-0.03\n");
    assert!(e.contains("no column `y_r`"), "{e}");
    let e = run(
        &good_rig,
        "t_s,feature,x_l,y_l,x_r,y_r\n0,1,0.01,NaN,-0.03,0.02\n",
    );
    assert!(e.contains("line 2, column `y_l`"), "{e}");
}
