//! [001] ground photometry: the service's identification against the truth (geometry, spin,
//! size, axis, every geometry's best), the UKF's attitude error and NEES, and the pictures:
//! the observed light curve with the best database match and the UKF's predicted curve, and
//! the attitude error with its 3σ bound over time.

use std::collections::HashMap;
use std::path::Path;

use anyhow::Result;
use glint_photometry::grp::Grp;
use glint_photometry::spin::spin_attitude;
use glint_physics::photometry::{apparent_magnitude, normalised_flux, Shape, SpecularDenominator};
use nalgebra::{Matrix6, Quaternion, Unit, UnitQuaternion, Vector3, Vector6};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use shared_types::{PhotometryEstimate, PhotometrySample, Scenario, TopicId, Truth};
use statrs::distribution::{ChiSquared, ContinuousCDF};

use super::{Material, Section};
use crate::plots::{line_chart, thin_by_half, Series, BLUE, GREY, ORANGE, RED};
use crate::report::{Results, Timing};
use crate::run::taps::Fold;

/// Points kept per plotted series (a long arc's series are thinned by half).
const MAX_POINTS: usize = 4000;
const DEN: SpecularDenominator = SpecularDenominator::Linares2014;

/// One geometry's best fit, as report.json gives it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct PhotometryMatchReport {
    pub geometry: String,
    /// Matching degree F / P̄ (0: a perfect match).
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    pub score: f64,
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    pub area_scale: f64,
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    pub area_m2: f64,
    #[serde(deserialize_with = "crate::report::model::triple_or_nan")]
    pub axis: [f64; 3],
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    pub spin_rad_s: f64,
}

/// `photometry.identification`: glint's answer beside the truth.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct PhotometryIdentification {
    /// The identified geometry (`None`: the arc fitted none).
    pub geometry: Option<String>,
    pub truth_geometry: String,
    pub correct: bool,
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    pub spin_rad_s: f64,
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    pub truth_spin_rad_s: f64,
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    pub area_m2: f64,
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    pub truth_area_m2: f64,
    /// The spin axis (ECI) and its angle from the true one [deg].
    #[serde(deserialize_with = "crate::report::model::triple_or_nan")]
    pub axis: [f64; 3],
    #[serde(deserialize_with = "crate::report::model::triple_or_nan")]
    pub truth_axis: [f64; 3],
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    pub axis_error_deg: f64,
    /// The angle to the true axis's mirror image through the plane of the arc's mean Sun and
    /// observer directions, `−v + 2(v·n)n` [deg]: a mirror-symmetric shape spinning about it
    /// shows the same light curve, so one arc cannot tell the two apart.
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    pub axis_error_mirror_deg: f64,
    /// When the identification was made [s].
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    pub at_s: f64,
    /// Every geometry's best, best first.
    pub matching: Vec<PhotometryMatchReport>,
}

/// `photometry.ukf`: the attitude filter against the truth.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct PhotometryUkf {
    /// Samples answered while tracking, and of them the ones that updated the filter.
    pub samples_tracked: u64,
    pub updates: u64,
    /// Attitude error at the last sample [deg], its 3σ bound, and the time of data it had
    /// [s] (from the first sample of the arc).
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    pub attitude_err_deg_final: f64,
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    pub attitude_3sigma_deg_final: f64,
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    pub data_s: f64,
    /// Body-rate error at the last sample [rad/s].
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    pub rate_err_rad_s_final: f64,
    /// Mean NEES over the tracked samples (6 expected) and its 95 % interval for one run.
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    pub nees_mean: f64,
    #[serde(deserialize_with = "crate::report::model::pair_or_nan")]
    pub nees_95: [f64; 2],
    /// Steps taken again with γ = 1; filter restarts from the identification.
    pub fallbacks: u32,
    pub restarts: u32,
}

/// The light curve's samples by status.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct PhotometrySamples {
    pub total: u64,
    pub seen: u64,
    pub shadow: u64,
    pub below_horizon: u64,
    pub no_flux: u64,
}

/// `photometry` in report.json.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct PhotometryReport {
    pub identification: PhotometryIdentification,
    pub ukf: PhotometryUkf,
    pub samples: PhotometrySamples,
}

