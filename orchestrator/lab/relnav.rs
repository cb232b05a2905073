//! [004] campaigns: every value of the swept parameter deployed with `seeds` seeds, side by
//! side ([`crate::lab::parallel`]); per value the RTMSE
//! pooled over the runs (math.md eq 40 with M runs), the runs' mean NEES against its M-run
//! 95 % interval and the share of epochs within 3σ; `DIR/campaign.json`, a table with the
//! paper's trends in `DIR/summary.md` and each group's error against the parameter in
//! `DIR/campaign.svg`.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use anyhow::Result;
use glint_relnav::score::Score;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use shared_types::scenario::Campaign;
use shared_types::Scenario;

use crate::lab::parallel::{deploy_all, value_text, Deployed};
use crate::plots::{line_chart, Series, BLUE, GREEN, ORANGE, PURPLE, RED};
use crate::report::sections::relnav::{RelNavErrors, RelNavShares};

/// Whether a campaign of `scenario` is a [004] one: it sweeps a `stereo.*` parameter, or the
/// scenario's only science is the stereo chain.
pub fn applies(scenario: &Scenario, campaign: &Campaign) -> bool {
    campaign.parameter.starts_with("stereo.")
        || (scenario.stereo.is_some() && scenario.spectra.is_none())
}

/// One deployment's figures.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct RunFigures {
    pub seed: u64,
    /// Its run directory, relative to the campaign's.
    pub run: String,
    /// The run's own verdict (every message accounted for, no service lost).
    pub success: bool,
    /// Epochs in its score (a filter restart's starting epochs are left out).
    pub epochs_scored: u64,
    pub rtmse: RelNavErrors,
    pub nees_mean: f64,
    pub within_3sigma: RelNavShares,
    pub starts: u32,
    pub diverged: u32,
    pub numerical_failures: u32,
}

/// One value of the swept parameter over its runs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct ValueFigures {
    pub value: String,
    pub runs: u32,
    /// Runs whose deployment failed or that scored nothing (left out of the figures below).
    pub failed: u32,
    /// RTMSE over the runs and the window's epochs (eq 40: the root of the mean square over
    /// every scored epoch of every run); NaN when no run scored.
    pub rtmse: RelNavErrors,
    /// The worst run's RTMSE, per group.
    pub rtmse_worst: RelNavErrors,
    /// Runs whose five RTMSE all lie within the paper's figures.
    pub runs_within_paper: u32,
    /// The runs' mean NEES (14 expected) and the 95 % interval of a mean over this many runs.
    pub nees_mean: f64,
    pub nees_95: [f64; 2],
    /// Mean over the runs of the share of epochs within 3σ, per group.
    pub within_3sigma: RelNavShares,
    /// Restarts of the filter after a divergence or a numerical failure, over the runs.
    pub restarts: u32,
    pub per_run: Vec<RunFigures>,
}

/// `DIR/campaign.json` of a [004] campaign.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct RelNavCampaign {
    pub scenario: String,
    pub parameter: String,
    pub seed: u64,
    pub seeds: u32,
    /// Wall time of the whole campaign [s] and deployments run at once.
    pub wall_s: f64,
    pub parallel: u32,
    pub rows: Vec<ValueFigures>,
    /// The paper's nominal figures (200 runs of its own, lost, case).
    pub paper: RelNavErrors,
}

/// The state groups, in the order of [`groups`].
const GROUP_NAMES: [&str; 5] = ["attitude", "ω", "k", "position", "velocity"];

fn groups(e: &RelNavErrors) -> [f64; 5] {
    [
        e.attitude_deg,
        e.rate_rad_s,
        e.inertia_k,
        e.position_m,
        e.velocity_m_s,
    ]
}

fn errors(g: [f64; 5]) -> RelNavErrors {
    RelNavErrors {
        attitude_deg: g[0],
        rate_rad_s: g[1],
        inertia_k: g[2],
        position_m: g[3],
        velocity_m_s: g[4],
    }
}

fn shares(s: &RelNavShares) -> [f64; 5] {
    [s.attitude, s.rate, s.inertia_k, s.position, s.velocity]
}

/// The paper's nominal figures (math.md §5.8).
pub fn paper() -> RelNavErrors {
    errors([0.1, 6e-5, 0.02, 0.010, 10e-6])
}

