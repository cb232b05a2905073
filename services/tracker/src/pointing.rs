//! Laser pointing with delay prediction (docs/math.md §3.7, eq 16).
//!
//! The laser fires `t_r` after the estimate (t_r = 0.03 s in the seed), so it is pointed where
//! the target will be: `[α_t, β_t] = [α₀, β₀] + t_r [α̇₀, β̇₀]`, from the angle filter's state
//! (§3.6). The shot succeeds when the true direction at `t + t_r` lies within half the beam width
//! (0.5°/2 in the seed) of the commanded one; the angle between two directions is the
//! great-circle angle between their unit vectors `u(α, β) = (cos β cos α, sin β, cos β sin α)`
//! (§3.5), evaluated as `atan2(‖u₁ × u₂‖, u₁ · u₂)`, which is accurate for tiny angles.

use crate::angle_filter::AngleEstimate;
use glint_physics::camera::position_from_angles;

/// Seed laser delay t_r \[s\] (§3.9 Table 2).
pub const SEED_LASER_DELAY_S: f64 = 0.03;
/// Seed beam full width \[rad\] (0.5°, §3.9 Table 2).
pub const SEED_BEAM_WIDTH_RAD: f64 = 0.5 * std::f64::consts::PI / 180.0;

/// Where to point the laser, and when.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PointingCommand {
    /// Time of the angle estimate the command is based on \[s\].
    pub estimate_t_s: f64,
    /// Time the laser fires, `estimate_t_s + t_r` \[s\].
    pub fire_t_s: f64,
    pub azimuth_rad: f64,
    pub elevation_rad: f64,
}

/// Eq 16: the direction predicted `delay_s` after the estimate.
pub fn predict_pointing(estimate: &AngleEstimate, delay_s: f64) -> PointingCommand {
    PointingCommand {
        estimate_t_s: estimate.t_s,
        fire_t_s: estimate.t_s + delay_s,
        azimuth_rad: estimate.azimuth_rad + delay_s * estimate.azimuth_rate_rad_s,
        elevation_rad: estimate.elevation_rad + delay_s * estimate.elevation_rate_rad_s,
    }
}

/// Great-circle angle between the directions (α₁, β₁) and (α₂, β₂) \[rad\], in \[0, π\].
pub fn great_circle_angle_rad(
    azimuth1_rad: f64,
    elevation1_rad: f64,
    azimuth2_rad: f64,
    elevation2_rad: f64,
) -> f64 {
    let u1 = position_from_angles(azimuth1_rad, elevation1_rad, 1.0);
    let u2 = position_from_angles(azimuth2_rad, elevation2_rad, 1.0);
    u1.cross(&u2).norm().atan2(u1.dot(&u2))
}

/// Whether the true direction lies within half the beam width of the command.
pub fn beam_hits(
    command: &PointingCommand,
    true_azimuth_rad: f64,
    true_elevation_rad: f64,
    beam_width_rad: f64,
) -> bool {
    great_circle_angle_rad(
        command.azimuth_rad,
        command.elevation_rad,
        true_azimuth_rad,
        true_elevation_rad,
    ) <= 0.5 * beam_width_rad
}

#[cfg(test)]
mod tests {
    use super::*;

    fn estimate(az: f64, az_rate: f64, el: f64, el_rate: f64) -> AngleEstimate {
        AngleEstimate {
            t_s: 2.0,
            azimuth_rad: az,
            azimuth_rate_rad_s: az_rate,
            elevation_rad: el,
            elevation_rate_rad_s: el_rate,
            covariance_diag: [0.0; 4],
        }
    }

    #[test]
    fn eq_16_extrapolates_by_the_delay() {
        let cmd = predict_pointing(&estimate(0.07, 0.1, 0.06, -0.2), SEED_LASER_DELAY_S);
        assert!((cmd.azimuth_rad - 0.073).abs() < 1e-15);
        assert!((cmd.elevation_rad - 0.054).abs() < 1e-15);
        assert_eq!((cmd.estimate_t_s, cmd.fire_t_s), (2.0, 2.03));
    }

    #[test]
    fn great_circle_angle_matches_simple_cases() {
        // Pure azimuth or pure elevation offsets at β = 0 are the offsets themselves.
        assert!((great_circle_angle_rad(0.0, 0.0, 0.3, 0.0) - 0.3).abs() < 1e-15);
        assert!((great_circle_angle_rad(0.1, 0.0, 0.1, -0.25) - 0.25).abs() < 1e-15);
        // At elevation β an azimuth step Δα spans ≈ Δα cos β.
        let beta = 60f64.to_radians();
        let d = great_circle_angle_rad(0.0, beta, 1e-6, beta);
        assert!((d - 1e-6 * beta.cos()).abs() < 1e-15);
        assert_eq!(great_circle_angle_rad(0.2, 0.1, 0.2, 0.1), 0.0);
        assert!(
            (great_circle_angle_rad(0.0, 0.0, std::f64::consts::PI, 0.0) - std::f64::consts::PI)
                .abs()
                < 1e-12
        );
    }

    #[test]
    fn beam_success_is_half_the_width() {
        let cmd = predict_pointing(&estimate(0.0, 0.0, 0.0, 0.0), 0.03);
        let half = 0.5 * SEED_BEAM_WIDTH_RAD;
        assert!(beam_hits(&cmd, 0.999 * half, 0.0, SEED_BEAM_WIDTH_RAD));
        assert!(!beam_hits(&cmd, 1.001 * half, 0.0, SEED_BEAM_WIDTH_RAD));
        assert!(beam_hits(&cmd, 0.7 * half, 0.7 * half, SEED_BEAM_WIDTH_RAD));
        assert!(!beam_hits(
            &cmd,
            0.75 * half,
            0.75 * half,
            SEED_BEAM_WIDTH_RAD
        ));
    }

    #[test]
    fn delay_prediction_beats_the_stale_direction() {
        // A target at the Table-4 angular rates (~0.6°/s) moves 0.018° in 30 ms: the stale
        // pointing error is larger than the predicted one.
        let (az0, el0, az_rate, el_rate) = (0.07, 0.06, 0.0105, -0.004);
        let cmd = predict_pointing(&estimate(az0, az_rate, el0, el_rate), 0.03);
        let (az_true, el_true) = (az0 + 0.03 * az_rate, el0 + 0.03 * el_rate);
        let predicted =
            great_circle_angle_rad(cmd.azimuth_rad, cmd.elevation_rad, az_true, el_true);
        let stale = great_circle_angle_rad(az0, el0, az_true, el_true);
        assert!(predicted < 1e-12 && stale > 3e-4);
    }
}
