//! The §3.4 gates and the normalised feature distance (see the parent module doc).

use super::{MatcherConfig, Object};
use crate::moments::{Blob, FeatureSet};

/// Whether every feature the matcher reads is finite.
pub(super) fn is_finite(blob: &Blob) -> bool {
    [blob.binary(), blob.weighted].iter().all(|e| {
        [
            e.m00,
            e.x_px,
            e.y_px,
            e.a_px,
            e.b_px,
            e.theta_rad,
            e.eccentricity,
        ]
        .iter()
        .all(|v| v.is_finite())
    })
}

/// Centroid \[x, y\] of the configured centroid set.
pub(super) fn centroid(cfg: &MatcherConfig, blob: &Blob) -> [f64; 2] {
    match cfg.centroid {
        FeatureSet::Binary => [blob.x_px, blob.y_px],
        FeatureSet::Weighted => [blob.weighted.x_px, blob.weighted.y_px],
    }
}

/// Difference of two axis angles modulo π, in \[0, π/2\].
pub(super) fn axis_diff_rad(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(std::f64::consts::PI);
    d.min(std::f64::consts::PI - d)
}

/// The normalised distance `Σ (Δ_i / T_i)²` if every applicable gate passes.
pub(super) fn gate(
    cfg: &MatcherConfig,
    obj: &Object,
    blob: &Blob,
    frame_index: u64,
) -> Option<f64> {
    let prev = &obj.features;
    let cur = blob.ellipse(cfg.features);
    let clipped = obj.touches_border || blob.touches_border;
    let mut cost = 0.0;
    let mut term = |delta: f64, tol: f64| -> bool {
        if delta > tol {
            return false;
        }
        if tol > 0.0 {
            cost += (delta / tol).powi(2);
        }
        true
    };
    if !clipped {
        let t_m = (cfg.m00_tol_frac * prev.m00.abs()).max(cfg.m00_tol_min);
        let t_a = (cfg.a_tol_frac * prev.a_px).max(cfg.a_tol_min_px);
        if !term((cur.m00 - prev.m00).abs(), t_m) || !term((cur.a_px - prev.a_px).abs(), t_a) {
            return None;
        }
    }
    let e_min = prev.eccentricity.min(cur.eccentricity);
    let e_max = prev.eccentricity.max(cur.eccentricity);
    // A clipped stub is shorter, and θ noise grows as the blob shortens.
    let t_theta = if clipped && prev.a_px.min(cur.a_px) > 0.0 {
        cfg.theta_tol_rad * prev.a_px.max(cur.a_px) / prev.a_px.min(cur.a_px)
    } else {
        cfg.theta_tol_rad
    };
    if e_min >= cfg.round_ecc && !term(axis_diff_rad(cur.theta_rad, prev.theta_rad), t_theta) {
        return None;
    }
    if !clipped
        && e_max >= cfg.round_ecc
        && !term((cur.eccentricity - prev.eccentricity).abs(), cfg.ecc_tol)
    {
        return None;
    }
    // Centroid gate, eq 8 scaled to Δf frames, around the predicted centroid.
    let frames = frame_index.saturating_sub(obj.last_frame).max(1) as f64;
    let v = obj.velocity.unwrap_or([0.0, 0.0]);
    let predicted = [
        obj.centroid[0] + frames * v[0],
        obj.centroid[1] + frames * v[1],
    ];
    let c = centroid(cfg, blob);
    let distance = (c[0] - predicted[0]).hypot(c[1] - predicted[1]);
    let a = prev.a_px.max(cur.a_px);
    let mut l_thr = frames * cfg.frame_period_s() * (2.0 * a / cfg.exposure_s) + cfg.gate_margin_px;
    if clipped {
        l_thr += prev.a_px;
    }
    if !term(distance, l_thr) {
        return None;
    }
    Some(cost)
}
