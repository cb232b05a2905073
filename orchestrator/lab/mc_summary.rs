//! The Monte-Carlo campaign's summary.md: the error table beside the paper's, then the
//! efficiency and honesty table (see [`crate::lab::mc`] for the statistics).

use std::fmt::Write as _;
use std::path::Path;

use anyhow::Result;
use serde_json::Value;
use shared_types::scenario::NoiseWindows;
use shared_types::Scenario;

use crate::lab::fmt;
use crate::lab::mc::vec3;
use crate::plots::{line_chart, Series, BLUE, GREEN, ORANGE, RED};

/// "k at [w_x, w_y, w_z] (Δ = …)" for the copy column, "—" without a copy.
fn copy_cell(e: &Value) -> String {
    match (
        vec3(&e["copy_deg_per_frame"]),
        e["copy_divergence"].as_f64(),
    ) {
        (Some(c), Some(d)) => format!(
            "{} at [{:.4}, {:.4}, {:.4}] (Δ = {d:.1e})",
            e["on_copy"], c[0], c[1], c[2]
        ),
        _ => "—".into(),
    }
}

/// "k" runs on the other sense, with "(m flagged)" when m of them reported the mirror.
fn other_sense_cell(e: &Value) -> String {
    match (e["other_sense"].as_u64(), e["other_sense_flagged"].as_u64()) {
        (Some(k), Some(m)) if k > 0 => format!("{k} ({m} flagged)"),
        (Some(k), _) => k.to_string(),
        _ => "—".into(),
    }
}

fn fmt_e(v: &Value) -> String {
    v.as_f64().map_or("—".into(), |x| format!("{x:.2e}"))
}

