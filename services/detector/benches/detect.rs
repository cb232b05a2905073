//! Full detection of one 1024² u16 frame (docs/architecture.md §6: aim < 0.7 ms single-threaded).
//!
//! The frame: background 20 DN with Gaussian noise σ = 5 DN (a seeded LCG + Box–Muller), 4
//! streaks of 9–30 px and 2 point targets with a Gaussian profile (σ = 0.8 px). Cases:
//! - `detect/full`: background estimate (1/16 subsample) + threshold + components + ellipses;
//! - `detect/background`: the background estimate alone;
//! - `detect/segment`: the labelling pass alone at the same threshold.
//!
//! Run: `cargo bench -p glint-detector --bench detect` (short measurement time set below).

use criterion::{criterion_group, criterion_main, Criterion};
use glint_detector::{BackgroundEstimator, Detector, DetectorConfig, SegmentParams, Segmenter};
use std::hint::black_box;
use std::time::Duration;

const SIDE: usize = 1024;

/// 64-bit LCG (Knuth MMIX constants), top 53 bits as a uniform in (0, 1).
struct Lcg(u64);

impl Lcg {
    fn uniform(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    fn gaussian(&mut self) -> f64 {
        (-2.0 * self.uniform().ln()).sqrt() * (std::f64::consts::TAU * self.uniform()).cos()
    }
}

fn add_segment(img: &mut [f64], p0: (f64, f64), p1: (f64, f64), peak_dn: f64) {
    let sigma = 0.8f64;
    let (dx, dy) = (p1.0 - p0.0, p1.1 - p0.1);
    let len2 = dx * dx + dy * dy;
    let r = 5.0;
    let x_lo = (p0.0.min(p1.0) - r).max(0.0) as usize;
    let x_hi = ((p0.0.max(p1.0) + r) as usize).min(SIDE - 1);
    let y_lo = (p0.1.min(p1.1) - r).max(0.0) as usize;
    let y_hi = ((p0.1.max(p1.1) + r) as usize).min(SIDE - 1);
    for y in y_lo..=y_hi {
        for x in x_lo..=x_hi {
            let (px, py) = (x as f64 - p0.0, y as f64 - p0.1);
            let t = if len2 > 0.0 {
                ((px * dx + py * dy) / len2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let d2 = (px - t * dx).powi(2) + (py - t * dy).powi(2);
            img[y * SIDE + x] += peak_dn * (-0.5 * d2 / (sigma * sigma)).exp();
        }
    }
}

fn frame() -> Vec<u16> {
    let mut rng = Lcg(0x5eed_2016);
    let mut img: Vec<f64> = (0..SIDE * SIDE)
        .map(|_| 20.0 + 5.0 * rng.gaussian())
        .collect();
    add_segment(&mut img, (186.4, 121.4), (202.9, 146.2), 200.0);
    add_segment(&mut img, (877.3, 950.4), (853.4, 932.4), 200.0);
    add_segment(&mut img, (901.7, 218.9), (873.4, 237.6), 200.0);
    add_segment(&mut img, (921.2, 160.4), (912.2, 161.1), 150.0);
    add_segment(&mut img, (402.7, 655.1), (402.7, 655.1), 400.0);
    add_segment(&mut img, (733.2, 88.9), (733.2, 88.9), 300.0);
    img.iter()
        .map(|v| v.round().clamp(0.0, 65535.0) as u16)
        .collect()
}

fn bench_detect(c: &mut Criterion) {
    let frame = frame();
    let mut det = match Detector::new(DetectorConfig::default()) {
        Ok(d) => d,
        Err(e) => panic!("default config rejected: {e}"),
    };
    let (n_blobs, threshold_dn, background) = match det.detect(&frame, SIDE, SIDE) {
        Ok(d) => (d.blobs.len(), d.threshold_dn, d.background),
        Err(e) => panic!("frame rejected: {e}"),
    };
    assert_eq!(n_blobs, 6, "the bench frame must yield its 6 targets");
    let mut group = c.benchmark_group("detect");
    group
        .sample_size(50)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(3));
    group.bench_function("full", |b| {
        b.iter(|| {
            let d = det.detect(black_box(&frame), SIDE, SIDE);
            black_box(d.map(|d| d.blobs.len()).ok())
        })
    });
    let mut est = BackgroundEstimator::new();
    group.bench_function("background", |b| {
        b.iter(|| black_box(est.estimate(black_box(&frame), SIDE, SIDE, 4).ok()))
    });
    let mut seg = Segmenter::new();
    let params = SegmentParams {
        threshold_dn,
        background_dn: background.background_dn,
        min_area_px: 3,
        saturation_dn: u16::MAX,
    };
    group.bench_function("segment", |b| {
        b.iter(|| {
            black_box(
                seg.segment(black_box(&frame), SIDE, SIDE, &params)
                    .map(|c| c.len())
                    .ok(),
            )
        })
    });
    group.finish();
}

criterion_group!(benches, bench_detect);
criterion_main!(benches);
