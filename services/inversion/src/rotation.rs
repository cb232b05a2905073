//! Attitude matrix R(t; p) of eq (17) and its analytic partials from one set of sines/cosines
//! (docs/math.md §1.6).
//!
//! With p = [w_x, w_y, w_z] in deg/frame and frame index t: θ = w_x t, φ = w_y t, ψ = w_z t
//! (degrees → radians before trigonometry), and
//!
//! ```text
//! Verbatim   (normative):  R = R3(ψ) R2(−φ) R1(θ)     (the seed's printed R_Z R_Y R_X)
//! Consistent (3-2-1 DCM):  R = R1(θ) R2(φ) R3(ψ)
//! ∂R/∂w_i = (π t/180) · (the same product with factor i replaced by its angle derivative)
//! ```
//!
//! [`TrigStepper`] advances the sines/cosines along consecutive frames by angle addition
//! (re-anchored exactly every 32 frames). This is the physics crate's [`glint_physics::two_facet::AttitudeConvention`] evaluated with
//! three `sin_cos` calls per frame instead of nine (the stage-3 hot loop); a test checks that the
//! two agree to rounding.

use glint_physics::two_facet::AttitudeConvention;
use nalgebra::Matrix3;
use serde::{Deserialize, Serialize};

/// Which eq-(17) convention the estimator uses; must match the simulator's (§1.6).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AttitudeModel {
    /// The seed's printed matrices `R_Z(ψ) R_Y(φ) R_X(θ)` (normative).
    #[default]
    Verbatim,
    /// The consistent passive 3-2-1 DCM `R1(θ) R2(φ) R3(ψ)`.
    Consistent,
}

impl From<AttitudeModel> for AttitudeConvention {
    fn from(m: AttitudeModel) -> Self {
        match m {
            AttitudeModel::Verbatim => Self::Verbatim,
            AttitudeModel::Consistent => Self::Consistent,
        }
    }
}

/// Passive R1 from (sin, cos).
fn r1(s: f64, c: f64) -> Matrix3<f64> {
    Matrix3::new(1.0, 0.0, 0.0, 0.0, c, s, 0.0, -s, c)
}
fn d_r1(s: f64, c: f64) -> Matrix3<f64> {
    Matrix3::new(0.0, 0.0, 0.0, 0.0, -s, c, 0.0, -c, -s)
}
/// Passive R2 from (sin, cos).
fn r2(s: f64, c: f64) -> Matrix3<f64> {
    Matrix3::new(c, 0.0, -s, 0.0, 1.0, 0.0, s, 0.0, c)
}
fn d_r2(s: f64, c: f64) -> Matrix3<f64> {
    Matrix3::new(-s, 0.0, -c, 0.0, 0.0, 0.0, c, 0.0, -s)
}
/// Passive R3 from (sin, cos).
fn r3(s: f64, c: f64) -> Matrix3<f64> {
    Matrix3::new(c, s, 0.0, -s, c, 0.0, 0.0, 0.0, 1.0)
}
fn d_r3(s: f64, c: f64) -> Matrix3<f64> {
    Matrix3::new(-s, c, 0.0, -c, -s, 0.0, 0.0, 0.0, 0.0)
}

/// (sin, cos) of the three angles θ = w_x t, φ = w_y t, ψ = w_z t.
pub type AngleTrig = [(f64, f64); 3];

/// Exact (sin, cos) of p·t (degrees → radians).
pub fn angle_trig(p_deg_per_frame: [f64; 3], t_frames: f64) -> AngleTrig {
    p_deg_per_frame.map(|w| (w * t_frames).to_radians().sin_cos())
}

/// Rotates (sin a, cos a) by (sin b, cos b): (sin(a + b), cos(a + b)).
fn add_angle((sa, ca): (f64, f64), (sb, cb): (f64, f64)) -> (f64, f64) {
    (sa * cb + ca * sb, ca * cb - sa * sb)
}

/// Frames advanced by the angle-addition recurrence before an exact re-anchor; bounds the
/// accumulated rounding to ~RECURRENCE_SPAN ulp.
const RECURRENCE_SPAN: usize = 32;

/// Trig of p·t along an increasing frame sequence: one exact `sin_cos` per axis every
/// `RECURRENCE_SPAN` (32) frames, angle addition in between when the frame step repeats.
#[derive(Debug, Clone)]
pub struct TrigStepper {
    p_deg_per_frame: [f64; 3],
    last: Option<(f64, AngleTrig)>,
    step: Option<(f64, AngleTrig)>,
    since_anchor: usize,
}

impl TrigStepper {
    /// A stepper for rates p \[deg/frame\].
    pub fn new(p_deg_per_frame: [f64; 3]) -> Self {
        Self {
            p_deg_per_frame,
            last: None,
            step: None,
            since_anchor: 0,
        }
    }

