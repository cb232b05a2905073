//! [001] identification campaigns through `glint lab campaign`: every geometry deployed with
//! its seeds (each its own spin axis), the confusion table recomputed here from each run's own
//! report.json, and the noise sweep's parameter applied.

mod common;

use common::*;
use glint::PhotometryCampaign;

#[test]
fn an_identification_campaign_tabulates_every_runs_own_answer() {
    let dir = temp_dir("photometry-campaign");
    let lib = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("shapes/shapes.toml");
    let shapes = format!("shapes = \"{}\"", lib.display());
    let file = scenario_variant(
        "campaign-photometry-id.toml",
        &[
            ("shapes = \"../shapes/shapes.toml\"", &shapes),
            (
                "values = [\"box-wing\", \"box\", \"cylinder\", \"box-panel\", \"plate\", \"hexagonal-prism\"]",
                "values = [\"box-wing\", \"plate\"]",
            ),
            ("seeds = 10", "seeds = 2"),
        ],
        &dir,
    );
    let out = dir.join("out");
    run_campaign_ok(&file, &out);
    let text = std::fs::read_to_string(out.join("campaign.json")).unwrap();
    let c: PhotometryCampaign = serde_json::from_str(&text).expect("campaign.json as glint's type");
    assert_eq!(c.parameter, "photometry.geometry");
    assert_eq!(c.sigma_mag, vec![0.05]);
    let f = &c.photometry.campaign;
    assert_eq!((f.runs, f.failed), (4, 0), "{f:?}");
    assert_eq!(f.geometries.len(), 6);
    assert_eq!(f.confusion.len(), 6);
    assert!(
        f.confusion.iter().all(|row| row.len() == 7),
        "six answers and none"
    );
    // recomputed from each run's own report
    let mut confusion = vec![vec![0u32; 7]; 6];
    let mut axes = vec![];
    for (i, run) in f.per_run.iter().enumerate() {
        assert_eq!(run.seed, c.seed + (i % 2) as u64, "{run:?}");
        let rep = read_report(&out.join(&run.run).join("report.json"));
        assert!(rep.results.success);
        let id = &rep.results.photometry.as_ref().unwrap().identification;
        assert_eq!(id.truth_geometry, ["box-wing", "plate"][i / 2]);
        assert_eq!(run.answer, id.geometry);
        let row = f
            .geometries
            .iter()
            .position(|g| *g == id.truth_geometry)
            .unwrap();
        let col =
            (id.geometry.as_ref()).map_or(6, |a| f.geometries.iter().position(|g| g == a).unwrap());
        confusion[row][col] += 1;
        axes.push(id.truth_axis);
    }
    assert_eq!(f.confusion, confusion);
    let right = (0..6).map(|g| confusion[g][g]).sum::<u32>();
    assert_eq!(f.correct, right);
    // each seed drew its own spin axis; the same seed the same axis for every geometry
    assert_ne!(axes[0], axes[1]);
    assert_eq!(axes[0], axes[2]);
    let summary = std::fs::read_to_string(out.join("summary.md")).unwrap();
    assert!(summary.contains("| truth \\ answer |"), "{summary}");
}
