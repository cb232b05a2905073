//! The [003] Earth sensor in the report: each method's error in the attitude angle against the
//! turntable's truth, per interval of the paper (|β| ≤ 10°, 10–40°, 40–50°), its time per
//! frame, and the pictures (error against angle, the β_k samples with their fitted t density,
//! one annotated frame).
//!
//! The error of a frame is `sign(tilt) · β − angle`: β with the sign of the measured tilt
//! about the turntable axis against the turntable's signed angle, so the ±10° sweep through
//! nadir is scored as the paper's turntable reads it.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use anyhow::Result;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use shared_types::{EarthAttitude, Truth};

use crate::plots::{line_chart, Series, BLUE, GREEN, ORANGE, RED};

/// The paper's intervals of |angle| [deg]: (report name, lower bound exclusive except the
/// first, upper bound inclusive).
pub const INTERVALS: [(&str, f64, f64); 3] = [
    ("within_10", 0.0, 10.0),
    ("10_to_40", 10.0, 40.0),
    ("40_to_50", 40.0, 50.0),
];

/// The paper's figures (math.md §4.8): error σ within ±10° of the cross-product method and of
/// the Hough baseline [deg], and the lookup version's time as a fraction of the baseline's.
pub const PAPER_SIGMA_CROSS_DEG: f64 = 0.03;
pub const PAPER_SIGMA_HOUGH_DEG: f64 = 0.06;
pub const PAPER_LOOKUP_TIME_RATIO: f64 = 0.13;

/// Error statistics over one interval.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct IntervalScore {
    pub frames: u64,
    pub err_mean_deg: f64,
    /// Sample standard deviation about the mean (n − 1).
    pub err_sigma_deg: f64,
    /// Largest |error|.
    pub err_max_deg: f64,
}

/// One method over the run.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MethodScore {
    pub name: &'static str,
    pub intervals: [IntervalScore; 3],
    /// Frames with truth the method gave no answer on.
    pub missed: u64,
    /// Those frames by the reason the method gave (`EarthMethod::UNDETERMINED_NAMES`).
    pub not_determined: BTreeMap<&'static str, u64>,
    /// Frames outside the paper's intervals (|angle| > 50°), scored nowhere.
    pub outside: u64,
    /// Mean compute time per answered frame, the shared edge extraction included [µs].
    pub time_us_per_frame: Option<f64>,
    /// (angle [deg], error [deg]) per answered frame, for the plot.
    pub errors: Vec<(f64, f64)>,
}

#[derive(Clone, Debug, Default, PartialEq)]
pub struct EarthScore {
    pub methods: Vec<MethodScore>,
    /// Frames with both an answer and a truth.
    pub frames: u64,
}

fn stats(errors: &[f64]) -> IntervalScore {
    let n = errors.len();
    if n == 0 {
        return IntervalScore::default();
    }
    let mean = errors.iter().sum::<f64>() / n as f64;
    let var = if n > 1 {
        errors.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / (n - 1) as f64
    } else {
        0.0
    };
    IntervalScore {
        frames: n as u64,
        err_mean_deg: mean,
        err_sigma_deg: var.sqrt(),
        err_max_deg: errors.iter().fold(0.0, |m, e| m.max(e.abs())),
    }
}

/// The interval of a turntable angle, if any.
fn interval_of(angle_deg: f64) -> Option<usize> {
    let a = angle_deg.abs();
    INTERVALS
        .iter()
        .position(|&(_, lo, hi)| (a > lo || lo == 0.0) && a <= hi)
}

