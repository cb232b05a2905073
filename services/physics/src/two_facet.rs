//! Seed-000 two-facet signal model (docs/math.md §1.2–1.6, eqs 4, 7–12, 15–20; §7.3d).
//!
//! The target is reduced to a sun-pointing panel facet (normal n_p) and one observed body facet
//! (normal n_b, default +X_B). With Y = [0, 1, 0]:
//!
//! ```text
//! n_p = normalize(s − (s·Y)Y)                                         (4, fixed)
//! Q   = Φ/K = [n_p·s]_+[n_p·o]_+ N_p + [n_b·s]_+[n_b·o]_+ N_b         (7–8)
//! N_p = Σ_m P_m β_m(n_p, o, s),  N_b = Σ_m B_m β_m(n_b, o, s)          (9–10)
//! ```
//!
//! with β_0 = 1/π and β_m (m = 1..=10) the Beckmann lobes of Table 4 widths. The unknowns
//! x = [P_0..P_10, B_0..B_10] \[m²\] enter linearly: Q = G x with the design row
//! `G_m = [n_p·s]_+[n_p·o]_+ β_m(n_p)`, `G_{11+m} = [n_b·s]_+[n_b·o]_+ β_m(n_b)` (11–12). For
//! lobes the masked product equals D(τ; μ)/4, which is how it is evaluated.
//!
//! Attitude motion (eqs 15–17): with p = [w_x, w_y, w_z] in deg/frame and frame index t,
//! θ = w_x t, φ = w_y t, ψ = w_z t and the seed's verbatim `R = R_Z(ψ) R_Y(φ) R_X(θ)` where
//! `R_Z = R3(ψ)`, `R_Y = R2(−φ)`, `R_X = R1(θ)`. The consistent 3-2-1 alternative is
//! `R1(θ) R2(φ) R3(ψ)`. The rotated geometry is `s' = R s`, `o' = R o` (eqs 18–19).

use crate::brdf::{LobeGeometry, DIFFUSE_BETA, LOBE_WIDTHS_TABLE4};
use crate::frames::{r1, r2, r3};
use nalgebra::{Matrix3, Vector3};

/// Number of basis functions per facet: the diffuse term plus the ten Table 4 lobes.
pub const TERMS_PER_FACET: usize = 1 + LOBE_WIDTHS_TABLE4.len();

/// Below this ‖s − (s·Y)Y‖ the panel normal is undefined (Sun along the panel axis).
const PANEL_AXIS_EPS: f64 = 1e-12;

/// Sun-pointing panel normal (eq 4, normalised). Keeps `prev_n_p` when |s·Y| ≈ 1.
pub fn panel_normal(s_body: Vector3<f64>, prev_n_p: Vector3<f64>) -> Vector3<f64> {
    let v = Vector3::new(s_body.x, 0.0, s_body.z);
    let norm = v.norm();
    if norm.is_finite() && norm > PANEL_AXIS_EPS {
        v / norm
    } else {
        prev_n_p
    }
}

/// Visibility mask `[n·s]_+ [n·o]_+` (§1.2, §6.7).
pub fn visibility(n: Vector3<f64>, s: Vector3<f64>, o: Vector3<f64>) -> f64 {
    n.dot(&s).max(0.0) * n.dot(&o).max(0.0)
}

/// Area × BRDF coefficients of both facets \[m²\]: index 0 = diffuse (β_0 = 1/π), 1..=10 = lobes
/// with μ = [`LOBE_WIDTHS_TABLE4`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TwoFacetCoefficients {
    /// P_m = A_p b^p_m.
    pub panel: [f64; TERMS_PER_FACET],
    /// B_m = A_b b^b_m.
    pub body: [f64; TERMS_PER_FACET],
}

impl TwoFacetCoefficients {
    /// Tan et al. Table 4 at 650 nm (§1.8); no diffuse term.
    pub fn table4() -> Self {
        Self {
            panel: [
                0.0, 0.0003, 0.0103, 0.0837, 0.1046, 0.8049, 0.1153, 0.0489, 0.0345, 0.0003, 0.0103,
            ],
            body: [
                0.0, 0.1722, 0.0248, 0.0102, 0.0517, 0.0312, 0.0083, 0.0137, 0.0077, 0.0002, 0.0,
            ],
        }
    }
}

