//! Scoring of a Monte-Carlo row's runs against p₀ (counts by construction).

use super::*;

fn bound(p0: [f64; 3]) -> Bound {
    let eye = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    Bound {
        p0: Some(p0),
        variances: [1e-6; 3],
        directions: eye,
        known_variances: [1e-6; 3],
        two_stage_variances: [1e-6; 3],
        hcr_variances: [1e-6; 3],
        copy: None,
    }
}

fn run(p: [f64; 3], mirror: Option<[f64; 3]>) -> Value {
    json!({
        "p_deg_per_frame": p,
        "covariance": [1e-6, 0.0, 0.0, 0.0, 1e-6, 0.0, 0.0, 0.0, 1e-6],
        "mirror_deg_per_frame": mirror,
    })
}

#[test]
fn runs_on_the_other_sense_are_counted_apart_with_those_that_said_so() {
    let p0 = [0.0, -0.003, 0.25];
    let m0 = mirror(p0);
    let runs = [
        // On p₀, 1σ off along Z: kept in RMS and NEES.
        run([0.0, -0.003, 0.251], None),
        // On p₀ and naming its mirror: still p₀'s sense, scored from p₀.
        run([0.0, -0.003, 0.249], Some(m0)),
        // On the mirror, naming p₀'s side as fitting as well: the sense reported undetermined.
        run(m0, Some(p0)),
        // On the mirror, claiming it.
        run([0.0, -0.003, -0.252], None),
        // No rate.
        json!({ "p_deg_per_frame": null }),
    ];
    let e = Estimator::from_runs(&runs, &|r| r, bound(p0), None).json();
    assert_eq!(e["determined"], 4, "{e}");
    assert_eq!(e["undetermined"], 1, "{e}");
    assert_eq!(e["other_sense"], 2, "{e}");
    assert_eq!(e["other_sense_flagged"], 1, "{e}");
    // The two runs on p₀'s sense are 1σ off along Z each: NEES 1 on average (3 dof each).
    let rms = e["rms_observable_deg_per_frame"].as_f64().unwrap();
    assert!((rms - 1e-3).abs() < 1e-12, "{e}");
    assert!((e["nees_mean"].as_f64().unwrap() - 1.0).abs() < 1e-9, "{e}");
}
