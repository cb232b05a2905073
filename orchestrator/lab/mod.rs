//! Campaigns: one full deployment per value of the swept parameter (each its own processes and
//! shared memory, in `DIR/NN-…/`), then `DIR/campaign.json`, a table beside the paper's figures
//! in `DIR/summary.md`, and a plot of the error against the parameter when it is numeric.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde_json::{json, Value};
use shared_types::Scenario;

pub mod identify;
pub mod mc;
pub mod mc_summary;
pub mod parallel;
pub mod photometry;
pub mod relnav;

use crate::plots::{line_chart, Series, BLUE, GREEN, RED};
use crate::run::{self, RunOptions};

pub fn run(
    scenario: &Scenario,
    file: &str,
    out_dir: Option<PathBuf>,
    progress: bool,
    rescore: bool,
) -> Result<(PathBuf, bool)> {
    let camp = scenario.campaign.clone().context("no [campaign] section")?;
    let dir = out_dir.unwrap_or_else(|| {
        PathBuf::from("runs").join(format!("{}-{}", scenario.name, run::utc_stamp()))
    });
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    if relnav::applies(scenario, &camp) {
        let ok = relnav::run(scenario, file, &dir, &camp, progress)?;
        return Ok((dir, ok));
    }
    if photometry::applies(scenario, &camp) {
        let ok = photometry::run(scenario, file, &dir, &camp, progress)?;
        return Ok((dir, ok));
    }
    let mut rows = vec![];
    let mut all_ok = true;
    for (i, value) in camp.values.iter().enumerate() {
        let variant = scenario
            .campaign_variant(i)
            .map_err(|e| anyhow::anyhow!("{file}: {e}"))?;
        let sub = dir.join(format!("{i:02}"));
        if camp.seeds > 1 {
            eprintln!(
                "campaign {}: {} = {} ({}/{}): noise-free reference + {} seeds",
                scenario.name,
                camp.parameter,
                value,
                i + 1,
                camp.values.len(),
                camp.seeds
            );
            let (mc, ok) =
                crate::lab::mc::run_value(&variant, file, &sub, camp.seeds, progress, rescore)?;
            all_ok &= ok;
            rows.push(json!({
                "value": value.to_string().trim_matches('"'),
                "run": sub.file_name().map(|n| n.to_string_lossy().to_string()),
                "success": ok,
                "err_paper_metric": mc["median_err_paper_metric"],
                "joint_err_paper_metric": mc["median_joint_err_paper_metric"],
                "crb_paper_metric": mc["joint"]["crb_observable_deg_per_frame"].as_f64().map(|c| 100.0 * c),
                "paper": camp.paper.get(i),
                "monte_carlo": mc,
            }));
            continue;
        }
        eprintln!(
            "campaign {}: {} = {} ({}/{})",
            scenario.name,
            camp.parameter,
            value,
            i + 1,
            camp.values.len()
        );
        let (run_dir, ok) = run::run(RunOptions {
            scenario: variant,
            scenario_file: file.to_string(),
            out_dir: Some(sub.clone()),
            // The campaign owns its directory: a sub-run there replaces the previous one.
            replace: true,
            progress,
            record: false,
            host: None,
        })?;
        run::bail_if_interrupted("campaign")?;
        all_ok &= ok;
        let report = crate::report::Report::read(&run_dir.join("report.json"))?;
        let s3 = (report.results.inversion.as_ref()).and_then(|i| i.stage3.as_ref());
        rows.push(json!({
            "value": value.to_string().trim_matches('"'),
            "run": sub.file_name().map(|n| n.to_string_lossy().to_string()),
            "success": report.results.success,
            "status": s3.map(|s3| match &s3.unobservable_reason {
                Some(why) => format!("{}: {why}", s3.status),
                None => s3.status.clone(),
            }),
            "band_nm": s3.map(|s3| s3.lambda_star.band_nm),
            "p_deg_per_frame": s3.and_then(|s3| s3.p_deg_per_frame),
            "err_paper_metric": s3.and_then(|s3| s3.lambda_star.err_paper_metric),
            "err_paper_metric_mirror": s3.and_then(|s3| s3.err_paper_metric_mirror),
            "joint_err_paper_metric": s3.and_then(|s3| s3.err_paper_metric),
            "bound_1sigma_deg_per_frame": s3.map(|s3| s3.directions.iter().map(|d| d.sigma_deg_per_frame).collect::<Vec<_>>()),
            "observable": s3.map(|s3| s3.directions.iter().map(|d| d.determined).collect::<Vec<_>>()),
            "paper": camp.paper.get(i),
        }));
    }
    let out = json!({
        "scenario": scenario.name,
        "parameter": camp.parameter,
        "seed": scenario.seed,
        "rows": rows,
    });
    std::fs::write(
        dir.join("campaign.json"),
        serde_json::to_string_pretty(&out)? + "\n",
    )?;
    let text = if camp.seeds > 1 {
        crate::lab::mc_summary::summary(scenario, &camp.parameter, camp.seeds, &rows)
    } else {
        summary(scenario, &camp.parameter, &rows)
    };
    std::fs::write(dir.join("summary.md"), text)?;
    plot(&dir, &camp.parameter, &rows)?;
    if camp.seeds > 1 {
        crate::lab::mc_summary::plot_honesty(&dir, &camp.parameter, &rows)?;
    }
    Ok((dir, all_ok))
}

