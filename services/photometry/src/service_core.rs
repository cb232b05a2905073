//! The `photometry` service's core, no I/O and no clock: light-curve samples in, one answer
//! out per sample. It gathers the arc until `identify_after_s` of it has been seen, builds the
//! database for the arc's mean Sun and observer directions, identifies the geometry, axis,
//! spin and size (math.md §2.5–2.7), starts the UKF (§2.9) from the best match at the first
//! gathered sample and runs it through what it gathered; from then on one UKF step per
//! sample. An arc that fits nothing is tried again after half as much more data. A filter that
//! fails is started again from the identification at that sample, and counted.
//!
//! Its state is plain data ([`State`]) so that a restarted service continues where its
//! checkpoint stands: the gathered samples (bounded by the identification window) or the
//! identification and the filter.

use std::sync::Arc;

use glint_physics::photometry::{flux_of_magnitude, Shape, SpecularDenominator};
use nalgebra::{Matrix6, Unit, UnitQuaternion, Vector3, Vector6};
use serde::{Deserialize, Serialize};

use crate::spin::spin_attitude;
use crate::{identify, Database, Identification, Match, Sample, Ukf, UkfSettings};

/// The UKF's start about the best match: 1σ of the attitude [rad] (the database's axes are
/// ~14° apart and its angles 45°, the phase found to a sample) and of the rate, relative.
pub const START_SIGMA_ATTITUDE_RAD: f64 = 0.1;
pub const START_SIGMA_RATE_FRACTION: f64 = 0.01;

/// The service's settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settings {
    pub identify_after_s: f64,
    pub axes: usize,
    pub angles: usize,
    pub ukf: UkfSettings,
}

/// The database for the samples' mean Sun and observer directions, and the identification
/// of their light curve; `None` when it has no spin line or fits no entry.
pub fn identify_samples(
    shapes: &[(String, Shape)],
    samples: &[Sample],
    axes: usize,
    angles: usize,
    den: SpecularDenominator,
) -> Option<Identification> {
    if samples.len() < 16 {
        return None;
    }
    let mean = |f: fn(&Sample) -> Vector3<f64>| -> Vector3<f64> {
        samples.iter().map(f).sum::<Vector3<f64>>().normalize()
    };
    let db = Database::build(
        shapes,
        &mean(|s| s.sun),
        &mean(|s| s.obs),
        axes,
        angles,
        den,
    );
    let t: Vec<f64> = samples.iter().map(|s| s.t_s).collect();
    let y: Vec<f64> = (samples.iter())
        .map(|s| flux_of_magnitude(s.mag, s.range_m))
        .collect();
    identify(&db, &t, &y)
}

/// The identified shape at its size.
pub fn scaled_shape(shapes: &[(String, Shape)], best: &Match) -> Option<Shape> {
    (shapes.iter())
        .find(|(n, _)| *n == best.geometry)
        .map(|(_, s)| s.scaled(best.area_scale.sqrt()))
}

/// The UKF started from a match at `t0_s`: its attitude there, its rate about its axis.
pub fn start_filter(best: &Match, t0_s: f64, settings: UkfSettings) -> Ukf {
    let axis = Unit::new_normalize(best.axis);
    let q0 = spin_attitude(&axis, best.spin_rad_s * (t0_s - best.t_s));
    let sa = START_SIGMA_ATTITUDE_RAD.powi(2);
    let sw = (START_SIGMA_RATE_FRACTION * best.spin_rad_s).powi(2);
    let p0 = Matrix6::from_diagonal(&Vector6::new(sa, sa, sa, sw, sw, sw));
    Ukf::new(q0, axis.into_inner() * best.spin_rad_s, p0, t0_s, settings)
}

/// A sample as kept in a checkpoint.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct KeptSample {
    pub t_s: f64,
    pub mag: f64,
    pub sigma_mag: f64,
    pub sun: [f64; 3],
    pub obs: [f64; 3],
    pub range_m: f64,
}

