//! The service's core as a checkpoint leaves it: a core restored from the state it had after
//! `k` samples — while gathering, and while tracking — answers every later sample exactly as
//! the core that never stopped (to the bit: a restarted service's answers are the run's).

use std::path::PathBuf;
use std::sync::Arc;

use glint_photometry::service_core::{Answer, Photometry, Settings};
use glint_photometry::shapes::read_shapes;
use glint_photometry::spin::spin_attitude;
use glint_photometry::{Sample, UkfSettings};
use glint_physics::photometry::{apparent_magnitude, normalised_flux, SpecularDenominator};
use glint_physics::rng::SeededRng;
use nalgebra::{Unit, Vector3};

/// Every sample of 20 minutes at 2 s of the shipped box-wing (`None` for the few without flux).
type Library = Arc<Vec<(String, glint_physics::photometry::Shape)>>;

fn light_curve() -> (Library, Vec<(f64, Option<Sample>)>) {
    let lib = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shapes/shapes.toml");
    let shapes = read_shapes(&lib).unwrap();
    let body = shapes
        .iter()
        .find(|(n, _)| n == "box-wing")
        .unwrap()
        .1
        .clone();
    let sun = Vector3::new(-0.8, 0.5, 0.2).normalize();
    let obs = Vector3::new(-1.0, 0.0, 0.1).normalize();
    let axis = Unit::new_normalize(Vector3::new(-0.6, 0.2, 0.77));
    let w = std::f64::consts::TAU / 120.0;
    let mut rng = SeededRng::new(7);
    let samples = (0..601)
        .map(|k| {
            let t_s = 2.0 * k as f64;
            let inv = spin_attitude(&axis, 0.5 + w * t_s).inverse();
            let m = normalised_flux(
                &body,
                &(inv * sun),
                &(inv * obs),
                SpecularDenominator::Linares2014,
            );
            let seen = apparent_magnitude(m, 3.6e7).map(|mag| Sample {
                t_s,
                mag: mag + 0.05 * rng.gaussian(),
                sigma_mag: 0.05,
                sun,
                obs,
                range_m: 3.6e7,
            });
            (t_s, seen)
        })
        .collect();
    (Arc::new(shapes), samples)
}

/// What an answer says, as bits.
fn bits(a: &Answer<'_>) -> Vec<u64> {
    match a {
        Answer::Gathering { tried } => vec![*tried as u64],
        Answer::Tracking {
            matching,
            filter,
            updated,
            fallbacks,
            restarts,
        } => {
            let mut v: Vec<u64> = (filter.q.coords.iter())
                .chain(filter.w.iter())
                .chain(filter.p.iter())
                .map(|x| x.to_bits())
                .collect();
            v.extend(matching.iter().map(|m| m.score.to_bits()));
            v.extend([*updated as u64, *fallbacks, *restarts as u64]);
            v
        }
    }
}

#[test]
fn a_restored_core_answers_as_the_one_that_never_stopped() {
    let (shapes, curve) = light_curve();
    let settings = Settings {
        identify_after_s: 600.0,
        axes: 200,
        angles: 8,
        ukf: UkfSettings::default(),
    };
    let mut straight = Photometry::new(shapes.clone(), settings);
    let answers: Vec<Vec<u64>> = (curve.iter())
        .map(|(t, s)| bits(&straight.sample(*t, *s)))
        .collect();
    assert!(
        matches!(straight.sample(1202.0, None), Answer::Tracking { .. }),
        "identified"
    );
    // gathering at 250, tracking at 450
    for k in [250, 450] {
        let mut before = Photometry::new(shapes.clone(), settings);
        for (t, s) in &curve[..k] {
            before.sample(*t, *s);
        }
        let state = before.state();
        assert_eq!(state.filter.is_some(), k > 300, "k = {k}");
        let mut after = Photometry::restore(shapes.clone(), settings, state);
        for (i, (t, s)) in curve.iter().enumerate().skip(k) {
            assert_eq!(
                bits(&after.sample(*t, *s)),
                answers[i],
                "sample {i} after a restore at {k}"
            );
        }
    }
}
