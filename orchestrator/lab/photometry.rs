//! [001] identification campaigns: every value of the swept parameter (a geometry of the
//! library, a noise level) deployed with `seeds` seeds side by side
//! ([`crate::lab::parallel`]), each seed drawing its own spin axis when the scenario gives
//! none; `DIR/campaign.json` with `photometry.campaign.{runs, correct, confusion}`, and the
//! confusion table (rows: the truth, columns: glint's answer) with the spin, area and attitude
//! errors of the correctly identified in `DIR/summary.md`.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use shared_types::scenario::Campaign;
use shared_types::Scenario;

use crate::lab::identify::median_and_worst;
use crate::lab::parallel::{deploy_all, Deployed};

/// Whether a campaign of `scenario` is a [001] one: it sweeps a `photometry.*` parameter, or
/// the scenario's only science is the light curve.
pub fn applies(scenario: &Scenario, campaign: &Campaign) -> bool {
    campaign.parameter.starts_with("photometry.")
        || (scenario.photometry.is_some()
            && scenario.spectra.is_none()
            && scenario.stereo.is_none())
}

/// One deployment's identification against its truth.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct IdentificationRun {
    pub seed: u64,
    /// Its run directory, relative to the campaign's.
    pub run: String,
    /// The run's own verdict (every message accounted for, no service lost).
    pub success: bool,
    pub truth: String,
    /// glint's answer (`None`: the arc fitted no geometry).
    pub answer: Option<String>,
    /// Relative errors of spin and area, the axis's angle [deg], the UKF's final attitude
    /// error [deg] and mean NEES (NaN without an identification).
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    pub spin_error: f64,
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    pub area_error: f64,
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    pub axis_error_deg: f64,
    /// The angle to the nearer of the true axis and its photometric mirror [deg].
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    pub axis_error_either_deg: f64,
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    pub attitude_err_deg_final: f64,
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    pub nees_mean: f64,
}

/// `photometry.campaign` of campaign.json.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct IdentificationFigures {
    pub runs: u32,
    pub correct: u32,
    /// The library's geometries: the rows (truth) and columns (answer) of `confusion`, whose
    /// last column counts the runs identified as nothing.
    pub geometries: Vec<String>,
    pub confusion: Vec<Vec<u32>>,
    /// Of the correctly identified: median and worst |spin error|, |area error| (relative),
    /// the median axis error (to the true axis, and to the nearer of it and its photometric
    /// mirror) and final attitude error [deg], the median of the mean NEES.
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    pub spin_error_median: f64,
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    pub spin_error_worst: f64,
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    pub area_error_median: f64,
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    pub area_error_worst: f64,
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    pub axis_error_deg_median: f64,
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    pub axis_error_either_deg_median: f64,
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    pub attitude_err_deg_median: f64,
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    pub nees_mean_median: f64,
    /// Runs whose deployment failed (left out of the figures).
    pub failed: u32,
    pub per_run: Vec<IdentificationRun>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct PhotometryCampaignPart {
    pub campaign: IdentificationFigures,
}

/// `DIR/campaign.json` of a [001] campaign.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct PhotometryCampaign {
    pub scenario: String,
    pub parameter: String,
    pub seed: u64,
    pub seeds: u32,
    /// The magnitude noise of the runs (each value's, for a `photometry.sigma_mag` sweep).
    pub sigma_mag: Vec<f64>,
    /// Wall time of the whole campaign [s] and deployments run at once.
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    pub wall_s: f64,
    pub parallel: u32,
    pub photometry: PhotometryCampaignPart,
}

fn figures(d: Deployed, truth: &str) -> (IdentificationRun, bool) {
    let p = d.report.results.photometry.as_ref();
    let id = p.map(|p| &p.identification);
    let right = id.is_some_and(|i| i.correct);
    let rel = |a: f64, b: f64| (a / b - 1.0).abs();
    let f = IdentificationRun {
        seed: d.seed,
        run: d.run.clone(),
        success: d.success && p.is_some(),
        truth: id.map_or(truth.to_string(), |i| i.truth_geometry.clone()),
        answer: id.and_then(|i| i.geometry.clone()),
        spin_error: id.map_or(f64::NAN, |i| rel(i.spin_rad_s, i.truth_spin_rad_s)),
        area_error: id.map_or(f64::NAN, |i| rel(i.area_m2, i.truth_area_m2)),
        axis_error_deg: id.map_or(f64::NAN, |i| i.axis_error_deg),
        axis_error_either_deg: id
            .map_or(f64::NAN, |i| i.axis_error_deg.min(i.axis_error_mirror_deg)),
        attitude_err_deg_final: match right {
            true => p.map_or(f64::NAN, |p| p.ukf.attitude_err_deg_final),
            false => f64::NAN,
        },
        nees_mean: match right {
            true => p.map_or(f64::NAN, |p| p.ukf.nees_mean),
            false => f64::NAN,
        },
    };
    let ok = f.success;
    (f, ok)
}