/// Writes the masked basis `[n·s]_+[n·o]_+ β_m(n, o, s)` for m = 0..=10 into `out`.
fn masked_basis(n: Vector3<f64>, s: Vector3<f64>, o: Vector3<f64>, out: &mut [f64]) {
    match LobeGeometry::new(n, o, s) {
        Some(g) => {
            out[0] = g.visibility() * DIFFUSE_BETA;
            for (slot, &mu) in out[1..].iter_mut().zip(LOBE_WIDTHS_TABLE4.iter()) {
                *slot = g.masked_beta(mu);
            }
        }
        None => out.fill(0.0),
    }
}

/// The design row G_j of eqs (11)–(12): `out[0..11]` panel, `out[11..22]` body \[sr⁻¹\].
pub fn design_row(
    n_p: Vector3<f64>,
    n_b: Vector3<f64>,
    s: Vector3<f64>,
    o: Vector3<f64>,
    out: &mut [f64; 2 * TERMS_PER_FACET],
) {
    let (panel, body) = out.split_at_mut(TERMS_PER_FACET);
    masked_basis(n_p, s, o, panel);
    masked_basis(n_b, s, o, body);
}

/// Normalised signal per facet `(q_p, q_b) = ([n_p·s]_+[n_p·o]_+ N_p, [n_b·s]_+[n_b·o]_+ N_b)`
/// [m² sr⁻¹] (eq 8); Q = q_p + q_b = Φ/K.
pub fn q_two_facet(
    coeffs: &TwoFacetCoefficients,
    n_p: Vector3<f64>,
    n_b: Vector3<f64>,
    s: Vector3<f64>,
    o: Vector3<f64>,
) -> (f64, f64) {
    let mut row = [0.0; 2 * TERMS_PER_FACET];
    design_row(n_p, n_b, s, o, &mut row);
    let (g_p, g_b) = row.split_at(TERMS_PER_FACET);
    let dot = |g: &[f64], x: &[f64]| g.iter().zip(x).map(|(a, b)| a * b).sum::<f64>();
    (dot(g_p, &coeffs.panel), dot(g_b, &coeffs.body))
}

/// Which attitude-matrix convention eq (17) uses (§1.6).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum AttitudeConvention {
    /// The seed's printed matrices: R_Z(ψ) R_Y(φ) R_X(θ) with the active R_Y (normative).
    #[default]
    Verbatim,
    /// The consistent passive 3-2-1 DCM R1(θ) R2(φ) R3(ψ).
    Consistent,
}

impl AttitudeConvention {
    /// R(t) for rates `p_deg_per_frame` after `t_frames` frames.
    pub fn matrix(self, p_deg_per_frame: [f64; 3], t_frames: f64) -> Matrix3<f64> {
        match self {
            Self::Verbatim => attitude_matrix_verbatim(p_deg_per_frame, t_frames),
            Self::Consistent => attitude_matrix_consistent(p_deg_per_frame, t_frames),
        }
    }

    /// [∂R/∂w_x, ∂R/∂w_y, ∂R/∂w_z] [per deg/frame].
    pub fn partials(self, p_deg_per_frame: [f64; 3], t_frames: f64) -> [Matrix3<f64>; 3] {
        match self {
            Self::Verbatim => attitude_matrix_verbatim_partials(p_deg_per_frame, t_frames),
            Self::Consistent => attitude_matrix_consistent_partials(p_deg_per_frame, t_frames),
        }
    }
}

/// Angles (θ, φ, ψ) \[rad\] = p t (deg → rad), eqs (15)–(16).
fn angles_rad(p_deg_per_frame: [f64; 3], t_frames: f64) -> [f64; 3] {
    p_deg_per_frame.map(|w| (w * t_frames).to_radians())
}

