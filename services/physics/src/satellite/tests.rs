use super::*;
use crate::brdf::LobeGeometry;
use crate::materials::band_brdf;
use crate::two_facet::panel_normal;

const APERTURE_M2: f64 = 0.017789;
const BANDS_NM: [f64; 8] = [400.0, 450.0, 500.0, 550.0, 600.0, 650.0, 700.0, 750.0];

fn geometry_7_3d() -> (Vector3<f64>, Vector3<f64>) {
    (
        Vector3::new(0.95, 0.05, -0.30).normalize(),
        Vector3::new(0.999, 0.0, -0.045).normalize(),
    )
}

/// Normalised flux Φ/(E_sun A_ap/r²) [m² sr⁻¹] at `lambda`.
fn q(model: &SatelliteModel, lambda: f64, s: Vector3<f64>, o: Vector3<f64>) -> f64 {
    let n_p = panel_normal(s, Vector3::x());
    let flux = model
        .flux_w_per_nm(lambda, s, o, 1.0, 1.0, n_p)
        .expect("valid inputs");
    flux / solar_irradiance_w_m2_nm(lambda).expect("in range")
}

#[test]
fn single_flat_facet_matches_closed_form() {
    let n = Vector3::z();
    let s = Vector3::new(0.3, 0.2, 0.9).normalize();
    let o = Vector3::new(-0.4, -0.1, 0.85).normalize();
    let (area_m2, range_m) = (2.0, 3.6e7);
    for preset in [MaterialPreset::Physical, MaterialPreset::PaperLike] {
        for material in Material::ALL {
            let facet = Facet {
                normal_body: n,
                area_m2,
                material,
            };
            let model = SatelliteModel::from_facets(vec![facet], 0.0, preset).expect("valid");
            for lambda in [400.0, 512.5, 650.0, 750.0] {
                let brdf = band_brdf(material, preset, lambda).expect("in range");
                let g = LobeGeometry::new(n, o, s).expect("visible");
                let e_sun = solar_irradiance_w_m2_nm(lambda).expect("in range");
                let want = e_sun * APERTURE_M2 / (range_m * range_m)
                    * area_m2
                    * g.visibility()
                    * brdf.eval(n, o, s);
                let got = model
                    .flux_w_per_nm(lambda, s, o, range_m, APERTURE_M2, Vector3::x())
                    .expect("valid");
                assert!((got - want).abs() <= 1e-12 * want, "{material:?} {lambda}");
            }
            // Facing away: nothing.
            let got = model
                .flux_w_per_nm(650.0, -s, o, range_m, APERTURE_M2, Vector3::x())
                .expect("valid");
            assert_eq!(got, 0.0);
        }
    }
}

#[test]
fn lambert_sphere_matches_analytic_phase_function() {
    let radius_m = 0.7445;
    let facets = shapes::sphere(radius_m, SPHERE_BANDS, FACETS_AROUND, Material::WhitePaint);
    let model = SatelliteModel::from_facets(facets, 0.0, MaterialPreset::Physical).expect("valid");
    let rho = 0.90;
    let s = Vector3::new(1.0, 0.2, 0.1).normalize();
    let axis = s.cross(&Vector3::new(0.0, 0.3, 1.0)).normalize();
    for g_deg in [0.0, 15.0, 30.0, 60.0, 90.0, 120.0, 150.0, 170.0] {
        let g = f64::to_radians(g_deg);
        let o = s * g.cos() + axis.cross(&s) * g.sin();
        let want = rho * radius_m * radius_m * (2.0 / (3.0 * PI)) * (g.sin() + (PI - g) * g.cos());
        let got = q(&model, 550.0, s, o);
        let tol = 5e-3 * rho * radius_m * radius_m; // discretisation error
        assert!((got - want).abs() < tol, "g = {g_deg}°: {got} vs {want}");
    }
}

#[test]
fn panel_and_observed_body_facet_dominate_near_glint() {
    // §7.3d geometry (phase 15.2°, close to the panel's specular direction).
    let (s, o) = geometry_7_3d();
    for preset in [MaterialPreset::Physical, MaterialPreset::PaperLike] {
        let full = SatelliteModel::tan2020(BodyShape::Cube, preset);
        let panel_only =
            SatelliteModel::from_facets(vec![], full.panel_area_m2(), preset).expect("valid");
        let body_x = *full.observed_body_facet().expect("cube has a +X face");
        assert_eq!(body_x.normal_body, Vector3::x());
        assert_eq!(body_x.area_m2, 1.44);
        let body_only = SatelliteModel::from_facets(vec![body_x], 0.0, preset).expect("valid");
        let (q_all, q_p, q_b) = (
            q(&full, 650.0, s, o),
            q(&panel_only, 650.0, s, o),
            q(&body_only, 650.0, s, o),
        );
        let share = (q_p + q_b) / q_all;
        assert!(
            q_p > q_b && q_p > q_all - q_p - q_b,
            "{preset:?}: {q_p} {q_b} {q_all}"
        );
        assert!(share > 0.6, "{preset:?}: two-facet share {share}");
    }
}

