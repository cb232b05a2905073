//! The filter on the sensor's simulated target (an independent integration of the truth: eq 9
//! with the inertia itself, the attitude composed through the inertial frame) reaches the
//! paper's figures over the last 50 minutes (math.md §5.8) and is consistent (NEES).

use glint_relnav::model::{Nominal, Rig};
use glint_relnav::score::Score;
use glint_relnav::{FeatureObs, RelNav, Settings, Start};
use glint_sensor::stereo_scene::StereoScene;
use shared_types::scenario::StereoScenario;

pub fn rig_of(scene: &StereoScene, s: &StereoScenario) -> Rig {
    Rig {
        mean_motion_rad_s: scene.mean_motion_rad_s,
        baseline_m: scene.baseline_m,
        sigma_norm: scene.sigma_norm,
        c_co: scene.c_co,
        features_m: scene.features_t.clone(),
        torque_psd: s.filter.torque_psd,
        accel_psd: s.filter.accel_psd,
    }
}

fn run(s: &StereoScenario, seed: u64) -> (Score, glint_relnav::Counters) {
    run_from(s, seed, |_| Start::Measurements)
}

fn run_from(
    s: &StereoScenario,
    seed: u64,
    start: impl Fn(&StereoScene) -> Start,
) -> (Score, glint_relnav::Counters) {
    let scene = StereoScene::new(s, seed);
    let mut core = RelNav::new(rig_of(&scene, s), Settings::default(), start(&scene));
    let mut score = Score::default();
    let window_from_s = s.duration_s - 3000.0;
    for k in 0..scene.len() {
        let obs: Vec<FeatureObs> = scene
            .observe(k)
            .iter()
            .map(|f| FeatureObs {
                feature: f.feature as usize,
                z: f.z,
            })
            .collect();
        let t = scene.t_ns(k) as f64 * 1e-9;
        if let Some(est) = core.epoch(t, &obs) {
            if t >= window_from_s {
                let tr = scene.truth(k);
                let truth = Nominal {
                    q_ct: tr.q_ct,
                    w_t: tr.w_t,
                    k: scene.k,
                    rho_o: tr.rho_o,
                    v_o: tr.v_o,
                };
                score.add(&est.x, &est.p, &truth);
            }
        }
    }
    (score, core.counters)
}

#[test]
fn the_nominal_case_meets_the_papers_figures() {
    let s = StereoScenario::default();
    let (score, counters) = run(&s, 1);
    let e = score.rtmse();
    eprintln!(
        "rtmse: att {:.4}°, ω {:.2e} rad/s, k {:.4}, ρ {:.2} mm, v {:.2} µm/s; nees {:.2}; {counters:?}; 3σ {:?}",
        e[0].to_degrees(),
        e[1],
        e[2],
        e[3] * 1e3,
        e[4] * 1e6,
        score.nees_mean(),
        score.within_3sigma
    );
    assert_eq!(counters.starts, 1);
    assert_eq!(counters.diverged + counters.numerical_failures, 0);
    assert!(e[0].to_degrees() < 0.1, "attitude");
    assert!(e[1] < 6e-5, "rate");
    assert!(e[2] < 0.02, "inertia k");
    assert!(e[3] < 0.010, "position");
    assert!(e[4] < 10e-6, "velocity");
    let (lo, hi) = Score::nees_interval(1);
    assert!(
        score.nees_mean() > lo && score.nees_mean() < hi,
        "NEES {}",
        score.nees_mean()
    );
}

/// Wrong matches, dropouts, back faces hidden (often fewer than three features) and a
/// five-minute gap: the gate refuses what it must, the filter keeps going and still converges.
#[test]
fn outliers_dropouts_hidden_features_and_gaps_are_survived_and_counted() {
    let s = StereoScenario {
        n_features: 9,
        hide_back_faces: true,
        dropout_probability: 0.3,
        wrong_match_probability: 0.2,
        gaps_s: vec![[1500.0, 1800.0]],
        ..StereoScenario::default()
    };
    let (score, counters) = run(&s, 3);
    let e = score.rtmse();
    eprintln!("rtmse {e:?}; nees {:.2}; {counters:?}", score.nees_mean());
    let epochs = s.epochs();
    assert_eq!(counters.epochs, epochs);
    // about one wrong match in five epochs, each refused (a few may fall inside the gate by
    // chance when the wrong feature is near the right one's image)
    let wrong = 0.2 * epochs as f64;
    assert!(
        counters.features_rejected as f64 > 0.8 * wrong,
        "{counters:?}"
    );
    assert!(
        (counters.features_rejected as f64) < 1.5 * wrong,
        "{counters:?}"
    );
    assert!(e[0].to_degrees() < 0.1 && e[1] < 6e-5 && e[2] < 0.02);
    assert!(e[3] < 0.010 && e[4] < 10e-6);
}

/// A filter given a start 60° off in attitude (and confident of it) refuses every feature:
/// it is taken as diverged, started again from the measurements, and converges.
#[test]
fn a_diverged_filter_is_started_again_from_the_measurements() {
    let s = StereoScenario::default();
    let wrong = |scene: &StereoScene| {
        let tr = scene.truth(0);
        let x = Nominal {
            q_ct: tr.q_ct
                * nalgebra::UnitQuaternion::from_scaled_axis(nalgebra::Vector3::new(1.0, 0.0, 0.0)),
            w_t: tr.w_t,
            k: nalgebra::Vector2::zeros(),
            rho_o: tr.rho_o,
            v_o: tr.v_o,
        };
        let p = glint_relnav::model::ErrMat::identity() * 1e-8;
        Start::Given {
            x,
            p: Box::new(p),
            t_s: 0.0,
        }
    };
    let (score, counters) = run_from(&s, 5, wrong);
    assert_eq!(counters.diverged, 1, "{counters:?}");
    assert_eq!(counters.starts, 1, "{counters:?}");
    let e = score.rtmse();
    assert!(e[0].to_degrees() < 0.1 && e[3] < 0.010, "{e:?}");
    // the refused epochs are counted: 4 features each until the restart
    assert!(counters.features_rejected >= 4 * 5, "{counters:?}");
}
