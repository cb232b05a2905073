//! [004] stereo relative navigation: the filter's estimates against the sensor's truth, RTMSE
//! per state group over the last 50 minutes (math.md eqs 40–41), NEES, each group's error and
//! 3σ bound over time, and the inertia estimated against the true one (up to scale).

use std::collections::HashMap;
use std::path::Path;

use anyhow::Result;
use glint_physics::rigid_body::inertia_from_k;
use glint_relnav::model::{ErrMat, Nominal};
use glint_relnav::score::Score;
use nalgebra::{Quaternion, UnitQuaternion, Vector2, Vector3};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use shared_types::{RelNavEstimate, Scenario, TopicId, Truth};

use super::{Material, Section};
use crate::plots::{line_chart, thin_by_half, Series, BLUE, GREEN, GREY, ORANGE, PURPLE, RED};
use crate::report::{Results, Timing};
use crate::run::taps::Fold;

/// The scoring window: the last 50 minutes (the whole run when shorter).
const WINDOW_S: f64 = 3000.0;
/// Points kept per plotted series (a long run's series are thinned by half).
const MAX_POINTS: usize = 4000;

/// `relnav.rtmse` and the paper's figures.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct RelNavErrors {
    pub attitude_deg: f64,
    pub rate_rad_s: f64,
    pub inertia_k: f64,
    pub position_m: f64,
    pub velocity_m_s: f64,
}

impl RelNavErrors {
    fn from_groups(g: [f64; 5]) -> Self {
        RelNavErrors {
            attitude_deg: g[0].to_degrees(),
            rate_rad_s: g[1],
            inertia_k: g[2],
            position_m: g[3],
            velocity_m_s: g[4],
        }
    }
}

/// Per state group, the fraction of the window's epochs whose every component lay within 3σ.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct RelNavShares {
    pub attitude: f64,
    pub rate: f64,
    pub inertia_k: f64,
    pub position: f64,
    pub velocity: f64,
}

/// What the filter did over the run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct RelNavEvents {
    /// Epochs answered with an estimate, and while starting from the measurements.
    pub estimates: u64,
    pub starting_epochs: u64,
    /// Starts from the measurements (the first included), restarts after a divergence, after
    /// a numerical failure.
    pub starts: u32,
    pub diverged: u32,
    pub numerical_failures: u32,
    /// Features used by the updates and refused by the gate.
    pub features_used: u64,
    pub features_rejected: u64,
}

/// `relnav` in report.json.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct RelNavReport {
    /// The scoring window [s]: the last 50 minutes of the run.
    pub window_s: [f64; 2],
    pub epochs_scored: u64,
    /// RTMSE per state group over the window (eq 40; attitude by eq 41).
    pub rtmse: RelNavErrors,
    /// Mean NEES over the window (14 expected) and its 95 % interval for one run.
    pub nees_mean: f64,
    pub nees_95: [f64; 2],
    /// Fraction of the window's epochs whose every component lay within 3σ, per group.
    pub within_3sigma: RelNavShares,
    /// J / tr J: true and estimated at the last epoch.
    pub inertia_true: [f64; 3],
    pub inertia_estimated: [f64; 3],
    pub filter: RelNavEvents,
    /// The paper's figures (200 runs, last 50 minutes; its own, lost, case).
    pub paper: RelNavErrors,
}

/// One plotted epoch: time, each group's error and 3σ bound (the root of the block's trace),
/// the estimated J / tr J.
type Point = (f64, [f64; 5], [f64; 5], [f64; 3]);

/// Truths and estimates matched by epoch as they arrive; the window's sums and a thinned
/// series kept (memory bounded however long the run).
pub(super) struct RelNavFold {
    window_from_s: f64,
    truths: HashMap<u64, Nominal>,
    estimates: HashMap<u64, RelNavEstimate>,
    score: Score,
    series: Vec<Point>,
    stride: u64,
    matched: u64,
    last: Option<RelNavEstimate>,
    k_true: Vector2<f64>,
    events: RelNavEvents,
}

fn nominal(q: [f64; 4], w: [f64; 3], k: [f64; 2], rho: [f64; 3], v: [f64; 3]) -> Nominal {
    Nominal {
        q_ct: UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3])),
        w_t: Vector3::from(w),
        k: Vector2::from(k),
        rho_o: Vector3::from(rho),
        v_o: Vector3::from(v),
    }
}

fn covariance(m: &RelNavEstimate) -> ErrMat {
    ErrMat::from_fn(|i, j| m.cov(i, j))
}

