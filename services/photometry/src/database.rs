//! The geometry–attitude–photometry database (docs/math.md §2.5): for each geometry, each axis
//! on the Fibonacci sphere and each of m rotation angles, the normalised flux M (m² sr⁻¹) the
//! geometry reflects at the observation's Sun and observer directions (taken as constant over
//! a short arc). M, not magnitudes: the observed curve is turned into the same units (§2.6).

use glint_physics::photometry::{normalised_flux, Shape, SpecularDenominator};
use nalgebra::{Unit, Vector3};

use crate::spin::{fibonacci_axes, rotation_angles, spin_attitude};

/// The paper's database sizes: 200 axes (assumed; the patent gives none), 8 angles.
pub const AXES: usize = 200;
pub const ANGLES: usize = 8;

#[derive(Debug, Clone)]
pub struct Database {
    /// Each geometry's name and total facet area A₀ [m²].
    pub geometries: Vec<(String, f64)>,
    pub axes: Vec<Unit<Vector3<f64>>>,
    /// φ_j [rad].
    pub angles: Vec<f64>,
    /// M [m² sr⁻¹], geometry-major, then axis, then angle.
    entries: Vec<f64>,
    /// What an entry off the lattice is computed from ([`Database::entry_about`]).
    shapes: Vec<Shape>,
    sun: Vector3<f64>,
    obs: Vector3<f64>,
    den: SpecularDenominator,
}

impl Database {
    /// Builds the database of `shapes` for unit directions `sun` and `obs` (inertial, from the
    /// satellite), `n_axes` axes and `m` angles.
    pub fn build(
        shapes: &[(String, Shape)],
        sun: &Vector3<f64>,
        obs: &Vector3<f64>,
        n_axes: usize,
        m: usize,
        den: SpecularDenominator,
    ) -> Database {
        let axes = fibonacci_axes(n_axes);
        let angles = rotation_angles(m);
        let mut entries = Vec::with_capacity(shapes.len() * n_axes * m);
        for (_, shape) in shapes {
            for axis in &axes {
                for &phi in &angles {
                    // body components of the inertial directions: q_IB⁻¹ x
                    let q = spin_attitude(axis, phi).inverse();
                    entries.push(normalised_flux(shape, &(q * sun), &(q * obs), den));
                }
            }
        }
        Database {
            geometries: shapes
                .iter()
                .map(|(n, s)| (n.clone(), s.area_m2()))
                .collect(),
            axes,
            angles,
            entries,
            shapes: shapes.iter().map(|(_, s)| s.clone()).collect(),
            sun: *sun,
            obs: *obs,
            den,
        }
    }

    /// Geometry `g`'s fluxes about any `axis` at the database's angles (an entry off the
    /// Fibonacci lattice, for refining a match).
    pub fn entry_about(&self, g: usize, axis: &Unit<Vector3<f64>>) -> Vec<f64> {
        (self.angles.iter())
            .map(|&phi| {
                let q = spin_attitude(axis, phi).inverse();
                normalised_flux(&self.shapes[g], &(q * self.sun), &(q * self.obs), self.den)
            })
            .collect()
    }

    /// M_{g,a,·}: geometry `g`'s fluxes about axis `a` at every angle.
    pub fn entry(&self, g: usize, a: usize) -> &[f64] {
        let m = self.angles.len();
        let start = (g * self.axes.len() + a) * m;
        &self.entries[start..start + m]
    }
}
