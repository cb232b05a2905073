//! Facet model of the seed-000 satellite and its spectral flux (docs/math.md §1.2, §1.7;
//! docs/materials.md §3).
//!
//! The flux at the entrance pupil sums eqs (2)–(3) over all facets k:
//!
//! ```text
//! Φ(λ) = E_sun(λ) A_ap / ‖T0‖² · Σ_k A_k [n_k·s]_+ [n_k·o]_+ f_k(λ; n_k, o, s)   [W nm⁻¹]
//! ```
//!
//! with f_k = b0/π + Σ_m b_m β(μ_m) (math.md eq 5–6). Because `[n·s]_+[n·o]_+ β = D(τ; μ)/4`, a
//! lobe costs one exponential per facet, and since the weights b_m(λ) depend only on the
//! material, the facet loop accumulates per-material geometric sums
//! `G[mat][m] = Σ_{k ∈ mat} A_k [n·s]_+[n·o]_+ β_m` once; every band is then a dot product with
//! the precomputed weights of a [`BandTable`].
//!
//! Geometry (Tan et al. 2020, §1.7): body (cube 1.2 m, or an equal-volume sphere, cylinder or
//! hexagonal prism, axis Z_B; all MLI), two solar-panel wings 6.8 m × 1.2 m along ±Y_B whose
//! normal n_p rotates about Y_B towards the Sun (eq 4; front = cells, back = black paint), an upper
//! cylinder Ø1 m × 0.3 m on −Z_B (zenith) with its outer end cap, and a lower cylinder
//! Ø1 m × 0.5 m on +Z_B (nadir) capped by a hemisphere of radius 0.3 m (the rest of its end is a
//! flat annulus); both white paint. Faces buried against the body are omitted and the cylinders'
//! footprints are removed from flat body ends (on the sphere body they simply sit at the poles).
//! The panel thickness (0.1 m) and the panel yokes are ignored.
//!
//! Far field and **no self-shadowing or occlusion**: every facet with `n·s > 0` and `n·o > 0`
//! contributes, exactly as in the seed's two-facet model. The observer and the Sun are at
//! infinity relative to the object size, so s, o and the half vector are shared by all facets.

mod shapes;

use crate::brdf::{beckmann_d, DIFFUSE_BETA};
use crate::frames::normalize;
use crate::materials::{
    band_weights, lobe_widths, solar_irradiance_w_m2_nm, Material, MaterialError, MaterialPreset,
    MAX_LOBES,
};
use nalgebra::Vector3;
use std::f64::consts::PI;
use std::fmt;

/// Patches around every axisymmetric part (≥ 24 required by the spec).
pub const FACETS_AROUND: usize = 48;
const _: () = assert!(FACETS_AROUND >= 24);
/// Latitude bands of the sphere body (odd: one band straddles the equator).
const SPHERE_BANDS: usize = 25;
/// Latitude bands of the hemisphere under the lower cylinder.
const HEMISPHERE_BANDS: usize = 8;
/// Cube body edge \[m\].
pub const CUBE_EDGE_M: f64 = 1.2;
/// One solar-panel wing: length × width \[m\]; there are two wings.
pub const PANEL_WING_M: (f64, f64) = (6.8, 1.2);
/// Radius of the upper and lower cylinders (Ø1 m) \[m\].
const APPENDAGE_RADIUS_M: f64 = 0.5;
/// Heights of the upper (zenith) and lower (nadir) cylinders \[m\].
const UPPER_CYLINDER_HEIGHT_M: f64 = 0.3;
const LOWER_CYLINDER_HEIGHT_M: f64 = 0.5;
/// Radius of the hemisphere under the lower cylinder \[m\].
const HEMISPHERE_RADIUS_M: f64 = 0.3;

const TERMS: usize = 1 + MAX_LOBES;
const N_MATERIALS: usize = Material::ALL.len();

/// A flat facet fixed in the body frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Facet {
    /// Outward unit normal in B.
    pub normal_body: Vector3<f64>,
    /// Area \[m²\].
    pub area_m2: f64,
    /// Surface material.
    pub material: Material,
}

/// Body shapes of Tan et al. (cube baseline; Table 6 variants), all MLI, volume ≈ 1.2³ m³.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum BodyShape {
    /// 1.2 m cube, faces along ±X, ±Y, ±Z.
    #[default]
    Cube,
    /// Cylinder along Z_B, height 1.2 m, equal volume (radius 0.677 m).
    Cylinder,
    /// Sphere of equal volume (radius 0.745 m).
    Sphere,
    /// Hexagonal prism along Z_B, height 1.2 m, equal volume, one face towards +X_B.
    HexagonalPrism,
}

