//! Masked two-facet basis of eqs (11)–(12) and (20) with analytic derivatives (docs/math.md
//! §1.2–1.3, §1.6).
//!
//! For a facet with unit normal n, Sun s and observer o (unit vectors in the rotated body frame
//! s' = R s, o' = R o), with `a = n·s`, `b = n·o`, `u = s + o`, `h = u/‖u‖`, `c = cos τ = n·h`:
//!
//! ```text
//! G_0 = [a]_+[b]_+ / π                         (diffuse, β_0 = 1/π)
//! G_m = [a]_+[b]_+ β_m = D(c; μ_m)/4            (lobes, m = 1..=10; 0 unless a > 0 and b > 0)
//! D(c; μ) = exp(−t/μ²)/(π μ² c⁴),  t = tan²τ = (1 − c²)/c²
//! dD/dc   = D · (2/(μ² c³) − 4/c)
//! ∂c/∂s = ∂c/∂o = (n − c h)/‖u‖,   ∂c/∂n = h
//! ∂G_0/∂s = b n/π,  ∂G_0/∂o = a n/π,  ∂G_0/∂n = (b s + a o)/π
//! β_m = D/(4ab):  ∇β_m = β_m (D'/D ∇c − ∇a/a − ∇b/b)
//! ```
//!
//! The visibility clamp makes G piecewise smooth: inside the lit-and-visible region the formulas
//! above hold; outside, G and its derivatives are 0. (G_m jumps at the horizon because the masked
//! lobe does not vanish there; the derivative is the one-sided one of the active branch.)
//!
//! The only approximation: a lobe with `t/μ² > LOBE_EXP_CUTOFF` (= 60) is set to 0; it contributes
//! less than e⁻⁶⁰ ≈ 9e-27 of its own peak `1/(4πμ²)`.

use glint_physics::brdf::LOBE_WIDTHS_TABLE4;
use glint_physics::two_facet::TERMS_PER_FACET;
use nalgebra::Vector3;
use std::f64::consts::{FRAC_1_PI, PI};

/// Basis terms per facet (diffuse + 10 lobes).
pub const TERMS: usize = TERMS_PER_FACET;

/// Lobes with `tan²τ/μ²` above this are treated as 0 (relative size < e⁻⁶⁰).
pub const LOBE_EXP_CUTOFF: f64 = 60.0;

/// Number of lobes M.
pub const LOBES: usize = LOBE_WIDTHS_TABLE4.len();

/// 1/μ_m².
const INV_MU2: [f64; LOBES] = {
    let mut out = [0.0; LOBES];
    let mut m = 0;
    while m < LOBES {
        out[m] = 1.0 / (LOBE_WIDTHS_TABLE4[m] * LOBE_WIDTHS_TABLE4[m]);
        m += 1;
    }
    out
};

/// The widths the power chain below relies on (1/μ² = 10⁴, 2500, 625, 400, ·, 156.25, 100, 25,
/// ·, 4).
const CHAIN_WIDTHS: [f64; LOBES] = [0.01, 0.02, 0.04, 0.05, 0.07, 0.08, 0.10, 0.20, 0.30, 0.50];

/// The lobes whose exponential the chain from e₄ gives.
const CHAIN_LOBES: [usize; 8] = [0, 1, 2, 3, 5, 6, 7, 9];

const CHAIN_APPLIES: bool = {
    let mut same = true;
    let mut m = 0;
    while m < LOBES {
        same &= LOBE_WIDTHS_TABLE4[m] == CHAIN_WIDTHS[m];
        m += 1;
    }
    same
};

/// `exp(−t/μ_m²)` for every lobe (t = tan²τ ≥ 0); 0 where `t/μ_m² > LOBE_EXP_CUTOFF`.
pub fn lobe_exponentials(tan2: f64) -> [f64; LOBES] {
    lobe_exponentials_of(tan2, &[true; LOBES])
}