/// The truth of one sample: q_IB, body rate.
#[derive(Clone, Copy)]
struct TruthState {
    q: UnitQuaternion<f64>,
    w: Vector3<f64>,
}

/// One plotted sample: time, attitude error and 3σ bound [deg], the UKF's predicted magnitude.
type Point = (f64, f64, f64, Option<f64>);

/// Samples kept for the light-curve picture; truths and estimates matched by sample index.
pub(super) struct PhotometryFold {
    shapes: Vec<(String, Shape)>,
    samples: Vec<PhotometrySample>,
    truths: HashMap<u64, TruthState>,
    estimates: HashMap<u64, PhotometryEstimate>,
    truth_const: Option<(usize, f64, f64, Vector3<f64>)>,
    last: Option<(PhotometryEstimate, TruthState)>,
    first_tracking_s: Option<f64>,
    nees_sum: f64,
    nees_n: u64,
    updates: u64,
    series: Vec<Point>,
    stride: u64,
    matched: u64,
    counts: PhotometrySamples,
    /// The estimated shape at its size, by (geometry, area scale bits).
    estimated_shape: Option<((u32, u64), Shape)>,
}

fn quaternion(q: [f64; 4]) -> UnitQuaternion<f64> {
    UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3]))
}

fn angle_deg(a: &UnitQuaternion<f64>, b: &UnitQuaternion<f64>) -> f64 {
    a.angle_to(b).to_degrees()
}

impl PhotometryFold {
    fn new(shapes: Vec<(String, Shape)>, samples: u64) -> Self {
        PhotometryFold {
            shapes,
            samples: Vec::with_capacity(samples as usize),
            truths: HashMap::new(),
            estimates: HashMap::new(),
            truth_const: None,
            last: None,
            first_tracking_s: None,
            nees_sum: 0.0,
            nees_n: 0,
            updates: 0,
            series: vec![],
            stride: 1,
            matched: 0,
            counts: PhotometrySamples {
                total: 0,
                seen: 0,
                shadow: 0,
                below_horizon: 0,
                no_flux: 0,
            },
            estimated_shape: None,
        }
    }

    /// The UKF's predicted magnitude for sample `k` with the estimate's shape and attitude.
    fn predicted_mag(&mut self, m: &PhotometryEstimate) -> Option<f64> {
        let s = self.samples.get(m.sample_index as usize)?;
        if s.status != PhotometrySample::SEEN {
            return None;
        }
        let best = m.best()?;
        let key = (best.geometry, best.area_scale.to_bits());
        if self.estimated_shape.as_ref().is_none_or(|(k, _)| *k != key) {
            let (_, shape) = self.shapes.get(best.geometry as usize)?;
            self.estimated_shape = Some((key, shape.scaled(best.area_scale.sqrt())));
        }
        let shape = &self.estimated_shape.as_ref()?.1;
        let inv = quaternion(m.q_ib).inverse();
        let flux = normalised_flux(
            shape,
            &(inv * Vector3::from(s.sun)),
            &(inv * Vector3::from(s.obs)),
            DEN,
        );
        apparent_magnitude(flux, s.range_m)
    }

    fn matched(&mut self, m: &PhotometryEstimate, truth: TruthState) {
        if m.status != PhotometryEstimate::TRACKING {
            return;
        }
        let t_s = m.meta.t_ns as f64 * 1e-9;
        self.first_tracking_s.get_or_insert(t_s);
        let q_hat = quaternion(m.q_ib);
        let p = Matrix6::from_fn(|i, j| m.cov(i, j));
        let dp = Grp::default().from_quaternion(&(q_hat.inverse() * truth.q));
        let dw = truth.w - Vector3::from(m.w_body_rad_s);
        let e = Vector6::new(dp.x, dp.y, dp.z, dw.x, dw.y, dw.z);
        if let Some(ch) = p.cholesky() {
            self.nees_sum += e.dot(&ch.solve(&e));
            self.nees_n += 1;
        }
        self.updates += m.updated as u64;
        if self.matched % self.stride == 0 {
            let bound = 3.0 * (p[(0, 0)] + p[(1, 1)] + p[(2, 2)]).sqrt().to_degrees();
            let predicted = self.predicted_mag(m);
            self.series
                .push((t_s, angle_deg(&q_hat, &truth.q), bound, predicted));
            if self.series.len() > MAX_POINTS {
                thin_by_half(&mut self.series);
                self.stride *= 2;
            }
        }
        self.matched += 1;
        self.last = Some((*m, truth));
    }
}