/// Errors of the facet model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SatelliteError {
    /// A wavelength outside the material or solar tables.
    Material(MaterialError),
    /// The range must be finite and > 0 \[m\].
    NonPositiveRange {
        /// The offending range \[m\].
        range_m: f64,
    },
    /// The output slice does not have one slot per band.
    OutputLength {
        /// Bands in the table.
        expected: usize,
        /// Slots provided.
        got: usize,
    },
    /// A facet has a zero/non-finite normal or a negative/non-finite area.
    InvalidFacet {
        /// Index in the input list.
        index: usize,
    },
    /// The panel area must be finite and ≥ 0 \[m²\].
    InvalidPanelArea {
        /// The offending area \[m²\].
        panel_area_m2: f64,
    },
}

impl fmt::Display for SatelliteError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Material(e) => write!(f, "{e}"),
            Self::NonPositiveRange { range_m } => write!(f, "range {range_m} m is not > 0"),
            Self::OutputLength { expected, got } => {
                write!(f, "output has {got} slots, band table has {expected}")
            }
            Self::InvalidFacet { index } => write!(f, "facet {index} is invalid"),
            Self::InvalidPanelArea { panel_area_m2 } => {
                write!(f, "panel area {panel_area_m2} m² is not ≥ 0")
            }
        }
    }
}

impl std::error::Error for SatelliteError {}

impl From<MaterialError> for SatelliteError {
    fn from(e: MaterialError) -> Self {
        Self::Material(e)
    }
}

/// Per-band solar irradiance and material weights, precomputed for a set of wavelengths.
#[derive(Debug, Clone, PartialEq)]
pub struct BandTable {
    wavelengths_nm: Vec<f64>,
    e_sun_w_m2_nm: Vec<f64>,
    /// `weights[band][material] = [b0, b_1..b_MAX_LOBES]`.
    weights: Vec<[[f64; TERMS]; N_MATERIALS]>,
}

impl BandTable {
    /// Band centre wavelengths \[nm\].
    pub fn wavelengths_nm(&self) -> &[f64] {
        &self.wavelengths_nm
    }
}

/// The facet model of the seed-000 satellite.
#[derive(Debug, Clone, PartialEq)]
pub struct SatelliteModel {
    fixed_facets: Vec<Facet>,
    observed_body_index: Option<usize>,
    panel_area_m2: f64,
    preset: MaterialPreset,
}

impl SatelliteModel {
    /// Tan et al. 2020 satellite with the given body shape and material preset.
    pub fn tan2020(body_shape: BodyShape, preset: MaterialPreset) -> Self {
        let mli = Material::MliKapton;
        let white = Material::WhitePaint;
        let volume_m3 = CUBE_EDGE_M.powi(3);
        // Ø1 m cylinders cover part of the flat body ends.
        let footprint_m2 = PI * APPENDAGE_RADIUS_M * APPENDAGE_RADIUS_M;
        let mut facets: Vec<Facet> = Vec::new();
        match body_shape {
            BodyShape::Cube => {
                let face_m2 = CUBE_EDGE_M * CUBE_EDGE_M;
                for n in [Vector3::x(), -Vector3::x(), Vector3::y(), -Vector3::y()] {
                    facets.push(shapes::flat(n, face_m2, mli));
                }
                facets.push(shapes::flat(Vector3::z(), face_m2 - footprint_m2, mli));
                facets.push(shapes::flat(-Vector3::z(), face_m2 - footprint_m2, mli));
            }
            BodyShape::Cylinder => {
                let radius_m = (volume_m3 / (PI * CUBE_EDGE_M)).sqrt();
                facets.extend(shapes::cylinder_side(
                    radius_m,
                    CUBE_EDGE_M,
                    FACETS_AROUND,
                    mli,
                ));
                let cap_m2 = PI * radius_m * radius_m - footprint_m2;
                facets.push(shapes::flat(Vector3::z(), cap_m2, mli));
                facets.push(shapes::flat(-Vector3::z(), cap_m2, mli));
            }
            BodyShape::Sphere => {
                let radius_m = (3.0 * volume_m3 / (4.0 * PI)).cbrt();
                facets.extend(shapes::sphere(radius_m, SPHERE_BANDS, FACETS_AROUND, mli));
            }
            BodyShape::HexagonalPrism => {
                let end_m2 = volume_m3 / CUBE_EDGE_M; // regular hexagon area 3√3/2 a²
                let circumradius_m = (2.0 * end_m2 / (3.0 * 3f64.sqrt())).sqrt();
                facets.extend(shapes::prism_sides(6, circumradius_m, CUBE_EDGE_M, mli));
                facets.push(shapes::flat(Vector3::z(), end_m2 - footprint_m2, mli));
                facets.push(shapes::flat(-Vector3::z(), end_m2 - footprint_m2, mli));
            }
        }
        // Upper cylinder on −Z (zenith): side and outer cap.
        facets.extend(shapes::cylinder_side(
            APPENDAGE_RADIUS_M,
            UPPER_CYLINDER_HEIGHT_M,
            FACETS_AROUND,
            white,
        ));
        facets.push(shapes::flat(-Vector3::z(), footprint_m2, white));
        // Lower cylinder on +Z (nadir): side, annulus around the hemisphere, hemisphere.
        facets.extend(shapes::cylinder_side(
            APPENDAGE_RADIUS_M,
            LOWER_CYLINDER_HEIGHT_M,
            FACETS_AROUND,
            white,
        ));
        let hemisphere_base_m2 = PI * HEMISPHERE_RADIUS_M * HEMISPHERE_RADIUS_M;
        facets.push(shapes::flat(
            Vector3::z(),
            footprint_m2 - hemisphere_base_m2,
            white,
        ));
        facets.extend(shapes::sphere_zone(
            HEMISPHERE_RADIUS_M,
            0.0,
            0.5 * PI,
            HEMISPHERE_BANDS,
            FACETS_AROUND,
            white,
        ));
        let panel_area_m2 = 2.0 * PANEL_WING_M.0 * PANEL_WING_M.1;
        let observed_body_index = most_x_facing(&facets, Some(mli));
        Self {
            fixed_facets: facets,
            observed_body_index,
            panel_area_m2,
            preset,
        }
    }

