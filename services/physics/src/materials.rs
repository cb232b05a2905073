//! Spectral material BRDFs and the solar spectrum (docs/materials.md §1–3, math.md §1.3, §1.7).
//!
//! Each material's BRDF is `f = b0/π + Σ_m b_m β(μ_m)` (math.md eq 5–6) with the per-band weights
//! of materials.md §3 ("recommended parameters"), tabulated at 400, 450, …, 750 nm (10-nm band
//! means) and interpolated linearly in wavelength in between; `b0 + Σ b_m = ρ(λ)` of §1.
//!
//! | material | lobes μ (Physical) | notes |
//! |---|---|---|
//! | Al-backed Kapton MLI, 25 µm | 0.01, 0.05, 0.20 + b0 | front Fresnel, Al return, wrinkles |
//! | triple-junction cell + coverglass | 0.07, 0.20 + b0 | b0 = b2 = 0.015 \[ASSUMP\] |
//! | organic black paint | b0 = 0.04 | Lambertian [SRC Tan 2020] |
//! | organic white paint | b0 = 0.90 | Lambertian [SRC Tan 2020] |
//!
//! [`MaterialPreset::PaperLike`] is the "Tan-like" variant of materials.md §3, which reproduces the
//! paper's "no signal beyond 35° phase": MLI b0 and b3 (μ = 0.2) move into b2 (μ = 0.05); the cell
//! b0 and μ = 0.2 lobe move into the μ = 0.07 lobe. The total albedo ρ(λ) is unchanged, paints stay
//! Lambertian.
//!
//! Solar spectral irradiance at 1 AU: 10-nm band means (λc ± 5 nm, trapezoidal) of the
//! extraterrestrial (AM0) column of ASTM G173-03 (which is Gueymard's SMARTS 2.9.2 AM0 spectrum,
//! close to ASTM E-490 in the visible), as distributed with pvlib-python (`pvlib/data/ASTMG173.csv`)
//! — the same spectrum materials.md §4 used. Tabulated every 10 nm from 380 to 780 nm
//! [W m⁻² nm⁻¹] and interpolated linearly.

use crate::brdf::MultiLobeBrdf;
use std::fmt;

/// Surface materials of the seed-000 satellite (materials.md §1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Material {
    /// Body: Al-backed Kapton multi-layer insulation, Kapton outside, 25 µm ("yellow film").
    MliKapton,
    /// Panel front: triple-junction solar cells with coverglass.
    SolarCellFront,
    /// Panel back: organic black paint (Lambertian).
    BlackPaint,
    /// Upper/lower cylinders: organic white paint (Lambertian).
    WhitePaint,
}

impl Material {
    /// All materials, in a fixed order (usable as a table index via [`Material::index`]).
    pub const ALL: [Material; 4] = [
        Material::MliKapton,
        Material::SolarCellFront,
        Material::BlackPaint,
        Material::WhitePaint,
    ];

    /// Position of this material in [`Material::ALL`].
    pub fn index(self) -> usize {
        match self {
            Material::MliKapton => 0,
            Material::SolarCellFront => 1,
            Material::BlackPaint => 2,
            Material::WhitePaint => 3,
        }
    }
}

/// Which parameter set to use (materials.md §3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum MaterialPreset {
    /// Recommended physical values (diffuse and broad lobes included).
    #[default]
    Physical,
    /// "Tan-like" variant: no diffuse or broad lobes on MLI and cells.
    PaperLike,
}

/// Errors of the spectral look-ups.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MaterialError {
    /// The wavelength is outside the tabulated range (or NaN).
    WavelengthOutOfRange {
        /// Requested wavelength \[nm\].
        wavelength_nm: f64,
        /// Lowest tabulated wavelength \[nm\].
        min_nm: f64,
        /// Highest tabulated wavelength \[nm\].
        max_nm: f64,
    },
}