/// Pools the runs of one value (those that scored).
pub fn pool(value: String, per_run: Vec<RunFigures>) -> ValueFigures {
    let scored: Vec<&RunFigures> = per_run
        .iter()
        .filter(|r| {
            r.success && r.epochs_scored > 0 && groups(&r.rtmse).iter().all(|x| x.is_finite())
        })
        .collect();
    // No run scored: every figure NaN (written null), not 0.
    let m = scored.len() as f64;
    let epochs = scored.iter().map(|r| r.epochs_scored).sum::<u64>() as f64;
    let over = |f: &dyn Fn(&RunFigures) -> [f64; 5], combine: fn(f64, f64) -> f64| {
        let mut acc = [0.0; 5];
        for r in &scored {
            for (a, x) in acc.iter_mut().zip(f(r)) {
                *a = combine(*a, x);
            }
        }
        acc
    };
    // eq 40: each run's mean square weighted by its epochs.
    let sum_sq = over(
        &|r| groups(&r.rtmse).map(|x| x * x * r.epochs_scored as f64),
        |a, x| a + x,
    );
    let worst = over(&|r| groups(&r.rtmse), f64::max);
    let within = over(&|r| shares(&r.within_3sigma), |a, x| a + x);
    let limit = groups(&paper());
    let (lo, hi) = Score::nees_interval(scored.len() as u64);
    ValueFigures {
        value,
        runs: per_run.len() as u32,
        failed: (per_run.len() - scored.len()) as u32,
        rtmse: errors(sum_sq.map(|s| (s / epochs).sqrt())),
        rtmse_worst: errors(if scored.is_empty() {
            [f64::NAN; 5]
        } else {
            worst
        }),
        runs_within_paper: scored
            .iter()
            .filter(|r| groups(&r.rtmse).iter().zip(limit).all(|(x, l)| *x <= l))
            .count() as u32,
        nees_mean: scored.iter().map(|r| r.nees_mean).sum::<f64>() / m,
        nees_95: [lo, hi],
        within_3sigma: {
            let w = within.map(|s| s / m);
            RelNavShares {
                attitude: w[0],
                rate: w[1],
                inertia_k: w[2],
                position: w[3],
                velocity: w[4],
            }
        },
        restarts: scored
            .iter()
            .map(|r| r.starts.saturating_sub(1))
            .sum::<u32>(),
        per_run,
    }
}

/// One deployment's figures, and whether it scored.
fn figures(d: Deployed) -> (RunFigures, bool) {
    let r = d.report.results.relnav.as_ref();
    let nan = errors([f64::NAN; 5]);
    let f = RunFigures {
        seed: d.seed,
        run: d.run.clone(),
        success: d.success && r.is_some(),
        epochs_scored: r.map_or(0, |r| r.epochs_scored),
        rtmse: r.map_or(nan, |r| r.rtmse.clone()),
        nees_mean: r.map_or(f64::NAN, |r| r.nees_mean),
        within_3sigma: r.map_or(
            RelNavShares {
                attitude: 0.0,
                rate: 0.0,
                inertia_k: 0.0,
                position: 0.0,
                velocity: 0.0,
            },
            |r| r.within_3sigma.clone(),
        ),
        starts: r.map_or(0, |r| r.filter.starts),
        diverged: r.map_or(0, |r| r.filter.diverged),
        numerical_failures: r.map_or(0, |r| r.filter.numerical_failures),
    };
    let ok = f.success;
    (f, ok)
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
    let seeds = camp.seeds.max(1);
    let (per_value, parallel) = deploy_all(scenario, file, dir, camp, progress, figures)?;
    let rows: Vec<ValueFigures> = (camp.values.iter().zip(per_value))
        .map(|(value, per_run)| pool(value_text(value), per_run))
        .collect();
    let out = RelNavCampaign {
        scenario: scenario.name.clone(),
        parameter: camp.parameter.clone(),
        seed: scenario.seed,
        seeds,
        wall_s: t0.elapsed().as_secs_f64(),
        parallel: parallel as u32,
        rows,
        paper: paper(),
    };
    std::fs::write(
        dir.join("campaign.json"),
        serde_json::to_string_pretty(&out)? + "\n",
    )?;
    std::fs::write(dir.join("summary.md"), summary(scenario, &out))?;
    plot(dir, &out)?;
    let all_ok = out.rows.iter().all(|r| r.failed == 0);
    eprintln!("{}", headline(&out));
    Ok(all_ok)
}