impl Fold for PhotometryFold {
    fn take(&mut self, topic: TopicId, msg: &dyn std::any::Any) {
        if let Some(t) = msg.downcast_ref::<Truth>() {
            if t.kind != Truth::KIND_PHOTOMETRY {
                return;
            }
            let s = &t.target_state;
            let truth = TruthState {
                q: quaternion([s[0], s[1], s[2], s[3]]),
                w: Vector3::new(s[4], s[5], s[6]),
            };
            let axis = (truth.q * truth.w).normalize();
            self.truth_const = Some((s[7] as usize, s[8], s[9], axis));
            match self.estimates.remove(&t.frame_index) {
                Some(m) => self.matched(&m, truth),
                None => {
                    self.truths.insert(t.frame_index, truth);
                }
            }
        } else if let Some(s) = msg.downcast_ref::<PhotometrySample>() {
            if topic != TopicId::Photometry {
                return;
            }
            let c = &mut self.counts;
            c.total += 1;
            match s.status {
                PhotometrySample::SEEN => c.seen += 1,
                PhotometrySample::SHADOW => c.shadow += 1,
                PhotometrySample::BELOW_HORIZON => c.below_horizon += 1,
                _ => c.no_flux += 1,
            }
            if s.sample_index as usize == self.samples.len() {
                self.samples.push(*s);
            }
        } else if let Some(m) = msg.downcast_ref::<PhotometryEstimate>() {
            match self.truths.remove(&m.sample_index) {
                Some(truth) => self.matched(m, truth),
                None => {
                    self.estimates.insert(m.sample_index, *m);
                }
            }
        }
    }
    fn as_any(&self) -> &dyn std::any::Any {
        self
    }
}

/// The axis `v`'s photometric mirror: `−v + 2(v·n)n`, `n` the normal of the plane of the
/// seen samples' mean Sun and observer directions.
fn mirror_axis(v: &Vector3<f64>, samples: &[PhotometrySample]) -> Vector3<f64> {
    let seen = samples
        .iter()
        .filter(|s| s.status == PhotometrySample::SEEN);
    let (sun, obs) = seen.fold((Vector3::zeros(), Vector3::zeros()), |(a, b), s| {
        (a + Vector3::from(s.sun), b + Vector3::from(s.obs))
    });
    match sun.cross(&obs).try_normalize(1e-12) {
        Some(n) => -v + n * (2.0 * v.dot(&n)),
        None => *v,
    }
}

/// [001] the ground-photometry section.
pub(super) struct PhotometrySection {
    report: PhotometryReport,
    series: Vec<Point>,
    /// Observed (t, mag) and the best match's (t, mag).
    observed: Vec<(f64, f64)>,
    matched_curve: Vec<(f64, f64)>,
}

impl PhotometrySection {
    pub(super) fn fold(scenario: &Scenario) -> Option<PhotometryFold> {
        let p = scenario.photometry.as_ref()?;
        // The run's sensor has read the same file; a failure here leaves the names empty.
        let shapes = glint_photometry::shapes::read_shapes(&p.shapes).unwrap_or_default();
        Some(PhotometryFold::new(shapes, p.samples()))
    }