/// The Monte-Carlo campaign's summary.md: Table-7-style medians beside the paper, then the
/// efficiency and NEES table.
pub fn summary(scenario: &Scenario, parameter: &str, seeds: u32, rows: &[Value]) -> String {
    let mut s = crate::lab::summary_head(scenario, parameter, Some(seeds));
    let windows = match scenario.spectra.as_ref().map(|sp| sp.noise_windows) {
        Some(NoiseWindows::Motion) => "the motion window noisy, the stable window exact",
        _ => "both windows noisy",
    };
    let _ = writeln!(
        s,
        "Noise σ = mean Φ / SNR per band and window, {windows}.\n"
    );
    s.push_str("## Error against the truth (median over seeds; paper metric 100·‖p − p*‖)\n\n");
    let _ = writeln!(
        s,
        "| {parameter} | noise-free p₀, λ* | median, λ* | median, glint's answer (joint) | paper | 100 × CRB 1σ, joint (observable) | run |\n|---|---|---|---|---|---|---|"
    );
    for r in rows {
        let mc = &r["monte_carlo"];
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} | [{}]({}/reference/summary.md) |",
            r["value"].as_str().unwrap_or("?"),
            fmt(&mc["reference_err_paper_metric"], 2),
            fmt(&r["err_paper_metric"], 2),
            fmt(&r["joint_err_paper_metric"], 2),
            fmt(&r["paper"], 2),
            fmt(&r["crb_paper_metric"], 2),
            r["run"].as_str().unwrap_or("?"),
            r["run"].as_str().unwrap_or("?"),
        );
    }
    s.push_str(
        "\n## Efficiency and honesty (scatter about the noise-free solution)\n\n\
         p₀, the noise-free solution, is the estimator's answer on the noise-free run's observations carrying the noisy runs' σ: σ sets the bands' weights, the stage-1 basis test and the joint fit's reweighting, so the reference deployment's own answer, solved without σ, is another estimator's (the *noise-free p₀* column above is p₀ at λ*; with σ, stage 1 also takes the spectral-pooling decision the noisy runs take on average). The CRB is the scenario's: the stage-1 coefficients are unknown and informed by both windows when both are noisy; the next column is the bound if they were known. The *two-stage* column is the variance of an efficient estimator that takes the coefficients from the stable window alone and plugs them in, as glint does: F⁺ + F⁺CF⁺, F = JᵀWJ and C the stage-1 coefficients' covariance propagated. The CRB lets the motion window inform the coefficients too; an estimator that does so takes the motion window's model mismatch into them (docs/adr/0012). The CRB sees only the light curve's slope at p₀. The Hammersley–Chapman–Robbins bound sup_h (v·h)²/(exp Δ(h) − 1) (Δ = the noise-free χ² between p₀ + h and p₀, with the stage-1 coefficients moved as the stable window allows, as in the CRB) sees the whole light curve: where it is far above the CRB, a rate h away fits nearly as well and no unbiased estimator reaches the CRB. When a rate fits within one noise variance (Δ < 1, the coefficients fixed) it is a *copy* of p₀: a Y rotation is nearly its own mirror (−w_x, w_y, −w_z), and the Sun's fraction of a degree off the body XZ plane moves the mirror a few 10⁻³ deg/frame off p₀. The data cannot tell p₀ from its copy at any SNR a campaign runs; runs nearer the copy are counted in its column and their deviation is taken from the copy. The joint fit tests stage 1's widest lobes in every run and re-fits them only when the data ask (`stage3.refit_widest_lobe = \"when-needed\"`): it has a noise-free solution per model, keeping the lobes and re-fitting them. Each run is measured from that of the model it reported (*joint, lobe re-fitted in k*: k runs re-fitted it), and the table's bound is that of the model most runs reported.\n\n\
         RMS = sqrt(mean ‖(p̂ − p₀ or its copy) projected on the observable CRB directions‖²) over the runs with p₀'s sense of rotation (those nearer the mirror of a rate that has a sense, |mirror(p₀) − p₀| ≥ |p₀|, are counted apart, with how many of them reported the sense as not determined: their answer named the mirror as fitting as well); efficiency = RMS / CRB (1 is efficient). *HCR / CRB* above 1.25 means the target RMS ≤ 1.25 × CRB is out of reach of every unbiased estimator (the light curve is not linear over the scatter the noise allows); *RMS / HCR* is then the efficiency against the bound that applies. NEES uses each run's reported covariance over its observable directions, about the same centre; its 95 % interval is for the mean over the runs. *NEES, speed and axis* measures the same deviation as a rate's speed and the arc between the two axes instead of a straight line (equal to first order): where a run's axis wanders along a direction its fit holds under the prior (about Y, w_z by a few 10⁻³ deg/frame), the straight line puts |p₀|(1 − cos angle) of that wander on the determined speed (docs/adr/0025). The target is the straight-line NEES; this column tells the curvature from a covariance that is too small.\n\n\
         | value | fit | runs determined | other sense | on p₀'s copy (Δ) | observable dirs | CRB 1σ [deg/frame] | CRB 1σ, coefficients known | two-stage 1σ | HCR 1σ | HCR / CRB | RMS [deg/frame] | efficiency (RMS / CRB) | RMS / two-stage | RMS / HCR | NEES mean (dof) | NEES 95 % | NEES, speed and axis |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        for (label, key) in [("λ*", "single"), ("joint", "joint")] {
            let e = &r["monte_carlo"][key];
            let refits = &r["monte_carlo"]["joint_widest_lobe_refits"];
            let label = match (key, refits.as_u64()) {
                ("joint", Some(k)) => format!("{label}, lobe re-fitted in {k}"),
                _ => label.to_string(),
            };
            let _ = writeln!(
                s,
                "| {} | {label} | {}/{} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} ({}) | {}–{} | {} |",
                r["value"].as_str().unwrap_or("?"),
                e["determined"],
                r["monte_carlo"]["runs"],
                other_sense_cell(e),
                copy_cell(e),
                e["observable_directions"],
                fmt_e(&e["crb_observable_deg_per_frame"]),
                fmt_e(&e["crb_known_coefficients_observable_deg_per_frame"]),
                fmt_e(&e["two_stage_observable_deg_per_frame"]),
                fmt_e(&e["hcr_observable_deg_per_frame"]),
                fmt(&e["hcr_over_crb"], 2),
                fmt_e(&e["rms_observable_deg_per_frame"]),
                fmt(&e["efficiency"], 2),
                fmt(&e["efficiency_two_stage"], 2),
                fmt(&e["efficiency_hcr"], 2),
                fmt(&e["nees_mean"], 2),
                fmt(&e["nees_dof_mean"], 1),
                fmt(&e["nees_bounds_95"][0], 2),
                fmt(&e["nees_bounds_95"][1], 2),
                fmt(&e["nees_mean_curvilinear"], 2),
            );
        }
    }
    s.push_str("\n![error against the parameter](campaign.svg)\n");
    s.push_str("\n![NEES against its 95 % interval](campaign-nees.svg)\n");
    s.push_str("\n![efficiency against the target](campaign-efficiency.svg)\n");
    s
}