/// Scores every answer against the Earth truths of its frame.
pub fn score(truths: &[Truth], answers: &[EarthAttitude]) -> EarthScore {
    let truth: BTreeMap<u64, &Truth> = (truths.iter())
        .filter(|t| t.kind == Truth::KIND_EARTH)
        .map(|t| (t.frame_index, t))
        .collect();
    let scored: Vec<(&EarthAttitude, &Truth)> = answers
        .iter()
        .filter_map(|a| truth.get(&a.frame_index).map(|t| (a, *t)))
        .collect();
    let methods = EarthAttitude::METHOD_NAMES
        .iter()
        .enumerate()
        .map(|(i, &name)| {
            let mut per: [Vec<f64>; 3] = Default::default();
            let mut m = MethodScore {
                name,
                ..Default::default()
            };
            let mut time_us = vec![];
            for (a, t) in &scored {
                let r = a.methods[i];
                if r.valid != 1 {
                    m.missed += 1;
                    *m.not_determined.entry(r.undetermined_name()).or_default() += 1;
                    continue;
                }
                let signed = if r.tilt_deg < 0.0 {
                    -r.beta_deg
                } else {
                    r.beta_deg
                };
                let err = signed - t.earth_tilt_deg;
                m.errors.push((t.earth_tilt_deg, err));
                time_us.push(r.time_us);
                match interval_of(t.earth_tilt_deg) {
                    Some(k) => per[k].push(err),
                    None => m.outside += 1,
                }
            }
            m.intervals = [stats(&per[0]), stats(&per[1]), stats(&per[2])];
            m.time_us_per_frame =
                (!time_us.is_empty()).then(|| time_us.iter().sum::<f64>() / time_us.len() as f64);
            m
        })
        .collect();
    EarthScore {
        methods,
        frames: scored.len() as u64,
    }
}

impl EarthScore {
    fn method(&self, name: &str) -> Option<&MethodScore> {
        self.methods.iter().find(|m| m.name == name)
    }

    /// σ within ±10° of a method, if it answered there.
    fn sigma_within_10(&self, name: &str) -> Option<f64> {
        let s = &self.method(name)?.intervals[0];
        (s.frames > 1).then_some(s.err_sigma_deg)
    }

    /// The lookup version's time per frame over the Hough baseline's.
    fn lookup_time_ratio(&self) -> Option<f64> {
        let l = self.method("lookup")?.time_us_per_frame?;
        let h = self.method("hough")?.time_us_per_frame?;
        (h > 0.0).then(|| l / h)
    }

    /// `earth` in report.json (each method's time per frame goes to the timing part:
    /// [`EarthScore::times`]).
    pub fn report(&self) -> EarthReport {
        let interval = |s: &IntervalScore| IntervalReport {
            frames: s.frames,
            err_mean_deg: (s.frames > 0).then_some(s.err_mean_deg),
            err_sigma_deg: (s.frames > 0).then_some(s.err_sigma_deg),
            err_max_deg: (s.frames > 0).then_some(s.err_max_deg),
        };
        let methods = (self.methods.iter())
            .map(|m| {
                let r = MethodReport {
                    within_10: interval(&m.intervals[0]),
                    from_10_to_40: interval(&m.intervals[1]),
                    from_40_to_50: interval(&m.intervals[2]),
                    missed: m.missed,
                    not_determined: (m.not_determined.iter())
                        .map(|(k, v)| (k.to_string(), *v))
                        .collect(),
                    outside_intervals: m.outside,
                };
                (m.name.to_string(), r)
            })
            .collect();
        EarthReport {
            frames: self.frames,
            methods,
            paper: EarthPaper {
                cross_product_sigma_within_10_deg: PAPER_SIGMA_CROSS_DEG,
                hough_sigma_within_10_deg: PAPER_SIGMA_HOUGH_DEG,
                lookup_time_over_hough: PAPER_LOOKUP_TIME_RATIO,
            },
        }
    }

    /// Each method's mean compute time per answered frame [µs] (`timing.earth_us_per_frame`).
    pub fn times(&self) -> BTreeMap<String, Option<f64>> {
        (self.methods.iter())
            .map(|m| (m.name.to_string(), m.time_us_per_frame))
            .collect()
    }