/// The first line a user reads: each value's pooled errors against the paper's.
fn headline(c: &RelNavCampaign) -> String {
    let mut s = String::new();
    for r in &c.rows {
        let e = &r.rtmse;
        let _ = writeln!(
            s,
            "{} = {} ({} runs{}): attitude {:.4}°, ω {:.2e} rad/s, k {:.2e}, position {:.3} mm, velocity {:.3} µm/s; mean NEES {:.2} (95 % {:.2}–{:.2})",
            c.parameter,
            r.value,
            r.runs,
            if r.failed > 0 { format!(", {} failed", r.failed) } else { String::new() },
            e.attitude_deg,
            e.rate_rad_s,
            e.inertia_k,
            e.position_m * 1e3,
            e.velocity_m_s * 1e6,
            r.nees_mean,
            r.nees_95[0],
            r.nees_95[1],
        );
    }
    let _ = write!(
        s,
        "paper (200 runs of its own case): attitude < 0.1°, ω < 6e-5 rad/s, k ≤ 0.02, position ≤ 10 mm, velocity < 10 µm/s; {:.1} s for {} deployments",
        c.wall_s,
        c.rows.iter().map(|r| r.runs).sum::<u32>()
    );
    s
}

/// How each group's pooled error moved from the first value to the last, in words.
fn trend(c: &RelNavCampaign) -> String {
    let (Some(first), Some(last)) = (c.rows.first(), c.rows.last()) else {
        return String::new();
    };
    if c.rows.len() < 2 {
        return String::new();
    }
    let moves: Vec<String> = GROUP_NAMES
        .iter()
        .zip(groups(&first.rtmse).iter().zip(groups(&last.rtmse)))
        .map(|(n, (a, b))| format!("{n} ×{:.2}", b / a))
        .collect();
    format!(
        "From {} = {} to {}: {}.",
        c.parameter,
        first.value,
        last.value,
        moves.join(", ")
    )
}

fn summary(scenario: &Scenario, c: &RelNavCampaign) -> String {
    let mut s = crate::lab::summary_head(scenario, &c.parameter, Some(c.seeds));
    let _ = writeln!(
        s,
        "RTMSE over the last 50 minutes, pooled over each value's runs (math.md eq 40 with M runs); \
         mean NEES over the runs with the 95 % interval of a mean over M runs; within 3σ: the \
         runs' mean share of epochs whose every component lay within 3σ (lowest group shown; \
         99.2 % expected of a consistent 3-component group). \
         The paper's figures are for its own nominal case over 200 runs (its Tables 2–7 were \
         lost: its sweeps give trends, not values). {} deployments, {} at a time, {:.1} s.\n",
        c.rows.iter().map(|r| r.runs).sum::<u32>(),
        c.parallel,
        c.wall_s
    );
    let _ = writeln!(
        s,
        "| {} | runs | attitude [°] | ω [rad/s] | k | position [mm] | velocity [µm/s] | mean NEES (95 %) | within 3σ | runs within the paper's figures | filter restarts |\n|---|---|---|---|---|---|---|---|---|---|---|",
        c.parameter
    );
    for r in &c.rows {
        let e = &r.rtmse;
        let lowest = shares(&r.within_3sigma)
            .into_iter()
            .fold(f64::INFINITY, f64::min);
        let runs = if r.failed > 0 {
            format!("{} ({} failed)", r.runs, r.failed)
        } else {
            r.runs.to_string()
        };
        let _ = writeln!(
            s,
            "| {} | {runs} | {:.4} | {:.2e} | {:.2e} | {:.3} | {:.3} | {:.2} ({:.2}–{:.2}) | {:.1} % | {} | {} |",
            r.value,
            e.attitude_deg,
            e.rate_rad_s,
            e.inertia_k,
            e.position_m * 1e3,
            e.velocity_m_s * 1e6,
            r.nees_mean,
            r.nees_95[0],
            r.nees_95[1],
            100.0 * lowest,
            r.runs_within_paper,
            r.restarts,
        );
    }
    let _ = writeln!(
        s,
        "| paper | 200 | < 0.1 | < 6e-5 | ≤ 0.02 | ≤ 10 | < 10 | — | all | — | — |\n"
    );
    let t = trend(c);
    if !t.is_empty() {
        let _ = writeln!(
            s,
            "{t} The paper: accuracy improves with more features and a larger target, degrades \
             with image noise; the inertia-parameter error is nearly insensitive.\n"
        );
        s.push_str(
            "![each group's RTMSE against the parameter, relative to the first value](campaign.svg)\n",
        );
    }
    s
}

