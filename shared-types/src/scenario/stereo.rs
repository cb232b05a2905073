//! The `[stereo]` section: the [004] chaser's stereo camera watching a tumbling,
//! non-cooperative target (docs/math.md §5), and what the `relnav` filter assumes.
//!
//! The paper's Tables 2 and 3 (features, orbit, inertia, rates, camera, noise PSDs, duration)
//! were lost; every default below is a placeholder of math.md §5.8, not the paper's value, and
//! the shipped scenario says so in its opening comment.

use serde::{Deserialize, Serialize};

use super::*;

/// The target, the rig and the filter's assumptions.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct StereoScenario {
    /// The chaser's circular-orbit altitude [km], 150–40000 (500 km: n = 1.1068e-3 rad/s).
    pub altitude_km: f64,
    /// Time between stereo epochs [s], 0.01–600.
    pub epoch_period_s: f64,
    /// Length of the run [s], 1–1e6: epochs at 0, Δt, 2Δt, … up to it.
    pub duration_s: f64,
    /// Stereo baseline [m], 0.01–100: the right camera at +baseline along x_C.
    pub baseline_m: f64,
    /// 1σ of each normalised image coordinate, 0–1e-2 (the paper: 1e-5).
    pub sigma_norm: f64,
    /// The target's principal moments [kg m²], each 1e-3–1e9, satisfying the triangle
    /// inequalities.
    pub inertia_kg_m2: [f64; 3],
    /// Its inertial angular velocity at t = 0, in T [rad/s], each −1–1.
    pub rate0_rad_s: [f64; 3],
    /// Its attitude at t = 0: the rotation vector of q_ct (T → C) [deg], norm ≤ 180.
    pub attitude0_rotvec_deg: [f64; 3],
    /// Its centre of mass relative to the camera at t = 0, in O (RSW: x radial, y
    /// along-track, z normal) [m], depth along y 0.5–10000.
    pub rho0_m: [f64; 3],
    /// Its velocity relative to the camera at t = 0, in O [m/s], each −10–10.
    pub v0_m_s: [f64; 3],
    /// Target size L [m], 0.01–100: the layout puts features at L/2 from the centre of mass.
    pub size_m: f64,
    /// Features of the layout, 3–14: ±x, ±y, ±z on the principal axes, then the corners of a
    /// cube inscribed in the sphere of radius L/2.
    pub n_features: u32,
    /// The features' coordinates in T [m] instead of the layout (3–16 of them).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub features_m: Vec<[f64; 3]>,
    /// A feature whose outward direction (from the centre of mass) faces away from the
    /// cameras is not seen.
    pub hide_back_faces: bool,
    /// The truth's disturbance: PSD of the normalised torque ε = τ/tr J [rad² s⁻³], 0–1e-6,
    /// and of the relative acceleration [m² s⁻³], 0–1e-6.
    pub torque_psd: f64,
    pub accel_psd: f64,
    /// Robustness: each feature missing at an epoch with this probability, 0–0.9.
    pub dropout_probability: f64,
    /// At an epoch, one seen feature reported with another feature's index (a wrong match)
    /// with this probability, 0–1.
    pub wrong_match_probability: f64,
    /// Intervals `[start_s, end_s]` without epochs (the target lost from view).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub gaps_s: Vec<[f64; 2]>,
    /// What the filter assumes and how it starts.
    pub filter: StereoFilter,
}

/// The `relnav` filter's settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct StereoFilter {
    /// `measurements` (default: triangulate, solve the pose, difference for the rates, k̂₀ =
    /// 0) or `table1` (the paper's Table 1: truth with attitude offset [1°, −1°, 1°], ω, ρ, v
    /// offset by +1σ of their initial covariances, k̂₀ = 0).
    pub start: StereoStart,
    /// The filter's PSDs of ε [rad² s⁻³] and of the relative acceleration [m² s⁻³], each
    /// 0–1e-3.
    pub torque_psd: f64,
    pub accel_psd: f64,
    /// Gate on a feature's squared Mahalanobis distance (χ², 4 dof), 4–1000.
    pub gate_chi2: f64,
    /// Epochs the start from the measurements fits, 2–100.
    pub start_epochs: u32,
}

/// How the filter starts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum StereoStart {
    #[default]
    Measurements,
    Table1,
}

impl Default for StereoFilter {
    fn default() -> Self {
        StereoFilter {
            start: StereoStart::Measurements,
            torque_psd: 1e-12,
            accel_psd: 1e-14,
            gate_chi2: 23.5,
            start_epochs: 5,
        }
    }
}

impl Default for StereoScenario {
    fn default() -> Self {
        StereoScenario {
            altitude_km: 500.0,
            epoch_period_s: 1.0,
            duration_s: 6000.0,
            baseline_m: 0.5,
            sigma_norm: 1e-5,
            inertia_kg_m2: [10.0, 12.0, 15.0],
            rate0_rad_s: [0.02, -0.03, 0.05],
            attitude0_rotvec_deg: [20.0, -30.0, 45.0],
            rho0_m: [0.0, 10.0, 0.0],
            v0_m_s: [-0.002, 0.0, 0.001],
            size_m: 1.0,
            n_features: 4,
            features_m: vec![],
            hide_back_faces: false,
            torque_psd: 1e-12,
            accel_psd: 1e-14,
            dropout_probability: 0.0,
            wrong_match_probability: 0.0,
            gaps_s: vec![],
            filter: StereoFilter::default(),
        }
    }
}

/// Most features an epoch can carry (the `stereo` topic's capacity).
pub const MAX_STEREO_FEATURES: usize = 16;

