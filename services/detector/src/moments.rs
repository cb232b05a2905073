//! Central moments and the second-moment ellipse of a blob (docs/math.md §3.3, eqs 5–7, FIXED).
//!
//! From raw moments `m_pq` about an origin o: centroid `x_c = o_x + m10/m00`,
//! `y_c = o_y + m01/m00` (eq 5), and central moments (eq 6)
//! `μ20 = m20 − m10²/m00`, `μ02 = m02 − m01²/m00`, `μ11 = m11 − m10 m01/m00`.
//! With `Δ = sqrt((μ20 − μ02)² + 4 μ11²)` (eq 7, fixed form):
//!
//! ```text
//! a = sqrt(2 (μ20 + μ02 + Δ) / μ00)     b = sqrt(2 (μ20 + μ02 − Δ) / μ00)
//! θ = ½ atan2(2 μ11, μ20 − μ02) ∈ (−π/2, π/2]     e = sqrt(1 − b²/a²) ∈ [0, 1]
//! ```
//!
//! a and b are twice the square roots of the eigenvalues of the covariance `C/μ00`, so a filled
//! ellipse with semi-axes (A, B) gives (a, b) = (A, B); θ is measured from +x (columns) toward
//! +y (rows, down), i.e. clockwise on screen. b is evaluated as `sqrt(8 det / (μ00 (μ20 + μ02 +
//! Δ)))` with `det = μ20 μ02 − μ11²`, which equals the form above without its cancellation.
//! Features are translation invariant; the centroid is in 0-based pixel coordinates (first pixel
//! centre at (0, 0)). A blob of one pixel (or a line) has b = 0; a single pixel has a = 0 and, by
//! convention, e = 0.

use crate::segment::{BoundingBox, Component, RawMoments};

/// Central moments and centroid of one moment set.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CentralMoments {
    pub mu00: f64,
    pub x_px: f64,
    pub y_px: f64,
    pub mu20: f64,
    pub mu02: f64,
    pub mu11: f64,
}

impl CentralMoments {
    /// Central moments from raw moments about (origin_x_px, origin_y_px); `None` unless
    /// `m00 > 0` and every moment is finite.
    pub fn from_raw(raw: &RawMoments, origin_x_px: f64, origin_y_px: f64) -> Option<Self> {
        let RawMoments {
            m00,
            m10,
            m01,
            m20,
            m02,
            m11,
        } = *raw;
        let all = [m00, m10, m01, m20, m02, m11, origin_x_px, origin_y_px];
        if all.iter().any(|v| !v.is_finite()) || m00 <= 0.0 {
            return None;
        }
        let (xr, yr) = (m10 / m00, m01 / m00);
        Some(Self {
            mu00: m00,
            x_px: origin_x_px + xr,
            y_px: origin_y_px + yr,
            mu20: (m20 - m10 * xr).max(0.0),
            mu02: (m02 - m01 * yr).max(0.0),
            mu11: m11 - m10 * yr,
        })
    }
}

/// Second-moment ellipse features of one moment set (eq 7).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Ellipse {
    /// Zeroth moment: pixel count (binary) or flux above background \[DN\] (weighted).
    pub m00: f64,
    /// Centroid, 0-based column \[px\].
    pub x_px: f64,
    /// Centroid, 0-based row \[px\].
    pub y_px: f64,
    /// Semi-major axis \[px\].
    pub a_px: f64,
    /// Semi-minor axis \[px\].
    pub b_px: f64,
    /// Major-axis angle from +x toward +y, in (−π/2, π/2] \[rad\].
    pub theta_rad: f64,
    /// `sqrt(1 − b²/a²)`, in \[0, 1\].
    pub eccentricity: f64,
}

impl Ellipse {
    /// The ellipse of the central moments `c`.
    pub fn from_central(c: &CentralMoments) -> Self {
        let sum = c.mu20 + c.mu02;
        let diff = c.mu20 - c.mu02;
        let delta = diff.hypot(2.0 * c.mu11);
        let a_sq = 2.0 * (sum + delta) / c.mu00;
        let det = (c.mu20 * c.mu02 - c.mu11 * c.mu11).max(0.0);
        let b_sq = if sum + delta > 0.0 {
            8.0 * det / (c.mu00 * (sum + delta))
        } else {
            0.0
        };
        let a_px = a_sq.max(0.0).sqrt();
        let b_px = b_sq.max(0.0).sqrt().min(a_px);
        let eccentricity = if a_sq > 0.0 {
            (1.0 - b_sq / a_sq).clamp(0.0, 1.0).sqrt()
        } else {
            0.0
        };
        Self {
            m00: c.mu00,
            x_px: c.x_px,
            y_px: c.y_px,
            a_px,
            b_px,
            theta_rad: 0.5 * (2.0 * c.mu11).atan2(diff),
            eccentricity,
        }
    }

