//! Matching degree and size (docs/math.md §2.7, eqs 10–11). For geometry g, axis a and spin
//! rate w, the observed normalised flux y is read at `τ_j(t) = t + j Δφ / w` (linear
//! interpolation) and divided by the database's `M_j`:
//!
//! ```text
//! P_j(t) = y(τ_j(t)) / M_j,   P̄(t) = mean_j P_j(t),   F(t) = std_j P_j(t)          (10)
//! ```
//!
//! The entry that explains the curve makes every `P_j` the same (the area ratio) at the phase
//! `t*` where the curve's rotation angle is the database's 0: `F(t*) = 0`. Geometries of
//! different sizes are compared by the scale-free `F / P̄` (the raw F favours small scale
//! factors); the size is `A = A₀ P̄(t*)` (11). The dominant line's rate and its 2nd to 4th
//! subharmonics are tried: a body symmetric under a half turn shows its line at twice its spin
//! or more (math.md names w and w/2; a cylinder's strongest line is often a higher harmonic).

use nalgebra::Vector3;

use crate::database::Database;

/// One candidate: a geometry at its best axis, rate and phase.
#[derive(Debug, Clone, PartialEq)]
pub struct Match {
    pub geometry: String,
    /// Spin axis (unit, inertial) and rate [rad/s].
    pub axis: Vector3<f64>,
    pub spin_rad_s: f64,
    /// P̄ at the best phase: the observed facet areas over the model's.
    pub area_scale: f64,
    /// The model's total facet area times `area_scale` [m²].
    pub area_m2: f64,
    /// `F / P̄` at the best phase (0: a perfect match) and the raw F (eq 10).
    pub score: f64,
    pub spread: f64,
    /// The best phase's start time [s] (the rotation angle there is the database's 0).
    pub t_s: f64,
}

/// The identified geometry and every geometry's best, best first.
#[derive(Debug, Clone, PartialEq)]
pub struct Identification {
    pub best: Match,
    pub matching: Vec<Match>,
    /// The light curve's dominant line [rad/s].
    pub line_rad_s: f64,
}

/// Candidate rates: the line's rate divided by 1 to this.
const SUBHARMONICS: usize = 4;
/// Candidates per geometry whose rate is refined, and the refinement: ± this many steps of
/// this relative size.
const REFINED: usize = 5;
const RATE_STEPS: i32 = 4;
const RATE_STEP: f64 = 5e-4;
/// The axis refinement's ring radii [rad] (8° then 3°, each ring also at half its radius) and
/// azimuths per ring.
const AXIS_REFINEMENT_RAD: [f64; 2] = [0.14, 0.05];
const AZIMUTHS: usize = 8;

/// Database entries below this fraction of the largest are skipped (j with no light).
const DARK: f64 = 1e-9;

/// A light curve: times (increasing), normalised flux, and the longest interval
/// interpolation may bridge (samples missing in shadow or below the horizon leave gaps that
/// must not be filled with a straight line).
struct Curve<'a> {
    t_s: &'a [f64],
    y: &'a [f64],
    max_gap_s: f64,
}

/// Intervals up to this many times the median one are bridged.
const GAP_FACTOR: f64 = 2.5;

impl Curve<'_> {
    /// `y` at `t` by linear interpolation; `None` outside the curve or inside a gap.
    fn at(&self, t: f64) -> Option<f64> {
        let (t_s, y) = (self.t_s, self.y);
        let k = t_s.partition_point(|&s| s <= t);
        if k == 0 || (k == t_s.len() && t > t_s[k - 1]) {
            return None;
        }
        if k == t_s.len() {
            return Some(y[k - 1]);
        }
        let (t0, t1) = (t_s[k - 1], t_s[k]);
        if t1 - t0 > self.max_gap_s && t != t0 {
            return None;
        }
        Some(y[k - 1] + (y[k] - y[k - 1]) * (t - t0) / (t1 - t0))
    }
}

/// The ratios' (score, spread, P̄) with the database angles read from `t` on, if every one
/// falls inside the curve.
fn ratios_at(
    curve: &Curve<'_>,
    lit: &[(usize, f64)],
    step: f64,
    t: f64,
    p: &mut [f64],
) -> Option<(f64, f64, f64)> {
    for (slot, &(j, mj)) in p.iter_mut().zip(lit) {
        *slot = curve.at(t + j as f64 * step)? / mj;
    }
    let mean = p.iter().sum::<f64>() / p.len() as f64;
    if mean <= 0.0 {
        return None;
    }
    let spread = (p.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / p.len() as f64).sqrt();
    Some((spread / mean, spread, mean))
}

