//! Normalised flux and apparent magnitude (docs/math.md §2.4–2.5, eqs 4-1, 4-2):
//!
//! ```text
//! M = Σ_i vis_i ρ_i A_i (n_i·s)(n_i·o)                  [m² sr⁻¹]
//! m = −26.7 − 2.5 log10(M / d²)
//! ```
//!
//! M is the database's entry (§2.5) and what the observed magnitudes are turned back into
//! (§2.6: `y = 10^(−0.4 (m + 26.7)) d²`); the Sun's irradiance cancels.

use nalgebra::Vector3;

use super::ashikhmin_shirley::{rho_total, SpecularDenominator};
use super::mesh::Shape;
use super::visibility::facet_visible;

/// The Sun's visual apparent magnitude (the patent's constant).
pub const SUN_MAGNITUDE: f64 = -26.7;

/// M of `shape` lit from unit direction `sun` and seen from unit direction `obs`, both in the
/// body frame [m² sr⁻¹].
pub fn normalised_flux(
    shape: &Shape,
    sun: &Vector3<f64>,
    obs: &Vector3<f64>,
    den: SpecularDenominator,
) -> f64 {
    (shape.facets.iter().enumerate())
        .filter(|(i, _)| facet_visible(shape, *i, sun, obs))
        .map(|(_, f)| {
            let rho = rho_total(&f.n, &f.u, &f.v, sun, obs, &f.material, den);
            rho * f.area_m2 * f.n.dot(sun) * f.n.dot(obs)
        })
        .sum()
}

/// The apparent magnitude of normalised flux `m_flux` [m² sr⁻¹] at range `range_m`; `None`
/// when nothing is reflected (the sample is unusable, §2.4).
pub fn apparent_magnitude(m_flux: f64, range_m: f64) -> Option<f64> {
    (m_flux > 0.0 && range_m > 0.0)
        .then(|| SUN_MAGNITUDE - 2.5 * (m_flux / (range_m * range_m)).log10())
}

/// The normalised flux of an apparent magnitude seen at `range_m` (§2.6).
pub fn flux_of_magnitude(magnitude: f64, range_m: f64) -> f64 {
    10f64.powf(-0.4 * (magnitude - SUN_MAGNITUDE)) * range_m * range_m
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::photometry::ashikhmin_shirley::Material;
    use crate::photometry::mesh::parse_obj;
    use std::f64::consts::PI;

    /// A 2 m × 1 m Lambertian plate (R_spec = 0) facing the Sun and the observer, 36,000 km
    /// away: M = ρ_diff A = 28 R_d/(23π) (31/32)² · 2, and its magnitude by hand.
    #[test]
    fn a_lambertian_plate_face_on() {
        let plate = "v 0 0 0\nv 2 0 0\nv 2 1 0\nv 0 1 0\nf 1 2 3 4\n";
        let m = Material {
            r_diff: 0.5,
            r_spec: 0.0,
            n_u: 1.0,
            n_v: 1.0,
        };
        let s = parse_obj(plate, m).unwrap();
        let z = Vector3::z();
        let expected = 28.0 * 0.5 / (23.0 * PI) * (31.0f64 / 32.0).powi(2) * 2.0;
        // R_spec = 0 leaves the specular term times F = (1 − s·h)⁵ = 0 face-on
        let got = normalised_flux(&s, &z, &z, SpecularDenominator::Linares2014);
        assert!((got - expected).abs() < 1e-15, "{got} vs {expected}");
        let d = 3.6e7;
        let mag = apparent_magnitude(got, d).unwrap();
        assert!((mag - (-26.7 - 2.5 * (expected / (d * d)).log10())).abs() < 1e-12);
        // about 12.2 mag, as GEO satellites of that size are seen
        assert!((11.7..12.7).contains(&mag), "{mag}");
        assert!((flux_of_magnitude(mag, d) - got).abs() < 1e-12 * got);
        // seen edge-on or from behind: nothing
        assert_eq!(apparent_magnitude(0.0, d), None);
        let behind = -z;
        assert_eq!(
            normalised_flux(&s, &z, &behind, SpecularDenominator::Linares2014),
            0.0
        );
    }
}
