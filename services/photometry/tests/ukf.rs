//! The attitude UKF on light curves of a shipped shape (docs/math.md §2.9): started near the
//! truth it tracks the attitude and rate.

use std::path::PathBuf;

use glint_photometry::spin::spin_attitude;
use glint_photometry::{Sample, StepOutcome, Ukf, UkfSettings};
use glint_physics::photometry::{
    apparent_magnitude, normalised_flux, parse_obj, Material, Shape, SpecularDenominator,
};
use glint_physics::rng::SeededRng;
use nalgebra::{Matrix6, Unit, UnitQuaternion, Vector3, Vector6};
use std::f64::consts::PI;

fn shape(name: &str) -> Shape {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../shapes")
        .join(format!("{name}.obj"));
    let m = Material {
        r_diff: 0.3,
        r_spec: 0.5,
        n_u: 20.0,
        n_v: 20.0,
    };
    parse_obj(&std::fs::read_to_string(path).unwrap(), m).unwrap()
}

struct Run {
    final_err_deg: f64,
    start_err_deg: f64,
    nees: Vec<f64>,
    updated: usize,
}

/// `minutes` of 1 s samples of `name` spinning about `axis` at one turn per 90 s, σ = 0.05 mag,
/// the filter started off the truth by `offset` (δθ [rad], δω [rad/s]).
fn run(
    name: &str,
    seed: u64,
    minutes: usize,
    offset: Vector6<f64>,
    sig: &[f64; 6],
    gamma: f64,
) -> Run {
    let body = shape(name);
    let sun = Vector3::new(1.0, 0.3, 0.1).normalize();
    let obs = Vector3::new(0.8, -0.4, 0.3).normalize();
    let range_m = 3.6e7;
    let axis = Unit::new_normalize(Vector3::new(0.3, 0.5, 0.8));
    let w = 2.0 * PI / 90.0;
    let truth = |t: f64| spin_attitude(&axis, 0.4 + w * t);
    let w_body = axis.into_inner() * w; // a spin about its own axis: the same in B and I
    let sigma = 0.05;
    let mut rng = SeededRng::new(seed);
    let p0 = Matrix6::from_diagonal(&Vector6::from_fn(|i, _| sig[i] * sig[i]));
    let dth: Vector3<f64> = offset.fixed_rows::<3>(0).into();
    let q0 = truth(0.0) * UnitQuaternion::from_scaled_axis(dth);
    let w0 = w_body + Vector3::from(offset.fixed_rows::<3>(3));
    let settings = UkfSettings {
        gamma,
        ..UkfSettings::default()
    };
    let mut ukf = Ukf::new(q0, w0, p0, 0.0, settings);
    let start_err_deg = ukf.q.angle_to(&truth(0.0)).to_degrees();
    let mut nees = vec![];
    let mut updated = 0;
    for k in 1..=minutes * 60 {
        let t = k as f64;
        let inv = truth(t).inverse();
        let flux = normalised_flux(
            &body,
            &(inv * sun),
            &(inv * obs),
            SpecularDenominator::Linares2014,
        );
        let Some(mag) = apparent_magnitude(flux, range_m) else {
            continue;
        };
        let s = Sample {
            t_s: t,
            mag: mag + sigma * rng.gaussian(),
            sigma_mag: sigma,
            sun,
            obs,
            range_m,
        };
        if let StepOutcome::Updated { .. } = ukf.step(&body, &s).expect("a step") {
            updated += 1;
        }
        nees.push(ukf.nees(&truth(t), &w_body).unwrap());
    }
    Run {
        final_err_deg: ukf.q.angle_to(&truth((minutes * 60) as f64)).to_degrees(),
        start_err_deg,
        nees,
        updated,
    }
}

#[test]
fn started_near_the_truth_the_ukf_tracks_the_attitude() {
    let offset = Vector6::new(0.05, -0.04, 0.03, 2e-4, -1e-4, 1e-4);
    let r = run(
        "box-panel",
        1,
        10,
        offset,
        &[0.1, 0.1, 0.1, 1e-3, 1e-3, 1e-3],
        1.0,
    );
    eprintln!(
        "start {:.2}°, after 10 min {:.3}°, updates {}, NEES mean {:.2}",
        r.start_err_deg,
        r.final_err_deg,
        r.updated,
        r.nees.iter().sum::<f64>() / r.nees.len() as f64
    );
    assert!(r.updated > 500);
    assert!(
        r.final_err_deg < 0.25 * r.start_err_deg,
        "{} → {}",
        r.start_err_deg,
        r.final_err_deg
    );
}

/// 20 runs with their start drawn from the filter's own initial covariance (1.7° per axis,
/// 3e-4 rad/s): every run converges. Their NEES averaged over the runs and the 10 minutes is
/// printed (8.5 here against a 20-run interval of 4.7–7.6: a little over-confident; see
/// docs/photometry.md).
#[test]
fn twenty_runs_started_from_the_initial_covariance_converge() {
    let mut draw = SeededRng::new(99);
    let sig = [0.03, 0.03, 0.03, 3e-4, 3e-4, 3e-4];
    let mut nees = vec![];
    let mut errs = vec![];
    for seed in 0..20 {
        let offset = Vector6::from_fn(|i, _| sig[i] * draw.gaussian());
        let r = run("box-panel", 100 + seed, 10, offset, &sig, 1.0);
        nees.push(r.nees.iter().sum::<f64>() / r.nees.len() as f64);
        errs.push(r.final_err_deg);
    }
    let mean = nees.iter().sum::<f64>() / nees.len() as f64;
    errs.sort_by(f64::total_cmp);
    eprintln!(
        "mean NEES {mean:.2}; final attitude error median {:.3}°, worst {:.3}°",
        errs[10], errs[19]
    );
    assert!(errs[10] < 0.5 && errs[19] < 3.0, "{errs:?}");
}
