//! Discretisation of the seed-000 satellite components into flat facets (docs/math.md §1.7).
//!
//! Curved surfaces are cut into patches; each patch keeps its **true area** and takes the
//! direction of its vector area `∫ n dA` as its normal. Axisymmetric parts have their axis along
//! Z_B, with the first patch centred on azimuth 0 (facing +X_B, towards the co-orbital observer).

use super::Facet;
use crate::materials::Material;
use nalgebra::Vector3;
use std::f64::consts::{PI, TAU};

/// Side of a cylinder (axis Z_B) of `radius_m` and `height_m`, cut into `around` patches.
pub(super) fn cylinder_side(
    radius_m: f64,
    height_m: f64,
    around: usize,
    material: Material,
) -> Vec<Facet> {
    let d_az = TAU / around as f64;
    let area_m2 = radius_m * d_az * height_m;
    (0..around)
        .map(|k| {
            let az = k as f64 * d_az;
            Facet {
                normal_body: Vector3::new(az.cos(), az.sin(), 0.0),
                area_m2,
                material,
            }
        })
        .collect()
}

/// Sphere zone between latitudes `lat_lo_rad < lat_hi_rad` (latitude measured from the X–Y
/// plane towards +Z), `bands` latitude bands × `around` longitude patches.
pub(super) fn sphere_zone(
    radius_m: f64,
    lat_lo_rad: f64,
    lat_hi_rad: f64,
    bands: usize,
    around: usize,
    material: Material,
) -> Vec<Facet> {
    let d_lat = (lat_hi_rad - lat_lo_rad) / bands as f64;
    let d_az = TAU / around as f64;
    let mut facets = Vec::with_capacity(bands * around);
    for i in 0..bands {
        let (lo, hi) = (
            lat_lo_rad + i as f64 * d_lat,
            lat_lo_rad + (i + 1) as f64 * d_lat,
        );
        // ∫ cos φ dφ (area), ∫ cos² φ dφ (in-plane vector area), ∫ sin φ cos φ dφ (along Z).
        let area_m2 = radius_m * radius_m * d_az * (hi.sin() - lo.sin());
        let radial = 0.5 * (hi - lo) + 0.25 * ((2.0 * hi).sin() - (2.0 * lo).sin());
        let axial = 0.5 * (hi.sin().powi(2) - lo.sin().powi(2));
        let radial = radial * (0.5 * d_az).sin() / (0.5 * d_az); // longitude averaging of cos az
        for k in 0..around {
            let az = k as f64 * d_az;
            let n = Vector3::new(radial * az.cos(), radial * az.sin(), axial).normalize();
            facets.push(Facet {
                normal_body: n,
                area_m2,
                material,
            });
        }
    }
    facets
}

/// Full lat-long sphere (odd `bands` keeps an equatorial band, so a patch faces +X_B).
pub(super) fn sphere(radius_m: f64, bands: usize, around: usize, material: Material) -> Vec<Facet> {
    sphere_zone(radius_m, -0.5 * PI, 0.5 * PI, bands, around, material)
}

/// A flat facet.
pub(super) fn flat(normal_body: Vector3<f64>, area_m2: f64, material: Material) -> Facet {
    Facet {
        normal_body,
        area_m2,
        material,
    }
}

/// Regular prism (axis Z_B) with `sides` faces of circumradius `circumradius_m`, first face
/// normal along +X_B; returns the side faces only.
pub(super) fn prism_sides(
    sides: usize,
    circumradius_m: f64,
    height_m: f64,
    material: Material,
) -> Vec<Facet> {
    let edge_m = 2.0 * circumradius_m * (PI / sides as f64).sin();
    cylinder_side(1.0, height_m, sides, material)
        .into_iter()
        .map(|f| Facet {
            area_m2: edge_m * height_m,
            ..f
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn total_area(f: &[Facet]) -> f64 {
        f.iter().map(|f| f.area_m2).sum()
    }

    fn vector_area(f: &[Facet]) -> Vector3<f64> {
        f.iter().map(|f| f.normal_body * f.area_m2).sum()
    }

    #[test]
    fn areas_are_exact() {
        let m = Material::WhitePaint;
        assert!((total_area(&cylinder_side(0.5, 0.3, 48, m)) - PI * 0.3).abs() < 1e-12);
        assert!((total_area(&sphere(0.7, 25, 48, m)) - 4.0 * PI * 0.49).abs() < 1e-12);
        let hemi = sphere_zone(0.3, 0.0, 0.5 * PI, 8, 48, m);
        assert!((total_area(&hemi) - 2.0 * PI * 0.09).abs() < 1e-12);
        // A closed sphere has zero vector area; a hemisphere projects to πr² along its axis.
        assert!(vector_area(&sphere(0.7, 25, 48, m)).norm() < 1e-3);
        assert!((vector_area(&hemi).z - PI * 0.09).abs() < 2e-3 * PI * 0.09);
        // A regular hexagon of circumradius a has edge a.
        let hex = prism_sides(6, 0.8, 1.2, m);
        assert!((hex[0].area_m2 - 0.96).abs() < 1e-12);
        assert!((hex[0].normal_body - Vector3::x()).norm() < 1e-15);
    }

    #[test]
    fn normals_are_unit() {
        let m = Material::MliKapton;
        for f in sphere(1.0, 25, 48, m)
            .iter()
            .chain(&cylinder_side(1.0, 1.0, 24, m))
        {
            assert!((f.normal_body.norm() - 1.0).abs() < 1e-14);
        }
    }
}
