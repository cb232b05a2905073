//! Seed-000 GEO "hover" observation geometry (docs/math.md §1.1, §1.7 Table 1).
//!
//! Target and observer fly circular orbits (ECI). The target is three-axis stable, so its body
//! frame B is its LVLH-nadir frame: `x_B = C_{LVLH_N←ECI}(t) x_ECI` (§1.1). At time t:
//!
//! ```text
//! d = r_obs(t) − r_tgt(t),  range = ‖d‖,  o_B = C(t) d/‖d‖,  s_B = C(t) ŝ_ECI
//! ```
//!
//! The Sun is at infinity (GEO parallax < 0.02°) and fixed over a scenario (it moves ≈ 0.04°/h):
//! `ŝ_ECI = (cos δ cos λ_s, cos δ sin λ_s, sin δ)`, with declination δ fixed per geometry and the
//! Sun's longitude λ_s (its right ascension, measured in the equatorial plane; at the seed's
//! March-equinox epoch this equals the ecliptic longitude to < 0.1°) as the free parameter.
//!
//! Phase g is the angle between s and o: `cos g = ŝ·ô = cos δ ρ cos(λ_s − φ) + sin δ ô_z`, with
//! `ρ, φ` the polar coordinates of ô in the equatorial plane, so λ_s = φ ± acos(…). The branch
//! is chosen from the sign of `d(cos g)/dt = ŝ·dô/dt`, with `dô/dt = (ḋ − ô(ô·ḋ))/‖d‖`: the phase
//! decreases (towards glint) when that derivative is positive.

use crate::frames::{angle_between_rad, normalize};
use crate::orbit::CircularOrbit;
use crate::sun::sun_eci_from_equatorial;
use nalgebra::Vector3;

/// Sun and observer directions in the target body frame, and the range.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HoverSample {
    /// Unit vector target → Sun in B.
    pub s_body: Vector3<f64>,
    /// Unit vector target → observer in B.
    pub o_body: Vector3<f64>,
    /// Target–observer distance ‖T0‖ \[m\].
    pub range_m: f64,
}

/// Co-orbital observer geometry around a three-axis-stable target.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HoverGeometry {
    /// Target orbit (elements at t = 0).
    pub target: CircularOrbit,
    /// Observer orbit (elements at t = 0).
    pub observer: CircularOrbit,
    /// Sun declination δ \[rad\], fixed over the scenario.
    pub sun_declination_rad: f64,
}

impl HoverGeometry {
    /// A geometry from two orbits and the Sun's declination \[rad\].
    pub fn new(target: CircularOrbit, observer: CircularOrbit, sun_declination_rad: f64) -> Self {
        Self {
            target,
            observer,
            sun_declination_rad,
        }
    }

    /// Tan et al. 2020 Table 1: target a = 42378.1 km, Ω = 181.803°, ν = 0°; observer
    /// a = 42408.0 km, Ω = 184.860°, ν = 359.93°; e = i = ω = 0.
    pub fn tan2020(sun_declination_rad: f64) -> Self {
        let orbit = |a_km: f64, raan_deg: f64, nu_deg: f64| CircularOrbit {
            a_m: a_km * 1e3,
            raan_rad: raan_deg.to_radians(),
            inc_rad: 0.0,
            arg_lat0_rad: nu_deg.to_radians(),
        };
        Self::new(
            orbit(42_378.1, 181.803, 0.0),
            orbit(42_408.0, 184.860, 359.93),
            sun_declination_rad,
        )
    }

    /// ŝ_ECI for Sun longitude `sun_lon_rad` and this geometry's declination.
    pub fn sun_eci(&self, sun_lon_rad: f64) -> Vector3<f64> {
        sun_eci_from_equatorial(sun_lon_rad, self.sun_declination_rad)
    }

