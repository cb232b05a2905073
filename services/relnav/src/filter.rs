//! The error-state EKF step (docs/math.md §5.6, the paper's Table 1): predict, gate each
//! feature by its Mahalanobis distance, update with the accepted ones in one batch (Joseph
//! form), inject the error multiplicatively into the attitude.

use nalgebra::{DMatrix, DVector, Matrix4, Vector4};

use crate::model::{ix, measure, symmetrise, ErrMat, ErrVec, Nominal, Propagator, Rig, N_ERR};

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
    pub fn update(
        &mut self,
        rig: &Rig,
        features: &[FeatureObs],
        gate_chi2: f64,
    ) -> Result<UpdateOutcome, NumericalFailure> {
        let r = rig.sigma_norm * rig.sigma_norm;
        let mut out = UpdateOutcome::default();
        let mut accepted: Vec<(Vector4<f64>, &nalgebra::Vector3<f64>)> =
            Vec::with_capacity(features.len());
        for f in features {
            let Some(r_t) = rig.features_m.get(f.feature) else {
                out.rejected += 1;
                continue;
            };
            let Some((z_hat, h)) = measure(rig, &self.x, r_t) else {
                out.rejected += 1;
                continue;
            };
            let z = Vector4::from(f.z);
            let nu = z - z_hat;
            let s = h * self.p * h.transpose() + Matrix4::identity() * r;
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
        let m = 4 * accepted.len();
        let p = DMatrix::from_column_slice(N_ERR, N_ERR, self.p.as_slice());
        let sig = self.sigmas();
        // Iterated update (Gauss–Newton on the measurement): relinearise h at the updated
        // state, δᵢ₊₁ = Kᵢ (z − h(xᵢ) + Hᵢ δᵢ), until the correction settles. One iteration is
        // the plain EKF; more matter when the prior is wide (a start, after a gap).
        let mut dx = ErrVec::zeros();
        let mut last: Option<(DMatrix<f64>, DMatrix<f64>)> = None;
        for iteration in 0..MAX_ITERATIONS {
            let xi = self.x.inject(&dx);
            let mut h = DMatrix::<f64>::zeros(m, N_ERR);
            let mut y = DVector::<f64>::zeros(m);
            let mut behind = false;
            for (i, (z, r_t)) in accepted.iter().enumerate() {
                let Some((z_hat, hi)) = measure(rig, &xi, r_t) else {
                    behind = true;
                    break;
                };
                h.view_mut((4 * i, 0), (4, N_ERR)).copy_from(&hi);
                y.rows_mut(4 * i, 4).copy_from(&(z - z_hat + hi * dx));
            }
            if behind {
                break; // keep the last iterate that saw every feature
            }
            let hp = &h * &p;
            let mut s = &hp * h.transpose();
            for i in 0..m {
                s[(i, i)] += r;
            }
            let chol = s.cholesky().ok_or(NumericalFailure::Innovation)?;
            // K = P Hᵀ S⁻¹ = (S⁻¹ H P)ᵀ
            let k = chol.solve(&hp).transpose();
            if iteration == 0 {
                out.nis = y.dot(&chol.solve(&y));
            }
            let next = ErrVec::from_column_slice((&k * &y).as_slice());
            let change = (next - dx)
                .iter()
                .zip(sig.iter())
                .map(|(d, s)| d.abs() / s.max(1e-300))
                .fold(0.0, f64::max);
            dx = next;
            last = Some((k, h));
            if change < SETTLED_SIGMAS {
                break;
            }
        }
        let Some((k, h)) = last else {
            return Err(NumericalFailure::State);
        };
        out.dof = m;
        out.used = accepted.len();
        let i_kh = DMatrix::<f64>::identity(N_ERR, N_ERR) - &k * &h;
        let p_new = &i_kh * &p * i_kh.transpose() + (&k * k.transpose()) * r;
        let mut p_new = ErrMat::from_column_slice(p_new.as_slice());
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