fn num(v: &Value) -> Option<f64> {
    v.as_f64()
}

/// A table cell: the number to `digits` decimals, or — when absent.
pub(crate) fn fmt(v: &Value, digits: usize) -> String {
    num(v).map_or("—".into(), |x| format!("{x:.digits$}"))
}

/// A campaign summary's title, the scenario's description and its windows (every figure
/// depends on them); `seeds` for a Monte-Carlo campaign.
pub(crate) fn summary_head(scenario: &Scenario, parameter: &str, seeds: Option<u32>) -> String {
    let per_value = seeds.map_or(String::new(), |n| format!(", {n} seeds per value"));
    let mut s = format!(
        "# glint campaign: {} — sweep of `{parameter}`{per_value}\n\n",
        scenario.name
    );
    if !scenario.description.is_empty() {
        let _ = writeln!(s, "{}\n", scenario.description.trim());
    }
    if let Some(sp) = &scenario.spectra {
        let last_seed = scenario.seed + seeds.map_or(0, |n| u64::from(n.max(1) - 1));
        let _ = writeln!(
            s,
            "Windows: stable {} samples from phase {}°, motion {} frames {} s apart (stage 3 fits the frames within {}° of rotation); materials `{:?}`, body `{:?}`; seeds {}…{}.\n",
            sp.stable_samples, sp.stable_start_phase_deg, sp.motion_frames, sp.frame_interval_s,
            glint_inversion::stage3::DEFAULT_MAX_ROTATION_DEG, sp.materials, sp.body_shape,
            scenario.seed, last_seed
        );
    }
    s
}

fn summary(scenario: &Scenario, parameter: &str, rows: &[Value]) -> String {
    let mut s = summary_head(scenario, parameter, None);
    s.push_str("Error = 100·‖p − p*‖ (deg/frame), as the paper prints it; 1σ bounds along the Fisher eigen-directions (weakest first).\n\n");
    let _ = writeln!(s, "| {parameter} | status | p, glint's answer [deg/frame] | error (glint) | error of an equally good mirror | paper | λ* [nm] | error at λ* alone | 1σ bounds [deg/frame] | run |\n|---|---|---|---|---|---|---|---|---|---|");
    for r in rows {
        let p = r["p_deg_per_frame"].as_array().map_or("—".into(), |p| {
            format!(
                "[{}]",
                p.iter().map(|x| fmt(x, 4)).collect::<Vec<_>>().join(", ")
            )
        });
        let b = r["bound_1sigma_deg_per_frame"]
            .as_array()
            .map_or("—".into(), |p| {
                p.iter()
                    .map(|x| num(x).map_or("∞".into(), |v| format!("{v:.2e}")))
                    .collect::<Vec<_>>()
                    .join(", ")
            });
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | [{}]({}/summary.md) |",
            r["value"].as_str().unwrap_or("?"),
            r["status"].as_str().unwrap_or("—"),
            p,
            fmt(&r["joint_err_paper_metric"], 2),
            fmt(&r["err_paper_metric_mirror"], 2),
            fmt(&r["paper"], 2),
            fmt(&r["band_nm"], 0),
            fmt(&r["err_paper_metric"], 2),
            b,
            r["run"].as_str().unwrap_or("?"),
            r["run"].as_str().unwrap_or("?"),
        );
    }
    s.push_str("\n![error against the parameter](campaign.svg)\n");
    s
}

