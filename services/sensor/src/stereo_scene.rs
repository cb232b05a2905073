//! The [004] scene (docs/math.md §5.1–5.5): a rigid target with body-fixed features in
//! torque-free rotation (eq 9 integrated with the inertia itself, not the filter's k form),
//! its centre of mass in CW motion ahead of a chaser that holds its orbit frame, seen by a
//! rectified stereo pair.
//!
//! Frames: I is the orbit frame O at t = 0; O turns about z_O at the mean motion n, so
//! `q_io(t) = exp(n t ẑ)`; the camera C is fixed in O (`C_CO`); `q_ct = q_co ⊗ q_oi ⊗ q_it`.
//! The truth is integrated once, at construction (RK4 in substeps of at most 50 ms, the
//! disturbances piecewise constant over a substep), so epoch `k` — its truth and its
//! measurements, whose noise is drawn from a generator keyed by (seed, k) — is a function of
//! `k` alone, as a restarted consumer needs (`Replay::Remade`).

use glint_physics::cw::{cw_stm_rsw, propagate_rsw};
use glint_physics::orbit::mean_motion_at_altitude_rad_s;
use glint_physics::rigid_body::{k_from_inertia, RigidBody, Spin};
use glint_physics::rng::SeededRng;
use glint_physics::stereo::{c_co_along_track, project};
use nalgebra::{Matrix3, UnitQuaternion, Vector2, Vector3, Vector6};
use shared_types::scenario::StereoScenario;

/// Longest truth substep [s].
const MAX_TRUTH_STEP_S: f64 = 0.05;

/// The target's true state at one epoch.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StereoTruth {
    pub t_ns: u64,
    /// Hamilton q_ct, `R(q) = C_CT`.
    pub q_ct: UnitQuaternion<f64>,
    /// ω_t [rad/s] in T.
    pub w_t: Vector3<f64>,
    /// ρ [m] and v [m/s] in O.
    pub rho_o: Vector3<f64>,
    pub v_o: Vector3<f64>,
}

/// One feature as the rig reports it: its index and `[x_l, y_l, x_r, y_r]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SeenFeature {
    pub feature: u32,
    pub z: [f64; 4],
}

/// The scene.
pub struct StereoScene {
    pub features_t: Vec<Vector3<f64>>,
    pub baseline_m: f64,
    pub sigma_norm: f64,
    pub c_co: Matrix3<f64>,
    pub mean_motion_rad_s: f64,
    /// The true inertia parameters (eq 16).
    pub k: Vector2<f64>,
    epochs: Vec<StereoTruth>,
    hide_back_faces: bool,
    dropout_probability: f64,
    wrong_match_probability: f64,
    seed: u64,
}

/// A stream of independent draws per epoch.
fn epoch_rng(seed: u64, k: u64) -> SeededRng {
    SeededRng::new(xxhash_rust::xxh3::xxh3_64(
        &[seed.to_le_bytes(), k.to_le_bytes(), *b"stereo\0\0"].concat(),
    ))
}

