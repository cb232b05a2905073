//! One 1024² seed-002 frame (docs/math.md §3.9), rendered in place into a reused buffer:
//! - `fast/frame_table4`: background + the 4 Table-4 debris streaks of frame 1 (start points and
//!   0.02 s smear projected with §3.2: 9.3, 7.5, 3.4 and 1.1 px long) + 2 point false targets;
//! - `fast/frame_long_streaks`: the same with the 4 streaks stretched to 12–30 px;
//! - `fast/background_only`: the table-lookup background pass alone;
//! - `baseline/box_muller_background`: the same background by Box–Muller per pixel (the
//!   reference renderer), measured in the same run for the ratio.
//!
//! - `earth/512`: one 512² [003] fisheye Earth frame.
//!
//! Run: `cargo bench --bench render` (criterion; short measurement time set below).

use criterion::{criterion_group, criterion_main, Criterion};
use glint_sensor::render::{FrameRenderer, RenderConfig, Streak};
use std::hint::black_box;
use std::time::Duration;

fn seg(x0_px: f64, y0_px: f64, x1_px: f64, y1_px: f64, total_signal_dn: f64) -> Streak {
    Streak {
        x0_px,
        y0_px,
        x1_px,
        y1_px,
        total_signal_dn,
    }
}

fn table4_frame() -> Vec<Streak> {
    vec![
        seg(186.38, 121.35, 191.51, 129.07, 3000.0),
        seg(877.26, 950.41, 871.32, 945.92, 3500.0),
        seg(901.65, 218.89, 898.82, 220.76, 4000.0),
        seg(921.15, 160.37, 920.03, 160.44, 2500.0),
        Streak::point(402.7, 655.1, 1500.0),
        Streak::point(733.2, 88.9, 1200.0),
    ]
}

fn long_streak_frame() -> Vec<Streak> {
    vec![
        seg(186.38, 121.35, 202.9, 146.2, 6000.0),
        seg(877.26, 950.41, 853.4, 932.4, 6000.0),
        seg(901.65, 218.89, 873.4, 237.6, 6000.0),
        seg(921.15, 160.37, 909.2, 161.1, 4000.0),
        Streak::point(402.7, 655.1, 1500.0),
        Streak::point(733.2, 88.9, 1200.0),
    ]
}

fn bench_render(c: &mut Criterion) {
    let renderer = match FrameRenderer::new(RenderConfig::default()) {
        Ok(r) => r,
        Err(e) => panic!("default render config rejected: {e}"),
    };
    let n_px = renderer.config().width_px * renderer.config().height_px;
    let mut out = vec![0u16; n_px];
    let cases: [(&str, Vec<Streak>); 3] = [
        ("fast/frame_table4", table4_frame()),
        ("fast/frame_long_streaks", long_streak_frame()),
        ("fast/background_only", Vec::new()),
    ];
    for (name, streaks) in &cases {
        let mut frame_index = 0u64;
        c.bench_function(name, |b| {
            b.iter(|| {
                frame_index += 1;
                let report = renderer.render(black_box(streaks), 2016, frame_index, &mut out);
                black_box(&out);
                report
            })
        });
    }
    let mut frame_index = 0u64;
    c.bench_function("baseline/box_muller_background", |b| {
        b.iter(|| {
            frame_index += 1;
            let report = renderer.render_reference(black_box(&[]), 2016, frame_index, &mut out);
            black_box(&out);
            report
        })
    });
}

/// One 512² [003] Earth frame of the turntable scenario's sensor, at 12° (`earth/512`).
fn bench_earth(c: &mut Criterion) {
    let section = shared_types::scenario::EarthScenario::default();
    let scene = glint_sensor::earth_scene::EarthScene::new(&section, 2003);
    let mut out = vec![0u16; section.pixels()];
    let mut header = shared_types::FrameHeader::default();
    let mut k = 0u64;
    c.bench_function("earth/512", |b| {
        b.iter(|| {
            k = (k + 1) % scene.frames();
            scene.render(k, &mut header, black_box(&mut out));
        })
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(3));
    targets = bench_render, bench_earth
}
criterion_main!(benches);
