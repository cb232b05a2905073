//! Circular Keplerian orbits and the LVLH-nadir frame (docs/math.md §1.1, §6.3, §7.1).
//!
//! A circular orbit of radius a, right ascension of the ascending node Ω and inclination i has
//! mean motion `n = sqrt(μ/a³)` and argument of latitude `u(t) = u0 + n t` (with ω = 0 and e = 0,
//! u equals the true anomaly ν). In ECI
//!
//! ```text
//! r(t) = a [cΩ cu − sΩ su ci,  sΩ cu + cΩ su ci,  su si]
//! v(t) = a n [−cΩ su − sΩ cu ci,  −sΩ su + cΩ cu ci,  cu si]
//! ĥ    = [sΩ si, −cΩ si, ci]
//! ```
//!
//! The LVLH-nadir frame (§1.1, §6.3) has x = ĥ×r̂ (along the velocity), y = −ĥ, z = −r̂ (nadir):
//! `C_{LVLH_N←ECI} = [(ĥ×r̂)ᵀ; −ĥᵀ; −r̂ᵀ]` (rows). The seed-000 target body frame at rest equals it.

use nalgebra::{Matrix3, RowVector3, Vector3};

/// Earth's gravitational parameter μ [m³ s⁻²] (§7.1).
pub const MU_EARTH_M3_S2: f64 = 3.986004418e14;

/// Earth's equatorial radius [m] (WGS 84).
pub const EARTH_RADIUS_M: f64 = 6_378_137.0;

/// Mean motion [rad/s] of a circular orbit `altitude_km` above the equatorial radius.
pub fn mean_motion_at_altitude_rad_s(altitude_km: f64) -> f64 {
    let a_m = EARTH_RADIUS_M + altitude_km * 1e3;
    (MU_EARTH_M3_S2 / (a_m * a_m * a_m)).sqrt()
}

/// A circular orbit; all angles in radians, ECI (≈ J2000) frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CircularOrbit {
    /// Orbit radius (semi-major axis) \[m\], must be > 0.
    pub a_m: f64,
    /// Right ascension of the ascending node Ω \[rad\].
    pub raan_rad: f64,
    /// Inclination i \[rad\].
    pub inc_rad: f64,
    /// Argument of latitude at t = 0 (ω + ν) \[rad\].
    pub arg_lat0_rad: f64,
}

impl CircularOrbit {
    /// Mean motion `n = sqrt(μ/a³)` \[rad/s\].
    pub fn mean_motion_rad_s(&self) -> f64 {
        (MU_EARTH_M3_S2 / (self.a_m * self.a_m * self.a_m)).sqrt()
    }

    /// Argument of latitude `u0 + n t` \[rad\] at `t_s` seconds after the element epoch.
    pub fn arg_lat_rad(&self, t_s: f64) -> f64 {
        self.arg_lat0_rad + self.mean_motion_rad_s() * t_s
    }

    /// Position in ECI \[m\] at `t_s`.
    pub fn position_eci_m(&self, t_s: f64) -> Vector3<f64> {
        self.in_plane_basis(t_s).0 * self.a_m
    }

    /// Velocity in ECI \[m/s\] at `t_s`.
    pub fn velocity_eci_mps(&self, t_s: f64) -> Vector3<f64> {
        self.in_plane_basis(t_s).1 * (self.a_m * self.mean_motion_rad_s())
    }

    /// Unit angular-momentum vector ĥ in ECI (constant).
    pub fn unit_h_eci(&self) -> Vector3<f64> {
        let (s_raan, c_raan) = self.raan_rad.sin_cos();
        let (s_inc, c_inc) = self.inc_rad.sin_cos();
        Vector3::new(s_raan * s_inc, -c_raan * s_inc, c_inc)
    }

    /// `C_{LVLH_N←ECI}` at `t_s`: rows `[(ĥ×r̂)ᵀ; −ĥᵀ; −r̂ᵀ]` (§1.1).
    pub fn c_lvlhn_eci(&self, t_s: f64) -> Matrix3<f64> {
        let (r_hat, along_hat) = self.in_plane_basis(t_s);
        let h_hat = self.unit_h_eci();
        Matrix3::from_rows(&[
            RowVector3::from(along_hat.transpose()),
            RowVector3::from(-h_hat.transpose()),
            RowVector3::from(-r_hat.transpose()),
        ])
    }

    /// (r̂, ĥ×r̂) at `t_s`; for a circular orbit ĥ×r̂ is the velocity direction.
    fn in_plane_basis(&self, t_s: f64) -> (Vector3<f64>, Vector3<f64>) {
        let (s_raan, c_raan) = self.raan_rad.sin_cos();
        let (s_inc, c_inc) = self.inc_rad.sin_cos();
        let (s_u, c_u) = self.arg_lat_rad(t_s).sin_cos();
        let r_hat = Vector3::new(
            c_raan * c_u - s_raan * s_u * c_inc,
            s_raan * c_u + c_raan * s_u * c_inc,
            s_u * s_inc,
        );
        let along_hat = Vector3::new(
            -c_raan * s_u - s_raan * c_u * c_inc,
            -s_raan * s_u + c_raan * c_u * c_inc,
            c_u * s_inc,
        );
        (r_hat, along_hat)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn orbit() -> CircularOrbit {
        CircularOrbit {
            a_m: 7.0e6,
            raan_rad: 0.7,
            inc_rad: 0.9,
            arg_lat0_rad: 0.3,
        }
    }

    #[test]
    fn geo_mean_motion_matches_reference() {
        let geo = CircularOrbit {
            a_m: 42_164_169.6,
            raan_rad: 0.0,
            inc_rad: 0.0,
            arg_lat0_rad: 0.0,
        };
        let n = geo.mean_motion_rad_s();
        assert!((n - 7.292115864164384e-05).abs() < 1e-19, "n = {n:e}");
    }

    #[test]
    fn velocity_is_derivative_of_position() {
        let o = orbit();
        let (t, h) = (1234.5, 0.01);
        let fd = (o.position_eci_m(t + h) - o.position_eci_m(t - h)) / (2.0 * h);
        let v = o.velocity_eci_mps(t);
        assert!((fd - v).norm() < 1e-6 * v.norm(), "{fd} vs {v}");
    }

    #[test]
    fn angular_momentum_direction_is_consistent() {
        let o = orbit();
        let r = o.position_eci_m(500.0);
        let v = o.velocity_eci_mps(500.0);
        let h = r.cross(&v).normalize();
        assert!((h - o.unit_h_eci()).norm() < 1e-14);
    }

    #[test]
    fn lvlhn_dcm_is_proper_and_maps_axes() {
        let o = orbit();
        let t = 3000.0;
        let c = o.c_lvlhn_eci(t);
        assert!((c * c.transpose() - Matrix3::identity()).abs().max() < 1e-14);
        assert!((c.determinant() - 1.0).abs() < 1e-14);
        // Position is straight up (−z), velocity along +x.
        let r_l = c * o.position_eci_m(t);
        assert!((r_l / o.a_m - Vector3::new(0.0, 0.0, -1.0)).norm() < 1e-14);
        let v_l = c * o.velocity_eci_mps(t).normalize();
        assert!((v_l - Vector3::x()).norm() < 1e-14);
    }
}