/// [`lobe_exponentials`] for the lobes flagged in `needed` (the others 0): only the
/// exponentials a needed lobe within the cutoff uses are computed, and each needed value is
/// bit-for-bit the one [`lobe_exponentials`] gives.
///
/// For the Table-4 widths one `exp` serves eight lobes: with e₄ = exp(−4t), e₁ = √√e₄,
/// e₂₅ = e₄⁶ e₁, e₁₀₀ = e₂₅⁴, e₄₀₀ = e₁₀₀⁴, e₆₂₅ = e₂₅²⁵, e₁₅₆.₂₅ = √√e₆₂₅, e₂₅₀₀ = e₆₂₅⁴,
/// e₁₀₀₀₀ = e₂₅₀₀⁴ (relative rounding ≲ 4e-13 on e₁₀₀₀₀, which is only used while ≥ e⁻⁶⁰);
/// the other two (μ = 0.07, 0.3) take their own. Far from the specular direction most lobes
/// are past the cutoff and cost nothing.
#[inline]
pub fn lobe_exponentials_of(tan2: f64, needed: &[bool; LOBES]) -> [f64; LOBES] {
    let mut out = [0.0; LOBES];
    let mut want = [false; LOBES];
    for m in 0..LOBES {
        want[m] = needed[m] && tan2 * INV_MU2[m] <= LOBE_EXP_CUTOFF;
    }
    if CHAIN_APPLIES {
        // Each power is formed only when it or a narrower lobe is wanted: every value formed is
        // then ≥ e⁻²⁴⁰, never subnormal (arithmetic on subnormals is tens of times slower).
        let from = |m: usize| want[..=m].iter().any(|&w| w);
        if CHAIN_LOBES.iter().any(|&m| want[m]) {
            let e4 = (-4.0 * tan2).exp();
            out[9] = e4;
            if from(7) {
                let e8 = e4 * e4;
                let e25 = (e8 * e8) * e8 * e4.sqrt().sqrt();
                out[7] = e25;
                if from(6) {
                    let x4 = (e25 * e25) * (e25 * e25);
                    out[6] = x4;
                    if from(5) {
                        let x8 = x4 * x4;
                        let x16 = x8 * x8;
                        let e625 = x16 * x8 * e25;
                        out[2] = e625;
                        out[3] = (x4 * x4) * (x4 * x4);
                        out[5] = e625.sqrt().sqrt();
                        if from(1) {
                            let e2500 = (e625 * e625) * (e625 * e625);
                            out[1] = e2500;
                            out[0] = (e2500 * e2500) * (e2500 * e2500);
                        }
                    }
                }
            }
            for m in CHAIN_LOBES {
                if !want[m] {
                    out[m] = 0.0;
                }
            }
        }
        for m in [4, 8] {
            if want[m] {
                out[m] = (-INV_MU2[m] * tan2).exp();
            }
        }
    } else {
        for m in 0..LOBES {
            if want[m] {
                out[m] = (-INV_MU2[m] * tan2).exp();
            }
        }
    }
    out
}

/// Per-facet Beckmann quantities: D_m/4 and d(D_m/4)/dc for every lobe (0 for inactive lobes,
/// c ≤ 0, or beyond the cutoff).
fn quarter_beckmann(
    cos_tau: f64,
    active: &[bool; LOBES],
    with_derivative: bool,
) -> ([f64; LOBES], [f64; LOBES]) {
    let (mut d, mut dd) = ([0.0; LOBES], [0.0; LOBES]);
    if cos_tau.is_nan() || cos_tau <= 0.0 || !active.iter().any(|&a| a) {
        return (d, dd);
    }
    let c2 = (cos_tau * cos_tau).min(1.0);
    let inv_c2 = 1.0 / c2;
    let tan2 = (1.0 - c2) * inv_c2;
    let e = lobe_exponentials_of(tan2, active);
    let k = 0.25 * inv_c2 * inv_c2 / PI;
    let inv_c = inv_c2.sqrt();
    for m in 0..LOBES {
        // Inactive lobes stay +0 (their e is 0, but 0 · k is NaN when k overflows).
        let value = e[m] * INV_MU2[m] * k;
        d[m] = if active[m] { value } else { 0.0 };
    }
    if with_derivative {
        for m in 0..LOBES {
            let slope = d[m] * inv_c * (2.0 * INV_MU2[m] * inv_c2 - 4.0);
            dd[m] = if active[m] { slope } else { 0.0 };
        }
    }
    (d, dd)
}

/// Geometry of a lit and visible facet.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FacetGeometry {
    /// a = n·s (> 0).
    pub cos_ns: f64,
    /// b = n·o (> 0).
    pub cos_no: f64,
    /// c = cos τ = n·h.
    pub cos_tau: f64,
    /// Unit half vector h = normalize(s + o).
    pub half: Vector3<f64>,
    /// 1/‖s + o‖.
    pub inv_half_norm: f64,
    /// The facet normal n.
    pub normal: Vector3<f64>,
}

impl FacetGeometry {
    /// `None` unless `n·s > 0`, `n·o > 0` and `s + o ≠ 0` (same rule as the physics crate).
    pub fn new(n: Vector3<f64>, s: Vector3<f64>, o: Vector3<f64>) -> Option<Self> {
        let (a, b) = (n.dot(&s), n.dot(&o));
        if !(a > 0.0 && b > 0.0) {
            return None;
        }
        let u = s + o;
        let len = u.norm();
        if !(len > 0.0 && len.is_finite()) {
            return None;
        }
        let half = u / len;
        Some(Self {
            cos_ns: a,
            cos_no: b,
            cos_tau: n.dot(&half),
            half,
            inv_half_norm: 1.0 / len,
            normal: n,
        })
    }

    /// ∂c/∂s = ∂c/∂o = (n − c h)/‖s + o‖.
    pub fn dcos_tau_dso(&self) -> Vector3<f64> {
        (self.normal - self.half * self.cos_tau) * self.inv_half_norm
    }

