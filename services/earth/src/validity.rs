//! Whether a method's answer holds for this frame, and why not when it does not.
//!
//! A method answers with a number only when the frame determines it: enough limb, samples that
//! pin β down, edge points that lie on the limb the answer implies, and — for the circle
//! baseline — a β where the limb's image is still close enough to a circle. Otherwise it says
//! "not determined" and why ([`Undetermined`]); on the wire [`Undetermined::code`].
//!
//! - **Precision.** The cross product's β is the location of a t distribution fitted to the
//!   β_k samples; its standard error is σ √((ν + 3) / ((ν + 1) n)) (the inverse Fisher
//!   information of a t location). A short or ragged visible limb gives few, scattered samples.
//! - **On the limb.** Every limb direction u satisfies ∠(u, ê) = ρ: the edge points must lie on
//!   one cone about the answer's nadir ê. Edges of something else — the lens's field boundary,
//!   a vignetting circle, the Sun — do not, and when they outnumber the limb the answer is off.
//! - **The circle's model bias.** Under r = f θ the limb's image is not a circle (math.md
//!   §4.7); the bias of the circle fit at the answer's β is computed from the same masks, and
//!   the baseline answers only where it is within the tolerance.

use std::f64::consts::PI;

use crate::hough::kasa_fit;
use crate::ring::Fisheye;
use crate::tfit::TFit;

/// Why a method has no answer on a frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Undetermined {
    /// Too few edge points or angle samples on the limb.
    NoLimb { edge_points: usize, samples: usize },
    /// The samples fix β only to ± this standard error [deg].
    Imprecise {
        standard_error_deg: f64,
        samples: usize,
    },
    /// Only this fraction of the edge points lies on the limb cone of the answer's nadir.
    OffTheLimb { on_limb_fraction: f64 },
    /// The circle fit's model bias at this β [deg] exceeds the tolerance.
    CircleModelBias { beta_deg: f64, bias_deg: f64 },
    /// The samples' mode (the lookup's answer) and their fitted location disagree by more
    /// than the error budget allows [deg]: the samples are skewed or fall in several clusters.
    ModeOffLocation {
        mode_deg: f64,
        location_deg: f64,
        allowed_deg: f64,
    },
}

impl Undetermined {
    /// Wire codes ([`shared_types::EarthMethod::undetermined`], named by
    /// `EarthMethod::UNDETERMINED_NAMES`): 0 is "determined".
    pub const NO_LIMB: u32 = 1;
    pub const IMPRECISE: u32 = 2;
    pub const OFF_THE_LIMB: u32 = 3;
    pub const CIRCLE_MODEL_BIAS: u32 = 4;
    pub const MODE_OFF_LOCATION: u32 = 5;

    pub fn code(&self) -> u32 {
        match self {
            Undetermined::NoLimb { .. } => Self::NO_LIMB,
            Undetermined::Imprecise { .. } => Self::IMPRECISE,
            Undetermined::OffTheLimb { .. } => Self::OFF_THE_LIMB,
            Undetermined::CircleModelBias { .. } => Self::CIRCLE_MODEL_BIAS,
            Undetermined::ModeOffLocation { .. } => Self::MODE_OFF_LOCATION,
        }
    }
}

impl std::fmt::Display for Undetermined {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match *self {
            Undetermined::NoLimb {
                edge_points,
                samples,
            } => write!(
                f,
                "not determined: {edge_points} edge points gave {samples} angle samples \
                 (too little limb in the field)"
            ),
            Undetermined::Imprecise {
                standard_error_deg,
                samples,
            } => write!(
                f,
                "not determined: the {samples} angle samples fix β to ±{standard_error_deg:.3}° \
                 only (the visible limb is too short or too ragged)"
            ),
            Undetermined::OffTheLimb { on_limb_fraction } => write!(
                f,
                "not determined: only {:.0} % of the edge points lie on the limb of the \
                 answer's nadir (other edges, e.g. the lens's field boundary, dominate)",
                100.0 * on_limb_fraction
            ),
            Undetermined::CircleModelBias { beta_deg, bias_deg } => write!(
                f,
                "not determined: at β ≈ {beta_deg:.1}° the limb's image departs from a circle: \
                 a circle fitted to the exact visible limb is off by {bias_deg:+.3}°"
            ),
            Undetermined::ModeOffLocation {
                mode_deg,
                location_deg,
                allowed_deg,
            } => write!(
                f,
                "not determined: the samples' mode {mode_deg:.3}° is {:.3}° from their fitted \
                 location {location_deg:.3}° (allowed {allowed_deg:.3}°: skewed or clustered \
                 samples)",
                (mode_deg - location_deg).abs()
            ),
        }
    }
}

