//! Campaign deployments run side by side: every value of the swept parameter with `seeds`
//! seeds, as many deployments at a time as the host has cores (at most [`MAX_PARALLEL`]),
//! each in `DIR/NN/sSSSS/` with its logs silenced, a progress bar over them, Ctrl-C obeyed.

use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

use anyhow::{Context, Result};
use shared_types::scenario::Campaign;
use shared_types::Scenario;

use crate::report::Report;
use crate::run::{self, RunOptions};

/// Deployments run at once: each is a few services and the orchestrator's thread, so one per
/// core keeps a 2-core host busy without the runs slowing each other.
pub const MAX_PARALLEL: usize = 4;

/// One deployment: the value's index, the seed it ran with, its directory relative to the
/// campaign's, its own verdict and its report.
pub struct Deployed {
    pub index: usize,
    pub seed: u64,
    pub run: String,
    pub success: bool,
    pub report: Report,
}

/// One deployment of value `index` with the value's seed + `offset`.
fn deploy(
    scenario: &Scenario,
    file: &str,
    index: usize,
    offset: u64,
    dir: &Path,
    sub: &str,
) -> Result<Deployed> {
    let mut variant = scenario
        .campaign_variant(index)
        .map_err(|e| anyhow::anyhow!("{file}: {e}"))?;
    // A `seed` sweep's value is the first seed of its runs.
    let seed = variant.seed + offset;
    variant.seed = seed;
    variant.name = format!("{}-s{seed}", variant.name);
    let (run_dir, ok) =
        tracing::subscriber::with_default(tracing::subscriber::NoSubscriber::default(), || {
            run::run(RunOptions {
                scenario: variant,
                scenario_file: file.to_string(),
                out_dir: Some(dir.join(sub)),
                // The campaign owns its directory: a sub-run there replaces the previous one.
                replace: true,
                progress: false,
                record: false,
                host: None,
            })
        })?;
    let report = Report::read(&run_dir.join("report.json"))?;
    Ok(Deployed {
        index,
        seed,
        run: sub.to_string(),
        success: ok,
        report,
    })
}

/// Every deployment of the campaign, each mapped by `figures` as it ends (a report is not
/// kept); per value, its runs in seed order. Returns them and how many ran at once.
pub fn deploy_all<T: Send>(
    scenario: &Scenario,
    file: &str,
    dir: &Path,
    camp: &Campaign,
    progress: bool,
    figures: impl Fn(Deployed) -> (T, bool) + Sync,
) -> Result<(Vec<Vec<T>>, usize)> {
    let seeds = camp.seeds.max(1);
    let jobs: Vec<(usize, u64)> = (0..camp.values.len())
        .flat_map(|i| (0..u64::from(seeds)).map(move |s| (i, s)))
        .collect();
    let parallel = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(MAX_PARALLEL)
        .min(jobs.len())
        .max(1);
    eprintln!(
        "campaign {}: {} = {} values × {seeds} seeds = {} deployments, {parallel} at a time",
        scenario.name,
        camp.parameter,
        camp.values.len(),
        jobs.len()
    );
    let bar = if progress {
        crate::progress::runs_bar(jobs.len() as u64)
    } else {
        indicatif::ProgressBar::hidden()
    };
    let next = AtomicUsize::new(0);
    let results: Mutex<Vec<Option<T>>> = Mutex::new((0..jobs.len()).map(|_| None).collect());
    let first_error: Mutex<Option<anyhow::Error>> = Mutex::new(None);
    std::thread::scope(|s| {
        for _ in 0..parallel {
            s.spawn(|| loop {
                let j = next.fetch_add(1, Ordering::SeqCst);
                let stop = first_error.lock().map_or(true, |e| e.is_some());
                if j >= jobs.len() || stop || run::bail_if_interrupted("campaign").is_err() {
                    break;
                }
                let (index, s) = jobs[j];
                let sub = format!("{index:02}/s{s:04}");
                match deploy(scenario, file, index, s, dir, &sub) {
                    Ok(d) => {
                        let seed = d.seed;
                        let (f, ok) = figures(d);
                        if !ok {
                            bar.suspend(|| {
                                eprintln!(
                                    "campaign {}: run {sub} (seed {seed}) failed: see {}",
                                    scenario.name,
                                    dir.join(&sub).join("summary.md").display()
                                )
                            });
                        }
                        if let Ok(mut r) = results.lock() {
                            r[j] = Some(f);
                        }
                        bar.set_message(format!(
                            "{} = {}",
                            camp.parameter,
                            value_text(&camp.values[index])
                        ));
                        bar.inc(1);
                    }
                    Err(e) => {
                        if let Ok(mut slot) = first_error.lock() {
                            slot.get_or_insert(e.context(format!("campaign run {sub}")));
                        }
                        break;
                    }
                }
            });
        }
    });
    bar.finish_and_clear();
    if let Some(e) = first_error.into_inner().ok().flatten() {
        return Err(e);
    }
    run::bail_if_interrupted("campaign")?;
    let mut results = results
        .into_inner()
        .map_err(|_| anyhow::anyhow!("a campaign worker panicked"))?
        .into_iter();
    let mut per_value = vec![];
    for _ in &camp.values {
        let runs: Vec<T> = results
            .by_ref()
            .take(seeds as usize)
            .collect::<Option<_>>()
            .context("a campaign run left no figures")?;
        per_value.push(runs);
    }
    Ok((per_value, parallel))
}

/// A swept value as text (a string without its quotes).
pub fn value_text(v: &toml::Value) -> String {
    v.to_string().trim_matches('"').to_string()
}