    /// Masked basis values `G_m`, m = 0..=10, for the terms flagged in `active` (others 0).
    pub fn basis(&self, active: &[bool; TERMS], out: &mut [f64; TERMS]) {
        out[0] = if active[0] {
            self.cos_ns * self.cos_no * FRAC_1_PI
        } else {
            0.0
        };
        let [_, lobes @ ..] = active;
        let (d, _) = quarter_beckmann(self.cos_tau, lobes, false);
        out[1..].copy_from_slice(&d);
    }

    /// Lobe values `D_m/4` and slopes `d(D_m/4)/dc` for the lobes flagged in `active` (M
    /// entries; the slopes are 0 unless `with_slope`).
    pub fn quarter_lobes(
        &self,
        active: &[bool; LOBES],
        with_slope: bool,
    ) -> ([f64; LOBES], [f64; LOBES]) {
        quarter_beckmann(self.cos_tau, active, with_slope)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glint_physics::brdf::beckmann_d;
    use glint_physics::two_facet::design_row;

    fn geometry() -> (Vector3<f64>, Vector3<f64>, Vector3<f64>) {
        (
            Vector3::new(0.2, 0.1, 1.0).normalize(),
            Vector3::new(0.3, 0.2, 0.9).normalize(),
            Vector3::new(-0.25, -0.1, 0.85).normalize(),
        )
    }

    #[test]
    fn values_match_physics_design_row() {
        let (n, s, o) = geometry();
        let mut row = [0.0; 22];
        design_row(n, -n, s, o, &mut row);
        let g = FacetGeometry::new(n, s, o).expect("visible");
        let mut out = [0.0; TERMS];
        g.basis(&[true; TERMS], &mut out);
        for m in 0..TERMS {
            // Below the cutoff the physics value is < e⁻⁶⁰ of the lobe peak.
            let (a, b) = (out[m], row[m]);
            // (1 − c²) cancels near the specular point, so c's last bit shows up ~1e-13.
            assert!(
                (a - b).abs() <= 1e-11 * b.abs() + 1e-22,
                "{m}: {a:e} vs {b:e}"
            );
        }
        for c in [0.9995, 0.995, 0.9] {
            let (d, _) = quarter_beckmann(c, &[true; LOBES], false);
            let tan2 = (1.0 - c * c) / (c * c);
            for (m, &mu) in LOBE_WIDTHS_TABLE4.iter().enumerate() {
                let cut = tan2 / (mu * mu) > LOBE_EXP_CUTOFF;
                let want = if cut { 0.0 } else { 0.25 * beckmann_d(c, mu) };
                assert!(
                    (d[m] - want).abs() <= 1e-12 * want.max(1e-300),
                    "μ {mu} c {c}"
                );
            }
        }
    }

    #[test]
    fn lobe_exponentials_of_a_subset_are_the_full_set_s_bits() {
        for k in 0..2000 {
            let t2 = 1e-7 * 1.01f64.powi(k);
            let all = lobe_exponentials(t2);
            for mask in [
                0b11_1111_1111u32,
                0b00_1111_1111,
                0b11_0011_0000,
                0b00_0000_0001,
                0,
            ] {
                let needed: [bool; LOBES] = std::array::from_fn(|m| mask >> m & 1 == 1);
                let some = lobe_exponentials_of(t2, &needed);
                for m in 0..LOBES {
                    let want = if needed[m] { all[m] } else { 0.0 };
                    assert_eq!(
                        some[m].to_bits(),
                        want.to_bits(),
                        "t2 {t2} m {m} mask {mask:b}"
                    );
                }
            }
        }
    }

    #[test]
    fn lobe_exponentials_match_exp() {
        const { assert!(CHAIN_APPLIES) };
        for k in 0..2000 {
            let t2 = 1e-7 * 1.01f64.powi(k);
            let e = lobe_exponentials(t2);
            for m in 0..LOBES {
                let arg = t2 * INV_MU2[m];
                let want = if arg > LOBE_EXP_CUTOFF {
                    0.0
                } else {
                    (-arg).exp()
                };
                assert!((e[m] - want).abs() <= 1e-12 * want, "t2 {t2} m {m}");
            }
        }
    }

    #[test]
    fn lobe_slopes_match_central_differences() {
        for c in [0.9995, 0.999, 0.99, 0.95, 0.9] {
            let (d, dd) = quarter_beckmann(c, &[true; LOBES], true);
            let h = 1e-7;
            let (up, _) = quarter_beckmann(c + h, &[true; LOBES], false);
            let (down, _) = quarter_beckmann(c - h, &[true; LOBES], false);
            for m in 0..LOBES {
                if d[m] == 0.0 {
                    continue;
                }
                let fd = (up[m] - down[m]) / (2.0 * h);
                assert!(
                    (fd - dd[m]).abs() <= 1e-5 * dd[m].abs().max(d[m]),
                    "lobe {m} c {c}"
                );
            }
        }
    }

    #[test]
    fn a_facet_not_lit_or_not_visible_has_no_geometry() {
        let (n, s, o) = geometry();
        assert!(FacetGeometry::new(n, s, o).is_some());
        assert!(FacetGeometry::new(-n, s, o).is_none());
        assert!(FacetGeometry::new(n, -s, o).is_none());
    }
}