    /// The summary's section: the answer first, then the table beside the paper.
    pub fn markdown(&self) -> String {
        let mut s = String::from("\n## Earth sensor [003]: attitude angle β\n\n");
        if self.frames == 0 {
            s.push_str("**No Earth frame was answered and scored.**\n");
            return s;
        }
        let f = |v: Option<f64>, d: usize| v.map_or("—".to_string(), |v| format!("{v:.d$}"));
        let (cross, hough) = (
            self.sigma_within_10("cross_product"),
            self.sigma_within_10("hough"),
        );
        let ratio = match (cross, hough) {
            (Some(c), Some(h)) if h > 0.0 => format!(" — {:.2}× the baseline's", c / h),
            _ => String::new(),
        };
        let _ = writeln!(
            s,
            "**β error σ within ±10°: cross product {}° (paper {PAPER_SIGMA_CROSS_DEG}°), Hough \
             baseline {}° (paper {PAPER_SIGMA_HOUGH_DEG}°){ratio}; the lookup version takes {}× \
             the baseline's time per frame (paper {PAPER_LOOKUP_TIME_RATIO}×).**\n",
            f(cross, 4),
            f(hough, 4),
            f(self.lookup_time_ratio(), 2),
        );
        let _ = writeln!(
            s,
            "Error = sign(tilt)·β − turntable angle over {} frames; mean / σ / max |error| in \
             degrees per interval of |angle|; time per frame includes the shared edge \
             extraction (this machine, not part of the deterministic results).\n",
            self.frames
        );
        let _ = writeln!(
            s,
            "| method | ≤ 10° | 10–40° | 40–50° | not determined | time/frame [µs] |\n|---|---|---|---|---|---|"
        );
        let missed = |m: &MethodScore| {
            let why: Vec<String> = (m.not_determined.iter())
                .map(|(k, v)| format!("{} {v}", k.replace('_', " ")))
                .collect();
            match why.is_empty() {
                true => m.missed.to_string(),
                false => format!("{} ({})", m.missed, why.join(", ")),
            }
        };
        for m in &self.methods {
            let cell = |i: &IntervalScore| {
                if i.frames == 0 {
                    "—".to_string()
                } else {
                    format!(
                        "{:+.4} / {:.4} / {:.4} ({})",
                        i.err_mean_deg, i.err_sigma_deg, i.err_max_deg, i.frames
                    )
                }
            };
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {} |",
                m.name,
                cell(&m.intervals[0]),
                cell(&m.intervals[1]),
                cell(&m.intervals[2]),
                missed(m),
                f(m.time_us_per_frame, 0)
            );
        }
        s.push_str(
            "\n![error against angle](earth-errors.svg)\n\n![β_k samples and the fitted t \
             density](earth-samples.svg)\n\n![annotated Earth frame](earth-frame-annotated.svg)\n",
        );
        s
    }
}

/// `earth-errors.svg`: every method's error against the turntable angle (the paper's
/// Figs. 11–13 in one chart).
pub fn error_plot(dir: &Path, score: &EarthScore) -> Result<()> {
    let colors = [BLUE, GREEN, RED];
    let series: Vec<Series> = (score.methods.iter().zip(colors))
        .map(|(m, color)| Series {
            label: m.name,
            points: m.errors.clone(),
            color,
            markers: true,
        })
        .collect();
    line_chart(
        &dir.join("earth-errors.svg"),
        "Attitude-angle error against the turntable angle, per method",
        "turntable angle [deg]",
        "sign(tilt)·β − angle [deg]",
        &series,
    )
}

/// The β_k samples of one frame and their fitted t density, as the earth service sent them.
pub struct SampleFigure {
    /// The frame's turntable angle [deg].
    pub angle_deg: f64,
    /// β_k samples in all.
    pub samples: u32,
    /// Their histogram over μ ± span·σ ([`EarthAttitude::samples_hist`]).
    pub hist: [u16; EarthAttitude::SAMPLE_BINS],
    /// The t location-scale fit (μ, σ [deg], ν), when there was one.
    pub fit: Option<(f64, f64, f64)>,
}