impl From<&Sample> for KeptSample {
    fn from(s: &Sample) -> Self {
        KeptSample {
            t_s: s.t_s,
            mag: s.mag,
            sigma_mag: s.sigma_mag,
            sun: s.sun.into(),
            obs: s.obs.into(),
            range_m: s.range_m,
        }
    }
}

impl From<&KeptSample> for Sample {
    fn from(s: &KeptSample) -> Self {
        Sample {
            t_s: s.t_s,
            mag: s.mag,
            sigma_mag: s.sigma_mag,
            sun: s.sun.into(),
            obs: s.obs.into(),
            range_m: s.range_m,
        }
    }
}

/// A match as kept in a checkpoint.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct KeptMatch {
    pub geometry: String,
    pub axis: [f64; 3],
    pub spin_rad_s: f64,
    pub area_scale: f64,
    pub area_m2: f64,
    pub score: f64,
    pub spread: f64,
    pub t_s: f64,
}

impl From<&Match> for KeptMatch {
    fn from(m: &Match) -> Self {
        KeptMatch {
            geometry: m.geometry.clone(),
            axis: m.axis.into(),
            spin_rad_s: m.spin_rad_s,
            area_scale: m.area_scale,
            area_m2: m.area_m2,
            score: m.score,
            spread: m.spread,
            t_s: m.t_s,
        }
    }
}

impl From<&KeptMatch> for Match {
    fn from(m: &KeptMatch) -> Self {
        Match {
            geometry: m.geometry.clone(),
            axis: m.axis.into(),
            spin_rad_s: m.spin_rad_s,
            area_scale: m.area_scale,
            area_m2: m.area_m2,
            score: m.score,
            spread: m.spread,
            t_s: m.t_s,
        }
    }
}

/// The filter as kept in a checkpoint.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct KeptFilter {
    pub q: [f64; 4],
    pub w: [f64; 3],
    pub p: Vec<f64>,
    pub t_s: f64,
    pub fallbacks: u64,
}

/// Everything the core knows: a checkpoint.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct State {
    /// Samples seen before the identification.
    pub gathered: Vec<KeptSample>,
    /// No identification is tried before this time [s].
    pub next_try_s: f64,
    /// Every geometry's best, best first, once identified.
    pub matching: Vec<KeptMatch>,
    pub filter: Option<KeptFilter>,
    pub restarts: u32,
    /// Steps of filters given up on, taken again with γ = 1.
    pub fallbacks_before: u64,
}

/// What the core answers to one sample.
#[derive(Debug, Clone, PartialEq)]
pub enum Answer<'a> {
    /// Gathering; `tried`: an identification was tried and fitted nothing.
    Gathering { tried: bool },
    /// Identified and tracking.
    Tracking {
        matching: &'a [Match],
        filter: &'a Ukf,
        /// Whether this sample updated the filter (not a gap, the step went through).
        updated: bool,
        fallbacks: u64,
        restarts: u32,
    },
}

/// The identification and its filter.
struct Tracker {
    matching: Vec<Match>,
    shape: Shape,
    ukf: Ukf,
}

pub struct Photometry {
    shapes: Arc<Vec<(String, Shape)>>,
    settings: Settings,
    gathered: Vec<Sample>,
    next_try_s: f64,
    tracker: Option<Tracker>,
    restarts: u32,
    fallbacks_before: u64,
}

impl Photometry {
    pub fn new(shapes: Arc<Vec<(String, Shape)>>, settings: Settings) -> Self {
        Photometry {
            shapes,
            settings,
            gathered: vec![],
            next_try_s: f64::NEG_INFINITY,
            tracker: None,
            restarts: 0,
            fallbacks_before: 0,
        }
    }

