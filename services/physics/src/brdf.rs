//! Multi-lobe Cook–Torrance/Beckmann BRDF of seed 000 (docs/math.md §1.3, eqs 5–6; §7.3).
//!
//! ```text
//! f(n, o, s) = b_0/π + Σ_m b_m β_m(n, o, s)                             (5)
//! β_m = D(τ; μ_m) / (4 (n·s)(n·o)),  D(τ; μ) = exp(−tan²τ/μ²) / (π μ² cos⁴τ)   (6)
//! ```
//!
//! τ is the angle between n and the half vector `h = normalize(s + o)`; it is never formed
//! explicitly: `c = n·h`, `tan²τ = (1 − c²)/c²`. Each lobe is a microfacet BRDF with F = G = 1,
//! so its directional albedo is ≈ 1 and the b_m are albedo fractions. All direction vectors
//! (n, o, s) must be unit vectors; the BRDF is 0 unless `n·s > 0` and `n·o > 0`.

use nalgebra::Vector3;
use std::f64::consts::{FRAC_1_PI, PI};

/// Lobe widths μ_m of Tan et al. Table 4 (m = 1..=10), rms facet slopes.
pub const LOBE_WIDTHS_TABLE4: [f64; 10] =
    [0.01, 0.02, 0.04, 0.05, 0.07, 0.08, 0.10, 0.20, 0.30, 0.50];

/// The Lambertian basis function β_0 = 1/π \[sr⁻¹\].
pub const DIFFUSE_BETA: f64 = FRAC_1_PI;

/// Beckmann distribution `D(τ; μ) = exp(−tan²τ/μ²)/(π μ² cos⁴τ)` from `cos_tau = n·h`.
/// Returns 0 for `cos_tau ≤ 0` (facet normal pointing away from the half vector).
pub fn beckmann_d(cos_tau: f64, mu: f64) -> f64 {
    if cos_tau.is_nan() || cos_tau <= 0.0 {
        return 0.0;
    }
    let c2 = (cos_tau * cos_tau).min(1.0);
    let tan2 = (1.0 - c2) / c2;
    let mu2 = mu * mu;
    let e = (-tan2 / mu2).exp();
    if e == 0.0 {
        // Avoid 0/0 when cos⁴τ underflows as well.
        return 0.0;
    }
    e / (PI * mu2 * c2 * c2)
}

/// Per-geometry quantities shared by every lobe: `n·s`, `n·o`, `cos τ = n·h`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LobeGeometry {
    /// n·s (> 0).
    pub cos_ns: f64,
    /// n·o (> 0).
    pub cos_no: f64,
    /// cos τ = n·normalize(s + o).
    pub cos_tau: f64,
}

impl LobeGeometry {
    /// `None` when the facet is not both lit and visible (`n·s ≤ 0` or `n·o ≤ 0`).
    pub fn new(n: Vector3<f64>, o: Vector3<f64>, s: Vector3<f64>) -> Option<Self> {
        let cos_ns = n.dot(&s);
        let cos_no = n.dot(&o);
        if !(cos_ns > 0.0 && cos_no > 0.0) {
            return None;
        }
        let half = s + o;
        let half_norm = half.norm();
        if !(half_norm > 0.0 && half_norm.is_finite()) {
            return None;
        }
        Some(Self {
            cos_ns,
            cos_no,
            cos_tau: n.dot(&half) / half_norm,
        })
    }

    /// Visibility factor `[n·s]_+ [n·o]_+`.
    pub fn visibility(&self) -> f64 {
        self.cos_ns * self.cos_no
    }

    /// Lobe β(μ) = D(τ; μ)/(4 (n·s)(n·o)) \[sr⁻¹\].
    pub fn beta(&self, mu: f64) -> f64 {
        beckmann_d(self.cos_tau, mu) / (4.0 * self.cos_ns * self.cos_no)
    }

    /// `[n·s]_+[n·o]_+ β(μ) = D(τ; μ)/4` \[sr⁻¹\]: the lobe times its visibility, without the
    /// cancelling division.
    pub fn masked_beta(&self, mu: f64) -> f64 {
        0.25 * beckmann_d(self.cos_tau, mu)
    }
}

/// Lobe β_m(n, o, s; μ) of eq (6) \[sr⁻¹\]; 0 unless `n·s > 0` and `n·o > 0`.
pub fn lobe_beta(n: Vector3<f64>, o: Vector3<f64>, s: Vector3<f64>, mu: f64) -> f64 {
    LobeGeometry::new(n, o, s).map_or(0.0, |g| g.beta(mu))
}

/// A BRDF `b_0/π + Σ w_m β(μ_m)` (eq 5).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct MultiLobeBrdf {
    /// Lambertian albedo fraction b_0.
    pub b0_diffuse: f64,
    /// Specular lobes as (μ, weight b_m).
    pub lobes: Vec<(f64, f64)>,
}

impl MultiLobeBrdf {
    /// f(n, o, s) \[sr⁻¹\]; 0 unless the facet is lit and visible.
    pub fn eval(&self, n: Vector3<f64>, o: Vector3<f64>, s: Vector3<f64>) -> f64 {
        LobeGeometry::new(n, o, s).map_or(0.0, |g| self.eval_geometry(&g))
    }

    /// f for a precomputed geometry \[sr⁻¹\].
    pub fn eval_geometry(&self, g: &LobeGeometry) -> f64 {
        self.b0_diffuse * DIFFUSE_BETA
            + self
                .lobes
                .iter()
                .map(|&(mu, w)| w * g.beta(mu))
                .sum::<f64>()
    }