impl RelNavFold {
    fn new(duration_s: f64) -> Self {
        RelNavFold {
            window_from_s: (duration_s - WINDOW_S).max(0.0),
            truths: HashMap::new(),
            estimates: HashMap::new(),
            score: Score::default(),
            series: Vec::new(),
            stride: 1,
            matched: 0,
            last: None,
            k_true: Vector2::zeros(),
            events: RelNavEvents {
                estimates: 0,
                starting_epochs: 0,
                starts: 0,
                diverged: 0,
                numerical_failures: 0,
                features_used: 0,
                features_rejected: 0,
            },
        }
    }

    fn matched(&mut self, m: &RelNavEstimate, truth: &Nominal) {
        let x = nominal(m.q_ct, m.w_t_rad_s, m.k, m.rho_o_m, m.v_o_m_s);
        let p = covariance(m);
        let t_s = m.meta.t_ns as f64 * 1e-9;
        if t_s >= self.window_from_s {
            self.score.add(&x, &p, truth);
        }
        if self.matched % self.stride == 0 {
            let e = glint_relnav::filter::group_errors(&x, truth);
            let bound = glint_relnav::filter::GROUPS.map(|(_, first, size)| {
                3.0 * (first..first + size).map(|i| p[(i, i)]).sum::<f64>().sqrt()
            });
            let j = inertia_from_k(x.k);
            self.series.push((t_s, e, bound, [j.x, j.y, j.z]));
            if self.series.len() > MAX_POINTS {
                thin_by_half(&mut self.series);
                self.stride *= 2;
            }
        }
        self.matched += 1;
    }
}

impl Fold for RelNavFold {
    fn take(&mut self, _topic: TopicId, msg: &dyn std::any::Any) {
        if let Some(t) = msg.downcast_ref::<Truth>() {
            if t.kind != Truth::KIND_STEREO {
                return;
            }
            let s = &t.target_state;
            let truth = nominal(
                [s[0], s[1], s[2], s[3]],
                [s[4], s[5], s[6]],
                [s[7], s[8]],
                [s[9], s[10], s[11]],
                [s[12], s[13], s[14]],
            );
            self.k_true = truth.k;
            match self.estimates.remove(&t.frame_index) {
                Some(m) => self.matched(&m, &truth),
                None => {
                    self.truths.insert(t.frame_index, truth);
                }
            }
        } else if let Some(m) = msg.downcast_ref::<RelNavEstimate>() {
            let ev = &mut self.events;
            (ev.starts, ev.diverged, ev.numerical_failures) =
                (m.starts, m.diverged, m.numerical_failures);
            if m.status == RelNavEstimate::STARTING {
                ev.starting_epochs += 1;
                self.truths.remove(&m.epoch_index);
                return;
            }
            ev.estimates += 1;
            ev.features_used += m.used as u64;
            ev.features_rejected += m.rejected as u64;
            self.last = Some(*m);
            match self.truths.remove(&m.epoch_index) {
                Some(truth) => self.matched(m, &truth),
                None => {
                    self.estimates.insert(m.epoch_index, *m);
                }
            }
        }
    }
    fn as_any(&self) -> &dyn std::any::Any {
        self
    }
}

/// [004] the relative-navigation section.
pub(super) struct RelNavSection {
    report: RelNavReport,
    series: Vec<Point>,
}

impl RelNavSection {
    pub(super) fn fold(scenario: &Scenario) -> Option<RelNavFold> {
        (scenario.stereo.as_ref()).map(|s| RelNavFold::new(s.duration_s))
    }

    pub(super) fn collect(m: &Material<'_>) -> Option<Self> {
        let s = m.scenario.stereo.as_ref()?;
        let fold = m.taps.fold::<RelNavFold>()?;
        let j_true = inertia_from_k(fold.k_true);
        let j_est = fold.last.map_or([f64::NAN; 3], |l| {
            let j = inertia_from_k(Vector2::from(l.k));
            [j.x, j.y, j.z]
        });
        let n = fold.score.epochs.max(1) as f64;
        let within = fold.score.within_3sigma.map(|c| c as f64 / n);
        let report = RelNavReport {
            window_s: [fold.window_from_s, s.duration_s],
            epochs_scored: fold.score.epochs,
            rtmse: RelNavErrors::from_groups(fold.score.rtmse()),
            nees_mean: fold.score.nees_mean(),
            nees_95: {
                let (lo, hi) = Score::nees_interval(1);
                [lo, hi]
            },
            within_3sigma: RelNavShares {
                attitude: within[0],
                rate: within[1],
                inertia_k: within[2],
                position: within[3],
                velocity: within[4],
            },
            inertia_true: [j_true.x, j_true.y, j_true.z],
            inertia_estimated: j_est,
            filter: fold.events.clone(),
            paper: RelNavErrors {
                attitude_deg: 0.1,
                rate_rad_s: 6e-5,
                inertia_k: 0.02,
                position_m: 0.010,
                velocity_m_s: 10e-6,
            },
        };
        Some(RelNavSection {
            report,
            series: fold.series.clone(),
        })
    }
}