    /// The core as a checkpoint left it.
    pub fn restore(shapes: Arc<Vec<(String, Shape)>>, settings: Settings, s: State) -> Self {
        let mut core = Photometry::new(shapes, settings);
        core.gathered = s.gathered.iter().map(Sample::from).collect();
        core.next_try_s = s.next_try_s;
        core.restarts = s.restarts;
        core.fallbacks_before = s.fallbacks_before;
        let matching: Vec<Match> = s.matching.iter().map(Match::from).collect();
        if let (Some(f), Some(best)) = (s.filter, matching.first()) {
            if let Some(shape) = scaled_shape(&core.shapes, best) {
                let mut ukf = start_filter(best, f.t_s, settings.ukf);
                // as kept, to the bit (normalising again would move the last bits)
                ukf.q = UnitQuaternion::new_unchecked(nalgebra::Quaternion::new(
                    f.q[0], f.q[1], f.q[2], f.q[3],
                ));
                ukf.w = f.w.into();
                ukf.p = Matrix6::from_column_slice(&f.p);
                ukf.fallbacks = f.fallbacks;
                core.tracker = Some(Tracker {
                    matching,
                    shape,
                    ukf,
                });
            }
        }
        core
    }

    pub fn state(&self) -> State {
        State {
            gathered: self.gathered.iter().map(KeptSample::from).collect(),
            next_try_s: self.next_try_s,
            matching: (self.tracker.iter())
                .flat_map(|t| t.matching.iter().map(KeptMatch::from))
                .collect(),
            filter: self.tracker.as_ref().map(|t| {
                let q = t.ukf.q.into_inner();
                KeptFilter {
                    q: [q.w, q.i, q.j, q.k],
                    w: t.ukf.w.into(),
                    p: t.ukf.p.as_slice().to_vec(),
                    t_s: t.ukf.t_s,
                    fallbacks: t.ukf.fallbacks,
                }
            }),
            restarts: self.restarts,
            fallbacks_before: self.fallbacks_before,
        }
    }

    /// One sample at `t_s`: its magnitude and geometry, or `None` for a gap.
    pub fn sample(&mut self, t_s: f64, seen: Option<Sample>) -> Answer<'_> {
        if self.tracker.is_none() {
            return match self.gather(t_s, seen) {
                Some(updated) => self.tracking(updated),
                None => Answer::Gathering {
                    tried: self.next_try_s > f64::NEG_INFINITY,
                },
            };
        }
        let updated = match seen {
            Some(s) => self.step(&s),
            None => false,
        };
        self.tracking(updated)
    }

    fn tracking(&self, updated: bool) -> Answer<'_> {
        let t = self.tracker.as_ref().expect("tracking");
        Answer::Tracking {
            matching: &t.matching,
            filter: &t.ukf,
            updated,
            fallbacks: self.fallbacks_before + t.ukf.fallbacks,
            restarts: self.restarts,
        }
    }

    /// Gathers a sample; identifies once the window is full. `Some(updated)` once identified.
    fn gather(&mut self, t_s: f64, seen: Option<Sample>) -> Option<bool> {
        let was_seen = seen.is_some();
        self.gathered.extend(seen);
        let first = self.gathered.first()?.t_s;
        let window = self.settings.identify_after_s;
        if t_s - first < window || t_s < self.next_try_s {
            return None;
        }
        let den = self.settings.ukf.den;
        let (axes, angles) = (self.settings.axes, self.settings.angles);
        let Some(id) = identify_samples(&self.shapes, &self.gathered, axes, angles, den) else {
            self.next_try_s = t_s + 0.5 * window;
            return None;
        };
        let shape = scaled_shape(&self.shapes, &id.best)?;
        let ukf = start_filter(&id.best, first, self.settings.ukf);
        self.tracker = Some(Tracker {
            matching: id.matching,
            shape,
            ukf,
        });
        let gathered = std::mem::take(&mut self.gathered);
        let mut updated = false;
        for s in &gathered {
            updated = self.step(s);
        }
        Some(updated && was_seen)
    }

    /// One UKF step; a failed filter starts again from the identification at this sample.
    fn step(&mut self, s: &Sample) -> bool {
        let t = self.tracker.as_mut().expect("tracking");
        match t.ukf.step(&t.shape, s) {
            Ok(crate::StepOutcome::Updated { .. }) => true,
            Ok(crate::StepOutcome::NoFlux) => false,
            Err(_) => {
                self.fallbacks_before += t.ukf.fallbacks;
                t.ukf = start_filter(&t.matching[0], s.t_s, self.settings.ukf);
                self.restarts += 1;
                false
            }
        }
    }
}
