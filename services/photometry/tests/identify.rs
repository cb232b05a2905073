//! Identification of light curves made from the shipped shapes (`shapes/`): a noise-free curve
//! generated from a database entry returns that entry (docs/math.md §2.5–2.7).

use std::path::PathBuf;

use glint_photometry::spin::spin_attitude;
use glint_photometry::{identify, Database};
use glint_physics::photometry::{normalised_flux, parse_obj, Material, Shape, SpecularDenominator};
use nalgebra::Vector3;
use std::f64::consts::PI;

const SHAPES: [&str; 6] = [
    "box-wing",
    "box",
    "cylinder",
    "box-panel",
    "plate",
    "hexagonal-prism",
];

fn library() -> Vec<(String, Shape)> {
    let m = Material {
        r_diff: 0.3,
        r_spec: 0.5,
        n_u: 100.0,
        n_v: 100.0,
    };
    SHAPES
        .iter()
        .map(|name| {
            let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
                .join("../../shapes")
                .join(format!("{name}.obj"));
            let text = std::fs::read_to_string(&path).unwrap();
            (name.to_string(), parse_obj(&text, m).unwrap())
        })
        .collect()
}

fn sun() -> Vector3<f64> {
    Vector3::new(1.0, 0.3, 0.1).normalize()
}

fn obs() -> Vector3<f64> {
    Vector3::new(0.8, -0.4, 0.3).normalize()
}

/// The normalised flux of `shape` scaled by `k` spinning about database axis `a` at `w`, with
/// its rotation angle 0 at t = 30 s, sampled every second for 12 minutes.
fn curve(db: &Database, shape: &Shape, a: usize, w: f64, k: f64) -> (Vec<f64>, Vec<f64>) {
    let big = shape.scaled(k);
    let t: Vec<f64> = (0..720).map(|s| s as f64).collect();
    let y = t
        .iter()
        .map(|&t| {
            let q = spin_attitude(&db.axes[a], w * (t - 30.0)).inverse();
            normalised_flux(
                &big,
                &(q * sun()),
                &(q * obs()),
                SpecularDenominator::Linares2014,
            )
        })
        .collect();
    (t, y)
}

#[test]
fn a_noise_free_curve_made_from_a_database_entry_returns_that_entry() {
    let shapes = library();
    let db = Database::build(
        &shapes,
        &sun(),
        &obs(),
        200,
        8,
        SpecularDenominator::Linares2014,
    );
    // one revolution per 120 s: the database's angles 15 s apart land on samples
    let w = 2.0 * PI / 120.0;
    for (g, a, k) in [(0, 37, 1.3), (2, 101, 0.8), (5, 160, 1.1)] {
        let (t, y) = curve(&db, &shapes[g].1, a, w, k);
        let id = identify(&db, &t, &y).expect("an identification");
        let b = &id.best;
        assert_eq!(b.geometry, SHAPES[g], "{id:#?}");
        assert!(
            (b.spin_rad_s / w - 1.0).abs() < 0.005,
            "spin {} vs {w}",
            b.spin_rad_s
        );
        assert!(
            (b.area_scale / (k * k) - 1.0).abs() < 0.05,
            "area {} vs {}",
            b.area_scale,
            k * k
        );
        // the entry itself (its axis), at a matching degree far better than the runner-up's
        assert!(
            b.axis.dot(&db.axes[a]) > 1.0 - 1e-12,
            "{b:?} vs axis {}",
            db.axes[a].into_inner()
        );
        assert!(
            b.score < 0.05 && b.score < 0.5 * id.matching[1].score,
            "{id:#?}"
        );
        assert_eq!(id.matching.len(), 6);
    }
}
