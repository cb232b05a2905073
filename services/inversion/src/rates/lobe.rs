//! The joint fit's choice between stage 1's widest lobes and their re-fit
//! ([`LobeRefit::WhenNeeded`](crate::stage3::LobeRefit::WhenNeeded)).
//!
//! The re-fit costs information: about Y, where stage 1's lobes explain the motion window, it
//! trebles the joint fit's error at SNR 5. About Z the noisy stable window's lobe is off by
//! several of the fit's σ and the re-fit removes that bias (4.7 → 0.55 at SNR 10). The two
//! cases differ in whether the fit keeping the lobes can stand beside the fit re-fitting them:
//! a pre-test estimator reports the simpler fit while the general one lies inside its
//! confidence region.
//!
//! The region is the covariance of the fit keeping stage 1's lobes: it carries the stage-1
//! coefficients' uncertainty, which is what the re-fit would remove. Both fits hold the
//! sun–observer bisector at the same prior, so the test is on the plane the hold leaves (2
//! dof).

use crate::stage3::{LobeTest, RateFit};

/// The χ²(2) quantile at `confidence` ∈ (0, 1): −2 ln(1 − c).
pub(crate) fn chi2_2dof_quantile(confidence: f64) -> f64 {
    -2.0 * (1.0 - confidence).ln()
}

/// The test of `refitted` (widest lobe re-fitted) against `kept` (stage 1's lobes), on the
/// plane orthogonal to the held unit direction `held`. `chi2` is ∞ when `kept`'s covariance is
/// singular on the plane.
pub(crate) fn lobe_test(
    kept: &RateFit,
    refitted: &RateFit,
    held: [f64; 3],
    confidence: f64,
) -> LobeTest {
    let [u, v] = plane_basis(held);
    let d: [f64; 3] =
        std::array::from_fn(|i| refitted.rate_deg_per_frame[i] - kept.rate_deg_per_frame[i]);
    let c = &kept.covariance_deg2_per_frame2;
    let quad = |a: [f64; 3], b: [f64; 3]| -> f64 {
        (0..3)
            .flat_map(|i| (0..3).map(move |j| (i, j)))
            .map(|(i, j)| a[i] * c[i][j] * b[j])
            .sum()
    };
    let (cuu, cuv, cvv) = (quad(u, u), quad(u, v), quad(v, v));
    let (du, dv) = (dot(u, d), dot(v, d));
    let det = cuu * cvv - cuv * cuv;
    let chi2 = if det > 0.0 && det.is_finite() {
        (cvv * du * du - 2.0 * cuv * du * dv + cuu * dv * dv) / det
    } else {
        f64::INFINITY
    };
    LobeTest {
        chi2,
        threshold: chi2_2dof_quantile(confidence),
        rate_traded: false,
        kept_off_minimum: false,
        other_rate_deg_per_frame: None,
    }
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|i| a[i] * b[i]).sum()
}

/// Two orthonormal vectors orthogonal to the unit vector `e`.
fn plane_basis(e: [f64; 3]) -> [[f64; 3]; 2] {
    // Start from the axis least aligned with e.
    let k = (0..3)
        .min_by(|&a, &b| e[a].abs().total_cmp(&e[b].abs()))
        .unwrap_or(0);
    let mut a = [0.0; 3];
    a[k] = 1.0;
    let ea = dot(e, a);
    let mut u: [f64; 3] = std::array::from_fn(|i| a[i] - ea * e[i]);
    let n = dot(u, u).sqrt();
    u.iter_mut().for_each(|x| *x /= n);
    let v = [
        e[1] * u[2] - e[2] * u[1],
        e[2] * u[0] - e[0] * u[2],
        e[0] * u[1] - e[1] * u[0],
    ];
    [u, v]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stage3::fixtures::with_covariance as fit;

    #[test]
    fn quantile_is_the_closed_form() {
        // χ²(2) has CDF 1 − exp(−x/2): its 95 % and 99 % points are 5.991 and 9.210.
        assert!((chi2_2dof_quantile(0.95) - 5.991_464_5).abs() < 1e-6);
        assert!((chi2_2dof_quantile(0.99) - 9.210_340_4).abs() < 1e-6);
    }

    #[test]
    fn statistic_is_the_mahalanobis_distance_on_the_plane() {
        // Held X: the plane is (y, z). Cov on it [[4, 1], [1, 2]] (1e-4 units); the X entries
        // (the held axis' stated prior) must not enter.
        let c = [[0.25, 0.3, 0.1], [0.3, 4e-4, 1e-4], [0.1, 1e-4, 2e-4]];
        let kept = fit([0.0, 0.25, 0.0], c);
        let refitted = fit([0.2, 0.25 + 0.03, -0.01], c);
        let t = lobe_test(&kept, &refitted, [1.0, 0.0, 0.0], 0.99);
        // d = (0.03, −0.01); C⁻¹ = [[2, −1], [−1, 4]]/7 × 1e4.
        let expected = (2.0 * 9e-4 + 2.0 * 3e-4 + 4.0 * 1e-4) / 7.0 * 1e4;
        assert!((t.chi2 - expected).abs() < 1e-9 * expected, "{}", t.chi2);
        assert!((expected - 4.0).abs() < 1e-9 && t.chi2 < t.threshold);
        // Twice the difference: 4 × the statistic, beyond the 99 % point.
        let farther = fit([0.2, 0.25 + 0.06, -0.02], c);
        let t2 = lobe_test(&kept, &farther, [1.0, 0.0, 0.0], 0.99);
        assert!((t2.chi2 - 16.0).abs() < 1e-9 && t2.chi2 > t2.threshold);
        // An oblique held direction gets an orthonormal basis of its plane.
        let e = [0.6, 0.8, 0.0];
        let [u, v] = plane_basis(e);
        for w in [u, v] {
            assert!(dot(w, e).abs() < 1e-15 && (dot(w, w) - 1.0).abs() < 1e-15);
        }
        assert!(dot(u, v).abs() < 1e-15);
    }

    #[test]
    fn a_difference_within_the_region_passes_and_singular_cov_refits() {
        let c = [[0.25, 0.0, 0.0], [0.0, 1e-4, 0.0], [0.0, 0.0, 1e-4]];
        let kept = fit([0.0, 0.25, 0.0], c);
        let near = fit([0.0, 0.26, 0.01], c);
        let t = lobe_test(&kept, &near, [1.0, 0.0, 0.0], 0.99);
        assert!((t.chi2 - 2.0).abs() < 1e-9 && t.chi2 < t.threshold);
        let singular = fit([0.0, 0.25, 0.0], [[0.0; 3]; 3]);
        assert_eq!(
            lobe_test(&singular, &near, [1.0, 0.0, 0.0], 0.99).chi2,
            f64::INFINITY
        );
    }
}
