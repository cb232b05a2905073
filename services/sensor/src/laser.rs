//! Laser rangefinder of seed 002 (docs/math.md §3.7, Table 2 of §3.9), as a pure function.
//!
//! Directions are camera-frame angles (§3.5): azimuth α = atan2(z_c, x_c) (in-plane), elevation
//! β = atan2(y_c, √(x_c² + z_c²)), i.e. the unit vector `(cos β cos α, sin β, cos β sin α)`.
//! A shot fired along (α_p, β_p) hits the target whose direction is nearest to the boresight,
//! provided that great-circle angle is ≤ half the full beam width (a circular beam, 0.25° for the
//! 0.5° beam; not an α/β box). The measured range is `r + σ_r·n` with n ~ N(0, 1) supplied by the
//! caller (so the model stays pure and the caller owns the random stream); σ_r = 0.1/3 m (0.1 m at
//! 3σ). The response is available `delay_s` = 0.03 s after the request (the caller schedules it;
//! §3.7 predicts the pointing over this delay).

use std::fmt;

/// Rangefinder parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LaserConfig {
    /// Full (not half) width of the circular beam, rad, in (0, π]. Table 2: 0.5°.
    pub beam_full_width_rad: f64,
    /// Range noise standard deviation, m, ≥ 0. Table 2: 0.1 m at 3σ.
    pub range_sigma_m: f64,
    /// Time from request to response, s, ≥ 0. Table 2: 0.03 s.
    pub delay_s: f64,
}

impl Default for LaserConfig {
    fn default() -> Self {
        Self {
            beam_full_width_rad: 0.5f64.to_radians(),
            range_sigma_m: 0.1 / 3.0,
            delay_s: 0.03,
        }
    }
}

/// Why a [`LaserConfig`] was rejected.
#[derive(Clone, Debug, PartialEq)]
pub struct LaserConfigError {
    /// The offending field.
    pub field: &'static str,
    /// Its value.
    pub value: f64,
    /// The allowed range, in words.
    pub allowed: &'static str,
}

impl fmt::Display for LaserConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "laser config: {} = {} is not in {}",
            self.field, self.value, self.allowed
        )
    }
}

impl std::error::Error for LaserConfigError {}

impl LaserConfig {
    /// Check every field against its documented range.
    pub fn validate(&self) -> Result<(), LaserConfigError> {
        let checks = [
            (
                "beam_full_width_rad",
                self.beam_full_width_rad,
                self.beam_full_width_rad > 0.0 && self.beam_full_width_rad <= std::f64::consts::PI,
                "(0, π]",
            ),
            (
                "range_sigma_m",
                self.range_sigma_m,
                self.range_sigma_m >= 0.0,
                "[0, ∞)",
            ),
            ("delay_s", self.delay_s, self.delay_s >= 0.0, "[0, ∞)"),
        ];
        for (field, value, ok, allowed) in checks {
            if !ok || !value.is_finite() {
                return Err(LaserConfigError {
                    field,
                    value,
                    allowed,
                });
            }
        }
        Ok(())
    }
}

/// A candidate target as the simulator knows it at the time of the shot.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LaserTarget {
    /// The caller's identifier, echoed in [`RangeOutcome::Hit`].
    pub id: u32,
    /// Azimuth α, rad.
    pub azimuth_rad: f64,
    /// Elevation β, rad.
    pub elevation_rad: f64,
    /// True range, m (> 0).
    pub range_m: f64,
}

impl From<(u32, f64, f64, f64)> for LaserTarget {
    /// From `(id, azimuth_rad, elevation_rad, range_m)`.
    fn from((id, azimuth_rad, elevation_rad, range_m): (u32, f64, f64, f64)) -> Self {
        Self {
            id,
            azimuth_rad,
            elevation_rad,
            range_m,
        }
    }
}