/// The confusion table and the errors of the correctly identified.
pub fn tabulate(geometries: Vec<String>, per_run: Vec<IdentificationRun>) -> IdentificationFigures {
    let n = geometries.len();
    let mut confusion = vec![vec![0u32; n + 1]; n];
    let scored: Vec<&IdentificationRun> = per_run.iter().filter(|r| r.success).collect();
    for r in &scored {
        let Some(row) = geometries.iter().position(|g| *g == r.truth) else {
            continue;
        };
        let col = (r.answer.as_ref())
            .and_then(|a| geometries.iter().position(|g| g == a))
            .unwrap_or(n);
        confusion[row][col] += 1;
    }
    let right: Vec<&&IdentificationRun> = (scored.iter())
        .filter(|r| r.answer.as_ref() == Some(&r.truth))
        .collect();
    let of_right =
        |f: fn(&IdentificationRun) -> f64| -> Vec<f64> { right.iter().map(|r| f(r)).collect() };
    let (spin_error_median, spin_error_worst) = median_and_worst(of_right(|r| r.spin_error));
    let (area_error_median, area_error_worst) = median_and_worst(of_right(|r| r.area_error));
    IdentificationFigures {
        runs: scored.len() as u32,
        correct: right.len() as u32,
        geometries,
        confusion,
        spin_error_median,
        spin_error_worst,
        area_error_median,
        area_error_worst,
        axis_error_deg_median: median_and_worst(of_right(|r| r.axis_error_deg)).0,
        axis_error_either_deg_median: median_and_worst(of_right(|r| r.axis_error_either_deg)).0,
        attitude_err_deg_median: median_and_worst(of_right(|r| r.attitude_err_deg_final)).0,
        nees_mean_median: median_and_worst(of_right(|r| r.nees_mean)).0,
        failed: (per_run.len() - scored.len()) as u32,
        per_run,
    }
}

/// Runs the campaign into `dir`. Returns whether every deployment succeeded.
pub fn run(
    scenario: &Scenario,
    file: &str,
    dir: &Path,
    camp: &Campaign,
    progress: bool,
) -> Result<bool> {
    let t0 = Instant::now();
    let p = (scenario.photometry.as_ref()).context("a [001] campaign needs [photometry]")?;
    let geometries: Vec<String> = glint_photometry::shapes::read_shapes(&p.shapes)?
        .into_iter()
        .map(|(n, _)| n)
        .collect();
    let mut truths = vec![];
    let mut sigma_mag = vec![];
    for i in 0..camp.values.len() {
        let v = scenario
            .campaign_variant(i)
            .map_err(|e| anyhow::anyhow!("{file}: {e}"))?;
        let vp = v
            .photometry
            .context("a [001] campaign needs [photometry]")?;
        truths.push(vp.geometry);
        sigma_mag.push(vp.sigma_mag);
    }
    sigma_mag.dedup();
    let (per_value, parallel) = deploy_all(scenario, file, dir, camp, progress, |d| {
        let truth = truths[d.index].clone();
        figures(d, &truth)
    })?;
    let figures = tabulate(geometries, per_value.into_iter().flatten().collect());
    let out = PhotometryCampaign {
        scenario: scenario.name.clone(),
        parameter: camp.parameter.clone(),
        seed: scenario.seed,
        seeds: camp.seeds.max(1),
        sigma_mag,
        wall_s: t0.elapsed().as_secs_f64(),
        parallel: parallel as u32,
        photometry: PhotometryCampaignPart { campaign: figures },
    };
    std::fs::write(
        dir.join("campaign.json"),
        serde_json::to_string_pretty(&out)? + "\n",
    )?;
    std::fs::write(dir.join("summary.md"), summary(scenario, &out))?;
    eprintln!("{}", headline(&out));
    Ok(out.photometry.campaign.failed == 0)
}

fn percent(a: u32, b: u32) -> f64 {
    100.0 * a as f64 / b.max(1) as f64
}

/// The first line a user reads.
fn headline(c: &PhotometryCampaign) -> String {
    let f = &c.photometry.campaign;
    format!(
        "[001] identification: {} of {} right ({:.1} %), noise {:?} mag; of the right ones spin \
         error median {:.2} %, area error median {:.1} %, attitude error median {:.2}°; {:.1} s \
         for {} deployments",
        f.correct,
        f.runs,
        percent(f.correct, f.runs),
        c.sigma_mag,
        100.0 * f.spin_error_median,
        100.0 * f.area_error_median,
        f.attitude_err_deg_median,
        c.wall_s,
        f.runs + f.failed,
    )
}

fn summary(scenario: &Scenario, c: &PhotometryCampaign) -> String {
    let f = &c.photometry.campaign;
    let mut s = crate::lab::summary_head(scenario, &c.parameter, Some(c.seeds));
    let _ = writeln!(s, "{}\n", headline(c));
    let _ = writeln!(
        s,
        "Rows: the truth; columns: glint's answer. Of the correctly identified: spin error \
         median {:.3} % (worst {:.2} %), area error median {:.1} % (worst {:.1} %), axis error \
         median {:.1}° ({:.1}° to the nearer of the axis and its mirror through the Sun–observer \
         plane, which shows the same curve), UKF attitude error at the end median {:.2}°, mean NEES median {:.2} (6 \
         expected).\n",
        100.0 * f.spin_error_median,
        100.0 * f.spin_error_worst,
        100.0 * f.area_error_median,
        100.0 * f.area_error_worst,
        f.axis_error_deg_median,
        f.axis_error_either_deg_median,
        f.attitude_err_deg_median,
        f.nees_mean_median,
    );
    let _ = write!(s, "| truth \\ answer |");
    for g in &f.geometries {
        let _ = write!(s, " {g} |");
    }
    let _ = writeln!(s, " none |");
    let _ = writeln!(s, "|---|{}", "---|".repeat(f.geometries.len() + 1));
    for (g, row) in f.geometries.iter().zip(&f.confusion) {
        if row.iter().all(|c| *c == 0) {
            continue;
        }
        let _ = write!(s, "| {g} |");
        for c in row {
            let _ = write!(s, " {c} |");
        }
        let _ = writeln!(s);
    }
    if f.failed > 0 {
        let _ = writeln!(
            s,
            "\n{} deployment(s) failed: see their directories.",
            f.failed
        );
    }
    s
}
