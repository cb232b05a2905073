//! glint's shipped shape library (`shapes/`, [001]): every OBJ reads as a closed surface with
//! outward faces, and its volume is the solid's closed form.

use std::f64::consts::PI;
use std::path::PathBuf;

use glint_physics::photometry::{parse_obj, Material, Shape};

fn load(name: &str) -> Shape {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../shapes")
        .join(format!("{name}.obj"));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let m = Material {
        r_diff: 0.3,
        r_spec: 0.5,
        n_u: 100.0,
        n_v: 100.0,
    };
    parse_obj(&text, m).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn every_shipped_shape_is_closed_outward_and_of_its_closed_form_volume() {
    let hexagon_area = 3.0 * 3f64.sqrt() / 2.0; // circumradius 1 m
    let sixteen_gon = 0.5 * 16.0 * 1.5f64.powi(2) * (2.0 * PI / 16.0).sin();
    let cases = [
        ("box", 1.0, 6),
        ("box-wing", 8.0 + 2.0 * (2.0 * 5.0 * 0.05), 18),
        ("cylinder", sixteen_gon * 8.0, 18),
        ("box-panel", 1.0 + 3.0 * 1.0 * 0.04, 12),
        ("plate", 2.0 * 1.0 * 0.02, 6),
        ("hexagonal-prism", hexagon_area * 2.0, 8),
    ];
    for (name, volume, faces) in cases {
        let s = load(name);
        assert_eq!(s.facets.len(), faces, "{name}");
        assert!(
            s.area_vector().norm() < 1e-9 * s.area_m2(),
            "{name}: not closed, Σ A n = {}",
            s.area_vector()
        );
        assert!(
            (s.volume_m3() - volume).abs() < 1e-9 * volume,
            "{name}: volume {} vs {volume} (negative: faces inward)",
            s.volume_m3()
        );
    }
}