    /// (sin, cos) of p·t.
    pub fn at(&mut self, t_frames: f64) -> AngleTrig {
        let p = self.p_deg_per_frame;
        let trig = match (self.last, self.step) {
            (Some((t_last, prev)), Some((dt, step)))
                if t_frames - t_last == dt && self.since_anchor < RECURRENCE_SPAN =>
            {
                self.since_anchor += 1;
                [0, 1, 2].map(|i| add_angle(prev[i], step[i]))
            }
            (Some((t_last, _)), _) => {
                let dt = t_frames - t_last;
                if self.step.is_none_or(|(d, _)| d != dt) {
                    self.step = Some((dt, angle_trig(p, dt)));
                }
                self.since_anchor = 0;
                angle_trig(p, t_frames)
            }
            (None, _) => angle_trig(p, t_frames),
        };
        self.last = Some((t_frames, trig));
        trig
    }
}

impl AttitudeModel {
    /// R(t; p).
    pub fn matrix(self, p_deg_per_frame: [f64; 3], t_frames: f64) -> Matrix3<f64> {
        self.matrix_from_trig(&angle_trig(p_deg_per_frame, t_frames))
    }

    /// R from the angles' (sin, cos).
    pub fn matrix_from_trig(self, trig: &AngleTrig) -> Matrix3<f64> {
        let [(sx, cx), (sy, cy), (sz, cz)] = *trig;
        match self {
            // R2(−φ): sin(−φ) = −sin φ.
            Self::Verbatim => r3(sz, cz) * r2(-sy, cy) * r1(sx, cx),
            Self::Consistent => r1(sx, cx) * r2(sy, cy) * r3(sz, cz),
        }
    }

    /// R(t; p) and `[∂R/∂w_x, ∂R/∂w_y, ∂R/∂w_z]` [per deg/frame].
    pub fn matrix_and_partials(
        self,
        p_deg_per_frame: [f64; 3],
        t_frames: f64,
    ) -> (Matrix3<f64>, [Matrix3<f64>; 3]) {
        self.matrix_and_partials_from_trig(&angle_trig(p_deg_per_frame, t_frames), t_frames)
    }

    /// R and its partials from the angles' (sin, cos) at frame `t_frames`.
    pub fn matrix_and_partials_from_trig(
        self,
        trig: &AngleTrig,
        t_frames: f64,
    ) -> (Matrix3<f64>, [Matrix3<f64>; 3]) {
        let [(sx, cx), (sy, cy), (sz, cz)] = *trig;
        let k = t_frames.to_radians();
        match self {
            Self::Verbatim => {
                let (a, b, c) = (r3(sz, cz), r2(-sy, cy), r1(sx, cx));
                // d/dφ R2(−φ) = −R2'(−φ).
                let db = -d_r2(-sy, cy);
                let ab = a * b;
                (
                    ab * c,
                    [
                        ab * d_r1(sx, cx) * k,
                        a * db * c * k,
                        d_r3(sz, cz) * b * c * k,
                    ],
                )
            }
            Self::Consistent => {
                let (a, b, c) = (r1(sx, cx), r2(sy, cy), r3(sz, cz));
                let bc = b * c;
                (
                    a * bc,
                    [
                        d_r1(sx, cx) * bc * k,
                        a * d_r2(sy, cy) * c * k,
                        a * b * d_r3(sz, cz) * k,
                    ],
                )
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_physics_conventions() {
        for model in [AttitudeModel::Verbatim, AttitudeModel::Consistent] {
            let conv = AttitudeConvention::from(model);
            for (p, t) in [
                ([0.1, -0.3, 0.25], 12.0),
                ([0.0, 0.0, 0.0], 40.0),
                ([0.4, 0.2, -0.5], 300.0),
            ] {
                let (r, d) = model.matrix_and_partials(p, t);
                assert!((r - conv.matrix(p, t)).abs().max() < 1e-14);
                assert!((model.matrix(p, t) - r).abs().max() < 1e-15);
                let want = conv.partials(p, t);
                for i in 0..3 {
                    assert!((d[i] - want[i]).abs().max() < 1e-13, "{model:?} {i}");
                }
            }
        }
    }

    #[test]
    fn stepper_tracks_exact_trig() {
        let p = [0.31, -0.47, 0.123];
        let mut st = TrigStepper::new(p);
        let frames: Vec<f64> = (0..400)
            .map(|t| t as f64)
            .chain((400..800).step_by(3).map(|t| t as f64))
            .chain([801.0, 900.0, 901.0, 902.0])
            .collect();
        for t in frames {
            let got = st.at(t);
            let want = angle_trig(p, t);
            for i in 0..3 {
                assert!((got[i].0 - want[i].0).abs() < 1e-14, "t {t}");
                assert!((got[i].1 - want[i].1).abs() < 1e-14, "t {t}");
            }
        }
    }
}
