//! One 512² fisheye Earth frame (f = 130 px/rad, β = 12°, the limb blurred by 1.2 px) through
//! each stage: the edge extraction, and every method with it (`pipeline/all_methods`).
//!
//! Run: `cargo bench -p glint-earth --bench frame`

use criterion::{criterion_group, criterion_main, Criterion};
use glint_earth::edges::{EdgeConfig, EdgeExtractor};
use glint_earth::pipeline::{EarthConfig, EarthCore};
use glint_earth::ring::Fisheye;
use std::hint::black_box;

const CAM: Fisheye = Fisheye {
    f_px: 130.0,
    x0_px: 255.5,
    y0_px: 255.5,
};

fn bench_frame(c: &mut Criterion) {
    let (w, h) = (512, 512);
    let px = glint_earth::synthetic::blurred_earth(w, h, &CAM, 12.0);
    let mut ex = EdgeExtractor::default();
    let cfg = EdgeConfig::default();
    c.bench_function("edges/512", |b| {
        b.iter(|| ex.extract(black_box(&px), w, h, &CAM, &cfg).expect("edges"))
    });
    let mut core = EarthCore::new(EarthConfig::new(CAM, 950.0));
    c.bench_function("pipeline/all_methods_512", |b| {
        b.iter(|| core.process(black_box(&px), w, h).expect("frame"))
    });
}

criterion_group!(benches, bench_frame);
criterion_main!(benches);