/// The answered frames at the turntable angles nearest `angles` (the paper's Figs. 6, 14 and
/// 15 are at 5°, 30° and 60°; a sweep that stops short gives its largest), each once: their
/// β_k histograms and fits, from the answers themselves.
pub fn sample_figures(
    answers: &[EarthAttitude],
    truths: &[Truth],
    angles: &[f64],
) -> Vec<SampleFigure> {
    let truth: BTreeMap<u64, f64> = (truths.iter())
        .filter(|t| t.kind == Truth::KIND_EARTH)
        .map(|t| (t.frame_index, t.earth_tilt_deg))
        .collect();
    let answered: Vec<(&EarthAttitude, f64)> = (answers.iter())
        .filter_map(|a| truth.get(&a.frame_index).map(|tilt| (a, *tilt)))
        .collect();
    let mut out: Vec<SampleFigure> = vec![];
    for &want in angles {
        let nearest = (answered.iter())
            .min_by(|(_, x), (_, y)| (x.abs() - want).abs().total_cmp(&(y.abs() - want).abs()));
        let Some((a, tilt)) = nearest else { continue };
        if out.iter().any(|f| f.angle_deg == tilt.abs()) {
            continue;
        }
        out.push(SampleFigure {
            angle_deg: tilt.abs(),
            samples: a.samples,
            hist: a.samples_hist,
            fit: (a.fit_sigma_deg > 0.0).then_some((a.fit_mu_deg, a.fit_sigma_deg, a.fit_nu)),
        });
    }
    out
}

/// The t location-scale density at `x` of the fit (μ, σ, ν).
fn t_density((mu, sigma, nu): (f64, f64, f64), x: f64) -> f64 {
    let z = (x - mu) / sigma;
    let ln_c = glint_earth::special::ln_gamma((nu + 1.0) / 2.0)
        - glint_earth::special::ln_gamma(nu / 2.0)
        - 0.5 * (nu * std::f64::consts::PI).ln()
        - sigma.ln();
    (ln_c - (nu + 1.0) / 2.0 * (z * z / nu).ln_1p()).exp()
}

/// `earth-samples.svg`: each figure's samples as a normalised histogram (steps) about its
/// fitted μ, and the fitted t density (markers), against β_k − μ.
pub fn samples_plot(dir: &Path, figures: &[SampleFigure]) -> Result<()> {
    let colors = [BLUE, GREEN, ORANGE];
    let mut labels = vec![];
    for f in figures {
        let fit = f.fit.map_or("no fit".to_string(), |(mu, sigma, nu)| {
            // ν at the fit's upper bound: the samples are normal.
            let nu = if nu >= 1e5 {
                "ν → ∞".to_string()
            } else {
                format!("ν {nu:.1}")
            };
            format!("μ {mu:.3}°, σ {sigma:.3}°, {nu}")
        });
        labels.push((
            format!("{}°: β_k ({} samples)", f.angle_deg, f.samples),
            format!("{}°: fitted t ({fit})", f.angle_deg),
        ));
    }
    let bins = EarthAttitude::SAMPLE_BINS;
    let mut series = vec![];
    for ((f, color), (hist_label, fit_label)) in figures.iter().zip(colors).zip(&labels) {
        let Some(fit) = f.fit else { continue };
        let half = EarthAttitude::SAMPLE_SPAN_SIGMA * fit.1;
        let width = 2.0 * half / bins as f64;
        let n = f64::from(f.samples.max(1));
        let mut steps = vec![];
        for (k, c) in f.hist.iter().enumerate() {
            let (x0, x1) = (-half + k as f64 * width, -half + (k + 1) as f64 * width);
            let d = f64::from(*c) / (n * width);
            steps.push((x0, d));
            steps.push((x1, d));
        }
        series.push(Series {
            label: hist_label,
            points: steps,
            color,
            markers: false,
        });
        series.push(Series {
            label: fit_label,
            points: (0..=bins)
                .map(|k| {
                    let x = -half + k as f64 * width;
                    (x, t_density(fit, fit.0 + x))
                })
                .collect(),
            color,
            markers: true,
        });
    }
    line_chart(
        &dir.join("earth-samples.svg"),
        "β_k samples of one frame and their fitted t location-scale density",
        "β_k − μ [deg]",
        "density [1/deg]",
        &series,
    )
}

