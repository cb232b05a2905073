//! [003] offline tools on files, as a user brings samples from a real sensor.

mod common;

use common::{glint, temp_dir};

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
    let out = glint().args(["tool", "tfit"]).arg(&file).output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let f = |k: &str| v[k].as_f64().unwrap();
    assert_eq!(v["n"], 20);
    assert!((f("mu") - 10.0087229834).abs() < 1e-8, "{v}");
    assert!((f("sigma") - 0.142487934787).abs() < 1e-9, "{v}");
    assert!((f("nu") - 2.03295355610).abs() < 1e-7, "{v}");
    assert!((f("nll") - 0.0524515737191).abs() < 1e-10, "{v}");
    assert!(v["iterations"].as_u64().unwrap() >= 1);
    let _ = std::fs::remove_dir_all(&dir);
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