    pub(super) fn collect(m: &Material<'_>) -> Option<Self> {
        let p = m.scenario.photometry.as_ref()?;
        let fold = m.taps.fold::<PhotometryFold>()?;
        let name = |g: usize| fold.shapes.get(g).map(|(n, _)| n.clone());
        let (_, truth_area, truth_spin, truth_axis) =
            fold.truth_const
                .unwrap_or((0, f64::NAN, f64::NAN, Vector3::from_element(f64::NAN)));
        let last = fold.last.as_ref();
        let best = last.and_then(|(e, _)| e.best().copied());
        let matching: Vec<PhotometryMatchReport> = last
            .map(|(e, _)| e.matches().to_vec())
            .unwrap_or_default()
            .iter()
            .map(|x| PhotometryMatchReport {
                geometry: name(x.geometry as usize).unwrap_or_default(),
                score: x.score,
                area_scale: x.area_scale,
                area_m2: x.area_m2,
                axis: x.axis,
                spin_rad_s: x.spin_rad_s,
            })
            .collect();
        let geometry = best.and_then(|b| name(b.geometry as usize));
        let nan3 = [f64::NAN; 3];
        let identification = PhotometryIdentification {
            correct: geometry.as_deref() == Some(p.geometry.as_str()),
            geometry,
            truth_geometry: p.geometry.clone(),
            spin_rad_s: best.map_or(f64::NAN, |b| b.spin_rad_s),
            truth_spin_rad_s: truth_spin,
            area_m2: best.map_or(f64::NAN, |b| b.area_m2),
            truth_area_m2: truth_area,
            axis: best.map_or(nan3, |b| b.axis),
            truth_axis: truth_axis.into(),
            axis_error_deg: best.map_or(f64::NAN, |b| {
                Vector3::from(b.axis).angle(&truth_axis).to_degrees()
            }),
            axis_error_mirror_deg: best.map_or(f64::NAN, |b| {
                Vector3::from(b.axis)
                    .angle(&mirror_axis(&truth_axis, &fold.samples))
                    .to_degrees()
            }),
            at_s: fold.first_tracking_s.unwrap_or(f64::NAN),
            matching,
        };
        let chi = ChiSquared::new(6.0).ok()?;
        let t_first = fold
            .samples
            .first()
            .map_or(0.0, |s| s.meta.t_ns as f64 * 1e-9);
        let ukf = match last {
            Some((e, truth)) => {
                let q_hat = quaternion(e.q_ib);
                PhotometryUkf {
                    samples_tracked: fold.matched,
                    updates: fold.updates,
                    attitude_err_deg_final: angle_deg(&q_hat, &truth.q),
                    attitude_3sigma_deg_final: 3.0
                        * (e.cov(0, 0) + e.cov(1, 1) + e.cov(2, 2))
                            .sqrt()
                            .to_degrees(),
                    data_s: e.meta.t_ns as f64 * 1e-9 - t_first,
                    rate_err_rad_s_final: (truth.w - Vector3::from(e.w_body_rad_s)).norm(),
                    nees_mean: fold.nees_sum / fold.nees_n.max(1) as f64,
                    nees_95: [chi.inverse_cdf(0.025), chi.inverse_cdf(0.975)],
                    fallbacks: e.fallbacks,
                    restarts: e.restarts,
                }
            }
            None => PhotometryUkf {
                samples_tracked: 0,
                updates: 0,
                attitude_err_deg_final: f64::NAN,
                attitude_3sigma_deg_final: f64::NAN,
                data_s: f64::NAN,
                rate_err_rad_s_final: f64::NAN,
                nees_mean: f64::NAN,
                nees_95: [chi.inverse_cdf(0.025), chi.inverse_cdf(0.975)],
                fallbacks: 0,
                restarts: 0,
            },
        };
        let seen: Vec<&PhotometrySample> = (fold.samples.iter())
            .filter(|s| s.status == PhotometrySample::SEEN)
            .collect();
        let observed = seen
            .iter()
            .map(|s| (s.meta.t_ns as f64 * 1e-9, s.mag))
            .collect();
        // The best match's own curve: its shape at its size, spinning at its rate about its
        // axis from its phase, under each sample's Sun and observer.
        let mut matched_curve = vec![];
        if let Some(b) = best {
            if let Some((_, shape)) = fold.shapes.get(b.geometry as usize) {
                let shape = shape.scaled(b.area_scale.sqrt());
                let axis = Unit::new_normalize(Vector3::from(b.axis));
                for s in &seen {
                    let t_s = s.meta.t_ns as f64 * 1e-9;
                    let inv = spin_attitude(&axis, b.spin_rad_s * (t_s - b.t0_s)).inverse();
                    let flux = normalised_flux(
                        &shape,
                        &(inv * Vector3::from(s.sun)),
                        &(inv * Vector3::from(s.obs)),
                        DEN,
                    );
                    if let Some(mag) = apparent_magnitude(flux, s.range_m) {
                        matched_curve.push((t_s, mag));
                    }
                }
            }
        }
        Some(PhotometrySection {
            report: PhotometryReport {
                identification,
                ukf,
                samples: fold.counts.clone(),
            },
            series: fold.series.clone(),
            observed,
            matched_curve,
        })
    }
}

