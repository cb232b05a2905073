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
    let runs: Vec<Value> = [a, -a]
        .iter()
        .map(|&t| {
            // 1e-5 deg/frame along the run's axis; 0.5 across it (unobservable).
            let (c, s) = (t.cos(), t.sin());
            let (sp, sx) = (1e-10, 0.25);
            let cov = [
                sx,
                0.0,
                0.0,
                0.0,
                sp * c * c + sx * s * s,
                (sp - sx) * c * s,
                0.0,
                (sp - sx) * c * s,
                sp * s * s + sx * c * c,
            ];
            json!({
                "p_deg_per_frame": [0.0, 0.25 * c, 0.25 * s],
                "covariance": cov,
            })
        })
        .collect();
    let e = Estimator::from_runs(&runs, &|r| r, bound(p0), None).json();
    // Straight: (|p0|(1 − cos a) / 1e-5)² ≈ 2.5² on the speed.
    let straight = 0.25 * (1.0 - a.cos()) / 1e-5;
    let nees = e["nees_mean"].as_f64().unwrap();
    assert!((nees - straight * straight).abs() < 1e-3 * nees, "{e}");
    assert!(e["nees_mean_curvilinear"].as_f64().unwrap() < 1e-12, "{e}");
}

/// The bound of a fit that held stage 1's coefficients by their prior (docs/adr/0030) comes from
/// the held model's own information; the plug-in path computes it as F − L (a Schur
/// complement). On motion data the model fits exactly, at the rate that made them, the two are
/// the same matrix, so `crb` must give the same bound either way, while the known-coefficient
/// and two-stage bounds, the plug-in model's in both, stay equal. Not vacuous: the
/// coefficients cost the bound a measurable share of the information.
#[test]
fn a_held_fit_is_bounded_by_the_information_its_coefficients_leave() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/y-snr50-seed7-400nm.csv");
    let file = crate::observations::read(&path).expect("observation file");
    let config = InversionConfig::default();
    let stage1 = glint_inversion::stage1::run_stage1_full(
        &file.set.stable,
        &file.set.wavelengths_nm,
        config.model.body_normal.into(),
        None,
        &config.stage1,
    )
    .expect("stage 1");
    let band = &stage1.bands[0];
    let covariance = band.coeff_covariance.clone();
    assert!(
        covariance.is_some(),
        "the noisy stable window gives a covariance"
    );
    let rate_bands = [RateBand {
        band_index: 0,
        wavelength_nm: band.wavelength_nm,
        coeffs: band.coeffs,
    }];
    let mut frames: Vec<Observation> = file.set.motion.clone();
    frames.sort_by_key(|o| o.frame_index);
    frames.truncate(100);
    let model = MotionModelConfig {
        epoch_frame: frames.first().map(|o| o.frame_index),
        refit_diffuse: true,
        ..MotionModelConfig::default()
    };
    let p = [0.0, 0.25, 0.0];
    // The motion window replaced by the plug-in model's own light curve at p.
    let exact = RateProblem::new(&frames, &rate_bands, &model)
        .expect("problem")
        .model_flux_w(p);
    for (t, o) in frames.iter_mut().enumerate() {
        o.flux_w[0] = exact[0][t];
    }
    let problem = RateProblem::new(&frames, &rate_bands, &model)
        .expect("problem")
        .with_coefficient_covariance(vec![covariance]);
    // χ² in noise variances: the data are the model to far below the noise.
    assert!(problem.cost(p) < 1e-6, "exact data: {}", problem.cost(p));

    let plain = crb(&problem, false, Some(p)).expect("plug-in bound");
    let held = crb(&problem, true, Some(p)).expect("held bound");
    for d in 0..3 {
        let (a, b) = (plain.variances[d], held.variances[d]);
        assert!(
            (a - b).abs() <= 1e-6 * a,
            "direction {d}: plug-in {a:e}, held {b:e}"
        );
        let along: f64 = (0..3)
            .map(|i| plain.directions[d][i] * held.directions[d][i])
            .sum();
        assert!(along.abs() > 1.0 - 1e-6, "direction {d}: {along}");
        // The plug-in model's bounds, along each bound's own (equal) directions.
        for (a, b) in [
            (plain.known_variances[d], held.known_variances[d]),
            (plain.two_stage_variances[d], held.two_stage_variances[d]),
        ] {
            assert!((a - b).abs() <= 1e-6 * a, "direction {d}: {a:e} vs {b:e}");
        }
    }
    let observable = plain.observable();
    assert!(
        observable.iter().filter(|o| **o).count() >= 2,
        "{observable:?}"
    );
    let cost_share = (0..3)
        .filter(|&d| observable[d])
        .map(|d| plain.variances[d] / plain.known_variances[d])
        .fold(0.0_f64, f64::max);
    assert!(
        cost_share > 1.01,
        "the coefficients cost nothing: {cost_share}"
    );
}