/// Each group's pooled RTMSE against the parameter, relative to its value at the first one
/// (the paper's sweeps give trends: every line starts at 1).
fn plot(dir: &Path, c: &RelNavCampaign) -> Result<()> {
    let x: Option<Vec<f64>> = c.rows.iter().map(|r| r.value.parse().ok()).collect();
    let (Some(x), Some(first)) = (x.filter(|x| x.len() > 1), c.rows.first()) else {
        return Ok(());
    };
    let base = groups(&first.rtmse);
    let colors = [BLUE, GREEN, ORANGE, PURPLE, RED];
    let series: Vec<Series> = (0..5)
        .map(|g| Series {
            label: GROUP_NAMES[g],
            points: c
                .rows
                .iter()
                .zip(&x)
                .map(|(r, &x)| (x, groups(&r.rtmse)[g] / base[g]))
                .collect(),
            color: colors[g],
            markers: false,
        })
        .collect();
    line_chart(
        &dir.join("campaign.svg"),
        &format!(
            "RTMSE against {}, relative to {} = {}",
            c.parameter, c.parameter, first.value
        ),
        &c.parameter,
        "RTMSE / RTMSE at the first value",
        &series,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run_with(seed: u64, rtmse: [f64; 5], nees: f64, success: bool) -> RunFigures {
        RunFigures {
            seed,
            run: format!("00/s{seed:04}"),
            success,
            epochs_scored: 3001,
            rtmse: errors(rtmse),
            nees_mean: nees,
            within_3sigma: RelNavShares {
                attitude: 1.0,
                rate: 0.9,
                inertia_k: 1.0,
                position: 1.0,
                velocity: 1.0,
            },
            starts: 1,
            diverged: 0,
            numerical_failures: 0,
        }
    }

    #[test]
    fn runs_pool_as_the_root_of_their_mean_square_and_failures_are_left_out() {
        let v = pool(
            "4".into(),
            vec![
                run_with(0, [0.03, 1e-5, 1e-4, 3e-4, 1e-6], 13.0, true),
                run_with(1, [0.04, 2e-5, 1e-4, 4e-4, 2e-6], 15.0, true),
                run_with(2, [9.0, 9.0, 9.0, 9.0, 9.0], 99.0, false),
            ],
        );
        assert_eq!((v.runs, v.failed), (3, 1));
        // eq 40 over M = 2 runs of equal windows: sqrt((0.03² + 0.04²) / 2).
        assert!((v.rtmse.attitude_deg - (0.0025f64 / 2.0).sqrt()).abs() < 1e-15);
        assert_eq!(v.rtmse_worst.position_m, 4e-4);
        assert_eq!(v.nees_mean, 14.0);
        let (lo, hi) = Score::nees_interval(2);
        assert_eq!(v.nees_95, [lo, hi]);
        assert!(lo < 14.0 && 14.0 < hi && hi - lo < Score::nees_interval(1).1);
        assert_eq!(v.runs_within_paper, 2);
        assert!((v.within_3sigma.rate - 0.9).abs() < 1e-12);
    }

    #[test]
    fn runs_weigh_by_their_scored_epochs_and_a_value_without_a_scored_run_is_nan() {
        let mut short = run_with(0, [0.02, 1e-5, 1e-4, 3e-4, 1e-6], 14.0, true);
        short.epochs_scored = 1000;
        let mut long = run_with(1, [0.04, 1e-5, 1e-4, 3e-4, 1e-6], 14.0, true);
        long.epochs_scored = 3000;
        let v = pool("4".into(), vec![short, long]);
        let expected = ((0.02f64.powi(2) * 1000.0 + 0.04f64.powi(2) * 3000.0) / 4000.0).sqrt();
        assert!((v.rtmse.attitude_deg - expected).abs() < 1e-15);
        let none = pool(
            "4".into(),
            vec![run_with(0, [0.02, 1e-5, 1e-4, 3e-4, 1e-6], 14.0, false)],
        );
        assert_eq!((none.runs, none.failed), (1, 1));
        assert!(none.rtmse.attitude_deg.is_nan() && none.nees_mean.is_nan());
        assert!(none.rtmse_worst.position_m.is_nan());
    }
}