/// The swept parameter's value of every row, when all are numeric (a chart's x axis).
pub(crate) fn numeric_values(rows: &[Value]) -> Option<Vec<f64>> {
    rows.iter()
        .map(|r| r["value"].as_str().and_then(|v| v.parse().ok()))
        .collect()
}

fn plot(dir: &Path, parameter: &str, rows: &[Value]) -> Result<()> {
    let Some(x) = numeric_values(rows) else {
        return Ok(());
    };
    let series = |key: &str| -> Vec<(f64, f64)> {
        rows.iter()
            .zip(&x)
            .filter_map(|(r, &x)| Some((x, num(&r[key])?)))
            .collect()
    };
    line_chart(
        &dir.join("campaign.svg"),
        &format!("Rate error against {parameter}: ours (line) and the paper (dots)"),
        parameter,
        "100·‖p − p*‖ [deg/frame]",
        &[
            Series {
                label: "glint",
                points: series("err_paper_metric"),
                color: BLUE,
                markers: false,
            },
            Series {
                label: "paper",
                points: series("paper"),
                color: RED,
                markers: true,
            },
            Series {
                label: "100 × Cramér–Rao 1σ (joint, observable directions)",
                points: series("crb_paper_metric"),
                color: GREEN,
                markers: false,
            },
        ],
    )
}

/// `glint lab campaign …`.
pub(crate) fn command(lab: crate::cli::LabCmd) -> std::process::ExitCode {
    use crate::cli::LabCmd;
    use crate::run::command::{finish, load_with_seed};
    use std::process::ExitCode;
    match lab {
        LabCmd::Identify {
            shapes,
            axes,
            noise,
            seed,
            out,
        } => {
            if !(noise.is_finite() && (0.0..=2.0).contains(&noise)) {
                eprintln!("error: --noise {noise}: out of range; allowed 0..=2 mag");
                return ExitCode::from(2);
            }
            let out = out.unwrap_or_else(|| {
                PathBuf::from("runs").join(format!("identify-{}", crate::run::utc_stamp()))
            });
            let progress = std::io::IsTerminal::is_terminal(&std::io::stderr());
            match identify::run(&shapes, axes as usize, noise, seed, &out, progress) {
                Ok(r) => {
                    println!("{}", identify::markdown(&r));
                    println!("{}", out.join("confusion.md").display());
                    ExitCode::SUCCESS
                }
                Err(e) => {
                    eprintln!("error: {e:#}");
                    ExitCode::from(2)
                }
            }
        }
        LabCmd::Campaign {
            scenario,
            out,
            seed,
            rescore,
        } => {
            glint_runtime::init_tracing("orchestrator");
            let (sc, file) = match load_with_seed(Some(&scenario), seed) {
                Ok(x) => x,
                Err(code) => return code,
            };
            let Some(campaign) = &sc.campaign else {
                eprintln!("error: {file}: no [campaign] section (run it with `glint run {file}`)");
                return ExitCode::from(2);
            };
            if rescore && (relnav::applies(&sc, campaign) || photometry::applies(&sc, campaign)) {
                eprintln!("error: {file}: --rescore re-scores [000] Monte-Carlo campaigns only");
                return ExitCode::from(2);
            }
            if rescore && campaign.seeds <= 1 {
                eprintln!("error: {file}: --rescore needs a [campaign] with seeds > 1");
                return ExitCode::from(2);
            }
            let progress = std::io::IsTerminal::is_terminal(&std::io::stderr());
            finish(run(&sc, &file, out, progress, rescore))
        }
    }
}
