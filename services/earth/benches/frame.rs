//! One 512² fisheye Earth frame (f = 130 px/rad, β = 12°, the limb blurred by 1.2 px, 10 DN of
//! noise) through each stage: the edge extraction, the undistortion and interval cross
//! products (`ring`), then each method on those (`cross_product`, `lookup`, `hough`), and every
//! method with the shared stages (`pipeline/all_methods`, what the earth service runs).
//!
//! Run: `cargo bench -p glint-earth --bench frame`

use criterion::{criterion_group, criterion_main, Criterion};
use glint_earth::edges::{EdgeConfig, EdgeExtractor};
use glint_earth::estimate::{self, SigmaTable};
use glint_earth::hough::Hough;
use glint_earth::pipeline::{EarthConfig, EarthCore};
use glint_earth::ring::{cross_product_samples, earth_angular_radius_rad, Fisheye};
use std::hint::black_box;

const CAM: Fisheye = Fisheye::ideal(130.0, 255.5, 255.5);

/// The closed-form frame with read noise of σ ≈ 10 DN (a sum of four uniforms, xorshift).
fn noisy_frame(w: usize, h: usize) -> Vec<u16> {
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut uniform = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    glint_earth::synthetic::blurred_earth(w, h, &CAM, 12.0)
        .into_iter()
        .map(|v| {
            let z = (uniform() + uniform() + uniform() + uniform() - 2.0) * 3.0f64.sqrt();
            (f64::from(v) + 10.0 * z).round().clamp(0.0, 4095.0) as u16
        })
        .collect()
}

fn bench_frame(c: &mut Criterion) {
    let (w, h) = (512, 512);
    let px = noisy_frame(w, h);
    let mut ex = EdgeExtractor::default();
    let cfg = EdgeConfig {
        image_circle_px: Some(255.0),
        ..Default::default()
    };
    c.bench_function("edges/512", |b| {
        b.iter(|| ex.extract(black_box(&px), w, h, &CAM, &cfg).expect("edges"))
    });
    let edges = ex.extract(&px, w, h, &CAM, &cfg).expect("edges");
    c.bench_function("ring/512", |b| {
        b.iter(|| {
            let points: Vec<[f64; 3]> = (edges.points_px.iter())
                .map(|&(x, y)| CAM.direction(x, y))
                .collect();
            cross_product_samples(black_box(&points))
        })
    });
    let points: Vec<[f64; 3]> = (edges.points_px.iter())
        .map(|&(x, y)| CAM.direction(x, y))
        .collect();
    let samples = cross_product_samples(&points);
    c.bench_function("cross_product/512", |b| {
        b.iter(|| estimate::cross_product(black_box(&samples)).expect("fit"))
    });
    let table = SigmaTable {
        points: vec![(0.0, 0.2), (20.0, 0.15), (60.0, 0.16)],
    };
    c.bench_function("lookup/512", |b| {
        b.iter(|| estimate::lookup(black_box(&samples), &table, 180).expect("lookup"))
    });
    let mut hough = Hough::default();
    let r = CAM.f_px * earth_angular_radius_rad(950.0);
    let band = 0.15 * CAM.f_px;
    c.bench_function("hough/512", |b| {
        b.iter(|| {
            let pts = black_box(&edges.points_px);
            hough.estimate(&px, w, h, pts, &CAM, r - band, r + band)
        })
    });
    let mut config = EarthConfig::new(CAM, 950.0);
    config.edges = cfg;
    config.sigma_table = Some(table);
    let mut core = EarthCore::new(config);
    c.bench_function("pipeline/all_methods_512", |b| {
        b.iter(|| core.process(black_box(&px), w, h).expect("frame"))
    });
}

criterion_group!(benches, bench_frame);
criterion_main!(benches);
