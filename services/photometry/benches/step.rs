//! One UKF step (13 sigma points, each a magnitude of a 12-facet model with its ray casts) and
//! the database of the six shipped shapes (200 axes × 8 angles each).

use std::path::PathBuf;

use criterion::{criterion_group, criterion_main, Criterion};
use glint_photometry::spin::spin_attitude;
use glint_photometry::{Database, Sample, Ukf, UkfSettings};
use glint_physics::photometry::{
    apparent_magnitude, normalised_flux, parse_obj, Material, Shape, SpecularDenominator,
};
use nalgebra::{Matrix6, Unit, Vector3};
use std::hint::black_box;

const SHAPES: [&str; 6] = [
    "box-wing",
    "box",
    "cylinder",
    "box-panel",
    "plate",
    "hexagonal-prism",
];

fn shape(name: &str) -> Shape {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../shapes")
        .join(format!("{name}.obj"));
    let m = Material {
        r_diff: 0.3,
        r_spec: 0.5,
        n_u: 100.0,
        n_v: 100.0,
    };
    parse_obj(&std::fs::read_to_string(path).unwrap(), m).unwrap()
}

fn bench(c: &mut Criterion) {
    let sun = Vector3::new(1.0, 0.3, 0.1).normalize();
    let obs = Vector3::new(0.8, -0.4, 0.3).normalize();
    let body = shape("box-panel");
    assert_eq!(body.facets.len(), 12);
    let axis = Unit::new_normalize(Vector3::new(0.3, 0.5, 0.8));
    let w = 0.07;
    let truth = spin_attitude(&axis, 1.0 + w);
    let inv = truth.inverse();
    let flux = normalised_flux(
        &body,
        &(inv * sun),
        &(inv * obs),
        SpecularDenominator::Linares2014,
    );
    let s = Sample {
        t_s: 1.0,
        mag: apparent_magnitude(flux, 3.6e7).unwrap(),
        sigma_mag: 0.05,
        sun,
        obs,
        range_m: 3.6e7,
    };
    let ukf = Ukf::new(
        spin_attitude(&axis, 1.0),
        axis.into_inner() * w,
        Matrix6::identity() * 1e-4,
        0.0,
        UkfSettings::default(),
    );
    c.bench_function("ukf step, 12 facets", |b| {
        b.iter(|| {
            let mut f = ukf.clone();
            black_box(f.step(&body, black_box(&s)).unwrap())
        })
    });
    let shapes: Vec<(String, Shape)> = SHAPES.iter().map(|n| (n.to_string(), shape(n))).collect();
    let mut g = c.benchmark_group("database");
    g.sample_size(10);
    g.bench_function("6 shapes × 200 axes × 8 angles", |b| {
        b.iter(|| {
            black_box(Database::build(
                &shapes,
                &sun,
                &obs,
                200,
                8,
                SpecularDenominator::Linares2014,
            ))
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