impl Section for PhotometrySection {
    fn report(&self, results: &mut Results, _timing: &mut Timing) {
        results.photometry = Some(self.report.clone());
    }

    fn markdown(&self) -> String {
        let r = &self.report;
        let (id, u, c) = (&r.identification, &r.ukf, &r.samples);
        let verdict = match (&id.geometry, id.correct) {
            (Some(g), true) => format!("**{g}**, the true geometry"),
            (Some(g), false) => format!("**{g}**; the truth is {}", id.truth_geometry),
            (None, _) => {
                return format!(
                    "## [001] Ground photometry\n\nIdentified nothing (the truth is {}): the \
                     arc was shorter than the identification window or fitted no geometry.\n\n\
                     Samples: {} seen, {} in the Earth's shadow, {} below the horizon, {} \
                     without flux, of {}.\n\n",
                    id.truth_geometry, c.seen, c.shadow, c.below_horizon, c.no_flux, c.total
                )
            }
        };
        let mut md = format!(
            "## [001] Ground photometry\n\n\
             Identified {verdict}, at t = {:.0} s. Spin {:.5} rad/s (true {:.5}, {:+.2} %); \
             area {:.2} m² (true {:.2}, {:+.1} %); axis {:.1}° from the true one ({:.1}° from \
             its mirror image through the Sun–observer plane, which shows the same curve).\n\n\
             UKF after {:.0} s of data: attitude error {:.2}° (3σ {:.2}°), rate error {:.2e} \
             rad/s; mean NEES {:.2} (6 expected; 95 % interval for one run {:.2}–{:.2}); {} \
             fallback step(s) to γ = 1, {} restart(s).\n\n\
             Samples: {} seen, {} in the Earth's shadow, {} below the horizon, {} without flux, \
             of {}.\n\n| geometry | matching degree | area [m²] | spin [rad/s] |\n|---|---|---|---|\n",
            id.at_s,
            id.spin_rad_s,
            id.truth_spin_rad_s,
            100.0 * (id.spin_rad_s / id.truth_spin_rad_s - 1.0),
            id.area_m2,
            id.truth_area_m2,
            100.0 * (id.area_m2 / id.truth_area_m2 - 1.0),
            id.axis_error_deg,
            id.axis_error_mirror_deg,
            u.data_s,
            u.attitude_err_deg_final,
            u.attitude_3sigma_deg_final,
            u.rate_err_rad_s_final,
            u.nees_mean,
            u.nees_95[0],
            u.nees_95[1],
            u.fallbacks,
            u.restarts,
            c.seen,
            c.shadow,
            c.below_horizon,
            c.no_flux,
            c.total,
        );
        for m in &id.matching {
            md.push_str(&format!(
                "| {} | {:.4} | {:.2} | {:.5} |\n",
                m.geometry, m.score, m.area_m2, m.spin_rad_s
            ));
        }
        md.push('\n');
        md
    }

    /// The light curve with the best match and the UKF's prediction; the attitude error and
    /// its 3σ bound.
    fn plots(&self, dir: &Path) -> Result<()> {
        let predicted: Vec<(f64, f64)> = (self.series.iter())
            .filter_map(|p| p.3.map(|m| (p.0, m)))
            .collect();
        line_chart(
            &dir.join("photometry-lightcurve.svg"),
            "[001] light curve: observed, best database match, UKF prediction",
            "t [s]",
            "apparent magnitude",
            &[
                Series {
                    label: "observed",
                    points: self.observed.clone(),
                    color: GREY,
                    markers: true,
                },
                Series {
                    label: "best database match",
                    points: self.matched_curve.clone(),
                    color: BLUE,
                    markers: false,
                },
                Series {
                    label: "UKF prediction",
                    points: predicted,
                    color: ORANGE,
                    markers: false,
                },
            ],
        )?;
        line_chart(
            &dir.join("photometry-attitude.svg"),
            "[001] UKF attitude error and its 3σ bound",
            "t [s]",
            "attitude error [deg]",
            &[
                Series {
                    label: "error",
                    points: self.series.iter().map(|p| (p.0, p.1)).collect(),
                    color: BLUE,
                    markers: false,
                },
                Series {
                    label: "3σ",
                    points: self.series.iter().map(|p| (p.0, p.2)).collect(),
                    color: RED,
                    markers: false,
                },
            ],
        )
    }
}
