//! `glint lab identify`: the [001] identification measured over light curves of every shape
//! about random axes; the same seed gives the same study.

mod common;

use common::*;

#[test]
fn an_identification_study_tabulates_every_curve_and_repeats_with_its_seed() {
    let dir = temp_dir("photometry-identify");
    let shapes = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("shapes/shapes.toml");
    let study = |out: &str| {
        let o = glint()
            .args([
                "lab", "identify", "--axes", "2", "--noise", "0.05", "--seed", "7",
            ])
            .arg("--shapes")
            .arg(&shapes)
            .arg("--out")
            .arg(dir.join(out))
            .output()
            .unwrap();
        assert_success(&o);
        read_json(&dir.join(out).join("identify.json"))
    };
    let a = study("a");
    assert_eq!(a["runs"], 12);
    let confusion = a["confusion"].as_array().unwrap();
    assert_eq!(confusion.len(), 6);
    for row in confusion {
        let n: u64 = row
            .as_array()
            .unwrap()
            .iter()
            .map(|c| c.as_u64().unwrap())
            .sum();
        assert_eq!(n, 2, "every shape's curves are in its row");
    }
    let diagonal: u64 = (0..6).map(|i| confusion[i][i].as_u64().unwrap()).sum();
    assert_eq!(a["correct"].as_u64().unwrap(), diagonal);
    assert_eq!(study("b"), a, "the same seed, the same study");
    let md = std::fs::read_to_string(dir.join("a").join("confusion.md")).unwrap();
    assert!(md.starts_with("# glint lab identify: "));
    let bad = glint()
        .args(["lab", "identify", "--noise", "5"])
        .arg("--shapes")
        .arg(&shapes)
        .output()
        .unwrap();
    assert_eq!(bad.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&bad.stderr).contains("--noise 5: out of range; allowed 0..=2 mag")
    );
}