/// What `glint run` prints of the Earth sensor (to stderr, the summary's path staying alone on
/// stdout): the figures beside the paper's and a line per method, from the report.
pub fn console(report: &super::Report) -> Option<String> {
    let methods = &report.results.earth.as_ref()?.methods;
    let times = &report.timing.earth_us_per_frame;
    let sigma = |m: &str, pick: fn(&MethodReport) -> &IntervalReport| {
        methods.get(m).and_then(|r| pick(r).err_sigma_deg)
    };
    let deg = |v: Option<f64>| v.map_or("—".to_string(), |v| format!("{v:.4}°"));
    let time = |m: &str| times.get(m).copied().flatten();
    let ratio = match (time("lookup"), time("hough")) {
        (Some(l), Some(h)) if h > 0.0 => format!("{:.2}×", l / h),
        _ => "—".into(),
    };
    let mut s = format!(
        "Earth sensor [003]: β error σ within ±10°: cross product {} (paper {PAPER_SIGMA_CROSS_DEG}°), \
         Hough baseline {} (paper {PAPER_SIGMA_HOUGH_DEG}°); lookup time {ratio} the baseline's \
         (paper {PAPER_LOOKUP_TIME_RATIO}×)\n",
        deg(sigma("cross_product", |r| &r.within_10)),
        deg(sigma("hough", |r| &r.within_10)),
    );
    let _ = writeln!(
        s,
        "  {:<14} {:>10} {:>10} {:>10} {:>12} {:>14}",
        "method", "σ ≤10°", "σ 10–40°", "σ 40–50°", "max 40–50°", "time/frame"
    );
    for m in EarthAttitude::METHOD_NAMES {
        let _ = writeln!(
            s,
            "  {:<14} {:>10} {:>10} {:>10} {:>12} {:>14}",
            m,
            deg(sigma(m, |r| &r.within_10)),
            deg(sigma(m, |r| &r.from_10_to_40)),
            deg(sigma(m, |r| &r.from_40_to_50)),
            deg(methods.get(m).and_then(|r| r.from_40_to_50.err_max_deg)),
            time(m).map_or("—".into(), |t| format!("{t:.0} µs")),
        );
    }
    Some(s)
}

/// `earth` in report.json: each method's error per interval of the paper.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct EarthReport {
    /// Frames with both an answer and a truth.
    pub frames: u64,
    /// By method: cross_product, lookup, hough.
    pub methods: BTreeMap<String, MethodReport>,
    pub paper: EarthPaper,
}

/// One method's error per interval of |angle|.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct MethodReport {
    pub within_10: IntervalReport,
    #[serde(rename = "10_to_40")]
    pub from_10_to_40: IntervalReport,
    #[serde(rename = "40_to_50")]
    pub from_40_to_50: IntervalReport,
    /// Frames with truth the method gave no answer on: the frame did not determine its β.
    pub missed: u64,
    /// Those frames by the reason the method gave: no_limb, imprecise, off_the_limb,
    /// circle_model_bias, mode_off_location (docs/earth-sensor.md, "Not determined").
    pub not_determined: BTreeMap<String, u64>,
    /// Frames outside the paper's intervals (|angle| > 50°).
    pub outside_intervals: u64,
}

/// Error statistics over one interval [deg] (absent without frames there).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct IntervalReport {
    pub frames: u64,
    pub err_mean_deg: Option<f64>,
    /// Sample standard deviation about the mean (n − 1).
    pub err_sigma_deg: Option<f64>,
    /// Largest |error|.
    pub err_max_deg: Option<f64>,
}

/// The paper's figures (math.md §4.8).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct EarthPaper {
    pub cross_product_sigma_within_10_deg: f64,
    pub hough_sigma_within_10_deg: f64,
    pub lookup_time_over_hough: f64,
}
