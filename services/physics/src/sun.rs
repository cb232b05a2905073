//! Low-precision Sun direction (docs/math.md §6.2), ≈ 0.01° over 1950–2050.
//!
//! With `D = JD − 2451545.0` (TT):
//!
//! ```text
//! L = 280.460° + 0.9856474° D          (mean longitude)
//! g = 357.528° + 0.9856003° D          (mean anomaly)
//! λ = L + 1.915° sin g + 0.020° sin 2g (ecliptic longitude)
//! ε = 23.439° − 4e-7° D                (obliquity)
//! ŝ_ECI = (cos λ, cos ε sin λ, sin ε sin λ)
//! ```
//!
//! The Earth-to-Sun direction is used as the target-to-Sun direction: the parallax of a GEO
//! object (4.2e7 m over 1.5e11 m) is below 0.02°.

use nalgebra::Vector3;

/// Julian date of the J2000.0 epoch (2000-01-01 12:00 TT).
pub const JD_J2000: f64 = 2_451_545.0;

/// Apparent ecliptic longitude of the Sun λ \[rad\] at Julian date `jd_tt` (TT), §6.2.
pub fn sun_ecliptic_longitude_rad(jd_tt: f64) -> f64 {
    let d = jd_tt - JD_J2000;
    let mean_lon_deg = 280.460 + 0.985_647_4 * d;
    let anomaly_rad = (357.528 + 0.985_600_3 * d).to_radians();
    let lon_deg = mean_lon_deg + 1.915 * anomaly_rad.sin() + 0.020 * (2.0 * anomaly_rad).sin();
    lon_deg.rem_euclid(360.0).to_radians()
}

/// Mean obliquity of the ecliptic ε \[rad\] at Julian date `jd_tt` (TT), §6.2.
pub fn obliquity_rad(jd_tt: f64) -> f64 {
    (23.439 - 4.0e-7 * (jd_tt - JD_J2000)).to_radians()
}

/// Unit vector Earth → Sun in ECI at Julian date `jd_tt` (TT), §6.2.
pub fn sun_eci_from_jd(jd_tt: f64) -> Vector3<f64> {
    sun_eci_from_longitude(sun_ecliptic_longitude_rad(jd_tt), obliquity_rad(jd_tt))
}

/// Unit vector Earth → Sun in ECI for an ecliptic longitude and an obliquity \[rad\]:
/// `(cos λ, cos ε sin λ, sin ε sin λ)`.
pub fn sun_eci_from_longitude(ecliptic_lon_rad: f64, obliquity_rad: f64) -> Vector3<f64> {
    let (s_lon, c_lon) = ecliptic_lon_rad.sin_cos();
    let (s_obl, c_obl) = obliquity_rad.sin_cos();
    Vector3::new(c_lon, c_obl * s_lon, s_obl * s_lon)
}

/// Unit vector Earth → Sun in ECI from equatorial coordinates (right ascension α, declination δ)
/// \[rad\]: `(cos δ cos α, cos δ sin α, sin δ)`.
pub fn sun_eci_from_equatorial(right_ascension_rad: f64, declination_rad: f64) -> Vector3<f64> {
    let (s_ra, c_ra) = right_ascension_rad.sin_cos();
    let (s_dec, c_dec) = declination_rad.sin_cos();
    Vector3::new(c_dec * c_ra, c_dec * s_ra, s_dec)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn j2000_matches_hand_computation() {
        // By hand at D = 0: g = 357.528°, λ = 280.460 + 1.915 sin g + 0.020 sin 2g
        // = 280.375680197°; ε = 23.439°.
        let lon_deg = sun_ecliptic_longitude_rad(JD_J2000).to_degrees();
        assert!((lon_deg - 280.375_680_197).abs() < 1e-8, "λ = {lon_deg}");
        let s = sun_eci_from_jd(JD_J2000);
        let expected = Vector3::new(0.180_101_641_634, -0.902_481_388_401, -0.391_268_120_692);
        assert!((s - expected).norm() < 1e-11, "{s}");
        // Astronomical Almanac, 2000-01-01 12h TT: α ≈ 18h45.2m (281.29°), δ ≈ −23.03°.
        let dec_deg = s.z.asin().to_degrees();
        let ra_deg = s.y.atan2(s.x).to_degrees().rem_euclid(360.0);
        assert!((dec_deg + 23.03).abs() < 0.02, "δ = {dec_deg}");
        assert!((ra_deg - 281.29).abs() < 0.03, "α = {ra_deg}");
    }

    #[test]
    fn march_equinox_2019_is_near_the_node() {
        // 2019-03-20 21:58 UTC equinox: λ ≈ 0, δ ≈ 0.
        let jd = 2_458_563.5 - 2.0 / 24.0 + 69.184 / 86400.0;
        let s = sun_eci_from_jd(jd);
        assert!(s.z.asin().to_degrees().abs() < 0.02);
        assert!((s.norm() - 1.0).abs() < 1e-15);
    }

    #[test]
    fn equatorial_and_ecliptic_forms_agree() {
        let (lon, obl) = (1.1, 0.409);
        let s = sun_eci_from_longitude(lon, obl);
        let e = sun_eci_from_equatorial(s.y.atan2(s.x), s.z.asin());
        assert!((s - e).norm() < 1e-15);
    }
}
