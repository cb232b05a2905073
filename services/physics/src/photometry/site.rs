//! Where the light comes from and who sees it ([001], docs/math.md §2.4): a ground station on
//! the WGS 84 ellipsoid, a satellite on a circular orbit (GEO by default), the Sun from the
//! almanac of [`crate::sun`], the Earth's cylindrical shadow and the station's horizon.
//!
//! Frames: ECI is the almanac's (≈ J2000 axes); the Earth turns in it by the Greenwich mean
//! sidereal angle `θ = 280.46061837° + 360.98564736629° (JD − 2451545)` (UT1 ≈ UTC here: a
//! second of it is 0.004° of turn). Directions handed to the photometry are unit vectors from
//! the satellite to the Sun and to the observer, in ECI.

use nalgebra::Vector3;

use crate::orbit::{CircularOrbit, EARTH_RADIUS_M};
use crate::sun::{sun_eci_from_jd, JD_J2000};

/// WGS 84 flattening.
const WGS84_F: f64 = 1.0 / 298.257_223_563;
/// The astronomical unit [m]: the Sun's distance for the satellite-to-Sun direction.
const AU_M: f64 = 1.495_978_707e11;
/// Seconds per day.
const DAY_S: f64 = 86_400.0;

/// Greenwich mean sidereal angle θ [rad] at Julian date `jd`.
pub fn gmst_rad(jd: f64) -> f64 {
    (280.460_618_37 + 360.985_647_366_29 * (jd - JD_J2000))
        .rem_euclid(360.0)
        .to_radians()
}

/// An Earth-fixed vector turned into ECI by the sidereal angle θ.
fn ecef_to_eci(v: Vector3<f64>, theta_rad: f64) -> Vector3<f64> {
    let (s, c) = theta_rad.sin_cos();
    Vector3::new(c * v.x - s * v.y, s * v.x + c * v.y, v.z)
}

/// A ground station: geodetic latitude and longitude [deg], height above the ellipsoid [m].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Station {
    pub latitude_deg: f64,
    pub longitude_deg: f64,
    pub altitude_m: f64,
}

impl Station {
    /// Earth-fixed position [m] and the local vertical (the ellipsoid's normal).
    pub fn ecef_m(&self) -> (Vector3<f64>, Vector3<f64>) {
        let (lat, lon) = (
            self.latitude_deg.to_radians(),
            self.longitude_deg.to_radians(),
        );
        let e2 = WGS84_F * (2.0 - WGS84_F);
        let n = EARTH_RADIUS_M / (1.0 - e2 * lat.sin().powi(2)).sqrt();
        let h = self.altitude_m;
        let p = Vector3::new(
            (n + h) * lat.cos() * lon.cos(),
            (n + h) * lat.cos() * lon.sin(),
            (n * (1.0 - e2) + h) * lat.sin(),
        );
        let up = Vector3::new(lat.cos() * lon.cos(), lat.cos() * lon.sin(), lat.sin());
        (p, up)
    }

    /// Position [m] and local vertical in ECI at Julian date `jd`.
    pub fn eci_m(&self, jd: f64) -> (Vector3<f64>, Vector3<f64>) {
        let (p, up) = self.ecef_m();
        let theta = gmst_rad(jd);
        (ecef_to_eci(p, theta), ecef_to_eci(up, theta))
    }
}

/// A geostationary orbit over `longitude_deg` at Julian date `jd0`: circular, equatorial,
/// radius 42 164.17 km, its argument of latitude the sidereal angle plus the longitude.
pub fn geostationary(longitude_deg: f64, jd0: f64) -> CircularOrbit {
    CircularOrbit {
        a_m: 42_164_170.0,
        raan_rad: 0.0,
        inc_rad: 0.0,
        arg_lat0_rad: gmst_rad(jd0) + longitude_deg.to_radians(),
    }
}

/// Why a sample has no magnitude.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Unseen {
    /// The satellite is in the Earth's (cylindrical) shadow.
    Shadow,
    /// It is below the station's horizon (or its minimum elevation).
    BelowHorizon,
}

/// One instant of the observation: the unit vectors from the satellite to the Sun and to the
/// observer (ECI), the range [m], the elevation at the station [deg].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Geometry {
    pub sun: Vector3<f64>,
    pub obs: Vector3<f64>,
    pub range_m: f64,
    pub elevation_deg: f64,
    pub in_shadow: bool,
}

