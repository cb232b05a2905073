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

fn run(p: [f64; 3], mirror: Option<[f64; 3]>) -> Fit {
    Fit {
        p: Some(p),
        covariance: Some([[1e-6, 0.0, 0.0], [0.0, 1e-6, 0.0], [0.0, 0.0, 1e-6]]),
        mirror,
        widest_lobe_refit: false,
    }
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
        Fit::default(),
    ];
    let e = Estimator::from_runs(&runs, bound(p0), None).json();
    assert_eq!(e["determined"], 4, "{e}");
    assert_eq!(e["undetermined"], 1, "{e}");
    assert_eq!(e["other_sense"], 2, "{e}");
    assert_eq!(e["other_sense_flagged"], 1, "{e}");
    // The two runs on p₀'s sense are 1σ off along Z each: NEES 1 on average (3 dof each).
    let rms = e["rms_observable_deg_per_frame"].as_f64().unwrap();
    assert!((rms - 1e-3).abs() < 1e-12, "{e}");
    assert!((e["nees_mean"].as_f64().unwrap() - 1.0).abs() < 1e-9, "{e}");
}

#[test]
fn curvilinear_deviation_is_speed_and_arc() {
    use super::estimator::curvilinear_deviation;
    let c = [0.0, 0.25, 0.0];
    let close = |a: [f64; 3], b: [f64; 3]| (0..3).all(|i| (a[i] - b[i]).abs() < 1e-15);
    // Along the axis: the straight line.
    let along = [0.0, 0.26, 0.0];
    assert!(close(
        curvilinear_deviation(along, c),
        [0.0, 0.26 - 0.25, 0.0]
    ));
    // On c's speed, 0.02 rad away about X: no radial part, an arc of 0.25 × 0.02 toward −Z.
    let a: f64 = 0.02;
    let p = [0.0, 0.25 * a.cos(), 0.25 * a.sin()];
    let d = curvilinear_deviation(p, c);
    let radial: f64 = (0..3).map(|i| d[i] * p[i]).sum::<f64>() / 0.25;
    assert!(radial.abs() < 1e-15, "{d:?}");
    let len = d.iter().map(|x| x * x).sum::<f64>().sqrt();
    assert!((len - 0.25 * a).abs() < 1e-15, "{d:?}");
    // The straight line's component along p̂ is |c|(1 − cos a), the arc's is 0.
    let straight_radial: f64 = (0..3).map(|i| (p[i] - c[i]) * p[i]).sum::<f64>() / 0.25;
    assert!((straight_radial - 0.25 * (1.0 - a.cos())).abs() < 1e-15);
    // Small deviations: the two agree to second order.
    let q = [1e-4, 0.25 + 2e-4, -1e-4];
    let (dq, sq) = (
        curvilinear_deviation(q, c),
        [q[0] - c[0], q[1] - c[1], q[2] - c[2]],
    );
    assert!(
        (0..3).all(|i| (dq[i] - sq[i]).abs() < 1e-6),
        "{dq:?} {sq:?}"
    );
    // Degenerate centres fall back to the straight line.
    assert_eq!(curvilinear_deviation(q, [0.0; 3]), q);
    assert!(close(
        curvilinear_deviation([0.0, -0.2, 0.0], c),
        [0.0, -0.2 - 0.25, 0.0]
    ));
}

/// Runs on the sphere of p₀'s speed, their axes a held angle away, with a covariance tight along
/// the speed and loose across it: the straight line's NEES counts the sphere's curvature on the
/// speed, the curvilinear one does not.
#[test]
fn a_held_axis_wander_costs_the_straight_nees_not_the_curvilinear_one() {
    let p0 = [0.0, 0.25, 0.0];
    let a: f64 = 0.02;
    let runs: Vec<Fit> = [a, -a]
        .iter()
        .map(|&t| {
            // 1e-5 deg/frame along the run's axis; 0.5 across it (unobservable).
            let (c, s) = (t.cos(), t.sin());
            let (sp, sx) = (1e-10, 0.25);
            let cov = [
                [sx, 0.0, 0.0],
                [0.0, sp * c * c + sx * s * s, (sp - sx) * c * s],
                [0.0, (sp - sx) * c * s, sp * s * s + sx * c * c],
            ];
            Fit {
                p: Some([0.0, 0.25 * c, 0.25 * s]),
                covariance: Some(cov),
                ..Fit::default()
            }
        })
        .collect();
    let e = Estimator::from_runs(&runs, bound(p0), None).json();
    // Straight: (|p0|(1 − cos a) / 1e-5)² ≈ 2.5² on the speed.
    let straight = 0.25 * (1.0 - a.cos()) / 1e-5;
    let nees = e["nees_mean"].as_f64().unwrap();
    assert!((nees - straight * straight).abs() < 1e-3 * nees, "{e}");
    assert!(e["nees_mean_curvilinear"].as_f64().unwrap() < 1e-12, "{e}");
}