impl Section for RelNavSection {
    fn report(&self, results: &mut Results, _timing: &mut Timing) {
        results.relnav = Some(self.report.clone());
    }

    fn markdown(&self) -> String {
        let r = &self.report;
        let (e, p, w) = (&r.rtmse, &r.paper, &r.within_3sigma);
        let f = &r.filter;
        format!(
            "## [004] Relative navigation of the tumbling target\n\n\
             RTMSE over t = {:.0}–{:.0} s ({} epochs), one run; the paper's over 200 runs of its own case.\n\n\
             | group | glint | within 3σ | paper |\n|---|---|---|---|\n\
             | attitude | {:.4}° | {:.1} % | < {}° |\n\
             | angular velocity | {:.2e} rad/s | {:.1} % | < {:.0e} rad/s |\n\
             | inertia parameters k | {:.2e} | {:.1} % | ≤ {} |\n\
             | position | {:.3} mm | {:.1} % | ≤ {:.0} mm |\n\
             | velocity | {:.3} µm/s | {:.1} % | < {:.0} µm/s |\n\n\
             Mean NEES {:.2} (14 expected; 95 % interval for one run {:.1}–{:.1}). J / tr J true \
             ({:.4}, {:.4}, {:.4}), estimated ({:.4}, {:.4}, {:.4}).\n\n\
             Filter: {} estimates, {} epochs starting, {} start(s), {} divergence restart(s), {} \
             numerical failure(s); features used {}, refused {}.\n\n",
            r.window_s[0],
            r.window_s[1],
            r.epochs_scored,
            e.attitude_deg,
            100.0 * w.attitude,
            p.attitude_deg,
            e.rate_rad_s,
            100.0 * w.rate,
            p.rate_rad_s,
            e.inertia_k,
            100.0 * w.inertia_k,
            p.inertia_k,
            e.position_m * 1e3,
            100.0 * w.position,
            p.position_m * 1e3,
            e.velocity_m_s * 1e6,
            100.0 * w.velocity,
            p.velocity_m_s * 1e6,
            r.nees_mean,
            r.nees_95[0],
            r.nees_95[1],
            r.inertia_true[0],
            r.inertia_true[1],
            r.inertia_true[2],
            r.inertia_estimated[0],
            r.inertia_estimated[1],
            r.inertia_estimated[2],
            f.estimates,
            f.starting_epochs,
            f.starts,
            f.diverged,
            f.numerical_failures,
            f.features_used,
            f.features_rejected,
        )
    }

    /// Each group's error and 3σ bound over time (the paper's figures), and J / tr J.
    fn plots(&self, dir: &Path) -> Result<()> {
        let groups: [(&str, &str, f64); 5] = [
            (
                "attitude",
                "attitude error [deg]",
                180.0 / std::f64::consts::PI,
            ),
            ("rate", "angular-velocity error [rad/s]", 1.0),
            ("inertia-k", "inertia-parameter error |Δk|", 1.0),
            ("position", "position error [mm]", 1e3),
            ("velocity", "velocity error [µm/s]", 1e6),
        ];
        for (g, (name, label, scale)) in groups.iter().enumerate() {
            let series = [
                Series {
                    label: "error",
                    points: self.series.iter().map(|p| (p.0, p.1[g] * scale)).collect(),
                    color: BLUE,
                    markers: false,
                },
                Series {
                    label: "3σ (root of the block's trace)",
                    points: self.series.iter().map(|p| (p.0, p.2[g] * scale)).collect(),
                    color: RED,
                    markers: false,
                },
            ];
            line_chart(
                &dir.join(format!("relnav-{name}.svg")),
                &format!("[004] {label} and its 3σ bound"),
                "t [s]",
                label,
                &series,
            )?;
        }
        let t_end = self.series.last().map_or(0.0, |p| p.0);
        let t0 = self.series.first().map_or(0.0, |p| p.0);
        let truth = self.report.inertia_true;
        let colors = [BLUE, GREEN, ORANGE];
        let names = ["Jxx/trJ", "Jyy/trJ", "Jzz/trJ"];
        let mut series: Vec<Series> = (0..3)
            .map(|i| Series {
                label: names[i],
                points: self.series.iter().map(|p| (p.0, p.3[i])).collect(),
                color: colors[i],
                markers: false,
            })
            .collect();
        for (i, label) in ["true Jxx/trJ", "true Jyy/trJ", "true Jzz/trJ"]
            .iter()
            .enumerate()
        {
            series.push(Series {
                label,
                points: vec![(t0, truth[i]), (t_end, truth[i])],
                color: [GREY, PURPLE, RED][i],
                markers: false,
            });
        }
        line_chart(
            &dir.join("relnav-inertia.svg"),
            "[004] inertia estimated against the truth (J / tr J)",
            "t [s]",
            "J / tr J",
            &series,
        )
    }
}