    /// s, o in B and the range at `t_s`, for Sun longitude `sun_lon_rad`. `None` only if the
    /// observer coincides with the target.
    pub fn sample(&self, t_s: f64, sun_lon_rad: f64) -> Option<HoverSample> {
        self.sample_with_sun_eci(t_s, self.sun_eci(sun_lon_rad))
    }

    /// As [`HoverGeometry::sample`], with any unit Sun vector in ECI (e.g. from [`crate::sun`]).
    pub fn sample_with_sun_eci(&self, t_s: f64, s_eci: Vector3<f64>) -> Option<HoverSample> {
        let d_eci = self.observer.position_eci_m(t_s) - self.target.position_eci_m(t_s);
        let range_m = d_eci.norm();
        let o_eci = normalize(d_eci)?;
        let c_body_eci = self.target.c_lvlhn_eci(t_s);
        Some(HoverSample {
            s_body: c_body_eci * s_eci,
            o_body: c_body_eci * o_eci,
            range_m,
        })
    }

    /// Phase angle g between s and o \[rad\] at `t_s`.
    pub fn phase_angle_rad(&self, t_s: f64, sun_lon_rad: f64) -> Option<f64> {
        let o_eci = self.observer_direction_eci(t_s)?.0;
        Some(angle_between_rad(self.sun_eci(sun_lon_rad), o_eci))
    }

    /// The Sun longitude [rad, in [0, 2π)] that gives phase `phase_rad` at `t_s`, on the branch
    /// where the phase is decreasing (`decreasing = true`, approaching glint) or increasing.
    /// `None` if no Sun longitude reaches that phase with this declination.
    pub fn sun_longitude_for_phase(
        &self,
        phase_rad: f64,
        t_s: f64,
        decreasing: bool,
    ) -> Option<f64> {
        let (o, o_dot) = self.observer_direction_eci(t_s)?;
        let (sin_dec, cos_dec) = self.sun_declination_rad.sin_cos();
        let rho = o.x.hypot(o.y);
        let scale = cos_dec * rho;
        if scale.is_nan() || scale <= 1e-12 {
            return None;
        }
        let c = (phase_rad.cos() - sin_dec * o.z) / scale;
        if !(-1.0..=1.0).contains(&c) {
            return None;
        }
        let phi = o.y.atan2(o.x);
        let offset = c.acos();
        let sign = if decreasing { 1.0 } else { -1.0 };
        let rate = |lon: f64| sign * self.sun_eci(lon).dot(&o_dot);
        let (a, b) = (phi + offset, phi - offset);
        let lon = if rate(a) >= rate(b) { a } else { b };
        Some(lon.rem_euclid(std::f64::consts::TAU))
    }