impl StereoScene {
    /// The scene of a validated `[stereo]` section.
    pub fn new(s: &StereoScenario, seed: u64) -> Self {
        let n = mean_motion_at_altitude_rad_s(s.altitude_km);
        let j = Vector3::from(s.inertia_kg_m2);
        let body = RigidBody { inertia_kg_m2: j };
        let c_co = c_co_along_track();
        let q_co = UnitQuaternion::from_matrix(&c_co);
        let q_ct0 = UnitQuaternion::from_scaled_axis(
            Vector3::from(s.attitude0_rotvec_deg).map(f64::to_radians),
        );
        let mut spin = Spin {
            q: q_co.inverse() * q_ct0, // q_it(0) = q_oc ⊗ q_ct(0), I = O(0)
            w_rad_s: Vector3::from(s.rate0_rad_s),
        };
        let x0 = Vector6::new(
            s.rho0_m[0],
            s.rho0_m[1],
            s.rho0_m[2],
            s.v0_m_s[0],
            s.v0_m_s[1],
            s.v0_m_s[2],
        );
        let mut x = x0;
        let times = s.epoch_times_ns();
        let mut rng = SeededRng::new(seed ^ 0x5745_5245_4f5f_5452);
        let noisy = s.torque_psd > 0.0 || s.accel_psd > 0.0;
        let mut t_s = 0.0;
        let mut epochs = Vec::with_capacity(times.len());
        for &t_ns in &times {
            let target = t_ns as f64 * 1e-9;
            let span = target - t_s;
            if span > 0.0 {
                let steps = (span / MAX_TRUTH_STEP_S).ceil().max(1.0) as usize;
                let h = span / steps as f64;
                let phi = cw_stm_rsw(n, h);
                for _ in 0..steps {
                    let mut torque = Vector3::zeros();
                    if s.torque_psd > 0.0 {
                        let sd = (s.torque_psd / h).sqrt() * j.sum();
                        torque = Vector3::from_fn(|_, _| sd * rng.gaussian());
                    }
                    spin = body.step(spin, torque, h);
                    if noisy {
                        x = phi * x;
                        if s.accel_psd > 0.0 {
                            let sd = (s.accel_psd / h).sqrt();
                            for i in 0..3 {
                                let a = sd * rng.gaussian();
                                x[i] += 0.5 * h * h * a;
                                x[i + 3] += h * a;
                            }
                        }
                    }
                }
                t_s = target;
            }
            if !noisy {
                x = propagate_rsw(x0, n, target); // exact from the start
            }
            let q_oi = UnitQuaternion::from_scaled_axis(Vector3::new(0.0, 0.0, -n * target));
            epochs.push(StereoTruth {
                t_ns,
                q_ct: q_co * q_oi * spin.q,
                w_t: spin.w_rad_s,
                rho_o: x.fixed_rows::<3>(0).into(),
                v_o: x.fixed_rows::<3>(3).into(),
            });
        }
        StereoScene {
            features_t: s.features().into_iter().map(Vector3::from).collect(),
            baseline_m: s.baseline_m,
            sigma_norm: s.sigma_norm,
            c_co,
            mean_motion_rad_s: n,
            k: k_from_inertia(j).unwrap_or_default(),
            epochs,
            hide_back_faces: s.hide_back_faces,
            dropout_probability: s.dropout_probability,
            wrong_match_probability: s.wrong_match_probability,
            seed,
        }
    }

    pub fn len(&self) -> u64 {
        self.epochs.len() as u64
    }

    pub fn is_empty(&self) -> bool {
        self.epochs.is_empty()
    }

    pub fn t_ns(&self, k: u64) -> u64 {
        self.epochs.get(k as usize).map_or(0, |e| e.t_ns)
    }

    pub fn truth(&self, k: u64) -> StereoTruth {
        self.epochs[k as usize]
    }

    /// Where feature `i` is in C at epoch `k` [m].
    pub fn feature_in_camera(&self, k: u64, i: usize) -> Vector3<f64> {
        let e = &self.epochs[k as usize];
        self.c_co * e.rho_o + e.q_ct * self.features_t[i]
    }

