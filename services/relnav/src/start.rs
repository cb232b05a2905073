//! Starting the filter from the measurements alone (no truth, no initial state): each epoch's
//! features are triangulated and the pose solved against the known feature coordinates
//! (absolute orientation by the SVD, Arun/Kabsch); a few epochs' poses are fitted with straight
//! lines in time for the rates; k̂₀ = 0; the covariance says how little is known.

use glint_physics::stereo::{depth_sigma_m, triangulate};
use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector2, Vector3};

use crate::filter::FeatureObs;
use crate::model::{ix, ErrMat, Nominal, Rig};

/// One epoch's pose from its features alone.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PoseFix {
    pub t_s: f64,
    pub q_ct: UnitQuaternion<f64>,
    /// ρ [m] in O.
    pub rho_o: Vector3<f64>,
    /// 1σ of one triangulated point [m] (the depth's, the largest).
    pub point_sigma_m: f64,
    /// RMS distance of the used features from their centroid, in T [m].
    pub spread_m: f64,
    /// Features used, and refused as inconsistent with the others.
    pub used: usize,
    pub rejected: usize,
}

/// A point's residual beyond this many of its σ marks a wrong match.
const RESIDUAL_SIGMAS: f64 = 8.0;
/// 1σ of each inertia parameter at the start (k̂₀ = 0; |k| ≲ 1 for any reasonable body).
pub const K_SIGMA_START: f64 = 1.0;
/// Factor on the start's covariance, against the errors the lines do not model.
const START_INFLATION: f64 = 3.0;

/// The pose of one epoch: triangulate, solve, and refuse the worst point while the fit says a
/// point is inconsistent with the rest (keeping at least three). `None` with fewer than three
/// usable, non-collinear features or with an inconsistency it cannot resolve.
pub fn pose_fix(rig: &Rig, t_s: f64, features: &[FeatureObs]) -> Option<PoseFix> {
    let mut pts: Vec<(Vector3<f64>, Vector3<f64>)> = features
        .iter()
        .filter_map(|f| {
            let r = *rig.features_m.get(f.feature)?;
            let p = triangulate(f.z, rig.baseline_m)?;
            Some((r, p))
        })
        .collect();
    let unusable = features.len() - pts.len();
    let mut rejected = 0;
    loop {
        if pts.len() < 3 {
            return None;
        }
        let (rot, t) = absolute_orientation(&pts)?;
        let depth = pts.iter().map(|(_, p)| p.z).fold(0.0, f64::max);
        let sigma = depth_sigma_m(depth, rig.baseline_m, rig.sigma_norm).max(1e-9);
        let (worst, worst_res) = pts
            .iter()
            .enumerate()
            .map(|(i, (r, p))| (i, (rot * r + t - p).norm()))
            .fold((0, 0.0), |a, b| if b.1 > a.1 { b } else { a });
        if worst_res > RESIDUAL_SIGMAS * sigma {
            if pts.len() == 3 {
                return None; // three points cannot say which one is wrong
            }
            pts.swap_remove(worst);
            rejected += 1;
            continue;
        }
        let centroid = pts.iter().map(|(r, _)| r).sum::<Vector3<f64>>() / pts.len() as f64;
        let spread = (pts
            .iter()
            .map(|(r, _)| (r - centroid).norm_squared())
            .sum::<f64>()
            / pts.len() as f64)
            .sqrt();
        return Some(PoseFix {
            t_s,
            q_ct: UnitQuaternion::from_rotation_matrix(&rot),
            rho_o: rig.c_co.transpose() * t,
            point_sigma_m: sigma,
            spread_m: spread,
            used: pts.len(),
            rejected: rejected + unusable,
        });
    }
}

/// The rotation `R` and translation `t` minimising `Σ ‖R r + t − p‖²` over pairs `(r, p)`;
/// `None` when the model points are collinear.
fn absolute_orientation(
    pts: &[(Vector3<f64>, Vector3<f64>)],
) -> Option<(Rotation3<f64>, Vector3<f64>)> {
    let n = pts.len() as f64;
    let rc = pts.iter().map(|(r, _)| r).sum::<Vector3<f64>>() / n;
    let pc = pts.iter().map(|(_, p)| p).sum::<Vector3<f64>>() / n;
    let mut h = Matrix3::zeros();
    for (r, p) in pts {
        h += (p - pc) * (r - rc).transpose();
    }
    let svd = h.svd(true, true);
    let mut sv = svd.singular_values;
    sv.as_mut_slice().sort_by(|a, b| b.total_cmp(a));
    if sv[1].is_nan() || sv[1] <= 1e-9 * sv[0].max(1e-300) {
        return None;
    }
    let (u, v_t) = (svd.u?, svd.v_t?);
    let d = (u * v_t).determinant().signum();
    let rot = u * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * v_t;
    let rot = Rotation3::from_matrix_unchecked(rot);
    Some((rot, pc - rot * rc))
}

