//! What the filter takes from a `[stereo]` section: the rig as the filter knows it, its
//! settings, and the paper's Table 1 start (math.md §5.6: truth with its stated offsets, k̂₀ =
//! 0) for a scenario that asks for it.

use glint_physics::orbit::mean_motion_at_altitude_rad_s;
use glint_physics::stereo::c_co_along_track;
use nalgebra::{UnitQuaternion, Vector2, Vector3};
use shared_types::scenario::{StereoScenario, StereoStart};

use crate::model::{ix, ErrMat, Nominal, Rig};
use crate::service_core::{Settings, Start};

/// The rig of a `[stereo]` section, with the filter's PSDs.
pub fn rig(s: &StereoScenario) -> Rig {
    Rig {
        mean_motion_rad_s: mean_motion_at_altitude_rad_s(s.altitude_km),
        baseline_m: s.baseline_m,
        sigma_norm: s.sigma_norm,
        c_co: c_co_along_track(),
        features_m: s.features().into_iter().map(Vector3::from).collect(),
        torque_psd: s.filter.torque_psd,
        accel_psd: s.filter.accel_psd,
    }
}

/// The core's settings of a `[stereo]` section.
pub fn settings(s: &StereoScenario) -> Settings {
    Settings {
        start_epochs: s.filter.start_epochs as usize,
        gate_chi2: s.filter.gate_chi2,
        ..Settings::default()
    }
}

/// Table 1's initial 1σ [ASSUMP; the paper's P₀ was lost]: attitude 1° per axis, ω 1e-3 rad/s,
/// k 1, ρ 0.05 m, v 1e-3 m/s.
const TABLE1_SIGMA: [f64; 5] = [0.017453292519943295, 1e-3, 1.0, 0.05, 1e-3];

/// How the section starts the filter.
pub fn start(s: &StereoScenario) -> Start {
    match s.filter.start {
        StereoStart::Measurements => Start::Measurements,
        StereoStart::Table1 => {
            let q_true = UnitQuaternion::from_scaled_axis(
                Vector3::from(s.attitude0_rotvec_deg).map(f64::to_radians),
            );
            let [sa, sw, sk, sr, sv] = TABLE1_SIGMA;
            let offset = Vector3::new(1.0, -1.0, 1.0).map(f64::to_radians);
            let x = Nominal {
                q_ct: q_true * UnitQuaternion::from_scaled_axis(offset),
                w_t: Vector3::from(s.rate0_rad_s).add_scalar(sw),
                k: Vector2::zeros(),
                rho_o: Vector3::from(s.rho0_m).add_scalar(sr),
                v_o: Vector3::from(s.v0_m_s).add_scalar(sv),
            };
            let mut p = ErrMat::zeros();
            for i in 0..3 {
                p[(ix::TH + i, ix::TH + i)] = sa * sa;
                p[(ix::W + i, ix::W + i)] = sw * sw;
                p[(ix::RHO + i, ix::RHO + i)] = sr * sr;
                p[(ix::V + i, ix::V + i)] = sv * sv;
            }
            for i in 0..2 {
                p[(ix::K + i, ix::K + i)] = sk * sk;
            }
            Start::Given {
                x,
                p: Box::new(p),
                t_s: 0.0,
            }
        }
    }
}