    /// What the rig reports at epoch `k`: every visible feature with noise, some missing
    /// (dropouts), one perhaps under another's index (a wrong match).
    pub fn observe(&self, k: u64) -> Vec<SeenFeature> {
        let e = &self.epochs[k as usize];
        let mut rng = epoch_rng(self.seed, k);
        let mut seen = Vec::with_capacity(self.features_t.len());
        for (i, r) in self.features_t.iter().enumerate() {
            let p = self.c_co * e.rho_o + e.q_ct * r;
            let noise = [
                rng.gaussian(),
                rng.gaussian(),
                rng.gaussian(),
                rng.gaussian(),
            ];
            let drop = rng.uniform() < self.dropout_probability;
            let facing = (e.q_ct * r).dot(&-p) > 0.0;
            if drop || (self.hide_back_faces && !facing) {
                continue;
            }
            let Some(z) = project(p, self.baseline_m) else {
                continue;
            };
            seen.push(SeenFeature {
                feature: i as u32,
                z: std::array::from_fn(|c| z[c] + self.sigma_norm * noise[c]),
            });
        }
        let n = self.features_t.len() as u32;
        if !seen.is_empty() && n > 1 && rng.uniform() < self.wrong_match_probability {
            let which = (rng.uniform() * seen.len() as f64) as usize % seen.len();
            let shift = 1 + (rng.uniform() * (n - 1) as f64) as u32 % (n - 1);
            seen[which].feature = (seen[which].feature + shift) % n;
        }
        seen
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene(s: &StereoScenario) -> StereoScene {
        StereoScene::new(s, 7)
    }

    /// Without disturbances, the truth's translation is CW's closed form (math.md §7.1's STM)
    /// and its rotation conserves the inertial angular momentum, through the frames'
    /// composition; with them, it does not.
    #[test]
    fn truth_follows_cw_and_conserves_momentum() {
        let noisy = scene(&StereoScenario {
            duration_s: 600.0,
            ..StereoScenario::default()
        });
        let quiet = StereoScenario {
            duration_s: 600.0,
            torque_psd: 0.0,
            accel_psd: 0.0,
            ..StereoScenario::default()
        };
        let s = quiet;
        let sc = scene(&s);
        assert_eq!(sc.len(), 601);
        assert!((noisy.truth(600).w_t - sc.truth(600).w_t).norm() > 1e-7);
        assert!((sc.mean_motion_rad_s - 1.1068e-3).abs() < 1e-6);
        let j = Vector3::from(s.inertia_kg_m2);
        let n = sc.mean_motion_rad_s;
        let inertial_h = |k: u64| {
            let e = sc.truth(k);
            let t = e.t_ns as f64 * 1e-9;
            let q_io = UnitQuaternion::from_scaled_axis(Vector3::new(0.0, 0.0, n * t));
            let q_it = q_io * UnitQuaternion::from_matrix(&sc.c_co).inverse() * e.q_ct;
            q_it * j.component_mul(&e.w_t)
        };
        let h0 = inertial_h(0);
        assert!((inertial_h(600) - h0).norm() < 1e-9 * h0.norm());
        // CW: ẋ0 < 0 carries the target away along-track and back (depth grows mid-orbit)
        let e = sc.truth(600);
        let t = 600.0;
        let y = 10.0 + 2.0 * 0.002 / n * (1.0 - (n * t).cos());
        assert!((e.rho_o.y - y).abs() < 1e-9, "{} vs {y}", e.rho_o.y);
    }

    #[test]
    fn observations_are_the_projection_with_the_stated_noise() {
        let s = StereoScenario {
            duration_s: 2000.0,
            ..StereoScenario::default()
        };
        let sc = scene(&s);
        let (mut sum2, mut count) = (0.0, 0);
        for k in 0..sc.len() {
            for f in sc.observe(k) {
                let z = project(sc.feature_in_camera(k, f.feature as usize), s.baseline_m).unwrap();
                for (seen, exact) in f.z.iter().zip(z) {
                    sum2 += (seen - exact).powi(2);
                    count += 1;
                }
            }
        }
        assert_eq!(count, 4 * 4 * 2001);
        let sd = (sum2 / count as f64).sqrt();
        assert!((sd / 1e-5 - 1.0).abs() < 0.03, "σ {sd}");
        assert_eq!(sc.observe(17), sc.observe(17), "epoch k is a function of k");
    }

    #[test]
    fn back_faces_dropouts_and_gaps_take_features_and_epochs_away() {
        let s = StereoScenario {
            duration_s: 100.0,
            hide_back_faces: true,
            gaps_s: vec![[10.0, 19.5]],
            ..StereoScenario::default()
        };
        let sc = scene(&s);
        assert_eq!(sc.len(), 101 - 10);
        let seen: usize = (0..sc.len()).map(|k| sc.observe(k).len()).sum();
        // ±x and ±y: at most two of each pair face the camera
        assert!(seen <= 2 * 91 && seen > 91, "{seen}");
        let s2 = StereoScenario {
            duration_s: 100.0,
            dropout_probability: 0.5,
            ..StereoScenario::default()
        };
        let seen2: usize = (0..101).map(|k| scene(&s2).observe(k).len()).sum();
        assert!((seen2 as f64 / 404.0 - 0.5).abs() < 0.1, "{seen2}");
    }
}