/// The state at the last fix and its covariance from a few epochs' fixes (at least two, at
/// distinct times): the attitude's rotation vectors and ρ fitted with straight lines in time
/// about the last fix; ω_t from the attitude's slope, v from ρ's; k̂₀ = 0.
pub fn start_state(rig: &Rig, fixes: &[PoseFix]) -> Option<(Nominal, ErrMat)> {
    let last = fixes.last()?;
    let t_ref = last.t_s;
    let taus: Vec<f64> = fixes.iter().map(|f| f.t_s - t_ref).collect();
    let n = taus.len() as f64;
    let tau_mean = taus.iter().sum::<f64>() / n;
    let sxx: f64 = taus.iter().map(|t| (t - tau_mean).powi(2)).sum();
    if fixes.len() < 2 || sxx.is_nan() || sxx <= 0.0 {
        return None;
    }
    // y ≈ a + b τ: returns (a, b) at τ = 0 (the last fix).
    let line = |ys: &[Vector3<f64>]| {
        let y_mean = ys.iter().sum::<Vector3<f64>>() / n;
        let b = ys
            .iter()
            .zip(&taus)
            .map(|(y, t)| (y - y_mean) * (t - tau_mean))
            .sum::<Vector3<f64>>()
            / sxx;
        (y_mean - b * tau_mean, b)
    };
    let phis: Vec<Vector3<f64>> = fixes
        .iter()
        .map(|f| (last.q_ct.inverse() * f.q_ct).scaled_axis())
        .collect();
    let (phi0, w_tc) = line(&phis);
    let q_ct = last.q_ct * UnitQuaternion::from_scaled_axis(phi0);
    let rhos: Vec<Vector3<f64>> = fixes.iter().map(|f| f.rho_o).collect();
    let (rho, v) = line(&rhos);
    let w_t = w_tc + q_ct.inverse() * rig.chaser_rate_c();
    let x = Nominal {
        q_ct,
        w_t,
        k: Vector2::zeros(),
        rho_o: rho,
        v_o: v,
    };

    // σ of one fix's position and attitude, then of the lines' value and slope.
    let sigma_p = fixes.iter().map(|f| f.point_sigma_m).fold(0.0, f64::max);
    let used = fixes.iter().map(|f| f.used).min().unwrap_or(3).max(1) as f64;
    let spread = fixes
        .iter()
        .map(|f| f.spread_m)
        .fold(f64::INFINITY, f64::min);
    let sig_pos = sigma_p / used.sqrt();
    let sig_att = sigma_p / (spread.max(1e-6) * used.sqrt());
    // A fix off the lines by more than RESIDUAL_SIGMAS is a bad one (a wrong match the epoch
    // itself could not see): fit again without the worst.
    let off = |j: usize| {
        let a = (phis[j] - phi0 - w_tc * taus[j]).amax() / sig_att;
        let r = (rhos[j] - rho - v * taus[j]).amax() / sig_pos;
        a.max(r)
    };
    let worst = (0..fixes.len()).max_by(|a, b| off(*a).total_cmp(&off(*b)))?;
    if off(worst) > RESIDUAL_SIGMAS {
        if fixes.len() <= 3 {
            return None; // too few left to say which is wrong: wait for more
        }
        let mut rest = fixes.to_vec();
        rest.remove(worst);
        return start_state(rig, &rest);
    }
    let value = (1.0 / n + tau_mean * tau_mean / sxx).sqrt();
    let slope = (1.0 / sxx).sqrt();
    // the rate's change over the window, which a straight line does not model
    let span = -taus[0];
    let w_model = w_t.norm().powi(2) * span;
    let inf2 = START_INFLATION * START_INFLATION;
    let mut p = ErrMat::zeros();
    for i in 0..3 {
        p[(ix::TH + i, ix::TH + i)] = inf2 * (sig_att * value).powi(2);
        p[(ix::W + i, ix::W + i)] = inf2 * ((sig_att * slope).powi(2) + w_model.powi(2));
        p[(ix::RHO + i, ix::RHO + i)] = inf2 * (sig_pos * value).powi(2);
        p[(ix::V + i, ix::V + i)] = inf2 * (sig_pos * slope).powi(2);
    }
    for i in 0..2 {
        p[(ix::K + i, ix::K + i)] = K_SIGMA_START * K_SIGMA_START;
    }
    Some((x, p))
}

#[cfg(test)]
mod tests {
    use super::*;
    use glint_physics::stereo::project;

    fn rig() -> Rig {
        crate::model::tests::rig()
    }

    fn observe(rig: &Rig, x: &Nominal) -> Vec<FeatureObs> {
        rig.features_m
            .iter()
            .enumerate()
            .map(|(i, r)| FeatureObs {
                feature: i,
                z: project(crate::model::feature_in_camera(rig, x, r), rig.baseline_m).unwrap(),
            })
            .collect()
    }

    #[test]
    fn a_noise_free_epoch_gives_the_exact_pose() {
        let rig = rig();
        let x = crate::model::tests::state();
        let fix = pose_fix(&rig, 0.0, &observe(&rig, &x)).unwrap();
        assert!(fix.q_ct.angle_to(&x.q_ct) < 1e-9);
        assert!((fix.rho_o - x.rho_o).norm() < 1e-9);
        assert_eq!((fix.used, fix.rejected), (4, 0));
    }

    #[test]
    fn a_wrong_match_is_refused_and_the_pose_still_found() {
        let mut rig = rig();
        rig.features_m.push(Vector3::new(0.0, 0.0, 0.5));
        let x = crate::model::tests::state();
        let mut obs = observe(&rig, &x);
        obs[0].z = obs[4].z; // a wrong match: feature 0 reported where feature 4 is
        let fix = pose_fix(&rig, 0.0, &obs).unwrap();
        assert_eq!((fix.used, fix.rejected), (4, 1));
        assert!(fix.q_ct.angle_to(&x.q_ct) < 1e-9);
    }

    #[test]
    fn collinear_or_too_few_features_give_no_pose() {
        let rig = rig();
        let x = crate::model::tests::state();
        let obs = observe(&rig, &x);
        assert!(pose_fix(&rig, 0.0, &obs[..2]).is_none());
        // ±x only, and a copy: collinear
        let line = [obs[0], obs[1], obs[0]];
        assert!(pose_fix(&rig, 0.0, &line).is_none());
    }
}
