//! The Ashikhmin–Shirley BRDF as used for light curves (docs/math.md §2.2, eqs 1–3; Linares,
//! Jah, Crassidis & Nebelecky 2014):
//!
//! ```text
//! ρ = ρ_spec + ρ_diff                                                          (1)
//! ρ_diff = 28 R_d / (23π) (1 − R_s) [1 − (1 − n·s/2)⁵] [1 − (1 − n·o/2)⁵]      (2)
//! ρ_spec = √((n_u+1)(n_v+1)) / (8π) · (n·h)^z / Den · F                        (3)
//! z = (n_u (h·u)² + n_v (h·v)²) / (1 − (n·h)²),  F = R_s + (1 − R_s)(1 − s·h)⁵
//! ```
//!
//! `h = normalize(s + o)`. `Den` is Linares 2014's `n·s + n·o − (n·s)(n·o)` by default, or the
//! original paper's `(h·s) max(n·s, n·o)`. A facet contributes only when `n·s > 0` and
//! `n·o > 0`. ρ is in sr⁻¹.

use nalgebra::Vector3;
use std::f64::consts::PI;

/// A facet's reflectance parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Material {
    /// Diffuse and specular reflectances, each 0–1.
    pub r_diff: f64,
    pub r_spec: f64,
    /// Phong-like exponents along the facet's u and v axes, ≥ 0.
    pub n_u: f64,
    pub n_v: f64,
}

/// Which denominator the specular term uses (docs/math.md §2.2).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SpecularDenominator {
    /// `n·s + n·o − (n·s)(n·o)` (Linares et al. 2014; the light-curve literature's default).
    #[default]
    Linares2014,
    /// `(h·s) max(n·s, n·o)` (Ashikhmin & Shirley 2000).
    AshikhminShirley2000,
}

/// Below this, `1 − (n·h)²` is taken as 0 and the exponent as `(n_u + n_v)/2`.
const SINGULAR_EXPONENT: f64 = 1e-12;

/// ρ_total (eqs 1–3) of a facet with outward normal `n` and in-plane axes `u`, `v`
/// (`u × v = n`), lit from unit direction `sun` and seen from unit direction `obs`; 0 when the
/// facet faces away from either.
pub fn rho_total(
    n: &Vector3<f64>,
    u: &Vector3<f64>,
    v: &Vector3<f64>,
    sun: &Vector3<f64>,
    obs: &Vector3<f64>,
    m: &Material,
    den: SpecularDenominator,
) -> f64 {
    let (ns, no) = (n.dot(sun), n.dot(obs));
    if !(ns > 0.0 && no > 0.0) {
        return 0.0;
    }
    let diffuse = 28.0 * m.r_diff / (23.0 * PI)
        * (1.0 - m.r_spec)
        * (1.0 - (1.0 - 0.5 * ns).powi(5))
        * (1.0 - (1.0 - 0.5 * no).powi(5));
    let sum = sun + obs;
    let Some(h) = sum.try_normalize(0.0) else {
        return diffuse; // Sun and observer opposite: no half vector, no specular lobe
    };
    let nh = n.dot(&h).clamp(-1.0, 1.0);
    let sin2 = 1.0 - nh * nh;
    let z = if sin2 < SINGULAR_EXPONENT {
        0.5 * (m.n_u + m.n_v)
    } else {
        (m.n_u * h.dot(u).powi(2) + m.n_v * h.dot(v).powi(2)) / sin2
    };
    let sh = sun.dot(&h);
    let fresnel = m.r_spec + (1.0 - m.r_spec) * (1.0 - sh).powi(5);
    let denominator = match den {
        SpecularDenominator::Linares2014 => ns + no - ns * no,
        SpecularDenominator::AshikhminShirley2000 => sh * ns.max(no),
    };
    let specular = ((m.n_u + 1.0) * (m.n_v + 1.0)).sqrt() / (8.0 * PI) * nh.max(0.0).powf(z)
        / denominator
        * fresnel;
    diffuse + specular
}

#[cfg(test)]
mod tests {
    use super::*;