/// The thresholds of [`Undetermined`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ValidityConfig {
    /// Largest standard error of β a method may answer with [deg].
    pub max_standard_error_deg: f64,
    /// Smallest fraction of edge points on the answer's limb cone.
    pub min_on_limb_fraction: f64,
    /// An edge point within this of the cone is on it [px].
    pub limb_tolerance_px: f64,
    /// Largest model bias of the circle fit [deg].
    pub max_circle_bias_deg: f64,
    /// The error budget of the lookup's answer [deg]: its distance from the fitted location
    /// plus two standard errors of that location must stay within it. The lookup's mode is a
    /// coarser estimator than the fit (a histogram bin and a mean shift); where the samples
    /// are skewed or clustered (a cut limb) it moves off β while the fit does not.
    pub lookup_error_budget_deg: f64,
}

impl Default for ValidityConfig {
    fn default() -> Self {
        Self {
            max_standard_error_deg: 0.015,
            min_on_limb_fraction: 0.8,
            limb_tolerance_px: 3.0,
            max_circle_bias_deg: 0.025,
            lookup_error_budget_deg: 0.05,
        }
    }
}

/// The standard error of a t fit's location: σ √((ν + 3) / ((ν + 1) n)) [the fit's units],
/// n the samples over their correlation time ([`correlation_time`]).
pub fn location_standard_error(fit: &TFit, correlation_time: f64) -> f64 {
    let n = fit.n.max(1) as f64 / correlation_time.max(1.0);
    fit.sigma * ((fit.nu + 3.0) / ((fit.nu + 1.0) * n)).sqrt()
}

/// The correlation time τ = (1 + ρ)/(1 − ρ) of samples in their order, ρ their lag-1
/// autocorrelation about `center` clamped to [0, 0.95]: neighbouring cross products share
/// neighbouring limb pixels, and their errors move together.
pub fn correlation_time(samples: &[f64], center: f64) -> f64 {
    let d: Vec<f64> = samples.iter().map(|x| x - center).collect();
    let energy: f64 = d.iter().map(|v| v * v).sum();
    if d.len() < 3 || energy <= 0.0 {
        return 1.0;
    }
    let lagged: f64 = d.windows(2).map(|w| w[0] * w[1]).sum();
    let rho = (lagged / energy).clamp(0.0, 0.95);
    (1.0 + rho) / (1.0 - rho)
}

/// The unit nadir of a β and the azimuth of its tilt about Z_S [deg].
pub fn nadir(beta_deg: f64, azimuth_deg: f64) -> [f64; 3] {
    let (sb, cb) = beta_deg.to_radians().sin_cos();
    let (sa, ca) = azimuth_deg.to_radians().sin_cos();
    [sb * ca, sb * sa, cb]
}

/// The fraction of `points` (unit directions) whose angle to `nadir` is within `tol_rad` of
/// the median such angle: how much of the edge is one limb cone about `nadir`.
pub fn on_limb_fraction(points: &[[f64; 3]], nadir: [f64; 3], tol_rad: f64) -> f64 {
    if points.is_empty() {
        return 0.0;
    }
    let mut angles: Vec<f64> = (points.iter())
        .map(|u| (u[0] * nadir[0] + u[1] * nadir[1] + u[2] * nadir[2]).clamp(-1.0, 1.0))
        .map(f64::acos)
        .collect();
    angles.sort_by(f64::total_cmp);
    let median = angles[angles.len() / 2];
    let on = angles
        .iter()
        .filter(|a| (*a - median).abs() <= tol_rad)
        .count();
    on as f64 / angles.len() as f64
}

/// Where edge points can be: inside the frame, outside the blind zone, inside the field.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Visible {
    pub width_px: usize,
    pub height_px: usize,
    /// Radii [px] from the principal point the edge extraction keeps.
    pub r_min_px: f64,
    pub r_max_px: f64,
}

impl Visible {
    fn contains(&self, cam: &Fisheye, (x, y): (f64, f64)) -> bool {
        let r = (x - cam.x0_px).hypot(y - cam.y0_px);
        x >= 1.0
            && y >= 1.0
            && x <= self.width_px as f64 - 2.0
            && y <= self.height_px as f64 - 2.0
            && r >= self.r_min_px
            && r <= self.r_max_px
    }
}