/// Result of one shot.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RangeOutcome {
    /// The beam illuminated `target_id`; `range_m` is the noisy measured range.
    Hit { target_id: u32, range_m: f64 },
    /// No valid target within half the beam width of the boresight.
    Miss,
}

/// Unit vector of the direction (α, β) in the camera frame (x boresight, y up, z = x × y).
pub fn direction(azimuth_rad: f64, elevation_rad: f64) -> [f64; 3] {
    let (sa, ca) = azimuth_rad.sin_cos();
    let (sb, cb) = elevation_rad.sin_cos();
    [cb * ca, sb, cb * sa]
}

/// Great-circle angle between two directions, rad, in [0, π]; accurate for tiny angles too
/// (atan2 of |a × b| and a·b rather than acos).
pub fn angular_distance_rad(az_a_rad: f64, el_a_rad: f64, az_b_rad: f64, el_b_rad: f64) -> f64 {
    let a = direction(az_a_rad, el_a_rad);
    let b = direction(az_b_rad, el_b_rad);
    let cross = [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ];
    let sin = (cross[0].powi(2) + cross[1].powi(2) + cross[2].powi(2)).sqrt();
    let cos = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    sin.atan2(cos)
}

/// Fire along (pointing_az_rad, pointing_el_rad). Targets with non-finite angles or a range
/// that is not finite and > 0 are ignored; ties go to the earlier target; a non-finite pointing
/// or noise draw gives [`RangeOutcome::Miss`].
pub fn respond(
    cfg: &LaserConfig,
    pointing_az_rad: f64,
    pointing_el_rad: f64,
    targets: &[LaserTarget],
    noise_draw: f64,
) -> RangeOutcome {
    if !(pointing_az_rad.is_finite() && pointing_el_rad.is_finite() && noise_draw.is_finite()) {
        return RangeOutcome::Miss;
    }
    let half_width_rad = 0.5 * cfg.beam_full_width_rad;
    let mut best: Option<(f64, &LaserTarget)> = None;
    for t in targets {
        let valid = t.azimuth_rad.is_finite()
            && t.elevation_rad.is_finite()
            && t.range_m.is_finite()
            && t.range_m > 0.0;
        if !valid {
            continue;
        }
        let off_rad = angular_distance_rad(
            pointing_az_rad,
            pointing_el_rad,
            t.azimuth_rad,
            t.elevation_rad,
        );
        if off_rad <= half_width_rad && best.is_none_or(|(b, _)| off_rad < b) {
            best = Some((off_rad, t));
        }
    }
    match best {
        Some((_, t)) => RangeOutcome::Hit {
            target_id: t.id,
            range_m: t.range_m + cfg.range_sigma_m * noise_draw,
        },
        None => RangeOutcome::Miss,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DEG: f64 = std::f64::consts::PI / 180.0;

    fn target(id: u32, az_deg: f64, el_deg: f64, range_m: f64) -> LaserTarget {
        (id, az_deg * DEG, el_deg * DEG, range_m).into()
    }

    #[test]
    fn defaults_are_table_2() {
        let c = LaserConfig::default();
        assert!((c.beam_full_width_rad - 0.008_726_646_259_971_648).abs() < 1e-15);
        assert!((3.0 * c.range_sigma_m - 0.1).abs() < 1e-15);
        assert_eq!(c.delay_s, 0.03);
        assert!(c.validate().is_ok());
        let bad = LaserConfig {
            range_sigma_m: f64::NAN,
            ..c
        };
        assert_eq!(bad.validate().unwrap_err().field, "range_sigma_m");
        assert!(LaserConfig {
            beam_full_width_rad: 0.0,
            ..c
        }
        .validate()
        .is_err());
    }

    #[test]
    fn hit_inside_half_beam_returns_noise_free_range_at_zero_draw() {
        // Debris #4 of Table 4: (α, β, r) = (4.0042°, 3.4253°, 10042.41 m); pointing 0.2° off.
        let t = [target(4, 4.0042, 3.4253, 10_042.41)];
        let out = respond(&LaserConfig::default(), 4.0042 * DEG, 3.2253 * DEG, &t, 0.0);
        assert_eq!(
            out,
            RangeOutcome::Hit {
                target_id: 4,
                range_m: 10_042.41
            }
        );
    }

    #[test]
    fn miss_outside_half_beam_and_circle_not_box() {
        let c = LaserConfig::default();
        let t = [target(1, 0.2, 0.2, 9000.0)];
        // 0.2° in both axes is inside a 0.25° box but 0.283° away on the sphere.
        assert_eq!(respond(&c, 0.0, 0.0, &t, 0.0), RangeOutcome::Miss);
        assert!(matches!(
            respond(&c, 0.0, 0.0, &[target(1, 0.24, 0.0, 9000.0)], 0.0),
            RangeOutcome::Hit { .. }
        ));
        assert_eq!(
            respond(&c, 0.0, 0.0, &[target(1, 0.26, 0.0, 9000.0)], 0.0),
            RangeOutcome::Miss
        );
        assert_eq!(respond(&c, 0.0, 0.0, &[], 0.0), RangeOutcome::Miss);
    }

    #[test]
    fn azimuth_offsets_shrink_with_elevation() {
        // At β = 60°, Δα = 0.4° is only 0.2° on the sphere: inside the beam.
        let c = LaserConfig::default();
        let t = [target(9, 10.4, 60.0, 5000.0)];
        assert!(matches!(
            respond(&c, 10.0 * DEG, 60.0 * DEG, &t, 0.0),
            RangeOutcome::Hit { .. }
        ));
        let d = angular_distance_rad(10.0 * DEG, 60.0 * DEG, 10.4 * DEG, 60.0 * DEG);
        assert!((d / DEG - 0.2).abs() < 1e-4, "{}", d / DEG);
    }

    #[test]
    fn nearest_of_two_wins_in_either_order() {
        let c = LaserConfig::default();
        let near = target(2, 1.05, 1.0, 8000.0);
        let far = target(3, 1.0, 1.2, 6000.0);
        for ts in [[near, far], [far, near]] {
            let out = respond(&c, 1.0 * DEG, 1.0 * DEG, &ts, 0.0);
            assert_eq!(
                out,
                RangeOutcome::Hit {
                    target_id: 2,
                    range_m: 8000.0
                }
            );
        }
    }

    #[test]
    fn range_noise_scales_with_sigma_and_draw() {
        let t = [target(1, 0.0, 0.0, 9000.0)];
        for (sigma, draw) in [(0.1 / 3.0, 1.0), (0.1 / 3.0, -3.0), (0.5, 2.0)] {
            let c = LaserConfig {
                range_sigma_m: sigma,
                ..LaserConfig::default()
            };
            let RangeOutcome::Hit { range_m, .. } = respond(&c, 0.0, 0.0, &t, draw) else {
                panic!("expected a hit");
            };
            assert!((range_m - (9000.0 + sigma * draw)).abs() < 1e-9);
        }
    }

    #[test]
    fn invalid_inputs_are_ignored_or_miss() {
        let c = LaserConfig::default();
        let good = target(5, 0.0, 0.0, 100.0);
        let ts = [
            target(1, f64::NAN, 0.0, 100.0),
            target(2, 0.0, 0.0, -1.0),
            good,
        ];
        assert_eq!(
            respond(&c, 0.0, 0.0, &ts, 0.0),
            RangeOutcome::Hit {
                target_id: 5,
                range_m: 100.0
            }
        );
        assert_eq!(respond(&c, f64::NAN, 0.0, &ts, 0.0), RangeOutcome::Miss);
        assert_eq!(
            respond(&c, 0.0, 0.0, &ts, f64::INFINITY),
            RangeOutcome::Miss
        );
    }
}
