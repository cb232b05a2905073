//! [004] campaigns through `glint lab campaign`: every value deployed with its seeds, the
//! pooled figures recomputed here from each run's own report.json, the paper's trend.

mod common;

use common::*;
use glint::RelNavCampaign;

/// The features sweep cut to N = 3 and 12, three seeds each, 60 minutes (the window is still
/// the last 50: the start's first 10 minutes are left out).
fn short_sweep(dir: &std::path::Path) -> std::path::PathBuf {
    scenario_variant(
        "campaign-relnav-features.toml",
        &[
            ("values = [3, 4, 6, 9, 12]", "values = [3, 12]"),
            ("seeds = 20", "seeds = 3"),
            ("duration_s = 6000.0", "duration_s = 3600.0"),
        ],
        dir,
    )
}

#[test]
fn a_features_sweep_pools_its_runs_and_more_features_help() {
    let dir = temp_dir("relnav-campaign");
    let file = short_sweep(&dir);
    let out = dir.join("out");
    run_campaign_ok(&file, &out);
    let text = std::fs::read_to_string(out.join("campaign.json")).unwrap();
    let c: RelNavCampaign = serde_json::from_str(&text).expect("campaign.json as glint's type");
    assert_eq!(c.parameter, "stereo.n_features");
    assert_eq!(c.rows.len(), 2);
    for row in &c.rows {
        assert_eq!((row.runs, row.failed), (3, 0), "{row:?}");
        // eq 40 over the runs, recomputed from each run's own report.
        let (mut sum_sq, mut epochs, mut nees) = (0.0, 0.0, 0.0);
        for (i, run) in row.per_run.iter().enumerate() {
            assert_eq!(run.seed, c.seed + i as u64);
            let rep = read_report(&out.join(&run.run).join("report.json"));
            assert!(rep.results.success);
            let nav = rep.results.relnav.as_ref().expect("a relnav section");
            assert_eq!(nav.window_s, [600.0, 3600.0]);
            assert_eq!(run.epochs_scored, nav.epochs_scored);
            sum_sq += nav.rtmse.attitude_deg.powi(2) * nav.epochs_scored as f64;
            epochs += nav.epochs_scored as f64;
            nees += nav.nees_mean;
        }
        let pooled = (sum_sq / epochs).sqrt();
        assert!(
            (row.rtmse.attitude_deg - pooled).abs() <= 1e-12 * pooled,
            "{} vs {pooled}",
            row.rtmse.attitude_deg
        );
        assert!((row.nees_mean - nees / 3.0).abs() < 1e-9);
        // the paper's figures hold for every run
        assert_eq!(row.runs_within_paper, 3, "{row:?}");
        let [lo, hi] = row.nees_95;
        assert!(lo < 14.0 && 14.0 < hi, "{row:?}");
        assert!((lo..=hi).contains(&row.nees_mean), "{row:?}");
    }
    // The paper's trend: more features, smaller pose errors; the inertia parameters nearly
    // insensitive.
    let (n3, n12) = (&c.rows[0].rtmse, &c.rows[1].rtmse);
    assert!(n12.attitude_deg < 0.7 * n3.attitude_deg, "{n3:?} {n12:?}");
    assert!(n12.position_m < 0.8 * n3.position_m, "{n3:?} {n12:?}");
    assert!((0.5..2.0).contains(&(n12.inertia_k / n3.inertia_k)));
    let summary = std::fs::read_to_string(out.join("summary.md")).unwrap();
    assert!(summary.contains("| stereo.n_features | runs | attitude [°]"));
    assert!(summary.contains("| paper | 200 |"));
    let svg = Svg::read(&out.join("campaign.svg"));
    for group in ["attitude", "ω", "k", "position", "velocity"] {
        assert!(svg.has_text(group), "{:?}", svg.texts);
    }
}

#[test]
fn a_stereo_campaign_value_out_of_range_is_bad_input_naming_the_field() {
    let dir = temp_dir("relnav-campaign-bad");
    let file = scenario_variant(
        "campaign-relnav-features.toml",
        &[("values = [3, 4, 6, 9, 12]", "values = [3, 40]")],
        &dir,
    );
    let out = glint()
        .args(["lab", "campaign"])
        .arg(&file)
        .arg("--out")
        .arg(dir.join("out"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("campaign.values[1] → stereo.n_features") && err.contains("14"),
        "{err}"
    );
}