/// The circle fit's model bias at `beta_deg` (tilt toward `azimuth_deg`): the exact limb of
/// angular radius `rho_rad` imaged through `cam`, kept where `visible`, fitted by Kåsa, minus
/// β [deg]; None when too little of it is visible to fit.
pub fn circle_model_bias(
    cam: &Fisheye,
    beta_deg: f64,
    azimuth_deg: f64,
    rho_rad: f64,
    visible: &Visible,
) -> Option<f64> {
    let e = nadir(beta_deg, azimuth_deg);
    // An orthonormal pair ⊥ ê.
    let a = if e[2].abs() < 0.9 {
        [0.0, 0.0, 1.0]
    } else {
        [1.0, 0.0, 0.0]
    };
    let u = normalise(cross(e, a));
    let v = cross(e, u);
    let (sr, cr) = rho_rad.sin_cos();
    let theta_max = match cam.undistort(visible.r_max_px / cam.f_px) {
        t if t.is_finite() => t,
        _ => PI,
    };
    const STEPS: usize = 720;
    let points: Vec<(f64, f64)> = (0..STEPS)
        .map(|k| 2.0 * PI * k as f64 / STEPS as f64)
        .map(|phi| {
            let (s, c) = phi.sin_cos();
            std::array::from_fn(|i| cr * e[i] + sr * (c * u[i] + s * v[i]))
        })
        // directions the lens images: within the field the visible radius bounds
        .filter(|d: &[f64; 3]| d[0].hypot(d[1]).atan2(d[2]) < theta_max)
        .filter(|&d| visible.contains(cam, cam.pixel(d)))
        // fitted where the baseline fits: in the ideal lens's image
        .map(|d| Fisheye::ideal(cam.f_px, cam.x0_px, cam.y0_px).pixel(d))
        .collect();
    if points.len() < STEPS / 36 {
        return None;
    }
    let circle = kasa_fit(&points)?;
    let fitted = (circle.x_px - cam.x0_px).hypot(circle.y_px - cam.y0_px) / cam.f_px;
    Some(fitted.to_degrees() - beta_deg)
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn normalise(a: [f64; 3]) -> [f64; 3] {
    let n = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
    a.map(|v| v / n)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ring::earth_angular_radius_rad;

    const CAM: Fisheye = Fisheye::ideal(130.0, 255.5, 255.5);

    fn visible() -> Visible {
        Visible {
            width_px: 512,
            height_px: 512,
            r_min_px: CAM.f_px * 30f64.to_radians(),
            r_max_px: 10_000.0,
        }
    }

    #[test]
    fn the_circle_fits_model_bias_is_math_md_4_7s() {
        // math.md §4.7 [DER]: ρ_E = 60.486°, θ < 30° masked.
        let rho = earth_angular_radius_rad(950.0);
        for (beta, expected) in [(5.0, 5.00043), (10.0, 10.00345), (20.0, 20.0283)] {
            let bias = circle_model_bias(&CAM, beta, 0.0, rho, &visible()).unwrap();
            assert!(
                (beta + bias - expected).abs() < 2e-4,
                "β {beta}: {} against {expected}",
                beta + bias
            );
        }
        let bias = circle_model_bias(&CAM, 30.0, 0.0, rho, &visible()).unwrap();
        assert!((30.0 + bias - 30.0997).abs() < 2e-3, "{bias}");
    }

    #[test]
    fn edge_points_on_one_cone_are_on_the_limb_and_others_are_not() {
        let rho = 60f64.to_radians();
        let e = nadir(20.0, 0.0);
        let ring: Vec<[f64; 3]> = (0..360)
            .map(|k| {
                let phi = (k as f64).to_radians();
                let d = [rho.sin() * phi.cos(), rho.sin() * phi.sin(), rho.cos()];
                // rotate the cone about Y by 20°
                let (s, c) = 20f64.to_radians().sin_cos();
                [c * d[0] + s * d[2], d[1], -s * d[0] + c * d[2]]
            })
            .collect();
        let tol = 3.0 / CAM.f_px;
        assert!(on_limb_fraction(&ring, e, tol) > 0.999);
        // a ring about the optical axis (a field boundary) is not on that cone
        let field: Vec<[f64; 3]> = (0..360)
            .map(|k| {
                let phi = (k as f64).to_radians();
                [phi.cos(), phi.sin(), 0.0]
            })
            .collect();
        let mixed: Vec<[f64; 3]> = ring.iter().take(100).chain(&field).copied().collect();
        assert!(on_limb_fraction(&mixed, e, tol) < 0.8);
    }

    #[test]
    fn the_standard_error_of_a_normal_location_is_sigma_over_root_n() {
        let fit = TFit {
            n: 100,
            mu: 0.0,
            sigma: 0.5,
            nu: 1e9,
            nll: 0.0,
            iterations: 0,
        };
        assert!((location_standard_error(&fit, 1.0) - 0.05).abs() < 1e-6);
        assert!((location_standard_error(&fit, 4.0) - 0.1).abs() < 1e-6);
        // alternating samples are not correlated; a slow drift is
        let alternating: Vec<f64> = (0..100)
            .map(|k| if k % 2 == 0 { 1.0 } else { -1.0 })
            .collect();
        assert_eq!(correlation_time(&alternating, 0.0), 1.0);
        let drift: Vec<f64> = (0..100).map(|k| (k as f64 / 30.0).sin()).collect();
        assert!(correlation_time(&drift, 0.0) > 10.0);
    }
}