    /// Total albedo b_0 + Σ b_m (≈ directional-hemispherical reflectance ρ for μ ≤ 0.3).
    pub fn total_albedo(&self) -> f64 {
        self.b0_diffuse + self.lobes.iter().map(|&(_, w)| w).sum::<f64>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn assert_rel(got: f64, want: f64, rel: f64) {
        assert!(
            (got - want).abs() <= rel * want.abs(),
            "got {got:.12e}, want {want:.12e}"
        );
    }

    fn in_plane(theta_i_deg: f64, theta_r_deg: f64) -> (Vector3<f64>, Vector3<f64>) {
        let (ti, tr) = (theta_i_deg.to_radians(), theta_r_deg.to_radians());
        let s = Vector3::new(-ti.sin(), 0.0, ti.cos());
        let o = Vector3::new(tr.sin(), 0.0, tr.cos());
        (s, o)
    }

    #[test]
    fn table_7_3a_in_plane_values() {
        let n = Vector3::z();
        let cases = [
            (45.0, 32.4806006310, 3.97887357730),
            (50.0, 24.3074515431, 4.18923469634),
            (60.0, 1.38315059997, 3.77586925069),
        ];
        for (theta_r, b007, b02) in cases {
            let (s, o) = in_plane(45.0, theta_r);
            assert_rel(lobe_beta(n, o, s, 0.07), b007, 1e-9);
            assert_rel(lobe_beta(n, o, s, 0.2), b02, 1e-9);
        }
    }

    #[test]
    fn table_7_3b_three_d_values() {
        let n = Vector3::z();
        let s = Vector3::new(0.3, 0.2, 0.9).normalize();
        let o = Vector3::new(-0.4, -0.1, 0.85).normalize();
        let g = LobeGeometry::new(n, o, s).expect("lit and visible");
        assert_rel(g.cos_tau, 0.996564701, 1e-9);
        assert_rel(g.cos_tau.acos().to_degrees(), 4.75055456, 1e-8);
        assert_rel(lobe_beta(n, o, s, 0.01), 9.81481726602e-28, 1e-9);
        assert_rel(lobe_beta(n, o, s, 0.07), 4.81586972954, 1e-9);
        assert_rel(lobe_beta(n, o, s, 0.2), 2.03203889769, 1e-9);
        assert_rel(lobe_beta(n, o, s, 0.5), 0.375869852901, 1e-9);
        // §7.3c: the unnormalised "cos τ" of the seed's eq (22) is wrong.
        assert_rel(n.dot(&((s + o) / 2.0)), 0.914007266, 1e-9);
    }

    #[test]
    fn masked_beta_equals_visibility_times_beta() {
        let n = Vector3::z();
        let (s, o) = in_plane(30.0, 41.0);
        let g = LobeGeometry::new(n, o, s).expect("visible");
        for mu in LOBE_WIDTHS_TABLE4 {
            assert_rel(g.masked_beta(mu), g.visibility() * g.beta(mu), 1e-14);
        }
    }

    #[test]
    fn invisible_or_unlit_is_zero() {
        let n = Vector3::z();
        let (s, o) = in_plane(45.0, 45.0);
        assert_eq!(lobe_beta(n, -o, s, 0.1), 0.0);
        assert_eq!(lobe_beta(n, o, -s, 0.1), 0.0);
        let brdf = MultiLobeBrdf {
            b0_diffuse: 0.5,
            lobes: vec![(0.1, 0.2)],
        };
        assert_eq!(brdf.eval(n, o, -s), 0.0);
        assert_eq!(beckmann_d(0.0, 0.1), 0.0);
        assert_eq!(beckmann_d(1e-200, 0.1), 0.0);
        assert_eq!(beckmann_d(f64::NAN, 0.1), 0.0);
    }

    #[test]
    fn multi_lobe_is_linear_in_weights() {
        let n = Vector3::z();
        let s = Vector3::new(0.3, 0.2, 0.9).normalize();
        let o = Vector3::new(-0.4, -0.1, 0.85).normalize();
        let brdf = MultiLobeBrdf {
            b0_diffuse: 0.1,
            lobes: vec![(0.07, 0.3), (0.2, 0.05)],
        };
        let want = 0.1 / PI + 0.3 * 4.81586972954 + 0.05 * 2.03203889769;
        assert_rel(brdf.eval(n, o, s), want, 1e-9);
        assert_rel(brdf.total_albedo(), 0.45, 1e-15);
    }

    #[test]
    fn lobe_albedo_is_about_one() {
        // ∫ β (n·o) dω over the hemisphere at 45° incidence (§1.3 [DER]: 1.0000 for μ = 0.07).
        let n = Vector3::z();
        let s = Vector3::new(-(45f64.to_radians().sin()), 0.0, 45f64.to_radians().cos());
        let (n_theta, n_phi) = (2000, 2000);
        let mut albedo = 0.0;
        for i in 0..n_theta {
            let th = (i as f64 + 0.5) * 0.5 * PI / n_theta as f64;
            for j in 0..n_phi {
                let ph = (j as f64 + 0.5) * 2.0 * PI / n_phi as f64;
                let o = Vector3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos());
                albedo += lobe_beta(n, o, s, 0.07) * th.cos() * th.sin();
            }
        }
        albedo *= (0.5 * PI / n_theta as f64) * (2.0 * PI / n_phi as f64);
        assert!((albedo - 1.0).abs() < 2e-3, "albedo {albedo}");
    }
}