impl StereoScenario {
    /// The features' coordinates in T [m]: the given ones, or the layout's first
    /// `n_features`.
    pub fn features(&self) -> Vec<[f64; 3]> {
        if !self.features_m.is_empty() {
            return self.features_m.clone();
        }
        let h = 0.5 * self.size_m;
        let c = h / 3f64.sqrt();
        let mut layout = vec![
            [h, 0.0, 0.0],
            [-h, 0.0, 0.0],
            [0.0, h, 0.0],
            [0.0, -h, 0.0],
            [0.0, 0.0, h],
            [0.0, 0.0, -h],
        ];
        for sx in [1.0, -1.0] {
            for sy in [1.0, -1.0] {
                for sz in [1.0, -1.0] {
                    layout.push([sx * c, sy * c, sz * c]);
                }
            }
        }
        layout.truncate(self.n_features as usize);
        layout
    }

    /// Epoch `k`'s time [ns] for every epoch outside the gaps, in order.
    pub fn epoch_times_ns(&self) -> Vec<u64> {
        let period = self.epoch_period_s;
        if period.is_nan() || period <= 0.0 || self.duration_s.is_nan() || self.duration_s < 0.0 {
            return vec![];
        }
        let n = (self.duration_s / period + 1e-9).floor() as u64 + 1;
        (0..n)
            .map(|k| k as f64 * period)
            .filter(|t| !self.gaps_s.iter().any(|g| *t >= g[0] && *t <= g[1]))
            .map(|t| (t * 1e9).round() as u64)
            .collect()
    }

    /// Epochs over the run.
    pub fn epochs(&self) -> u64 {
        self.epoch_times_ns().len() as u64
    }
}

pub(super) fn check_stereo(c: &mut Checker, s: &StereoScenario) {
    c.range("stereo.altitude_km", s.altitude_km, 150.0, 40_000.0);
    c.range("stereo.epoch_period_s", s.epoch_period_s, 0.01, 600.0);
    c.range("stereo.duration_s", s.duration_s, 1.0, 1e6);
    if s.epoch_period_s > 0.0 {
        c.range(
            "stereo.duration_s / stereo.epoch_period_s (epochs)",
            s.duration_s / s.epoch_period_s,
            1.0,
            1e6,
        );
    }
    c.range("stereo.baseline_m", s.baseline_m, 0.01, 100.0);
    c.range("stereo.sigma_norm", s.sigma_norm, 0.0, 1e-2);
    for (i, j) in s.inertia_kg_m2.iter().enumerate() {
        c.range(&format!("stereo.inertia_kg_m2[{i}]"), *j, 1e-3, 1e9);
    }
    let [a, b, d] = s.inertia_kg_m2;
    if a + b <= d || b + d <= a || d + a <= b {
        c.fail(
            "stereo.inertia_kg_m2",
            format!("{a}, {b}, {d} break the triangle inequalities (each moment below the sum of the other two)"),
        );
    }
    for (i, w) in s.rate0_rad_s.iter().enumerate() {
        c.range(&format!("stereo.rate0_rad_s[{i}]"), *w, -1.0, 1.0);
    }
    let rv = s.attitude0_rotvec_deg;
    let norm = (rv[0] * rv[0] + rv[1] * rv[1] + rv[2] * rv[2]).sqrt();
    c.range("stereo.attitude0_rotvec_deg (norm)", norm, 0.0, 180.0);
    for i in [0, 2] {
        c.range(
            &format!("stereo.rho0_m[{i}]"),
            s.rho0_m[i],
            -10_000.0,
            10_000.0,
        );
    }
    c.range("stereo.rho0_m[1] (depth)", s.rho0_m[1], 0.5, 10_000.0);
    for (i, v) in s.v0_m_s.iter().enumerate() {
        c.range(&format!("stereo.v0_m_s[{i}]"), *v, -10.0, 10.0);
    }
    c.range("stereo.size_m", s.size_m, 0.01, 100.0);
    if s.features_m.is_empty() {
        c.range_u("stereo.n_features", s.n_features as u64, 3, 14);
    } else {
        c.range_u(
            "stereo.features_m (count)",
            s.features_m.len() as u64,
            3,
            MAX_STEREO_FEATURES as u64,
        );
        for (i, f) in s.features_m.iter().enumerate() {
            for (j, v) in f.iter().enumerate() {
                c.range(&format!("stereo.features_m[{i}][{j}]"), *v, -100.0, 100.0);
            }
        }
    }
    c.range("stereo.torque_psd", s.torque_psd, 0.0, 1e-6);
    c.range("stereo.accel_psd", s.accel_psd, 0.0, 1e-6);
    c.range(
        "stereo.dropout_probability",
        s.dropout_probability,
        0.0,
        0.9,
    );
    c.range(
        "stereo.wrong_match_probability",
        s.wrong_match_probability,
        0.0,
        1.0,
    );
    for (i, g) in s.gaps_s.iter().enumerate() {
        c.range(&format!("stereo.gaps_s[{i}][0]"), g[0], 0.0, s.duration_s);
        c.range(
            &format!("stereo.gaps_s[{i}][1]"),
            g[1],
            g[0].max(0.0),
            s.duration_s,
        );
    }
    let f = &s.filter;
    c.range("stereo.filter.torque_psd", f.torque_psd, 0.0, 1e-3);
    c.range("stereo.filter.accel_psd", f.accel_psd, 0.0, 1e-3);
    c.range("stereo.filter.gate_chi2", f.gate_chi2, 4.0, 1000.0);
    c.range_u("stereo.filter.start_epochs", f.start_epochs as u64, 2, 100);
}