    /// A model from explicit body-fixed facets plus a sun-pointing panel of `panel_area_m2`
    /// (one side, all wings; 0 for none). Normals are normalised.
    pub fn from_facets(
        facets: Vec<Facet>,
        panel_area_m2: f64,
        preset: MaterialPreset,
    ) -> Result<Self, SatelliteError> {
        let mut fixed_facets = Vec::with_capacity(facets.len());
        for (index, f) in facets.into_iter().enumerate() {
            let normal_body =
                normalize(f.normal_body).ok_or(SatelliteError::InvalidFacet { index })?;
            if !(f.area_m2 >= 0.0 && f.area_m2.is_finite()) {
                return Err(SatelliteError::InvalidFacet { index });
            }
            fixed_facets.push(Facet { normal_body, ..f });
        }
        if !(panel_area_m2 >= 0.0 && panel_area_m2.is_finite()) {
            return Err(SatelliteError::InvalidPanelArea { panel_area_m2 });
        }
        let observed_body_index = most_x_facing(&fixed_facets, None);
        Ok(Self {
            fixed_facets,
            observed_body_index,
            panel_area_m2,
            preset,
        })
    }

    /// The body-fixed facets (body and cylinders; the panel is not included).
    pub fn facets(&self) -> &[Facet] {
        &self.fixed_facets
    }

    /// The body facet facing +X_B, used as n_b by the two-facet model (§1.2).
    pub fn observed_body_facet(&self) -> Option<&Facet> {
        self.observed_body_index
            .and_then(|i| self.fixed_facets.get(i))
    }

    /// Sun-pointing panel area, one side, all wings \[m²\].
    pub fn panel_area_m2(&self) -> f64 {
        self.panel_area_m2
    }

    /// Material preset of this model.
    pub fn preset(&self) -> MaterialPreset {
        self.preset
    }

    /// Precomputes E_sun(λ) and the material weights for `wavelengths_nm` ∈ [400, 750] nm.
    pub fn band_table(&self, wavelengths_nm: &[f64]) -> Result<BandTable, SatelliteError> {
        let mut table = BandTable {
            wavelengths_nm: wavelengths_nm.to_vec(),
            e_sun_w_m2_nm: Vec::with_capacity(wavelengths_nm.len()),
            weights: Vec::with_capacity(wavelengths_nm.len()),
        };
        for &lambda in wavelengths_nm {
            table.e_sun_w_m2_nm.push(solar_irradiance_w_m2_nm(lambda)?);
            table.weights.push(self.material_weights(lambda)?);
        }
        Ok(table)
    }

    /// Spectral flux at the pupil Φ(λ) [W nm⁻¹] at one wavelength (eqs 2–3). `s_body`, `o_body`
    /// and `panel_normal` are unit vectors in B, `range_m` > 0, `aperture_m2` = π D²/4.
    pub fn flux_w_per_nm(
        &self,
        wavelength_nm: f64,
        s_body: Vector3<f64>,
        o_body: Vector3<f64>,
        range_m: f64,
        aperture_m2: f64,
        panel_normal: Vector3<f64>,
    ) -> Result<f64, SatelliteError> {
        let k = pupil_factor(range_m, aperture_m2)? * solar_irradiance_w_m2_nm(wavelength_nm)?;
        let weights = self.material_weights(wavelength_nm)?;
        let sums = self.geometric_sums(s_body, o_body, panel_normal);
        Ok(k * combine(&weights, &sums))
    }