impl fmt::Display for MaterialError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::WavelengthOutOfRange {
                wavelength_nm,
                min_nm,
                max_nm,
            } => write!(
                f,
                "wavelength {wavelength_nm} nm outside the tabulated range [{min_nm}, {max_nm}] nm"
            ),
        }
    }
}

impl std::error::Error for MaterialError {}

/// Largest number of lobes of any material/preset.
pub const MAX_LOBES: usize = 3;

/// Band centres of the material tables \[nm\].
pub const MATERIAL_BANDS_NM: [f64; 8] = [400.0, 450.0, 500.0, 550.0, 600.0, 650.0, 700.0, 750.0];

/// Rows: b0, then the lobes of [`lobe_widths`] for the Physical preset (materials.md §3).
const MLI_TABLE: [[f64; 8]; 4] = [
    [0.000, 0.000, 0.042, 0.081, 0.092, 0.095, 0.096, 0.095],
    [0.103, 0.095, 0.089, 0.086, 0.084, 0.082, 0.081, 0.080],
    [0.000, 0.001, 0.183, 0.350, 0.398, 0.413, 0.417, 0.412],
    [0.000, 0.000, 0.056, 0.108, 0.122, 0.127, 0.128, 0.127],
];
const CELL_TABLE: [[f64; 8]; 3] = [
    [0.015; 8],
    [0.145, 0.066, 0.033, 0.030, 0.030, 0.029, 0.029, 0.030],
    [0.015; 8],
];
const BLACK_PAINT_B0: f64 = 0.04;
const WHITE_PAINT_B0: f64 = 0.90;

/// ASTM G173-03 AM0 10-nm band means, 380, 390, …, 780 nm [W m⁻² nm⁻¹].
const SOLAR_START_NM: f64 = 380.0;
const SOLAR_STEP_NM: f64 = 10.0;
const SOLAR_W_M2_NM: [f64; 41] = [
    1.0873, 1.0585, 1.5042, 1.7067, 1.7398, 1.5627, 1.8263, 1.9906, 2.0415,
    1.9992, // 380–470
    2.0404, 1.8916, 1.9191, 1.9246, 1.8188, 1.8737, 1.8652, 1.8668, 1.8330,
    1.8366, // 480–570
    1.8366, 1.7782, 1.7669, 1.7284, 1.6856, 1.6586, 1.6299, 1.5828, 1.5145,
    1.5315, // 580–670
    1.4913, 1.4625, 1.4227, 1.3933, 1.3509, 1.3270, 1.2899, 1.2779, 1.2565,
    1.2137, // 680–770
    1.1967, // 780
];

/// Linear interpolation on a uniform grid; `Err` outside `[start, start + step (len − 1)]`.
fn interp_uniform(table: &[f64], start: f64, step: f64, x: f64) -> Result<f64, MaterialError> {
    let last = table.len().saturating_sub(1);
    let end = start + step * last as f64;
    if !(x >= start && x <= end) || last == 0 {
        return Err(MaterialError::WavelengthOutOfRange {
            wavelength_nm: x,
            min_nm: start,
            max_nm: end,
        });
    }
    let pos = (x - start) / step;
    let i = (pos.floor() as usize).min(last - 1);
    let frac = pos - i as f64;
    Ok(table[i] + frac * (table[i + 1] - table[i]))
}

/// Extraterrestrial solar spectral irradiance at 1 AU [W m⁻² nm⁻¹] for λ in [380, 780] nm.
pub fn solar_irradiance_w_m2_nm(wavelength_nm: f64) -> Result<f64, MaterialError> {
    interp_uniform(&SOLAR_W_M2_NM, SOLAR_START_NM, SOLAR_STEP_NM, wavelength_nm)
}

