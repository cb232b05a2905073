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

/// Database entries below this fraction of the largest are skipped (j with no light).
const DARK: f64 = 1e-9;

/// `y` at `t` by linear interpolation of the samples (`t_s` increasing); `None` outside.
fn interpolate(t_s: &[f64], y: &[f64], t: f64) -> Option<f64> {
    let k = t_s.partition_point(|&s| s <= t);
    if k == 0 || k > t_s.len() || (k == t_s.len() && t > t_s[k - 1]) {
        return None;
    }
    if k == t_s.len() {
        return Some(y[k - 1]);
    }
    let (t0, t1) = (t_s[k - 1], t_s[k]);
    Some(y[k - 1] + (y[k] - y[k - 1]) * (t - t0) / (t1 - t0))
}

/// The best phase of entry `m` at rate `w`: (score, spread, P̄, t*).
fn best_phase(t_s: &[f64], y: &[f64], m: &[f64], w: f64) -> Option<(f64, f64, f64, f64)> {
    let max_m = m.iter().cloned().fold(0.0, f64::max);
    let lit: Vec<(usize, f64)> = (m.iter().copied().enumerate())
        .filter(|(_, v)| *v > DARK * max_m)
        .collect();
    if lit.len() < 2 {
        return None;
    }
    let step = 2.0 * std::f64::consts::PI / m.len() as f64 / w;
    let last = *t_s.last()?;
    let mut best: Option<(f64, f64, f64, f64)> = None;
    let mut p = vec![0.0; lit.len()];
    for &t in t_s {
        if t + step * (m.len() - 1) as f64 > last {
            break;
        }
        let mut ok = true;
        for (slot, &(j, mj)) in p.iter_mut().zip(&lit) {
            match interpolate(t_s, y, t + j as f64 * step) {
                Some(v) => *slot = v / mj,
                None => ok = false,
            }
        }
        if !ok {
            continue;
        }
        let mean = p.iter().sum::<f64>() / p.len() as f64;
        if mean <= 0.0 {
            continue;
        }
        let spread = (p.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / p.len() as f64).sqrt();
        let score = spread / mean;
        if best.is_none_or(|b| score < b.0) {
            best = Some((score, spread, mean, t));
        }
    }
    best
}

/// Identifies the geometry, axis, spin and size of normalised-flux samples `y` at times `t_s`
/// (increasing) against `db`; `None` when the curve has no dominant line or no entry fits.
pub fn identify(db: &Database, t_s: &[f64], y: &[f64]) -> Option<Identification> {
    let line = crate::rate::dominant_angular_frequency(t_s, y)?;
    let mut per_geometry: Vec<Match> = vec![];
    for (g, (name, area0)) in db.geometries.iter().enumerate() {
        let mut best: Option<Match> = None;
        for w in (1..=SUBHARMONICS).map(|k| line / k as f64) {
            for (a, axis) in db.axes.iter().enumerate() {
                let Some((score, spread, mean, t)) = best_phase(t_s, y, db.entry(g, a), w) else {
                    continue;
                };
                if best.as_ref().is_none_or(|b| score < b.score) {
                    best = Some(Match {
                        geometry: name.clone(),
                        axis: axis.into_inner(),
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
        per_geometry.extend(best);
    }
    per_geometry.sort_by(|a, b| a.score.total_cmp(&b.score));
    Some(Identification {
        best: per_geometry.first()?.clone(),
        matching: per_geometry,
        line_rad_s: line,
    })
}