    /// ô and dô/dt in ECI at `t_s`.
    fn observer_direction_eci(&self, t_s: f64) -> Option<(Vector3<f64>, Vector3<f64>)> {
        let d = self.observer.position_eci_m(t_s) - self.target.position_eci_m(t_s);
        let d_dot = self.observer.velocity_eci_mps(t_s) - self.target.velocity_eci_mps(t_s);
        let o = normalize(d)?;
        Some((o, (d_dot - o * o.dot(&d_dot)) / d.norm()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sun::sun_eci_from_jd;

    #[test]
    fn range_follows_the_chord_formula() {
        let geo = HoverGeometry::tan2020(0.0);
        let (a_t, a_o) = (geo.target.a_m, geo.observer.a_m);
        let dn = geo.observer.mean_motion_rad_s() - geo.target.mean_motion_rad_s();
        let lead0 = (184.860f64 + 359.93 - 360.0 - 181.803).to_radians();
        assert!((lead0.to_degrees() - 2.987).abs() < 1e-9);
        let mut prev = f64::INFINITY;
        for k in 0..=11 {
            let t_s = 1800.0 * f64::from(k);
            let sample = geo.sample(t_s, 0.3).expect("distinct orbits");
            let lead = lead0 + dn * t_s;
            let chord = (a_t * a_t + a_o * a_o - 2.0 * a_t * a_o * lead.cos()).sqrt();
            assert!((sample.range_m - chord).abs() < 1e-6 * chord);
            assert!(
                (2_145e3..2_211e3).contains(&sample.range_m),
                "{}",
                sample.range_m
            );
            assert!(sample.range_m < prev, "the target closes in");
            prev = sample.range_m;
            // The observer leads (+x_B) in the same plane; the chord dips ≈ 1.5° below the local
            // horizontal while the observer is 30 km higher, so o is within 1° of +x_B.
            assert!(sample.o_body.x > 0.9998, "{}", sample.o_body);
            assert!(sample.o_body.y.abs() < 1e-12);
            assert!((sample.s_body.norm() - 1.0).abs() < 1e-14);
        }
        assert!(prev < 2_150e3, "≈ 2146 km after 5.5 h: {prev}");
    }

    #[test]
    fn solved_sun_longitude_reproduces_the_phase() {
        let h = 1.0;
        for dec_deg in [0.0, -10.0, 23.0] {
            let geo = HoverGeometry::tan2020(f64::to_radians(dec_deg));
            for t_s in [0.0, 7200.0, 19800.0] {
                // Reachable phases lie in [|δ|, 180° − |δ|].
                for phase_deg in
                    [3.0, 15.0, 35.0, 90.0, 150.0].map(|p: f64| p.max(dec_deg.abs() + 3.0))
                {
                    let phase = f64::to_radians(phase_deg);
                    for decreasing in [true, false] {
                        let lon = geo
                            .sun_longitude_for_phase(phase, t_s, decreasing)
                            .unwrap_or_else(|| panic!("{dec_deg} {t_s} {phase_deg}"));
                        let got = geo.phase_angle_rad(t_s, lon).expect("distinct");
                        assert!((got - phase).abs() < 1e-9, "{dec_deg} {t_s} {phase_deg}");
                        let sample = geo.sample(t_s, lon).expect("distinct");
                        let body = angle_between_rad(sample.s_body, sample.o_body);
                        assert!((body - phase).abs() < 1e-9);
                        let rate = (geo.phase_angle_rad(t_s + h, lon).expect("ok")
                            - geo.phase_angle_rad(t_s - h, lon).expect("ok"))
                            / (2.0 * h);
                        assert_eq!(rate < 0.0, decreasing, "{dec_deg} {t_s} {phase_deg}");
                    }
                }
            }
        }
    }

    #[test]
    fn unreachable_phase_is_none() {
        // With the observer in the equatorial plane the phase is at least |δ|.
        let geo = HoverGeometry::tan2020(0.3);
        assert!(geo.sun_longitude_for_phase(0.2, 0.0, true).is_none());
        assert!(geo.sun_longitude_for_phase(0.31, 0.0, true).is_some());
        assert!(geo.sun_longitude_for_phase(f64::NAN, 0.0, true).is_none());
    }

    #[test]
    fn elements_at_march_21_give_the_documented_phase() {
        // §1.7 [DER]: elements at 2019-03-21 00:00 UTC, Sun from §6.2 → phase 5.7° at 05:30.
        let t_s = 5.5 * 3600.0;
        let jd_tt = 2_458_563.5 + (t_s + 69.184) / 86_400.0;
        let s_eci = sun_eci_from_jd(jd_tt);
        let geo = HoverGeometry::tan2020(s_eci.z.asin());
        let sample = geo.sample_with_sun_eci(t_s, s_eci).expect("distinct");
        let phase_deg = angle_between_rad(sample.s_body, sample.o_body).to_degrees();
        assert!((phase_deg - 5.7).abs() < 0.1, "phase {phase_deg}°");
        let via_lon = geo
            .phase_angle_rad(t_s, s_eci.y.atan2(s_eci.x))
            .expect("ok");
        assert!((via_lon.to_degrees() - phase_deg).abs() < 1e-9);
    }
}