    /// Φ(λ_j) [W nm⁻¹] for every band of `bands` in one pass over the facets (hot path; no
    /// allocation). `out` must have one slot per band.
    #[allow(clippy::too_many_arguments)]
    pub fn flux_bands(
        &self,
        bands: &BandTable,
        s_body: Vector3<f64>,
        o_body: Vector3<f64>,
        range_m: f64,
        aperture_m2: f64,
        panel_normal: Vector3<f64>,
        out: &mut [f64],
    ) -> Result<(), SatelliteError> {
        if out.len() != bands.weights.len() {
            return Err(SatelliteError::OutputLength {
                expected: bands.weights.len(),
                got: out.len(),
            });
        }
        let k = pupil_factor(range_m, aperture_m2)?;
        let sums = self.geometric_sums(s_body, o_body, panel_normal);
        for ((slot, weights), e_sun) in out.iter_mut().zip(&bands.weights).zip(&bands.e_sun_w_m2_nm)
        {
            *slot = k * e_sun * combine(weights, &sums);
        }
        Ok(())
    }

    fn material_weights(
        &self,
        wavelength_nm: f64,
    ) -> Result<[[f64; TERMS]; N_MATERIALS], MaterialError> {
        let mut w = [[0.0; TERMS]; N_MATERIALS];
        for m in Material::ALL {
            w[m.index()] = band_weights(m, self.preset, wavelength_nm)?;
        }
        Ok(w)
    }

    /// `G[mat][0] = Σ A [n·s]_+[n·o]_+/π`, `G[mat][m] = Σ A D(τ; μ_m)/4` over lit, visible facets.
    fn geometric_sums(
        &self,
        s: Vector3<f64>,
        o: Vector3<f64>,
        n_p: Vector3<f64>,
    ) -> [[f64; TERMS]; N_MATERIALS] {
        let mut sums = [[0.0; TERMS]; N_MATERIALS];
        let Some(h) = normalize(s + o) else {
            return sums; // s = −o: no facet is both lit and visible.
        };
        let widths = Material::ALL.map(|m| lobe_widths(m, self.preset));
        let mut add = |n: Vector3<f64>, area_m2: f64, material: Material| {
            let (cos_ns, cos_no) = (n.dot(&s), n.dot(&o));
            if !(cos_ns > 0.0 && cos_no > 0.0) {
                return;
            }
            let acc = &mut sums[material.index()];
            acc[0] += area_m2 * cos_ns * cos_no * DIFFUSE_BETA;
            let mu_list = widths[material.index()];
            if !mu_list.is_empty() {
                let cos_tau = n.dot(&h);
                for (slot, &mu) in acc[1..].iter_mut().zip(mu_list) {
                    *slot += area_m2 * 0.25 * beckmann_d(cos_tau, mu);
                }
            }
        };
        for f in &self.fixed_facets {
            add(f.normal_body, f.area_m2, f.material);
        }
        if self.panel_area_m2 > 0.0 {
            add(n_p, self.panel_area_m2, Material::SolarCellFront);
            add(-n_p, self.panel_area_m2, Material::BlackPaint);
        }
        sums
    }
}

/// `A_ap / ‖T0‖²` \[sr\], validating the range.
fn pupil_factor(range_m: f64, aperture_m2: f64) -> Result<f64, SatelliteError> {
    if !(range_m > 0.0 && range_m.is_finite()) {
        return Err(SatelliteError::NonPositiveRange { range_m });
    }
    Ok(aperture_m2 / (range_m * range_m))
}

/// Σ_mat Σ_m w\[mat\]\[m\] G\[mat\]\[m\] [m² sr⁻¹].
fn combine(weights: &[[f64; TERMS]; N_MATERIALS], sums: &[[f64; TERMS]; N_MATERIALS]) -> f64 {
    weights
        .iter()
        .flatten()
        .zip(sums.iter().flatten())
        .map(|(w, g)| w * g)
        .sum()
}

/// Index of the facet whose normal is closest to +X_B (optionally of one material).
fn most_x_facing(facets: &[Facet], material: Option<Material>) -> Option<usize> {
    facets
        .iter()
        .enumerate()
        .filter(|(_, f)| material.is_none_or(|m| f.material == m))
        .max_by(|(_, a), (_, b)| a.normal_body.x.total_cmp(&b.normal_body.x))
        .map(|(i, _)| i)
}

#[cfg(test)]
mod tests;