/// The best phase of entry `m` at rate `w`: (score, spread, P̄, t*). Each phase in the first
/// turn is scored by the mean of eq (10) over every turn the curve holds from it (the same
/// entry at the same phase, one turn later), so that noise in one turn does not pick the phase.
fn best_phase(curve: &Curve<'_>, m: &[f64], w: f64) -> Option<(f64, f64, f64, f64)> {
    let t_s = curve.t_s;
    let max_m = m.iter().cloned().fold(0.0, f64::max);
    let lit: Vec<(usize, f64)> = (m.iter().copied().enumerate())
        .filter(|(_, v)| *v > DARK * max_m)
        .collect();
    if lit.len() < 2 {
        return None;
    }
    let step = 2.0 * std::f64::consts::PI / m.len() as f64 / w;
    let turn = step * m.len() as f64;
    let (first, last) = (*t_s.first()?, *t_s.last()?);
    let span = step * (m.len() - 1) as f64;
    let mut best: Option<(f64, f64, f64, f64)> = None;
    let mut p = vec![0.0; lit.len()];
    for &t in t_s {
        if t >= first + turn || t + span > last {
            break;
        }
        let (mut n, mut score, mut spread, mut mean) = (0.0, 0.0, 0.0, 0.0);
        let mut start = t;
        while start + span <= last {
            if let Some((sc, sp, me)) = ratios_at(curve, &lit, step, start, &mut p) {
                n += 1.0;
                score += sc;
                spread += sp;
                mean += me;
            }
            start += turn;
        }
        if n == 0.0 {
            continue;
        }
        let (score, spread, mean) = (score / n, spread / n, mean / n);
        if best.is_none_or(|b| score < b.0) {
            best = Some((score, spread, mean, t));
        }
    }
    best
}

/// Refines a match's axis off the lattice (whose axes are up to ~8° from any direction):
/// rings of axes about it, shrinking, each with its rate refined by ±1 step; the best kept.
fn refine_axis(db: &Database, g: usize, mut best: Match, curve: &Curve<'_>) -> Match {
    for radius in AXIS_REFINEMENT_RAD {
        let centre = best.axis;
        // two unit vectors across the axis
        let across = if centre.x.abs() < 0.9 {
            Vector3::x()
        } else {
            Vector3::y()
        };
        let e1 = centre.cross(&across).normalize();
        let e2 = centre.cross(&e1);
        for ring in [0.5, 1.0] {
            for k in 0..AZIMUTHS {
                let az = 2.0 * std::f64::consts::PI * k as f64 / AZIMUTHS as f64;
                let r = radius * ring;
                let axis = nalgebra::Unit::new_normalize(
                    centre * r.cos() + (e1 * az.cos() + e2 * az.sin()) * r.sin(),
                );
                let m = db.entry_about(g, &axis);
                for i in -1..=1 {
                    let w = best.spin_rad_s * (1.0 + RATE_STEP * i as f64);
                    if let Some((score, spread, mean, t)) = best_phase(curve, &m, w) {
                        if score < best.score {
                            best = Match {
                                axis: axis.into_inner(),
                                spin_rad_s: w,
                                area_scale: mean,
                                area_m2: best.area_m2 / best.area_scale * mean,
                                score,
                                spread,
                                t_s: t,
                                ..best
                            };
                        }
                    }
                }
            }
        }
    }
    best
}

/// Identifies the geometry, axis, spin and size of normalised-flux samples `y` at times `t_s`
/// (increasing) against `db`; `None` when the curve has no dominant line or no entry fits.
pub fn identify(db: &Database, t_s: &[f64], y: &[f64]) -> Option<Identification> {
    let line = crate::rate::dominant_angular_frequency(t_s, y)?;
    let mut dts: Vec<f64> = t_s.windows(2).map(|w| w[1] - w[0]).collect();
    dts.sort_by(f64::total_cmp);
    let curve = Curve {
        t_s,
        y,
        max_gap_s: GAP_FACTOR * dts[dts.len() / 2],
    };
    let mut per_geometry: Vec<Match> = vec![];
    for (g, (name, area0)) in db.geometries.iter().enumerate() {
        // Every axis at every candidate rate, then the best few with their rate refined: the
        // line's rate is good to a few 1e-4, and a turn-averaged score drifts with the error.
        let mut coarse: Vec<(f64, usize, f64)> = vec![];
        for w in (1..=SUBHARMONICS).map(|k| line / k as f64) {
            for a in 0..db.axes.len() {
                if let Some((score, ..)) = best_phase(&curve, db.entry(g, a), w) {
                    coarse.push((score, a, w));
                }
            }
        }
        coarse.sort_by(|x, y| x.0.total_cmp(&y.0));
        let mut best: Option<Match> = None;
        for &(_, a, w0) in coarse.iter().take(REFINED) {
            for i in -RATE_STEPS..=RATE_STEPS {
                let w = w0 * (1.0 + RATE_STEP * i as f64);
                let Some((score, spread, mean, t)) = best_phase(&curve, db.entry(g, a), w) else {
                    continue;
                };
                if best.as_ref().is_none_or(|b| score < b.score) {
                    best = Some(Match {
                        geometry: name.clone(),
                        axis: db.axes[a].into_inner(),
                        spin_rad_s: w,
                        area_scale: mean,
                        area_m2: area0 * mean,
                        score,
                        spread,
                        t_s: t,
                    });
                }
            }
        }
        per_geometry.extend(best.map(|b| refine_axis(db, g, b, &curve)));
    }
    per_geometry.sort_by(|a, b| a.score.total_cmp(&b.score));
    Some(Identification {
        best: per_geometry.first()?.clone(),
        matching: per_geometry,
        line_rad_s: line,
    })
}
