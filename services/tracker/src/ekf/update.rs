//! The shared EKF measurement update for the full (α, β, r) and the angles-only (α, β) models.

use super::{measurement, measurement_jacobian, residual, CwEkf, EkfError};
use nalgebra::{Matrix6, SMatrix, SVector};

impl CwEkf {
    /// Predicts to `t_s`, then applies the first M rows of h (M = 3: α, β, r; M = 2: α, β) with
    /// covariance `r`. Returns the innovation and its NIS; leaves the filter unchanged on error.
    pub(super) fn apply<const M: usize>(
        &mut self,
        t_s: f64,
        z: SVector<f64, M>,
        r: SMatrix<f64, M, M>,
    ) -> Result<(SVector<f64, M>, f64), EkfError> {
        if z.iter().any(|v| !v.is_finite()) {
            return Err(EkfError::NonFinite {
                what: "measurement",
            });
        }
        let (x, p) = self.predicted(t_s)?;
        let h: SMatrix<f64, M, 6> = measurement_jacobian(&x)
            .ok_or(EkfError::SingularGeometry)?
            .fixed_rows::<M>(0)
            .into_owned();
        let nu = residual::<M>(&z, &measurement(&x));
        let s = h * p * h.transpose() + r;
        let s_inv = s.cholesky().ok_or(EkfError::SingularInnovation)?.inverse();
        let k = p * h.transpose() * s_inv;
        let x_new = x + k * nu;
        let i_kh = Matrix6::identity() - k * h;
        let p_new = i_kh * p * i_kh.transpose() + k * r * k.transpose();
        let p_new = 0.5 * (p_new + p_new.transpose());
        if x_new.iter().chain(p_new.iter()).any(|v| !v.is_finite()) {
            return Err(EkfError::NonFinite { what: "update" });
        }
        self.x = x_new;
        self.p = p_new;
        self.t_s = self.t_s.max(t_s);
        Ok((nu, (nu.transpose() * s_inv * nu)[0]))
    }
}

impl CwEkf {
    /// Predicts to `t_s` and applies the range row of h alone (the laser echo of a shot fired
    /// after the angles were measured, §3.7). Joseph form; unchanged on error.
    pub fn update_range(&mut self, t_s: f64, range_m: f64) -> Result<f64, EkfError> {
        if !(range_m.is_finite() && range_m > 0.0) {
            return Err(EkfError::NonFinite { what: "range" });
        }
        let (x, p) = self.predicted(t_s)?;
        let h: SMatrix<f64, 1, 6> = measurement_jacobian(&x)
            .ok_or(EkfError::SingularGeometry)?
            .fixed_rows::<1>(2)
            .into_owned();
        let nu = range_m - measurement(&x)[2];
        let r = self.config.sigma_range_m.powi(2);
        let s = (h * p * h.transpose())[0] + r;
        if !(s.is_finite() && s > 0.0) {
            return Err(EkfError::SingularInnovation);
        }
        let k = p * h.transpose() / s;
        let x_new = x + k * nu;
        let i_kh = Matrix6::identity() - k * h;
        let p_new = i_kh * p * i_kh.transpose() + k * r * k.transpose();
        let p_new = 0.5 * (p_new + p_new.transpose());
        if x_new.iter().chain(p_new.iter()).any(|v| !v.is_finite()) {
            return Err(EkfError::NonFinite { what: "update" });
        }
        self.x = x_new;
        self.p = p_new;
        self.t_s = self.t_s.max(t_s);
        Ok(nu)
    }
}
