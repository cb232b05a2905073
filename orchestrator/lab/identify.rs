//! `glint lab identify --shapes SHAPES.toml [--axes N] [--noise MAG] [--seed S] [--out DIR]`:
//! how often the [001] identification names the right geometry (docs/photometry.md). For every
//! shape of the file and N random spin axes (rate one turn per 60–300 s, size 0.7–1.5 in length,
//! random phase), a 20-minute light curve at 2 s is rendered with glint's physics at a fixed
//! GEO geometry (Sun and observer 40° apart), magnitude noise added, and identified against
//! the same shapes. Writes DIR/identify.json and DIR/confusion.md (rows: the truth, columns:
//! glint's answer), with the spin and area errors of the correctly identified.

use std::fmt::Write as _;
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

use anyhow::{Context, Result};
use glint_photometry::spin::spin_attitude;
use glint_photometry::{identify, Database};
use glint_physics::photometry::{
    apparent_magnitude, flux_of_magnitude, normalised_flux, Shape, SpecularDenominator,
};
use glint_physics::rng::SeededRng;
use nalgebra::{Unit, Vector3};
use serde::{Deserialize, Serialize};

/// One identified light curve.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Trial {
    pub truth: String,
    pub answer: Option<String>,
    pub spin_error: Option<f64>,
    pub area_error: Option<f64>,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct IdentifyReport {
    pub noise_mag: f64,
    pub axes_per_shape: usize,
    pub seed: u64,
    pub runs: usize,
    pub correct: usize,
    /// `confusion[i][j]`: curves of shape i identified as shape j (j = shapes: none).
    pub shapes: Vec<String>,
    pub confusion: Vec<Vec<usize>>,
    /// Of the correctly identified: the median and worst |spin error| and |area error|
    /// (relative).
    pub spin_error_median: f64,
    pub spin_error_worst: f64,
    pub area_error_median: f64,
    pub area_error_worst: f64,
    pub trials: Vec<Trial>,
}

const SAMPLES: usize = 600;
const CADENCE_S: f64 = 2.0;
const RANGE_M: f64 = 3.6e7;

fn geometry() -> (Vector3<f64>, Vector3<f64>) {
    let sun = Vector3::new(-0.8, 0.5, 0.2).normalize();
    let obs = Vector3::new(-1.0, 0.0, 0.1).normalize();
    (sun, obs)
}

/// One trial: shape `g` drawn from `rng`'s axis, rate, size and phase, identified.
fn trial(
    db: &Database,
    shapes: &[(String, Shape)],
    g: usize,
    rng: &mut SeededRng,
    noise: f64,
) -> Trial {
    let (sun, obs) = geometry();
    let axis = loop {
        let v = Vector3::new(rng.gaussian(), rng.gaussian(), rng.gaussian());
        if v.norm() > 1e-6 {
            break Unit::new_normalize(v);
        }
    };
    let period = 60.0 + 240.0 * rng.uniform();
    let w = 2.0 * std::f64::consts::PI / period;
    let k = 0.7 + 0.8 * rng.uniform();
    let phase = 2.0 * std::f64::consts::PI * rng.uniform();
    let body = shapes[g].1.scaled(k);
    let mut t = vec![];
    let mut y = vec![];
    for s in 0..SAMPLES {
        let ts = s as f64 * CADENCE_S;
        let inv = spin_attitude(&axis, phase + w * ts).inverse();
        let m = normalised_flux(
            &body,
            &(inv * sun),
            &(inv * obs),
            SpecularDenominator::Linares2014,
        );
        let noisy = rng.gaussian() * noise;
        if let Some(mag) = apparent_magnitude(m, RANGE_M) {
            t.push(ts);
            y.push(flux_of_magnitude(mag + noisy, RANGE_M));
        }
    }
    let id = (t.len() >= 16).then(|| identify(db, &t, &y)).flatten();
    let truth = shapes[g].0.clone();
    match id {
        None => Trial {
            truth,
            answer: None,
            spin_error: None,
            area_error: None,
        },
        Some(id) => {
            let b = id.best;
            let right = b.geometry == truth;
            Trial {
                truth,
                answer: Some(b.geometry),
                spin_error: right.then(|| (b.spin_rad_s / w - 1.0).abs()),
                area_error: right.then(|| (b.area_scale / (k * k) - 1.0).abs()),
            }
        }
    }
}

/// The median and the largest of the finite values (NaN, NaN without any).
pub(crate) fn median_and_worst(mut v: Vec<f64>) -> (f64, f64) {
    v.retain(|x| x.is_finite());
    if v.is_empty() {
        return (f64::NAN, f64::NAN);
    }
    v.sort_by(f64::total_cmp);
    (v[v.len() / 2], v[v.len() - 1])
}

