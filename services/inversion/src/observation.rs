//! Input data of the three-stage solve: per-frame geometry and per-band flux (docs/math.md
//! §1.1, §1.4, §1.6).
//!
//! Geometry is given in the target body frame B of the **three-axis-stable** attitude (the
//! nominal frame): during the motion window the estimator rotates it by R(t; p) itself. Flux is
//! the band-integrated flux at the entrance pupil, Φ(t, λ)·Δλ \[W\].

use crate::error::InversionError;
use nalgebra::Vector3;

/// One frame of observations.
#[derive(Debug, Clone, PartialEq)]
pub struct Observation {
    /// Frame counter; stage 3 uses `t = frame_index − epoch` (frames).
    pub frame_index: u64,
    /// Time tag \[s\] (informational; the solve works in frames).
    pub t_s: f64,
    /// Unit vector target → Sun in the nominal body frame B.
    pub sun_body: Vector3<f64>,
    /// Unit vector target → observer entrance pupil in the nominal body frame B.
    pub observer_body: Vector3<f64>,
    /// Target–observer range ‖T0‖ \[m\].
    pub range_m: f64,
    /// Band-integrated flux per band \[W\], same order as `ObservationSet::wavelengths_nm`.
    pub flux_w: Vec<f64>,
    /// 1σ flux noise per band \[W\]; empty when unknown.
    pub sigma_w: Vec<f64>,
}

/// The two windows of one pass.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ObservationSet {
    /// Band centres \[nm\].
    pub wavelengths_nm: Vec<f64>,
    /// Three-axis-stable window (stage 1).
    pub stable: Vec<Observation>,
    /// Attitude-motion window (stage 3).
    pub motion: Vec<Observation>,
}

const UNIT_TOL: f64 = 1e-6;

fn is_unit(v: &Vector3<f64>) -> bool {
    v.iter().all(|c| c.is_finite()) && (v.norm() - 1.0).abs() <= UNIT_TOL
}

impl ObservationSet {
    /// Checks shapes and values: unit geometry vectors, positive range, finite flux, σ either
    /// empty or positive per band.
    pub fn validate(&self) -> Result<(), InversionError> {
        let bands = self.wavelengths_nm.len();
        if bands == 0 {
            return Err(InversionError::NoBands);
        }
        for (window, list) in [("stable", &self.stable), ("motion", &self.motion)] {
            for (index, obs) in list.iter().enumerate() {
                let invalid = |field| InversionError::InvalidObservation {
                    window,
                    index,
                    field,
                };
                if obs.flux_w.len() != bands {
                    return Err(InversionError::BandCountMismatch {
                        window,
                        index,
                        field: "flux_w",
                        len: obs.flux_w.len(),
                        bands,
                    });
                }
                if !obs.sigma_w.is_empty() && obs.sigma_w.len() != bands {
                    return Err(InversionError::BandCountMismatch {
                        window,
                        index,
                        field: "sigma_w",
                        len: obs.sigma_w.len(),
                        bands,
                    });
                }
                if !is_unit(&obs.sun_body) {
                    return Err(invalid("sun_body"));
                }
                if !is_unit(&obs.observer_body) {
                    return Err(invalid("observer_body"));
                }
                if !(obs.range_m.is_finite() && obs.range_m > 0.0) {
                    return Err(invalid("range_m"));
                }
                if !obs.flux_w.iter().all(|f| f.is_finite()) {
                    return Err(invalid("flux_w"));
                }
                if !obs.sigma_w.iter().all(|s| s.is_finite() && *s > 0.0) {
                    return Err(invalid("sigma_w"));
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn obs() -> Observation {
        Observation {
            frame_index: 0,
            t_s: 0.0,
            sun_body: Vector3::x(),
            observer_body: Vector3::x(),
            range_m: 2.0e6,
            flux_w: vec![1.0, 2.0],
            sigma_w: vec![],
        }
    }

    #[test]
    fn validation_names_the_field() {
        let mut set = ObservationSet {
            wavelengths_nm: vec![600.0, 650.0],
            stable: vec![obs()],
            motion: vec![obs()],
        };
        assert_eq!(set.validate(), Ok(()));
        set.motion[0].sigma_w = vec![1.0];
        assert!(matches!(
            set.validate(),
            Err(InversionError::BandCountMismatch {
                window: "motion",
                field: "sigma_w",
                ..
            })
        ));
        set.motion[0].sigma_w.clear();
        set.stable[0].sun_body *= 2.0;
        assert!(matches!(
            set.validate(),
            Err(InversionError::InvalidObservation {
                field: "sun_body",
                ..
            })
        ));
        assert_eq!(
            ObservationSet::default().validate(),
            Err(InversionError::NoBands)
        );
    }
}
