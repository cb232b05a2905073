//! One frame of the tracker's core with K confirmed tracks: angle-filter and CW-EKF updates for
//! every track, then a laser range applied to each (docs/math.md §3.6–3.7). The cost should grow
//! linearly with K; `tracker/step/K` for K = 1, 10, 100, 1000.
//!
//! Run: `cargo bench -p glint-tracker --bench step`.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use glint_tracker::track::{TrackManager, TrackManagerConfig, TrackObservation};
use std::hint::black_box;
use std::time::Duration;

const FRAME_S: f64 = 0.04;

/// Target `i` of `k` at frame `n`: a slow straight drift across a 10° field, 8–9 km away.
fn observation(i: usize, k: usize, n: u64) -> TrackObservation {
    let t_s = n as f64 * FRAME_S;
    let u = i as f64 / k as f64;
    TrackObservation {
        track_id: i as u64 + 1,
        t_s,
        azimuth_rad: -0.08 + 0.16 * u + 2e-4 * t_s,
        elevation_rad: 0.05 - 0.1 * u - 1e-4 * t_s,
        range_m: None,
        range_t_s: None,
        sigma_rad: Some(2e-5),
        ekf_angles: None,
    }
}

fn step(tm: &mut TrackManager, k: usize, n: u64) -> usize {
    let obs: Vec<TrackObservation> = (0..k).map(|i| observation(i, k, n)).collect();
    let outcome = tm.process_frame(&obs);
    for o in &obs {
        let range_m = 8000.0 + 1000.0 * (o.track_id as f64 / k as f64);
        black_box(tm.apply_range(o.track_id, o.t_s, range_m));
    }
    outcome.faults.len()
}

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("tracker/step");
    g.measurement_time(Duration::from_secs(3));
    g.warm_up_time(Duration::from_secs(1));
    for k in [1usize, 10, 100, 1000] {
        let mut tm = TrackManager::new(TrackManagerConfig::default()).expect("config");
        // Confirmed tracks with running EKFs before measuring.
        let mut n = 0;
        while n < 20 {
            step(&mut tm, k, n);
            n += 1;
        }
        assert_eq!(tm.tracks().count(), k, "every target tracked");
        g.throughput(Throughput::Elements(k as u64));
        g.bench_with_input(BenchmarkId::from_parameter(k), &k, |b, &k| {
            b.iter(|| {
                n += 1;
                black_box(step(&mut tm, k, n))
            })
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
