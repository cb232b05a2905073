//! The whole three-stage solve: 8 bands, stable window 720 samples, motion window 360 frames,
//! rotation 0.25 deg/frame about Y, single-threaded (faer built without rayon).
//!
//! Run: `cargo bench -p glint-inversion --bench solve`

#[path = "../tests/common/mod.rs"]
mod common;

use criterion::{criterion_group, criterion_main, Criterion};
use glint_inversion::{solve_three_stage, InversionConfig};
use std::hint::black_box;

fn bench_solve(c: &mut Criterion) {
    let set = common::scenario(720, 360, [0.0, 0.25, 0.0]);
    let mut group = c.benchmark_group("three_stage");
    group.sample_size(20);
    for joint in [false, true] {
        let config = InversionConfig {
            joint_fit: joint,
            ..InversionConfig::default()
        };
        let name = if joint { "8_bands_joint" } else { "8_bands" };
        group.bench_function(name, |b| {
            b.iter(|| solve_three_stage(black_box(&set), black_box(&config)).expect("solve"))
        });
    }
    group.finish();
}

criterion_group!(benches, bench_solve);
criterion_main!(benches);