/// Runs the study; returns the report (also written into `out`).
pub fn run(
    shapes_file: &Path,
    axes: usize,
    noise: f64,
    seed: u64,
    out: &Path,
    progress: bool,
) -> Result<IdentifyReport> {
    let shapes = crate::tools::photometry::read_shapes(shapes_file)?;
    let (sun, obs) = geometry();
    let db = Database::build(
        &shapes,
        &sun,
        &obs,
        200,
        8,
        SpecularDenominator::Linares2014,
    );
    let jobs: Vec<(usize, usize)> = (0..shapes.len())
        .flat_map(|g| (0..axes).map(move |a| (g, a)))
        .collect();
    let bar = if progress {
        crate::progress::runs_bar(jobs.len() as u64)
    } else {
        indicatif::ProgressBar::hidden()
    };
    let next = AtomicUsize::new(0);
    let trials: Mutex<Vec<Option<Trial>>> = Mutex::new(vec![None; jobs.len()]);
    let workers = std::thread::available_parallelism().map_or(1, |n| n.get());
    std::thread::scope(|s| {
        for _ in 0..workers {
            s.spawn(|| loop {
                let j = next.fetch_add(1, Ordering::SeqCst);
                let Some(&(g, a)) = jobs.get(j) else {
                    break;
                };
                // Each trial its own stream: the same seed gives the same study on any host.
                let mut rng = SeededRng::new(seed ^ ((g as u64) << 32) ^ a as u64);
                let t = trial(&db, &shapes, g, &mut rng, noise);
                if let Ok(mut v) = trials.lock() {
                    v[j] = Some(t);
                }
                bar.set_message(shapes[g].0.clone());
                bar.inc(1);
            });
        }
    });
    bar.finish_and_clear();
    let trials: Vec<Trial> = trials
        .into_inner()
        .map_err(|_| anyhow::anyhow!("a worker panicked"))?
        .into_iter()
        .collect::<Option<_>>()
        .context("a trial left no answer")?;
    let names: Vec<String> = shapes.iter().map(|(n, _)| n.clone()).collect();
    let mut confusion = vec![vec![0usize; names.len() + 1]; names.len()];
    for t in &trials {
        let i = names.iter().position(|n| *n == t.truth).unwrap_or(0);
        let j = (t.answer.as_ref())
            .and_then(|a| names.iter().position(|n| n == a))
            .unwrap_or(names.len());
        confusion[i][j] += 1;
    }
    let correct = (0..names.len()).map(|i| confusion[i][i]).sum();
    let (spin_error_median, spin_error_worst) =
        median_and_worst(trials.iter().filter_map(|t| t.spin_error).collect());
    let (area_error_median, area_error_worst) =
        median_and_worst(trials.iter().filter_map(|t| t.area_error).collect());
    let report = IdentifyReport {
        noise_mag: noise,
        axes_per_shape: axes,
        seed,
        runs: trials.len(),
        correct,
        shapes: names,
        confusion,
        spin_error_median,
        spin_error_worst,
        area_error_median,
        area_error_worst,
        trials,
    };
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    std::fs::write(
        out.join("identify.json"),
        serde_json::to_string_pretty(&report)? + "\n",
    )?;
    std::fs::write(out.join("confusion.md"), markdown(&report))?;
    Ok(report)
}

/// The headline and the confusion table.
pub fn markdown(r: &IdentifyReport) -> String {
    let mut s = format!(
        "# glint lab identify: {} of {} correct ({:.1} %), noise {} mag\n\n\
         Of the correctly identified: spin error median {:.2} %, worst {:.2} %; area error \
         median {:.1} %, worst {:.1} %. {} axes per shape, seed {}.\n\n| truth \\ answer |",
        r.correct,
        r.runs,
        100.0 * r.correct as f64 / r.runs.max(1) as f64,
        r.noise_mag,
        100.0 * r.spin_error_median,
        100.0 * r.spin_error_worst,
        100.0 * r.area_error_median,
        100.0 * r.area_error_worst,
        r.axes_per_shape,
        r.seed
    );
    for n in &r.shapes {
        let _ = write!(s, " {n} |");
    }
    s.push_str(" none |\n|---|");
    for _ in 0..=r.shapes.len() {
        s.push_str("---|");
    }
    s.push('\n');
    for (n, row) in r.shapes.iter().zip(&r.confusion) {
        let _ = write!(s, "| {n} |");
        for c in row {
            let _ = write!(s, " {c} |");
        }
        s.push('\n');
    }
    s
}