impl Geometry {
    /// Whether the station sees it lit, above `min_elevation_deg`.
    pub fn visible(&self, min_elevation_deg: f64) -> Result<(), Unseen> {
        if self.elevation_deg < min_elevation_deg {
            Err(Unseen::BelowHorizon)
        } else if self.in_shadow {
            Err(Unseen::Shadow)
        } else {
            Ok(())
        }
    }
}

/// The geometry of `orbit` seen from `station`, `t_s` after Julian date `jd0`.
pub fn geometry(orbit: &CircularOrbit, station: &Station, jd0: f64, t_s: f64) -> Geometry {
    let jd = jd0 + t_s / DAY_S;
    let r_sat = orbit.position_eci_m(t_s);
    let (r_sta, up) = station.eci_m(jd);
    let s_hat = sun_eci_from_jd(jd);
    let to_obs = r_sta - r_sat;
    let range_m = to_obs.norm();
    let obs = to_obs / range_m;
    let sun = (s_hat * AU_M - r_sat).normalize();
    let elevation_deg = (-obs).dot(&up).clamp(-1.0, 1.0).asin().to_degrees();
    let along = r_sat.dot(&s_hat);
    let in_shadow = along < 0.0 && (r_sat - s_hat * along).norm() < EARTH_RADIUS_M;
    Geometry {
        sun,
        obs,
        range_m,
        elevation_deg,
        in_shadow,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// J2000.0 at 12:00 UT: θ = 280.46061837° (the formula's constant, IAU 1982).
    #[test]
    fn sidereal_angle_at_j2000() {
        assert!((gmst_rad(JD_J2000).to_degrees() - 280.460_618_37).abs() < 1e-9);
        // One sidereal day later the Earth has turned 360°: 86164.0905 s.
        let sidereal_day = 86_164.090_5 / DAY_S;
        let d = gmst_rad(JD_J2000 + sidereal_day) - gmst_rad(JD_J2000);
        assert!(
            d.rem_euclid(std::f64::consts::TAU)
                .min((-d).rem_euclid(std::f64::consts::TAU))
                < 1e-6
        );
    }

    /// A geostationary satellite stays over its longitude: its Earth-fixed direction is
    /// constant, at the equator, over a day.
    #[test]
    fn geostationary_stays_put() {
        let jd0 = 2_461_120.25;
        let orbit = geostationary(100.0, jd0);
        for t_s in [0.0, 3_600.0, 43_200.0, 86_000.0] {
            let r = orbit.position_eci_m(t_s);
            let theta = gmst_rad(jd0 + t_s / DAY_S);
            let lon = (r.y.atan2(r.x) - theta).to_degrees().rem_euclid(360.0);
            assert!((lon - 100.0).abs() < 0.01, "{lon}");
            assert!(r.z.abs() < 1e-6);
        }
    }

    /// A station under the satellite (equator, same longitude, sea level) sees it at the
    /// zenith at the orbit radius less the Earth's radius; one 90° away sees it below the
    /// horizon.
    #[test]
    fn range_and_elevation_by_hand() {
        let jd0 = 2_461_120.25;
        let orbit = geostationary(0.0, jd0);
        let under = Station {
            latitude_deg: 0.0,
            longitude_deg: 0.0,
            altitude_m: 0.0,
        };
        let g = geometry(&orbit, &under, jd0, 100.0);
        assert!((g.range_m - (42_164_170.0 - EARTH_RADIUS_M)).abs() < 1.0);
        assert!(g.elevation_deg > 89.99);
        let aside = Station {
            longitude_deg: 90.0,
            ..under
        };
        assert!(geometry(&orbit, &aside, jd0, 100.0).elevation_deg < 0.0);
    }

    /// At an equinox's local midnight the satellite is behind the Earth from the Sun: in
    /// shadow; at local noon it is lit.
    #[test]
    fn shadow_at_midnight_near_equinox() {
        // 2026-03-20 00:00 UT (the equinox is at 14:46 UT): local midnight at longitude 0.
        let jd0 = 2_461_119.5;
        let orbit = geostationary(0.0, jd0);
        let station = Station {
            latitude_deg: 0.0,
            longitude_deg: 0.0,
            altitude_m: 0.0,
        };
        assert!(geometry(&orbit, &station, jd0, 0.0).in_shadow);
        assert!(!geometry(&orbit, &station, jd0, 43_200.0).in_shadow);
        // Two hours before midnight it is lit (the shadow's half-width is 8.7° of orbit).
        assert!(!geometry(&orbit, &station, jd0, -7_200.0).in_shadow);
    }
}
