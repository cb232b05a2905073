//! Tests of the stage-3 decisions in `rates`: the joint fit's lobe choice.

use super::*;
use crate::stage3::fixtures::{no_glint, with_covariance};
use crate::stage3::Refit;

/// The record of a fit that held X and re-fitted the widest lobe or not, before the lobe test.
fn refit_record(widest_lobe: bool) -> Refit {
    Refit {
        widest_lobe,
        lobes: if widest_lobe { [10, 10] } else { [0, 0] },
        held_direction: [1.0, 0.0, 0.0],
        lobe_test: None,
        glint_lobes_only: false,
    }
}

/// A slow re-fitted rate, as the paper-like phase-30° joint fit found.
fn refitted() -> (RateSolution, usize) {
    let mut fit = with_covariance([0.0, 0.034, 0.011], [[1e-8; 3]; 3]);
    fit.refit = Some(refit_record(true));
    (RateSolution::Determined(fit), 711)
}

/// A fit keeping stage 1's lobes at 0.25 deg/frame about Z, σ 1e-3 on the plane X leaves.
fn kept_at_quarter() -> (RateSolution, usize) {
    let mut fit = with_covariance([0.0, 0.0, 0.25], [[1e-6; 3]; 3]);
    fit.covariance_deg2_per_frame2 = [[0.25, 0.0, 0.0], [0.0, 1e-6, 0.0], [0.0, 0.0, 1e-6]];
    fit.refit = Some(refit_record(false));
    (RateSolution::Determined(fit), 101)
}

/// The re-fit of [`refitted`] moved to `z` deg/frame about Z.
fn refitted_about_z(z: f64) -> (RateSolution, usize) {
    let mut r = refitted();
    if let RateSolution::Determined(f) = &mut r.0 {
        f.rate_deg_per_frame = [0.0, 0.0, z];
    }
    r
}

#[test]
fn a_re_fit_that_ends_below_half_the_kept_rate_traded_the_rate_for_the_lobe() {
    // χ² alone would take the re-fit: it lies 10⁴ of the kept fit's σ away.
    let kept = || {
        let mut fit = with_covariance([0.0, 0.0, 0.25], [[1e-8; 3]; 3]);
        fit.refit = Some(refit_record(false));
        (RateSolution::Determined(fit), 101)
    };
    let (chosen, frames) = choose_lobes(kept(), refitted(), 0.99, |_| Ok(false))
        .unwrap()
        .into_inner();
    let fit = chosen.fit().expect("a rate");
    assert_eq!((fit.rate_deg_per_frame, frames), ([0.0, 0.0, 0.25], 101));
    let test = fit
        .refit
        .and_then(|r| r.lobe_test)
        .expect("the test is recorded");
    assert!(test.rate_traded && test.chi2 > test.threshold, "{test:?}");
    // A re-fit at the kept rate's pace is judged by χ² alone.
    let mut fast = refitted();
    if let RateSolution::Determined(f) = &mut fast.0 {
        f.rate_deg_per_frame = [0.0, 0.01, 0.25];
    }
    let (chosen, frames) = choose_lobes(kept(), fast, 0.99, |_| Ok(false))
        .unwrap()
        .into_inner();
    assert_eq!(frames, 711, "{chosen:?}");
}

#[test]
fn a_re_fitted_lobe_cannot_make_a_glint_stage_one_s_lobes_do_not_show() {
    // Keeping stage 1's lobes: no glint. The joint fit says so, whatever the re-fit found.
    let (chosen, frames) = choose_lobes((no_glint(4e-4), 29), refitted(), 0.99, |_| Ok(false))
        .unwrap()
        .into_inner();
    assert!(chosen.fit().is_none() && frames == 29, "{chosen:?}");
    // Unobservable for another reason (its best start left the search box): the re-fit
    // answers, as before.
    let RateSolution::Unobservable {
        bounds_deg_per_frame,
        observability,
        wavelengths_nm,
        ..
    } = no_glint(4e-4)
    else {
        unreachable!()
    };
    let outside = RateSolution::Unobservable {
        reason: crate::observability::UnobservableReason::OutsideSearchBox {
            rate_deg_per_frame: [0.0, 1.2, 0.0],
        },
        bounds_deg_per_frame,
        observability,
        wavelengths_nm,
    };
    let (chosen, frames) = choose_lobes((outside, 29), refitted(), 0.99, |_| Ok(false))
        .unwrap()
        .into_inner();
    assert!(chosen.fit().is_some() && frames == 711, "{chosen:?}");
}

#[test]
fn a_kept_fit_with_a_clearly_better_neighbour_is_no_reference_for_the_lobe_test() {
    // The re-fit lies 1σ from the kept fit on the plane (χ² = 1, within the 99 % region).
    let near = refitted_about_z;
    let lobe_test_of = |chosen: &RateSolution| {
        chosen
            .fit()
            .and_then(|f| f.refit)
            .and_then(|r| r.lobe_test)
            .expect("the test is recorded")
    };
    // The kept fit is its model's best fit: the test alone decides, and keeps.
    let (chosen, frames) = choose_lobes(kept_at_quarter(), near(0.251), 0.99, |_| Ok(false))
        .unwrap()
        .into_inner();
    let t = lobe_test_of(&chosen);
    assert_eq!(frames, 101, "{chosen:?}");
    assert!((t.chi2 - 1.0).abs() < 1e-9 && !t.kept_off_minimum, "{t:?}");
    // A clearly better minimum beside it: the re-fit is reported, and says why.
    let (chosen, frames) = choose_lobes(kept_at_quarter(), near(0.251), 0.99, |_| Ok(true))
        .unwrap()
        .into_inner();
    let t = lobe_test_of(&chosen);
    assert_eq!(frames, 711, "{chosen:?}");
    assert!(t.chi2 < t.threshold && t.kept_off_minimum, "{t:?}");
    // The χ² alone rejects stage 1's lobes (5σ): the neighbours are not looked for.
    let (chosen, frames) = choose_lobes(kept_at_quarter(), near(0.255), 0.99, |_| {
        panic!("not asked")
    })
    .unwrap()
    .into_inner();
    let t = lobe_test_of(&chosen);
    assert!(
        frames == 711 && t.chi2 > t.threshold && !t.kept_off_minimum,
        "{t:?}"
    );
    // A re-fit that traded the rate for the lobe is not taken, neighbour or not.
    let (chosen, frames) = choose_lobes(kept_at_quarter(), near(0.1), 0.99, |_| Ok(true))
        .unwrap()
        .into_inner();
    assert_eq!(frames, 101, "{chosen:?}");
    assert!(lobe_test_of(&chosen).rate_traded);
}

#[test]
fn the_lobe_test_records_the_rate_of_the_model_it_did_not_report() {
    let (kept, refit_at) = (kept_at_quarter, refitted_about_z);
    let other_of = |chosen: &RateSolution| {
        let t = chosen.fit().and_then(|f| f.refit).and_then(|r| r.lobe_test);
        t.and_then(|t| t.other_rate_deg_per_frame)
    };
    // Kept (χ² = 1): the re-fit's rate is the other. Re-fitted (χ² = 25): the kept fit's.
    let (chosen, _) = choose_lobes(kept(), refit_at(0.251), 0.99, |_| Ok(false))
        .unwrap()
        .into_inner();
    assert_eq!(other_of(&chosen), Some([0.0, 0.0, 0.251]));
    let (chosen, _) = choose_lobes(kept(), refit_at(0.255), 0.99, |_| Ok(false))
        .unwrap()
        .into_inner();
    assert_eq!(other_of(&chosen), Some([0.0, 0.0, 0.25]));
}