#[test]
fn flux_bands_matches_single_band_and_validates() {
    let (s, o) = geometry_7_3d();
    let n_p = panel_normal(s, Vector3::x());
    for shape in [
        BodyShape::Cube,
        BodyShape::Cylinder,
        BodyShape::Sphere,
        BodyShape::HexagonalPrism,
    ] {
        let model = SatelliteModel::tan2020(shape, MaterialPreset::Physical);
        let table = model.band_table(&BANDS_NM).expect("in range");
        assert_eq!(table.wavelengths_nm(), &BANDS_NM);
        let mut out = [0.0; 8];
        model
            .flux_bands(&table, s, o, 2.2e6, APERTURE_M2, n_p, &mut out)
            .expect("valid");
        for (lambda, got) in BANDS_NM.iter().zip(out) {
            let want = model
                .flux_w_per_nm(*lambda, s, o, 2.2e6, APERTURE_M2, n_p)
                .expect("valid");
            assert!(
                got > 0.0 && (got - want).abs() <= 1e-13 * want,
                "{shape:?} {lambda}"
            );
        }
        let mut short = [0.0; 7];
        let err = model.flux_bands(&table, s, o, 2.2e6, APERTURE_M2, n_p, &mut short);
        assert!(matches!(
            err,
            Err(SatelliteError::OutputLength {
                expected: 8,
                got: 7
            })
        ));
        let err = model.flux_bands(&table, s, o, 0.0, APERTURE_M2, n_p, &mut out);
        assert!(matches!(err, Err(SatelliteError::NonPositiveRange { .. })));
    }
    let model = SatelliteModel::tan2020(BodyShape::Cube, MaterialPreset::Physical);
    assert!(model.band_table(&[380.0]).is_err());
    assert!(model.flux_w_per_nm(800.0, s, o, 1.0, 1.0, n_p).is_err());
    // Opposite Sun and observer: nothing is both lit and visible.
    let flux = model
        .flux_w_per_nm(650.0, s, -s, 1.0, 1.0, n_p)
        .expect("valid");
    assert_eq!(flux, 0.0);
}

#[test]
fn tan2020_geometry() {
    let white_area_m2 = PI * 0.3 + PI * 0.25 + PI * 0.5 + PI * (0.25 - 0.09) + 2.0 * PI * 0.09;
    for (shape, body_area_m2) in [
        (BodyShape::Cube, 6.0 * 1.44 - 2.0 * PI * 0.25),
        (
            BodyShape::Sphere,
            4.0 * PI * (1.728 * 3.0 / (4.0 * PI)).powf(2.0 / 3.0),
        ),
    ] {
        let model = SatelliteModel::tan2020(shape, MaterialPreset::Physical);
        let area = |m: Material| -> f64 {
            model
                .facets()
                .iter()
                .filter(|f| f.material == m)
                .map(|f| f.area_m2)
                .sum()
        };
        assert!((area(Material::WhitePaint) - white_area_m2).abs() < 1e-12);
        assert!(
            (area(Material::MliKapton) - body_area_m2).abs() < 1e-9,
            "{shape:?}"
        );
        assert!((model.panel_area_m2() - 16.32).abs() < 1e-12);
    }
    for shape in [
        BodyShape::Cylinder,
        BodyShape::Sphere,
        BodyShape::HexagonalPrism,
    ] {
        let model = SatelliteModel::tan2020(shape, MaterialPreset::Physical);
        let observed = model.observed_body_facet().expect("has a +X facet");
        assert!(
            (observed.normal_body - Vector3::x()).norm() < 1e-12,
            "{shape:?}"
        );
        assert_eq!(observed.material, Material::MliKapton);
        assert!(model.facets().iter().all(|f| f.area_m2 > 0.0));
    }
    let bad = Facet {
        normal_body: Vector3::zeros(),
        area_m2: 1.0,
        material: Material::BlackPaint,
    };
    let err = SatelliteModel::from_facets(vec![bad], 0.0, MaterialPreset::Physical);
    assert!(matches!(
        err,
        Err(SatelliteError::InvalidFacet { index: 0 })
    ));
}
