//! λ* checked by the joint fit when the joint fit finds no rate: a single band's rate stands
//! only where the joint cost (every band) has a determined minimum near it.

mod common;

use common::*;
use glint_inversion::{confirmed_by_joint, solve_three_stage, InversionConfig};

#[test]
fn the_joint_cost_confirms_the_band_s_rate_and_not_a_slow_one_far_from_its_minimum() {
    let p_true = [0.0, 0.0, 0.25];
    let set = scenario(720, 360, p_true);
    let config = InversionConfig {
        joint_fit: true,
        ..InversionConfig::default()
    };
    let result = solve_three_stage(&set, &config).expect("solve");
    let fit = result.rate.fit().expect("λ* rate").clone();
    let confirmed = |fit: &glint_inversion::RateFit, stage3: &glint_inversion::Stage3Config| {
        confirmed_by_joint(&set.motion, &result.stage1, &config.model, stage3, fit).expect("check")
    };
    assert!(confirmed(&fit, &config.stage3), "{fit:?}");
    // A slow rate with tight bounds, as a single band fitted one at SNR 1 (0.015 deg/frame
    // over all 720 frames, 1σ ≈ 1e-3): the joint cost has no minimum near it.
    let mut slow = fit.clone();
    slow.rate_deg_per_frame = [0.0, -0.0116, 0.0098];
    slow.covariance_deg2_per_frame2 = [[0.25, 0.0, 0.0], [0.0, 1e-6, 0.0], [0.0, 0.0, 1e-6]];
    assert!(!confirmed(&slow, &config.stage3));
    // The other sense of rotation: the joint model polished from it does not stay there.
    let mut mirror = fit.clone();
    mirror.rate_deg_per_frame = glint_inversion::stage3::mirror(fit.rate_deg_per_frame);
    assert!(!confirmed(&mirror, &config.stage3));
    // With the gate off nothing is checked.
    let mut off = config.stage3.clone();
    off.joint_gate_sigma = None;
    assert!(confirmed(&slow, &off));
}