    /// The ellipse of raw moments about an origin; `None` if `m00 ≤ 0` or not finite.
    pub fn from_raw(raw: &RawMoments, origin_x_px: f64, origin_y_px: f64) -> Option<Self> {
        CentralMoments::from_raw(raw, origin_x_px, origin_y_px).map(|c| Self::from_central(&c))
    }
}

/// Which moment set a feature, gate or centroid comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FeatureSet {
    /// f = 1 on every foreground pixel (the seed's binary map).
    #[default]
    Binary,
    /// f = pixel − background.
    Weighted,
}

/// A detected blob: the binary-moment ellipse at the top level, the weighted one in `weighted`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Blob {
    /// Pixel count (binary m00) \[px\].
    pub area_px: u32,
    /// Binary centroid \[px\].
    pub x_px: f64,
    pub y_px: f64,
    /// Binary semi-axes \[px\].
    pub a_px: f64,
    pub b_px: f64,
    pub theta_rad: f64,
    pub eccentricity: f64,
    /// Intensity-weighted ellipse (f = v − background). If the weighted m00 is not positive
    /// (only possible with an absolute threshold below the background) it repeats the binary
    /// ellipse with `m00 = flux_dn`.
    pub weighted: Ellipse,
    /// Σ (v − background) over the blob \[DN\].
    pub flux_dn: f64,
    /// Largest pixel value \[DN\].
    pub peak_dn: u16,
    pub bbox: BoundingBox,
    pub touches_border: bool,
    pub saturated_px: u32,
}

impl Blob {
    /// Features of a component; `None` only for an empty component.
    pub fn from_component(c: &Component) -> Option<Self> {
        let (ox, oy) = (f64::from(c.origin_x_px), f64::from(c.origin_y_px));
        let binary = Ellipse::from_raw(&c.binary, ox, oy)?;
        let flux_dn = c.weighted.m00;
        let weighted = Ellipse::from_raw(&c.weighted, ox, oy).unwrap_or(Ellipse {
            m00: flux_dn,
            ..binary
        });
        Some(Self {
            area_px: c.area_px,
            x_px: binary.x_px,
            y_px: binary.y_px,
            a_px: binary.a_px,
            b_px: binary.b_px,
            theta_rad: binary.theta_rad,
            eccentricity: binary.eccentricity,
            weighted,
            flux_dn,
            peak_dn: c.peak_dn,
            bbox: c.bbox,
            touches_border: c.touches_border,
            saturated_px: c.saturated_px,
        })
    }

    /// The binary ellipse (m00 = area).
    pub fn binary(&self) -> Ellipse {
        Ellipse {
            m00: f64::from(self.area_px),
            x_px: self.x_px,
            y_px: self.y_px,
            a_px: self.a_px,
            b_px: self.b_px,
            theta_rad: self.theta_rad,
            eccentricity: self.eccentricity,
        }
    }

    /// The ellipse of the requested moment set.
    /// 1σ of the intensity-weighted centroid \[px\] (RMS of the x and y errors), propagated from
    /// per-pixel noise: background σ_bg \[DN\] on every pixel of the blob plus shot noise of the
    /// signal, `var(x̄) = (σ_bg² Σ(x−x̄)² + Σ s (x−x̄)²/g) / F²`, with F the flux \[DN\] and g the
    /// gain \[e⁻/DN\]. The sums come from the binary and weighted second moments.
    pub fn centroid_sigma_px(&self, background_sigma_dn: f64, gain_e_per_dn: f64) -> f64 {
        let f = self.weighted.m00;
        if !(f > 0.0 && gain_e_per_dn > 0.0) {
            return f64::NAN;
        }
        // Σ over the blob of squared offsets, summed over x and y: for an ellipse with semi-axes
        // a, b the per-axis variances are a²/4 and b²/4 (trace is rotation-invariant).
        let trace = |e: &Ellipse| (e.a_px * e.a_px + e.b_px * e.b_px) / 4.0;
        let bin = self.binary();
        let sum_bg = background_sigma_dn.powi(2) * bin.m00 * trace(&bin);
        let sum_shot = f * trace(&self.weighted) / gain_e_per_dn;
        ((sum_bg + sum_shot) / (f * f) / 2.0).sqrt()
    }

    pub fn ellipse(&self, set: FeatureSet) -> Ellipse {
        match set {
            FeatureSet::Binary => self.binary(),
            FeatureSet::Weighted => self.weighted,
        }
    }
}

#[cfg(test)]
mod tests;