    fn axes() -> (Vector3<f64>, Vector3<f64>, Vector3<f64>) {
        (Vector3::z(), Vector3::x(), Vector3::y())
    }

    /// Sun overhead, observer 60° off the normal in the u–n plane; every factor by hand:
    /// n·s = 1, n·o = ½, h = normalize(sin60, 0, 1 + cos60) at 30° from n, so n·h = cos 30°,
    /// h·u = sin 30° = ½, h·v = 0, s·h = cos 30°.
    #[test]
    fn a_hand_computed_geometry() {
        let (n, u, v) = axes();
        let sun = Vector3::z();
        let obs = Vector3::new(60f64.to_radians().sin(), 0.0, 0.5);
        let m = Material {
            r_diff: 0.3,
            r_spec: 0.5,
            n_u: 10.0,
            n_v: 20.0,
        };
        let c30 = 3f64.sqrt() / 2.0;
        // (2): [1 − (1 − 1/2)⁵] = 31/32, [1 − (1 − 1/4)⁵] = 1 − 243/1024 = 781/1024
        let diffuse = 28.0 * 0.3 / (23.0 * PI) * 0.5 * (31.0 / 32.0) * (781.0 / 1024.0);
        // z = n_u (½)² / (1 − ¾) = n_u = 10
        let z = 10.0;
        let fresnel = 0.5 + 0.5 * (1.0 - c30).powi(5);
        let spec_base = (11.0f64 * 21.0).sqrt() / (8.0 * PI) * c30.powf(z) * fresnel;
        let linares = diffuse + spec_base / (1.0 + 0.5 - 0.5);
        let original = diffuse + spec_base / (c30 * 1.0);
        let got = |den| rho_total(&n, &u, &v, &sun, &obs, &m, den);
        assert!((got(SpecularDenominator::Linares2014) - linares).abs() < 1e-14 * linares);
        assert!(
            (got(SpecularDenominator::AshikhminShirley2000) - original).abs() < 1e-14 * original
        );
    }

    /// With n_u = n_v = n, z ≡ n exactly: (h·u)² + (h·v)² = 1 − (n·h)² (math.md §2.2).
    #[test]
    fn equal_exponents_give_z_equal_to_n_for_any_geometry() {
        let (n, u, v) = axes();
        let m = Material {
            r_diff: 0.0,
            r_spec: 1.0, // specular only, F = 1
            n_u: 37.0,
            n_v: 37.0,
        };
        for (sun, obs) in [
            (Vector3::new(0.3, 0.4, 0.866), Vector3::new(-0.2, 0.1, 0.97)),
            (Vector3::new(0.7, -0.1, 0.7), Vector3::new(0.1, 0.6, 0.79)),
        ] {
            let (sun, obs) = (sun.normalize(), obs.normalize());
            let h = (sun + obs).normalize();
            let (ns, no, nh) = (n.dot(&sun), n.dot(&obs), n.dot(&h));
            let expected = 38.0 / (8.0 * PI) * nh.powf(37.0) / (ns + no - ns * no);
            let got = rho_total(&n, &u, &v, &sun, &obs, &m, SpecularDenominator::Linares2014);
            assert!(
                (got - expected).abs() < 1e-12 * expected,
                "{got} vs {expected}"
            );
        }
    }

    #[test]
    fn a_facet_facing_away_from_the_sun_or_the_observer_reflects_nothing() {
        let (n, u, v) = axes();
        let m = Material {
            r_diff: 0.5,
            r_spec: 0.5,
            n_u: 5.0,
            n_v: 5.0,
        };
        let up = Vector3::z();
        let below = Vector3::new(0.0, 0.6, -0.8);
        let den = SpecularDenominator::Linares2014;
        assert_eq!(rho_total(&n, &u, &v, &below, &up, &m, den), 0.0);
        assert_eq!(rho_total(&n, &u, &v, &up, &below, &m, den), 0.0);
        assert!(rho_total(&n, &u, &v, &up, &up, &m, den) > 0.0);
    }
}