/// `campaign-nees.svg` and `campaign-efficiency.svg`: each fit's NEES mean (markers: measured in
/// speed and axis) beside the joint fit's 95 % interval, and its RMS / CRB beside the 1.25 target and its HCR / CRB (markers:
/// above the target, no unbiased estimator reaches it), against the parameter, on
/// log10 axes (the values span 0.1 to 10⁴). Nothing is drawn for a non-numeric parameter.
pub fn plot_honesty(dir: &Path, parameter: &str, rows: &[Value]) -> Result<()> {
    let Some(x) = crate::lab::numeric_values(rows) else {
        return Ok(());
    };
    let series = |fit: &str, key: &str, index: Option<usize>| -> Vec<(f64, f64)> {
        rows.iter()
            .zip(&x)
            .filter_map(|(r, &x)| {
                let v = &r["monte_carlo"][fit][key];
                let v = match index {
                    Some(i) => v[i].as_f64(),
                    None => v.as_f64(),
                }?;
                (v > 0.0).then(|| (x, v.log10()))
            })
            .collect()
    };
    let line = |label, points, color| Series {
        label,
        points,
        color,
        markers: false,
    };
    line_chart(
        &dir.join("campaign-nees.svg"),
        &format!("Honesty against {parameter}: mean NEES over the runs (log10)"),
        parameter,
        "log10 NEES mean",
        &[
            line("λ*", series("single", "nees_mean", None), BLUE),
            line("joint", series("joint", "nees_mean", None), GREEN),
            // The diagnostic measure in speed and axis (docs/adr/0025), as markers.
            Series {
                markers: true,
                ..line(
                    "λ*, speed and axis",
                    series("single", "nees_mean_curvilinear", None),
                    BLUE,
                )
            },
            Series {
                markers: true,
                ..line(
                    "joint, speed and axis",
                    series("joint", "nees_mean_curvilinear", None),
                    GREEN,
                )
            },
            line(
                "joint's 95 % interval, low",
                series("joint", "nees_bounds_95", Some(0)),
                RED,
            ),
            line(
                "joint's 95 % interval, high",
                series("joint", "nees_bounds_95", Some(1)),
                RED,
            ),
        ],
    )?;
    let target: Vec<(f64, f64)> = x.iter().map(|&v| (v, 1.25f64.log10())).collect();
    line_chart(
        &dir.join("campaign-efficiency.svg"),
        &format!("Efficiency against {parameter}: RMS about p₀ / CRB, and HCR / CRB (log10)"),
        parameter,
        "log10 (RMS / CRB)",
        &[
            line("λ*", series("single", "efficiency", None), BLUE),
            line("joint", series("joint", "efficiency", None), GREEN),
            line("target 1.25", target, ORANGE),
            // Where the HCR lies above the target, no unbiased estimator reaches it.
            Series {
                markers: true,
                ..line(
                    "λ*: HCR / CRB (above the target: out of reach)",
                    series("single", "hcr_over_crb", None),
                    BLUE,
                )
            },
            Series {
                markers: true,
                ..line(
                    "joint: HCR / CRB",
                    series("joint", "hcr_over_crb", None),
                    GREEN,
                )
            },
        ],
    )
}