/// Lobe widths μ of a material under a preset (the order of the weights of [`band_weights`]).
pub fn lobe_widths(material: Material, preset: MaterialPreset) -> &'static [f64] {
    match (material, preset) {
        (Material::MliKapton, MaterialPreset::Physical) => &[0.01, 0.05, 0.20],
        (Material::MliKapton, MaterialPreset::PaperLike) => &[0.01, 0.05],
        (Material::SolarCellFront, MaterialPreset::Physical) => &[0.07, 0.20],
        (Material::SolarCellFront, MaterialPreset::PaperLike) => &[0.07],
        (Material::BlackPaint | Material::WhitePaint, _) => &[],
    }
}

/// `[b0, b_1, …, b_MAX_LOBES]` at `wavelength_nm` ∈ [400, 750]; lobe k pairs with
/// `lobe_widths(material, preset)[k − 1]`, unused slots are 0.
pub fn band_weights(
    material: Material,
    preset: MaterialPreset,
    wavelength_nm: f64,
) -> Result<[f64; 1 + MAX_LOBES], MaterialError> {
    let (start, step) = (
        MATERIAL_BANDS_NM[0],
        MATERIAL_BANDS_NM[1] - MATERIAL_BANDS_NM[0],
    );
    let at = |row: &[f64; 8]| interp_uniform(row, start, step, wavelength_nm);
    // Paints are flat, but still reject wavelengths outside the material tables.
    let flat = |b0: f64| at(&[b0; 8]);
    let w = match (material, preset) {
        (Material::MliKapton, MaterialPreset::Physical) => [
            at(&MLI_TABLE[0])?,
            at(&MLI_TABLE[1])?,
            at(&MLI_TABLE[2])?,
            at(&MLI_TABLE[3])?,
        ],
        (Material::MliKapton, MaterialPreset::PaperLike) => {
            let moved = at(&MLI_TABLE[0])? + at(&MLI_TABLE[2])? + at(&MLI_TABLE[3])?;
            [0.0, at(&MLI_TABLE[1])?, moved, 0.0]
        }
        (Material::SolarCellFront, MaterialPreset::Physical) => [
            at(&CELL_TABLE[0])?,
            at(&CELL_TABLE[1])?,
            at(&CELL_TABLE[2])?,
            0.0,
        ],
        (Material::SolarCellFront, MaterialPreset::PaperLike) => {
            let moved = at(&CELL_TABLE[0])? + at(&CELL_TABLE[1])? + at(&CELL_TABLE[2])?;
            [0.0, moved, 0.0, 0.0]
        }
        (Material::BlackPaint, _) => [flat(BLACK_PAINT_B0)?, 0.0, 0.0, 0.0],
        (Material::WhitePaint, _) => [flat(WHITE_PAINT_B0)?, 0.0, 0.0, 0.0],
    };
    Ok(w)
}

