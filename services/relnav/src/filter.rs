//! The error-state EKF step (docs/math.md §5.6, the paper's Table 1): predict, gate each
//! feature by its Mahalanobis distance, update with the accepted ones in one batch (Joseph
//! form), inject the error multiplicatively into the attitude.

use nalgebra::{Matrix4, Matrix6, SMatrix, Vector4, Vector6};

use crate::model::{
    ix, measure_observed, symmetrise, ErrMat, ErrVec, Nominal, Propagator, Rig, N_ERR, OBSERVED,
};

/// Most Gauss–Newton iterations of one update.
const MAX_ITERATIONS: usize = 6;
/// An iteration whose correction moved no component by more than this many of its prior σ
/// ends the update.
const SETTLED_SIGMAS: f64 = 1e-3;

/// One feature seen at one epoch: its index in the rig's features and `[x_l, y_l, x_r, y_r]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FeatureObs {
    pub feature: usize,
    pub z: [f64; 4],
}

/// What an update did with an epoch's features.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct UpdateOutcome {
    /// Features used in the update.
    pub used: usize,
    /// Features refused: Mahalanobis distance beyond the gate, predicted behind the cameras, or
    /// an index the rig does not have.
    pub rejected: usize,
    /// Normalised innovation squared of the accepted batch, and its degrees of freedom (4 per
    /// feature used).
    pub nis: f64,
    pub dof: usize,
}

/// Why the filter cannot go on: a covariance that lost positive definiteness, a state that is
/// no longer finite.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum NumericalFailure {
    #[error("innovation covariance not positive definite")]
    Innovation,
    #[error("state or covariance not finite, or a variance not positive")]
    State,
}

/// The filter: the nominal state, its error covariance and the time they hold at.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Filter {
    pub x: Nominal,
    pub p: ErrMat,
    pub t_s: f64,
    propagator: Propagator,
}

impl Filter {
    pub fn new(x: Nominal, p: ErrMat, t_s: f64) -> Self {
        Filter {
            x,
            p,
            t_s,
            propagator: Propagator::new(),
        }
    }

    /// Propagates to `t_s` (no-op unless it is later).
    pub fn predict_to(&mut self, rig: &Rig, t_s: f64) {
        let dt = t_s - self.t_s;
        if dt > 0.0 {
            let (x, p) = self.propagator.propagate(rig, &self.x, &self.p, dt);
            self.x = x;
            self.p = p;
            self.t_s = t_s;
        }
    }