/// d/dθ of a passive elementary rotation about `axis` (0, 1, 2) at angle θ.
fn d_elementary(axis: usize, theta_rad: f64) -> Matrix3<f64> {
    let (s, c) = theta_rad.sin_cos();
    match axis {
        0 => Matrix3::new(0.0, 0.0, 0.0, 0.0, -s, c, 0.0, -c, -s),
        1 => Matrix3::new(-s, 0.0, -c, 0.0, 0.0, 0.0, c, 0.0, -s),
        _ => Matrix3::new(-s, c, 0.0, -c, -s, 0.0, 0.0, 0.0, 0.0),
    }
}

/// Seed eq (17) verbatim: `R_Z(ψ) R_Y(φ) R_X(θ)` = `R3(ψ) R2(−φ) R1(θ)`.
pub fn attitude_matrix_verbatim(p_deg_per_frame: [f64; 3], t_frames: f64) -> Matrix3<f64> {
    let [theta, phi, psi] = angles_rad(p_deg_per_frame, t_frames);
    r3(psi) * r2(-phi) * r1(theta)
}

/// Consistent alternative: `R1(θ) R2(φ) R3(ψ)`.
pub fn attitude_matrix_consistent(p_deg_per_frame: [f64; 3], t_frames: f64) -> Matrix3<f64> {
    let [theta, phi, psi] = angles_rad(p_deg_per_frame, t_frames);
    r1(theta) * r2(phi) * r3(psi)
}

/// Analytic `[∂R/∂w_x, ∂R/∂w_y, ∂R/∂w_z]` of the verbatim matrix [per deg/frame].
pub fn attitude_matrix_verbatim_partials(
    p_deg_per_frame: [f64; 3],
    t_frames: f64,
) -> [Matrix3<f64>; 3] {
    let [theta, phi, psi] = angles_rad(p_deg_per_frame, t_frames);
    let k = t_frames.to_radians(); // dθ/dw_x = t · π/180, same for φ, ψ.
    let (rz, ry, rx) = (r3(psi), r2(-phi), r1(theta));
    // d R2(−φ)/dφ = −R2'(−φ).
    [
        rz * ry * d_elementary(0, theta) * k,
        rz * (-d_elementary(1, -phi)) * rx * k,
        d_elementary(2, psi) * ry * rx * k,
    ]
}

