//! The summary's sentences on stage 3's decisions: λ* against the joint fit (the gate, the
//! widening) and the joint fit's lobe test.

use glint_inversion::rate_error_metric;
use shared_types::SolveResponse;

/// A warning when the reported rate and the joint fit's are further apart than the joint-fit
/// gate and the rate was kept (its band has no minimum near the joint solution): neither
/// covariance covers the difference, so the rate's own error bars understate its error.
pub(super) fn disagreement_phrase(r: &SolveResponse) -> Option<String> {
    let d = r.stage3_joint_disagreement_sigma;
    let gate = glint_inversion::stage3::DEFAULT_JOINT_GATE_SIGMA;
    (d.is_finite() && d > gate).then(|| {
        format!(
            "**This rate and the joint fit's are {d:.1}σ apart** (beyond the {gate}σ gate), and {} nm's cost has no minimum near the joint solution, so the band keeps its own: its coefficients point there{}; the joint fit is the one to use.",
            r.wavelength_nm[r.stage3_band as usize],
            widened_phrase(r)
        )
    })
}

/// How the rate's covariance was widened to cover its distance from the joint fit (empty when
/// it was not: the two agree within their errors, or no widening was done).
pub(super) fn widened_phrase(r: &SolveResponse) -> String {
    let scale = r.stage3_covariance_scale;
    if scale.is_finite() && scale > 1.0 {
        format!(
            "; the rate's covariance is widened ×{scale:.1} (the Birge ratio of the two) to cover it"
        )
    } else {
        String::new()
    }
}

/// What a fit that held stage 1's coefficients by their prior says of it (docs/adr/0030).
pub(super) const HELD_SENTENCE: &str = "Stage 1's coefficients held by their stable-window prior and re-estimated with the motion window (`spectra.held_coefficients`, docs/adr/0030).";

/// The joint fit's test of stage 1's widest lobes, as a sentence (empty when not tested).
pub(super) fn lobe_test_text(r: &SolveResponse) -> String {
    let chi2 = r.stage3_joint_lobe_test_chi2;
    if r.stage3_flags & SolveResponse::JOINT_GLINT_LOBES_ONLY != 0 {
        return format!(
            " Stage 1's lobes kept, untested: each facet's widest lobe in use is a glint lobe (μ < {}), whose amplitude sets the glint's height and width and so trades against the rate; only broad lobes are re-fitted (docs/adr/0015).",
            glint_inversion::model::refit::BROAD_LOBE_MIN_MU
        );
    }
    if !chi2.is_finite() {
        return String::new();
    }
    if r.stage3_flags & SolveResponse::JOINT_LOBE_RATE_TRADED != 0 {
        return format!(
            " Stage 1's widest lobes kept: the fit re-fitting them ended below half this rate, trading the rate for the lobe (χ² = {chi2:.1}, 2 dof, not used)."
        );
    }
    if r.stage3_flags & SolveResponse::JOINT_LOBE_KEPT_OFF_MINIMUM != 0 {
        return format!(
            " Each facet's widest lobe re-fitted from the motion window: the fit keeping stage 1's has a minimum a frame's shift away that fits clearly better, so it is not its own model's best fit and its confidence region is no reference (χ² = {chi2:.1}, 2 dof, not used; docs/adr/0022)."
        );
    }
    if r.stage3_flags & SolveResponse::JOINT_LOBE_REFIT != 0 {
        format!(
            " Each facet's widest lobe re-fitted from the motion window: the fit keeping stage 1's lies outside its confidence region from it (χ² = {chi2:.1}, 2 dof; `stage3.lobe_test_confidence`)."
        )
    } else {
        format!(
            " Stage 1's widest lobes kept: the fit re-fitting them lies within this one's confidence region (χ² = {chi2:.1}, 2 dof; `stage3.lobe_test_confidence`)."
        )
    }
}

/// The lobe model the joint fit did not report and the weight its covariance gives it, as a
/// sentence (empty when it carries none).
pub(super) fn lobe_other_text(r: &SolveResponse, truth: [f64; 3]) -> String {
    let q = r.p_joint_lobe_other_deg_per_frame;
    let w = r.stage3_joint_lobe_other_weight;
    if !(q.iter().all(|v| v.is_finite()) && w.is_finite() && w > 0.0) {
        return String::new();
    }
    format!(
        " The other lobe model's rate, [{:.5}, {:.5}, {:.5}] (error {:.3}), is carried in the covariance at weight {w:.2}: the nearer the test was to going the other way, the more (½ at its threshold; docs/adr/0023).",
        q[0],
        q[1],
        q[2],
        rate_error_metric(q, truth)
    )
}

/// What the joint-fit check did to λ* (`SolveResponse::LAMBDA_REJECTED`).
pub(super) fn set_aside_phrase(r: &SolveResponse) -> String {
    let lambda = r.wavelength_nm[r.chosen_band as usize];
    let why = format!(
        "its solution and the joint fit's are more than {}σ apart and the band's cost has a separate minimum at the joint solution: that band's stage-1 coefficients, most often their noise, make another minimum its lowest",
        glint_inversion::stage3::DEFAULT_JOINT_GATE_SIGMA
    );
    if r.stage3_band == r.chosen_band {
        format!("**The joint fit rejects the solution at λ* = {lambda} nm and at every other candidate band** ({why}); λ*'s is reported, and the joint fit is the one to use.")
    } else {
        format!(
            "**The joint fit rejected the solution at λ* = {lambda} nm** ({why}); stage 3 is reported at {} nm, the next candidate of stage 2's ranking the joint fit accepts ({} set aside, λ* included).",
            r.wavelength_nm[r.stage3_band as usize],
            match r.stage3_set_aside {
                1 => "1 band".to_string(),
                n => format!("{n} bands"),
            }
        )
    }
}