    /// Updates with one epoch's features; `gate_chi2` bounds each feature's squared Mahalanobis
    /// distance (4 degrees of freedom).
    ///
    /// A stereo measurement sees only the six [`OBSERVED`] components (δθ, δρ) and its noise is
    /// white (R = σ² I), so the batch update is solved in those six dimensions whatever the
    /// number of features: with P₆ the observed block of P, P₍:,6₎ its columns, A = H₆ᵀH₆ / σ²
    /// and b = H₆ᵀ y / σ² summed over the features, and M = I + A P₆,
    /// `K y = P₍:,6₎ M⁻¹ b` and `K H = P₍:,6₎ M⁻¹ A E` (E picks the observed components) — the
    /// push-through identity `Hᵀ(H P Hᵀ + σ² I)⁻¹ = (Hᵀ H P + σ² I)⁻¹ Hᵀ`. The Joseph form
    /// `(I − KH) P (I − KH)ᵀ + K R Kᵀ` is then two 14 × 6 × 14 products and `K R Kᵀ =
    /// P₍:,6₎ M⁻¹ A M⁻ᵀ P₍6,:₎`.
    pub fn update(
        &mut self,
        rig: &Rig,
        features: &[FeatureObs],
        gate_chi2: f64,
    ) -> Result<UpdateOutcome, NumericalFailure> {
        let r = rig.sigma_norm * rig.sigma_norm;
        let p_x6 = SMatrix::<f64, N_ERR, 6>::from_fn(|i, c| self.p[(i, OBSERVED[c])]);
        let p66 = Matrix6::from_fn(|a, c| self.p[(OBSERVED[a], OBSERVED[c])]);
        let mut out = UpdateOutcome::default();
        let mut accepted: Vec<(Vector4<f64>, &nalgebra::Vector3<f64>)> =
            Vec::with_capacity(features.len());
        for f in features {
            let Some(r_t) = rig.features_m.get(f.feature) else {
                out.rejected += 1;
                continue;
            };
            let Some((z_hat, h)) = measure_observed(rig, &self.x, r_t) else {
                out.rejected += 1;
                continue;
            };
            let z = Vector4::from(f.z);
            let nu = z - z_hat;
            let s = h * p66 * h.transpose() + Matrix4::identity() * r;
            let Some(chol) = s.cholesky() else {
                return Err(NumericalFailure::Innovation);
            };
            let d2 = nu.dot(&chol.solve(&nu));
            if d2.is_finite() && d2 <= gate_chi2 {
                accepted.push((z, r_t));
            } else {
                out.rejected += 1;
            }
        }
        if accepted.is_empty() {
            return Ok(out);
        }
        let sig = self.sigmas();
        // Iterated update (Gauss–Newton on the measurement): relinearise h at the updated
        // state, δᵢ₊₁ = Kᵢ (z − h(xᵢ) + Hᵢ δᵢ), until the correction settles. One iteration is
        // the plain EKF; more matter when the prior is wide (a start, after a gap).
        let mut dx = ErrVec::zeros();
        let mut last: Option<(Matrix6<f64>, Matrix6<f64>)> = None;
        for iteration in 0..MAX_ITERATIONS {
            let xi = self.x.inject(&dx);
            let dx6 = Vector6::from_fn(|c, _| dx[OBSERVED[c]]);
            let (mut a, mut b, mut yy) = (Matrix6::<f64>::zeros(), Vector6::<f64>::zeros(), 0.0);
            let mut behind = false;
            for (z, r_t) in &accepted {
                let Some((z_hat, h)) = measure_observed(rig, &xi, r_t) else {
                    behind = true;
                    break;
                };
                let y = z - z_hat + h * dx6;
                a += h.transpose() * h;
                b += h.transpose() * y;
                yy += y.norm_squared();
            }
            if behind {
                break; // keep the last iterate that saw every feature
            }
            let (a, b) = (a / r, b / r);
            let m_inv = (Matrix6::identity() + a * p66)
                .try_inverse()
                .filter(|m| m.iter().all(|v| v.is_finite()))
                .ok_or(NumericalFailure::Innovation)?;
            let u = m_inv * b;
            if iteration == 0 {
                // yᵀ S⁻¹ y = yᵀy / σ² − bᵀ P₆ M⁻¹ b (Woodbury)
                out.nis = yy / r - b.dot(&(p66 * u));
            }
            let next = p_x6 * u;
            let change = (next - dx)
                .iter()
                .zip(sig.iter())
                .map(|(d, s)| d.abs() / s.max(1e-300))
                .fold(0.0, f64::max);
            dx = next;
            last = Some((a, m_inv));
            if change < SETTLED_SIGMAS {
                break;
            }
        }
        let Some((a, m_inv)) = last else {
            return Err(NumericalFailure::State);
        };
        out.dof = 4 * accepted.len();
        out.used = accepted.len();
        // K H = L E with L = P₍:,6₎ M⁻¹ A; (I − KH) P (I − KH)ᵀ in two 14 × 6 × 14 products.
        let k_r = p_x6 * m_inv;
        let l = k_r * a;
        let q = self.p - l * p_x6.transpose();
        let q_x6 = SMatrix::<f64, N_ERR, 6>::from_fn(|i, c| q[(i, OBSERVED[c])]);
        let mut p_new = q - q_x6 * l.transpose() + k_r * a * k_r.transpose();
        symmetrise(&mut p_new);
        let x_new = self.x.inject(&dx);
        if !x_new.is_finite() || !covariance_ok(&p_new) {
            return Err(NumericalFailure::State);
        }
        self.x = x_new;
        self.p = p_new;
        Ok(out)
    }

    /// 1σ of each error-state component.
    pub fn sigmas(&self) -> ErrVec {
        self.p.diagonal().map(|v| v.max(0.0).sqrt())
    }

    /// The normalised estimation error squared against a true state.
    pub fn nees(&self, truth: &Nominal) -> Option<f64> {
        let e = self.x.error_to(truth);
        let chol = self.p.cholesky()?;
        Some(e.dot(&chol.solve(&e)))
    }
}

/// A covariance the filter can go on with: finite, positive variances.
pub fn covariance_ok(p: &ErrMat) -> bool {
    p.iter().all(|v| v.is_finite()) && (0..N_ERR).all(|i| p[(i, i)] > 0.0)
}

/// Per-group error magnitudes of `est` against `truth`: attitude [rad] (2 arccos|δq_w|), rate
/// [rad/s], k, position [m], velocity [m/s].
pub fn group_errors(est: &Nominal, truth: &Nominal) -> [f64; 5] {
    let dq = est.q_ct.inverse() * truth.q_ct;
    let att = 2.0 * dq.w.abs().min(1.0).acos();
    [
        att,
        (est.w_t - truth.w_t).norm(),
        (est.k - truth.k).norm(),
        (est.rho_o - truth.rho_o).norm(),
        (est.v_o - truth.v_o).norm(),
    ]
}