/// Analytic `[∂R/∂w_x, ∂R/∂w_y, ∂R/∂w_z]` of the consistent matrix [per deg/frame].
pub fn attitude_matrix_consistent_partials(
    p_deg_per_frame: [f64; 3],
    t_frames: f64,
) -> [Matrix3<f64>; 3] {
    let [theta, phi, psi] = angles_rad(p_deg_per_frame, t_frames);
    let k = t_frames.to_radians();
    let (ra, rb, rc) = (r1(theta), r2(phi), r3(psi));
    [
        d_elementary(0, theta) * rb * rc * k,
        ra * d_elementary(1, phi) * rc * k,
        ra * rb * d_elementary(2, psi) * k,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brdf::lobe_beta;
    use crate::frames::angle_between_rad;

    fn assert_rel(got: f64, want: f64, rel: f64) {
        assert!(
            (got - want).abs() <= rel * want.abs(),
            "got {got:.12e}, want {want:.12e}"
        );
    }

    fn geometry_7_3d() -> (Vector3<f64>, Vector3<f64>) {
        (
            Vector3::new(0.95, 0.05, -0.30).normalize(),
            Vector3::new(0.999, 0.0, -0.045).normalize(),
        )
    }

    #[test]
    fn two_facet_q_matches_7_3d() {
        let (s, o) = geometry_7_3d();
        let n_b = Vector3::x();
        let n_p = panel_normal(s, Vector3::x());
        assert!((n_p - Vector3::new(0.95358267, 0.0, -0.30113137)).norm() < 1e-8);
        assert_rel(angle_between_rad(s, o).to_degrees(), 15.2139, 1e-5);
        let c = TwoFacetCoefficients::table4();
        let (q_p, q_b) = q_two_facet(&c, n_p, n_b, s, o);
        assert_rel(q_p, 0.562322541331, 1e-9);
        assert_rel(q_b, 0.0136787944020, 1e-9);
        assert_rel(q_p + q_b, 0.576001335733, 1e-9);
        // After 10 frames at p = [0, 0, 0.25] deg/frame, verbatim R, n_p held.
        let r = attitude_matrix_verbatim([0.0, 0.0, 0.25], 10.0);
        let (q_p, q_b) = q_two_facet(&c, n_p, n_b, r * s, r * o);
        assert_rel(q_p, 0.593846662657, 1e-9);
        assert_rel(q_b, 0.0139996787073, 1e-9);
    }

    #[test]
    fn design_row_matches_direct_formula() {
        let (s, o) = geometry_7_3d();
        let n_p = panel_normal(s, Vector3::x());
        let n_b = Vector3::x();
        let mut row = [0.0; 22];
        design_row(n_p, n_b, s, o, &mut row);
        for (k, n) in [(0, n_p), (11, n_b)] {
            let vis = visibility(n, s, o);
            assert_rel(row[k], vis / std::f64::consts::PI, 1e-14);
            for (m, &mu) in LOBE_WIDTHS_TABLE4.iter().enumerate() {
                let want = vis * lobe_beta(n, o, s, mu);
                assert!((row[k + 1 + m] - want).abs() <= 1e-12 * want.abs().max(1e-300));
            }
        }
        // A facet facing away contributes nothing.
        design_row(-n_p, -n_b, s, o, &mut row);
        assert!(row.iter().all(|&g| g == 0.0));
    }

    #[test]
    fn panel_normal_keeps_previous_on_axis() {
        let prev = Vector3::new(0.6, 0.0, 0.8);
        assert_eq!(panel_normal(Vector3::y(), prev), prev);
        assert_eq!(panel_normal(-Vector3::y(), prev), prev);
        let n = panel_normal(Vector3::new(0.0, 0.6, 0.8), prev);
        assert!((n - Vector3::z()).norm() < 1e-15);
    }

    #[test]
    fn verbatim_matrices_are_the_printed_ones() {
        let t = 7.0;
        let p = [0.3, -0.2, 0.5];
        let [th, ph, ps] = p.map(|w: f64| (w * t).to_radians());
        let rz = Matrix3::new(
            ps.cos(),
            ps.sin(),
            0.0,
            -ps.sin(),
            ps.cos(),
            0.0,
            0.0,
            0.0,
            1.0,
        );
        let ry = Matrix3::new(
            ph.cos(),
            0.0,
            ph.sin(),
            0.0,
            1.0,
            0.0,
            -ph.sin(),
            0.0,
            ph.cos(),
        );
        let rx = Matrix3::new(
            1.0,
            0.0,
            0.0,
            0.0,
            th.cos(),
            th.sin(),
            0.0,
            -th.sin(),
            th.cos(),
        );
        let r = attitude_matrix_verbatim(p, t);
        assert!((r - rz * ry * rx).abs().max() < 1e-15);
        let rc = attitude_matrix_consistent(p, t);
        assert!((rc - r1(th) * r2(ph) * r3(ps)).abs().max() < 1e-15);
        // Single-axis cases differ only by the sign of w_y.
        let a = attitude_matrix_verbatim([0.0, 0.25, 0.0], t);
        let b = attitude_matrix_consistent([0.0, -0.25, 0.0], t);
        assert!((a - b).abs().max() < 1e-15);
    }

    #[test]
    fn analytic_partials_match_central_differences() {
        let h = 1e-6;
        for conv in [AttitudeConvention::Verbatim, AttitudeConvention::Consistent] {
            for (p, t) in [([0.1, -0.3, 0.25], 12.0), ([0.0, 0.0, 0.0], 40.0)] {
                let d = conv.partials(p, t);
                for (i, d_i) in d.iter().enumerate() {
                    let (mut pp, mut pm) = (p, p);
                    pp[i] += h;
                    pm[i] -= h;
                    let fd = (conv.matrix(pp, t) - conv.matrix(pm, t)) / (2.0 * h);
                    let err = (fd - d_i).abs().max();
                    assert!(err < 1e-8, "{conv:?} axis {i}: {err:e}");
                }
            }
        }
    }
}
