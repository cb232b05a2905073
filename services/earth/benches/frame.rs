//! One 512² fisheye Earth frame (f = 130 px/rad, β = 12°, the limb blurred by 1.2 px) through
//! each stage: the edge extraction, and every method with it (`pipeline/all_methods`).
//!
//! Run: `cargo bench -p glint-earth --bench frame`

use criterion::{criterion_group, criterion_main, Criterion};
use glint_earth::edges::{EdgeConfig, EdgeExtractor};
use glint_earth::pipeline::{EarthConfig, EarthCore};
use glint_earth::ring::{earth_angular_radius_rad, Fisheye};
use std::hint::black_box;

const CAM: Fisheye = Fisheye {
    f_px: 130.0,
    x0_px: 255.5,
    y0_px: 255.5,
};

fn frame(w: usize, h: usize, tilt_deg: f64) -> Vec<u16> {
    let rho = earth_angular_radius_rad(950.0);
    let t = tilt_deg.to_radians();
    let e = [t.sin(), 0.0, t.cos()];
    (0..w * h)
        .map(|i| {
            let u = CAM.direction((i % w) as f64, (i / w) as f64);
            let angle = (u[0] * e[0] + u[1] * e[1] + u[2] * e[2])
                .clamp(-1.0, 1.0)
                .acos();
            let d_px = (angle - rho) * CAM.f_px;
            (20.0 + 3000.0 * 0.5 * libm::erfc(d_px / (1.2 * std::f64::consts::SQRT_2))) as u16
        })
        .collect()
}

fn bench_frame(c: &mut Criterion) {
    let (w, h) = (512, 512);
    let px = frame(w, h, 12.0);
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
