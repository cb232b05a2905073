//! The t location-scale MLE on n = 1000 samples (t₁₅, scale 3e-5: angles in radians), and on
//! the 20 samples of docs/math.md §7.4.
//!
//! Run: `cargo bench -p glint-earth --bench tfit`

use criterion::{criterion_group, criterion_main, Criterion};
use glint_earth::tfit;
use std::hint::black_box;

/// t₁₅ samples: a splitmix64 stream, Box–Muller normals, Z / √(χ²₁₅/15).
fn samples(n: usize) -> Vec<f64> {
    let mut state = 17u64;
    let mut uniform = move || {
        state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64 + 1e-17
    };
    let mut normal = move || {
        let (u1, u2) = (uniform(), uniform());
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    };
    (0..n)
        .map(|_| {
            let z = normal();
            let chi2: f64 = (0..15).map(|_| normal().powi(2)).sum();
            0.1 + 3e-5 * z / (chi2 / 15.0).sqrt()
        })
        .collect()
}

fn bench_tfit(c: &mut Criterion) {
    let x = samples(1000);
    c.bench_function("tfit/n1000", |b| {
        b.iter(|| tfit::fit(black_box(&x)).expect("fit"))
    });
    let small = [
        10.12, 9.87, 10.05, 9.96, 10.31, 9.74, 10.02, 10.08, 9.91, 10.44, 9.99, 10.15, 9.82, 10.01,
        9.58, 10.06, 9.95, 10.23, 9.89, 10.97,
    ];
    c.bench_function("tfit/n20", |b| {
        b.iter(|| tfit::fit(black_box(&small)).expect("fit"))
    });
}

criterion_group!(benches, bench_tfit);
criterion_main!(benches);
