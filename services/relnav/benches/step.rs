//! One filter step (predict over 1 s, update with N features) at steady state, N = 4 and 12;
//! and the start from the measurements' pose fix, for scale.

use criterion::{criterion_group, criterion_main, Criterion};
use glint_physics::stereo::{c_co_along_track, project};
use glint_relnav::model::{feature_in_camera, Nominal, Rig};
use glint_relnav::service_core::{RelNav, Settings, Start};
use glint_relnav::start::pose_fix;
use glint_relnav::{FeatureObs, Filter};
use nalgebra::{UnitQuaternion, Vector2, Vector3};
use std::hint::black_box;

fn rig(n: usize) -> Rig {
    let s = shared_types::scenario::StereoScenario {
        n_features: n as u32,
        ..Default::default()
    };
    Rig {
        mean_motion_rad_s: 1.1068e-3,
        baseline_m: 0.5,
        sigma_norm: 1e-5,
        c_co: c_co_along_track(),
        features_m: s.features().into_iter().map(Vector3::from).collect(),
        torque_psd: 1e-12,
        accel_psd: 1e-14,
    }
}

/// A filter run for 600 epochs on noise-free measurements of a tumbling target (the steady
/// state the step is timed in), and the next epoch's features.
fn steady(n: usize) -> (Rig, Filter, Vec<FeatureObs>, f64) {
    let rig = rig(n);
    let truth = |t: f64| Nominal {
        q_ct: UnitQuaternion::from_scaled_axis(
            Vector3::new(0.3, -0.5, 0.8) + Vector3::new(0.02, -0.03, 0.05) * t,
        ),
        w_t: Vector3::new(0.02, -0.03, 0.05),
        k: Vector2::new(-0.31, 0.44),
        rho_o: Vector3::new(0.0, 10.0, 0.0),
        v_o: Vector3::zeros(),
    };
    let observe = |x: &Nominal| -> Vec<FeatureObs> {
        (rig.features_m.iter().enumerate())
            .map(|(i, r)| FeatureObs {
                feature: i,
                z: project(feature_in_camera(&rig, x, r), rig.baseline_m).unwrap(),
            })
            .collect()
    };
    let mut core = RelNav::new(rig.clone(), Settings::default(), Start::Measurements);
    let mut last = None;
    for k in 0..600 {
        last = core.epoch(k as f64, &observe(&truth(k as f64))).or(last);
    }
    let e = last.unwrap();
    (
        rig.clone(),
        Filter::new(e.x, e.p, e.t_s),
        observe(&truth(600.0)),
        600.0,
    )
}

fn bench(c: &mut Criterion) {
    for n in [4, 12] {
        let (rig, filter, obs, t) = steady(n);
        c.bench_function(&format!("relnav step N={n}"), |b| {
            b.iter(|| {
                let mut f = filter.clone();
                f.predict_to(&rig, t);
                black_box(f.update(&rig, black_box(&obs), 23.5).unwrap())
            })
        });
    }
    let (rig, _, obs, _) = steady(4);
    c.bench_function("relnav pose fix N=4", |b| {
        b.iter(|| black_box(pose_fix(&rig, 0.0, black_box(&obs))))
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