/// The error-state groups: name, first index, size.
pub const GROUPS: [(&str, usize, usize); 5] = [
    ("attitude", ix::TH, 3),
    ("rate", ix::W, 3),
    ("inertia_k", ix::K, 2),
    ("position", ix::RHO, 3),
    ("velocity", ix::V, 3),
];

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::measure;
    use crate::model::tests::{rig, state};
    use nalgebra::{DMatrix, DVector};

    /// The textbook iterated update with the whole H, S = H P Hᵀ + R (4N × 4N), K = P Hᵀ S⁻¹
    /// and the Joseph form in 14 × 14: the reference the six-dimensional solve must equal.
    fn dense_update(f: &Filter, rig: &Rig, features: &[FeatureObs]) -> (Nominal, ErrMat, f64) {
        let r = rig.sigma_norm * rig.sigma_norm;
        let m = 4 * features.len();
        let p = DMatrix::from_column_slice(N_ERR, N_ERR, f.p.as_slice());
        let sig = f.sigmas();
        let mut dx = ErrVec::zeros();
        let mut nis = f64::NAN;
        let mut last = None;
        for iteration in 0..MAX_ITERATIONS {
            let xi = f.x.inject(&dx);
            let mut h = DMatrix::<f64>::zeros(m, N_ERR);
            let mut y = DVector::<f64>::zeros(m);
            for (i, o) in features.iter().enumerate() {
                let (z_hat, hi) = measure(rig, &xi, &rig.features_m[o.feature]).unwrap();
                h.view_mut((4 * i, 0), (4, N_ERR)).copy_from(&hi);
                y.rows_mut(4 * i, 4)
                    .copy_from(&(Vector4::from(o.z) - z_hat + hi * dx));
            }
            let s = &h * &p * h.transpose() + DMatrix::<f64>::identity(m, m) * r;
            let s_inv = s.try_inverse().unwrap();
            let k = &p * h.transpose() * &s_inv;
            if iteration == 0 {
                nis = (y.transpose() * &s_inv * &y)[(0, 0)];
            }
            let next = ErrVec::from_column_slice((&k * &y).as_slice());
            let change = (next - dx)
                .iter()
                .zip(sig.iter())
                .map(|(d, s)| d.abs() / s)
                .fold(0.0, f64::max);
            dx = next;
            last = Some((k, h));
            if change < SETTLED_SIGMAS {
                break;
            }
        }
        let (k, h) = last.unwrap();
        let i_kh = DMatrix::<f64>::identity(N_ERR, N_ERR) - &k * &h;
        let p_new = &i_kh * &p * i_kh.transpose() + (&k * k.transpose()) * r;
        (
            f.x.inject(&dx),
            ErrMat::from_column_slice(p_new.as_slice()),
            nis,
        )
    }

    /// A prior with every component correlated, at a state off the truth by about its σ, and
    /// noisy features: the update in six dimensions against the dense one.
    #[test]
    fn the_six_dimensional_update_equals_the_dense_batch_update() {
        let rig = rig();
        let truth = state();
        let sig = [
            2e-3, 2e-3, 2e-3, 1e-4, 1e-4, 1e-4, 0.05, 0.05, 5e-3, 5e-3, 5e-3, 1e-5, 1e-5, 1e-5,
        ];
        // P = D C D with C a correlation matrix of a random-looking but fixed factor.
        let g = ErrMat::from_fn(|i, j| ((i * 7 + j * 13) % 11) as f64 / 11.0 - 0.45);
        let c = g * g.transpose() + ErrMat::identity() * 2.0;
        let d = ErrMat::from_diagonal(&ErrVec::from_fn(|i, _| sig[i] / c[(i, i)].sqrt()));
        let p = d * c * d;
        let offset = ErrVec::from_fn(|i, _| sig[i] * if i % 2 == 0 { 0.8 } else { -0.6 });
        let filter = Filter::new(truth.inject(&offset), p, 0.0);
        let features: Vec<FeatureObs> = (0..rig.features_m.len())
            .map(|i| {
                let (z, _) = measure(&rig, &truth, &rig.features_m[i]).unwrap();
                let noise = Vector4::new(1.0, -0.5, 0.3, 0.7) * rig.sigma_norm * (i as f64 - 1.5);
                FeatureObs {
                    feature: i,
                    z: (z + noise).into(),
                }
            })
            .collect();
        let (x_ref, p_ref, nis_ref) = dense_update(&filter, &rig, &features);
        let mut f = filter.clone();
        let out = f.update(&rig, &features, 1e9).unwrap();
        assert_eq!((out.used, out.rejected, out.dof), (4, 0, 16));
        let dx = x_ref.error_to(&f.x);
        let post = f.sigmas();
        for i in 0..N_ERR {
            assert!(dx[i].abs() < 1e-6 * post[i], "component {i}: {dx}");
            for j in 0..N_ERR {
                let scale = (p_ref[(i, i)] * p_ref[(j, j)]).sqrt();
                assert!(
                    (f.p[(i, j)] - p_ref[(i, j)]).abs() < 1e-8 * scale,
                    "P[{i},{j}]: {} vs {}",
                    f.p[(i, j)],
                    p_ref[(i, j)]
                );
            }
        }
        assert!(
            (out.nis - nis_ref).abs() < 1e-6 * nis_ref,
            "{} vs {nis_ref}",
            out.nis
        );
        // The update did something: the observed components' σ shrank.
        assert!(post[ix::TH] < 0.5 * sig[ix::TH] && post[ix::RHO] < 0.5 * sig[ix::RHO]);
    }

    /// A target at rest (ω = 0, v = 0, no disturbance, mean motion ≈ 0): the error dynamics
    /// are linear and constant (δθ̇ = δω, δρ̇ = δv, the rest held), so after n noise-free
    /// epochs the filter's covariance must be the batch least-squares one in closed form,
    /// `Φ(tₙ) (P₀⁻¹ + Σₖ (Hₖ Φ(tₖ))ᵀ R⁻¹ Hₖ Φ(tₖ))⁻¹ Φ(tₙ)ᵀ`.
    #[test]
    fn a_target_at_rest_matches_the_closed_form_batch_covariance() {
        let mut rig = rig();
        rig.mean_motion_rad_s = 1e-9;
        rig.torque_psd = 0.0;
        rig.accel_psd = 0.0;
        let mut x0 = state();
        x0.w_t = nalgebra::Vector3::zeros();
        x0.v_o = nalgebra::Vector3::zeros();
        let sig0 = [
            1e-2, 1e-2, 1e-2, 1e-3, 1e-3, 1e-3, 0.1, 0.1, 1e-2, 1e-2, 1e-2, 1e-3, 1e-3, 1e-3,
        ];
        let p0 = ErrMat::from_diagonal(&ErrVec::from_fn(|i, _| sig0[i] * sig0[i]));
        let phi = |t: f64| {
            let mut m = ErrMat::identity();
            for i in 0..3 {
                m[(ix::TH + i, ix::W + i)] = t;
                m[(ix::RHO + i, ix::V + i)] = t;
            }
            m
        };
        let r = rig.sigma_norm * rig.sigma_norm;
        let mut info = p0.try_inverse().unwrap();
        let mut f = Filter::new(x0, p0, 0.0);
        let n = 10;
        for k in 1..=n {
            let t = k as f64;
            f.predict_to(&rig, t);
            // noise-free features where the filter predicts them: the estimate stays on the
            // truth and every Jacobian is the truth's
            let obs: Vec<FeatureObs> = (0..rig.features_m.len())
                .map(|i| {
                    let (z, h) = measure(&rig, &f.x, &rig.features_m[i]).unwrap();
                    let hp = h * phi(t);
                    info += hp.transpose() * hp / r;
                    FeatureObs {
                        feature: i,
                        z: z.into(),
                    }
                })
                .collect();
            let out = f.update(&rig, &obs, 1e9).unwrap();
            assert_eq!(out.used, 4);
        }
        let p_closed = phi(n as f64) * info.try_inverse().unwrap() * phi(n as f64).transpose();
        for i in 0..N_ERR {
            for j in 0..N_ERR {
                let scale = (p_closed[(i, i)] * p_closed[(j, j)]).sqrt();
                assert!(
                    (f.p[(i, j)] - p_closed[(i, j)]).abs() < 1e-6 * scale,
                    "P[{i},{j}]: {} vs {}",
                    f.p[(i, j)],
                    p_closed[(i, j)]
                );
            }
        }
        // The measurements taught the filter: δθ and δρ shrank, k (unobservable at rest) did not.
        assert!(f.p[(ix::TH, ix::TH)] < 1e-3 * p0[(ix::TH, ix::TH)]);
        assert!((f.p[(ix::K, ix::K)] / p0[(ix::K, ix::K)] - 1.0).abs() < 1e-9);
    }
}
