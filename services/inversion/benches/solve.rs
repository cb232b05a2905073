//! The three-stage solve on 8 bands, stable window 720 samples, motion window 360 frames,
//! rotation 0.25 deg/frame about Y, single-threaded (faer built without rayon): the whole solve
//! (`three_stage/*`) and each stage on its own (`stage/*`: stage 1 the per-band NNLS fits,
//! stage 2 the band selection, stage 3 the LM rate fit at the chosen band), each stage fed
//! the previous stages' outputs computed once outside the timing.
//!
//! Run: `cargo bench -p glint-inversion --bench solve`

#[path = "../tests/common/mod.rs"]
mod common;

use criterion::{criterion_group, criterion_main, Criterion};
use glint_inversion::{fit_rates, solve_three_stage, stage1, stage2, InversionConfig};
use nalgebra::Vector3;
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

fn bench_stages(c: &mut Criterion) {
    let set = common::scenario(720, 360, [0.0, 0.25, 0.0]);
    let config = InversionConfig::default();
    let normal = Vector3::from(config.model.body_normal);
    let scale = config.band_scale_w.as_deref();
    let run1 = || {
        stage1::run_stage1_full(
            &set.stable,
            &set.wavelengths_nm,
            normal,
            scale,
            &config.stage1,
        )
        .expect("stage 1")
    };
    let s1 = run1();
    let s2 = stage2::run_stage2_with(s1.single_band(), &config.stage2).expect("stage 2");
    let mut group = c.benchmark_group("stage");
    group.sample_size(20);
    group.bench_function("1_nnls_8_bands", |b| b.iter(|| black_box(run1())));
    group.bench_function("2_band_selection", |b| {
        b.iter(|| {
            stage2::run_stage2_with(black_box(s1.single_band()), &config.stage2).expect("stage 2")
        })
    });
    group.bench_function("3_lm_rates", |b| {
        b.iter(|| {
            let fits = fit_rates(
                black_box(&set.motion),
                &s1.bands,
                s1.single_band(),
                &s2.ranking,
                &config.model,
                &config.stage3,
                false,
            );
            fits.expect("stage 3")
        })
    });
    group.finish();
}

criterion_group!(benches, bench_solve, bench_stages);
criterion_main!(benches);