/// The material's BRDF at `wavelength_nm` ∈ [400, 750] nm.
pub fn band_brdf(
    material: Material,
    preset: MaterialPreset,
    wavelength_nm: f64,
) -> Result<MultiLobeBrdf, MaterialError> {
    let w = band_weights(material, preset, wavelength_nm)?;
    let lobes = lobe_widths(material, preset)
        .iter()
        .zip(&w[1..])
        .map(|(&mu, &b)| (mu, b))
        .collect();
    Ok(MultiLobeBrdf {
        b0_diffuse: w[0],
        lobes,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const PRESETS: [MaterialPreset; 2] = [MaterialPreset::Physical, MaterialPreset::PaperLike];

    #[test]
    fn albedo_matches_reflectance_tables() {
        // materials.md §3 Σ rows (3 decimals) and §1 ρ rows (2 decimals).
        let sum_rows = [
            (
                Material::MliKapton,
                [0.103, 0.096, 0.370, 0.625, 0.696, 0.718, 0.722, 0.714],
                [0.10, 0.10, 0.37, 0.62, 0.70, 0.72, 0.72, 0.71],
            ),
            (
                Material::SolarCellFront,
                [0.175, 0.096, 0.063, 0.060, 0.060, 0.059, 0.059, 0.060],
                [0.175, 0.096, 0.063, 0.060, 0.060, 0.059, 0.059, 0.060],
            ),
            (Material::BlackPaint, [0.04; 8], [0.04; 8]),
            (Material::WhitePaint, [0.90; 8], [0.90; 8]),
        ];
        for (material, sigma3, rho1) in sum_rows {
            for (k, &lambda) in MATERIAL_BANDS_NM.iter().enumerate() {
                for preset in PRESETS {
                    let rho = band_brdf(material, preset, lambda)
                        .expect("in range")
                        .total_albedo();
                    assert!(
                        (rho - sigma3[k]).abs() <= 1.0e-3 + 1e-12,
                        "{material:?} {lambda}"
                    );
                    assert!((rho - rho1[k]).abs() <= 6.0e-3, "{material:?} {lambda}");
                }
            }
        }
    }

    #[test]
    fn paper_like_has_no_diffuse_or_broad_lobes_and_same_albedo() {
        for lambda in [400.0, 437.5, 650.0, 712.3, 750.0] {
            for material in Material::ALL {
                let phys = band_brdf(material, MaterialPreset::Physical, lambda).expect("ok");
                let paper = band_brdf(material, MaterialPreset::PaperLike, lambda).expect("ok");
                assert!((phys.total_albedo() - paper.total_albedo()).abs() < 1e-15);
                if matches!(material, Material::MliKapton | Material::SolarCellFront) {
                    assert_eq!(paper.b0_diffuse, 0.0);
                    assert!(paper.lobes.iter().all(|&(mu, _)| mu < 0.2));
                } else {
                    assert_eq!(phys, paper);
                    assert!(paper.lobes.is_empty());
                }
            }
        }
    }

    #[test]
    fn interpolates_linearly_between_bands() {
        let b = band_brdf(Material::MliKapton, MaterialPreset::Physical, 425.0).expect("ok");
        assert!((b.lobes[0].1 - 0.099).abs() < 1e-15);
        assert_eq!(b.lobes[0].0, 0.01);
        let b = band_brdf(Material::SolarCellFront, MaterialPreset::Physical, 410.0).expect("ok");
        assert!((b.lobes[0].1 - (0.145 + 0.2 * (0.066 - 0.145))).abs() < 1e-15);
    }

    #[test]
    fn rejects_out_of_range_wavelengths() {
        for bad in [399.9, 750.1, f64::NAN, f64::INFINITY] {
            for material in Material::ALL {
                assert!(band_brdf(material, MaterialPreset::Physical, bad).is_err());
            }
        }
        assert!(solar_irradiance_w_m2_nm(379.0).is_err());
        assert!(solar_irradiance_w_m2_nm(780.5).is_err());
        let e = solar_irradiance_w_m2_nm(800.0).expect_err("out of range");
        assert!(e.to_string().contains("800"));
    }

    #[test]
    fn solar_spectrum_values() {
        let at = |l: f64| solar_irradiance_w_m2_nm(l).expect("in range");
        assert!((at(650.0) - 1.5828).abs() < 1e-12);
        assert!((at(750.0) - 1.2779).abs() < 1e-12);
        assert!((at(380.0) - 1.0873).abs() < 1e-12 && (at(780.0) - 1.1967).abs() < 1e-12);
        assert!((at(655.0) - 0.5 * (1.5828 + 1.5145)).abs() < 1e-12);
        for l in (440..=560).step_by(10) {
            let e = at(f64::from(l));
            assert!((1.75..2.1).contains(&e), "{l} nm: {e}");
        }
        // Trapezoid over the band means reproduces the 1-nm G173 AM0 integral 400–700 nm
        // (529.965 W m⁻²) to the band-averaging error.
        let integral: f64 = (400..700)
            .step_by(10)
            .map(|l| 5.0 * (at(f64::from(l)) + at(f64::from(l + 10))))
            .sum();
        assert!((integral / 529.965 - 1.0).abs() < 5e-3, "{integral}");
    }
}
