//! The [000] spectral scene: the facet-modelled satellite in the GEO hover geometry, observed
//! first in a three-axis-stable window (stage 1 of the inversion) and then while it rotates at
//! the scenario's rates (stage 3).
//!
//! Geometry (math.md §1.7): the Sun longitude is chosen so that the phase angle equals
//! `start_phase_deg` at the motion start (t = 0) on the rising branch after the glint pass. The
//! stable window runs from the time the phase was `stable_start_phase_deg` on the falling branch,
//! through the minimum-phase pass, up to the motion start; its samples are evenly spaced. Motion
//! frame j is at t = j·frame_interval with attitude R(j) (eq 17; j = 0 is the frame before the
//! motion starts, R = I); s' = R s, o' = R o (eqs 18–19). The panel normal follows eq (4) on
//! the nominal s (math.md §1.6 option (a)).
//!
//! Flux per band = Φ(λ_c) · Δλ (band centre times width) [W]. Noise: σ_b = mean over the window
//! of Φ_b / SNR, a Gaussian draw per sample and band from a stream keyed by (seed, window, index).

use glint_physics::hover::HoverGeometry;
use glint_physics::materials::Material;
use glint_physics::materials::MaterialPreset;
use glint_physics::satellite::{BandTable, BodyShape, Facet, SatelliteModel, CUBE_EDGE_M};
use glint_physics::two_facet::{panel_normal, AttitudeConvention};
use nalgebra::{Matrix3, Vector3};
use shared_types::scenario::{
    AttitudeConvention as ScenarioConvention, BodyShapeName, MaterialPresetName, NoiseWindows,
    SpectraScenario,
};
use shared_types::{Spectrum, Truth, Window, MAX_BANDS};

use crate::render::noise::{inverse_normal_cdf, Xoshiro256pp};

const SPECTRUM_STREAM: u64 = 1 << 48;
/// Search step and horizon for the stable-window start [s].
const SEARCH_STEP_S: f64 = 30.0;
const SEARCH_HORIZON_S: f64 = 86_400.0;

#[derive(Debug, thiserror::Error)]
pub enum SpectraSceneError {
    #[error("no Sun longitude gives a phase of {phase_deg}° with this geometry")]
    PhaseUnreachable { phase_deg: f64 },
    #[error("the phase never reaches spectra.stable_start_phase_deg = {phase_deg}° before the motion start")]
    StableStartUnreachable { phase_deg: f64 },
    #[error("geometry is degenerate at t = {t_s} s")]
    Degenerate { t_s: f64 },
    #[error("satellite model: {0}")]
    Model(String),
}

/// One sample before noise.
struct Clean {
    s_body: Vector3<f64>,
    o_body: Vector3<f64>,
    range_m: f64,
    attitude: Matrix3<f64>,
    flux_w: [f64; MAX_BANDS],
}

pub struct SpectraScene {
    geometry: HoverGeometry,
    sun_lon_rad: f64,
    model: SatelliteModel,
    bands: BandTable,
    n_bands: usize,
    band_width_nm: f64,
    aperture_m2: f64,
    convention: AttitudeConvention,
    rate_deg_per_frame: [f64; 3],
    frame_interval_s: f64,
    stable_start_s: f64,
    stable_samples: u64,
    motion_frames: u64,
    /// Per window, per band: noise σ [W] (0 = noise-free).
    sigma_w: [[f64; MAX_BANDS]; 2],
    seed: u64,
}

impl SpectraScene {
    pub fn new(sc: &SpectraScenario, seed: u64) -> Result<Self, SpectraSceneError> {
        let geometry = HoverGeometry::tan2020(sc.sun_declination_deg.to_radians());
        let start_phase = sc.start_phase_deg.to_radians();
        let sun_lon_rad = geometry
            .sun_longitude_for_phase(start_phase, 0.0, false)
            .ok_or(SpectraSceneError::PhaseUnreachable {
                phase_deg: sc.start_phase_deg,
            })?;
        let stable_start_s = find_stable_start(
            &geometry,
            sun_lon_rad,
            sc.stable_start_phase_deg.to_radians(),
        )?;
        let preset = match sc.materials {
            MaterialPresetName::Physical => MaterialPreset::Physical,
            MaterialPresetName::PaperLike => MaterialPreset::PaperLike,
        };
        let shape = |b: BodyShape| SatelliteModel::tan2020(b, preset);
        let model = match sc.body_shape {
            BodyShapeName::Cube => shape(BodyShape::Cube),
            BodyShapeName::Cylinder => shape(BodyShape::Cylinder),
            BodyShapeName::Sphere => shape(BodyShape::Sphere),
            BodyShapeName::HexagonalPrism => shape(BodyShape::HexagonalPrism),
            BodyShapeName::TwoFacet => {
                let cube = shape(BodyShape::Cube);
                let face = Facet {
                    normal_body: Vector3::x(),
                    area_m2: CUBE_EDGE_M * CUBE_EDGE_M,
                    material: Material::MliKapton,
                };
                SatelliteModel::from_facets(vec![face], cube.panel_area_m2(), preset)
                    .map_err(|e| SpectraSceneError::Model(format!("{e:?}")))?
            }
        };
        let wavelengths = sc.wavelengths_nm();
        let bands = model
            .band_table(&wavelengths)
            .map_err(|e| SpectraSceneError::Model(format!("{e:?}")))?;
        let mut scene = SpectraScene {
            geometry,
            sun_lon_rad,
            model,
            bands,
            n_bands: wavelengths.len(),
            band_width_nm: sc.band_width_nm,
            aperture_m2: std::f64::consts::PI * sc.aperture_diameter_m.powi(2) / 4.0,
            convention: match sc.attitude_convention {
                ScenarioConvention::Verbatim => AttitudeConvention::Verbatim,
                ScenarioConvention::Consistent => AttitudeConvention::Consistent,
            },
            rate_deg_per_frame: sc.rate_deg_per_frame,
            frame_interval_s: sc.frame_interval_s,
            stable_start_s,
            stable_samples: sc.stable_samples,
            motion_frames: sc.motion_frames,
            sigma_w: [[0.0; MAX_BANDS]; 2],
            seed,
        };
        if let Some(snr) = sc.snr {
            let windows = match sc.noise_windows {
                NoiseWindows::Both => &[
                    (Window::Stable, sc.stable_samples),
                    (Window::Motion, sc.motion_frames),
                ][..],
                NoiseWindows::Motion => &[(Window::Motion, sc.motion_frames)][..],
            };
            for &(w, count) in windows {
                let mut sum = [0.0; MAX_BANDS];
                for i in 0..count {
                    let c = scene.clean(w, i)?;
                    for (s, f) in sum.iter_mut().zip(c.flux_w.iter()) {
                        *s += f;
                    }
                }
                let n = scene.n_bands;
                for (sigma, total) in scene.sigma_w[w as usize][..n].iter_mut().zip(&sum[..n]) {
                    *sigma = total / count as f64 / snr;
                }
            }
        }
        Ok(scene)
    }

    /// Total samples: the stable window, then the motion window.
    pub fn len(&self) -> u64 {
        self.stable_samples + self.motion_frames
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Simulated time of the stable window start relative to the motion start [s] (negative).
    pub fn stable_start_s(&self) -> f64 {
        self.stable_start_s
    }

    fn window_of(&self, k: u64) -> (Window, u64) {
        if k < self.stable_samples {
            (Window::Stable, k)
        } else {
            (Window::Motion, k - self.stable_samples)
        }
    }

    /// Simulated time of sample k since the scenario start [ns] (without computing the sample).
    pub fn t_ns(&self, k: u64) -> u64 {
        let (window, index) = self.window_of(k);
        let t_s = match window {
            Window::Stable => {
                self.stable_start_s
                    + index as f64 * (-self.stable_start_s / self.stable_samples as f64)
            }
            Window::Motion => index as f64 * self.frame_interval_s,
        };
        ((t_s - self.stable_start_s) * 1e9).round().max(0.0) as u64
    }

    fn clean(&self, window: Window, index: u64) -> Result<Clean, SpectraSceneError> {
        let (t_s, attitude) = match window {
            Window::Stable => {
                let dt = -self.stable_start_s / self.stable_samples as f64;
                (self.stable_start_s + index as f64 * dt, Matrix3::identity())
            }
            Window::Motion => (
                index as f64 * self.frame_interval_s,
                self.convention
                    .matrix(self.rate_deg_per_frame, index as f64),
            ),
        };
        let g = self
            .geometry
            .sample(t_s, self.sun_lon_rad)
            .ok_or(SpectraSceneError::Degenerate { t_s })?;
        let n_p = panel_normal(g.s_body, Vector3::x());
        let (s_rot, o_rot) = (attitude * g.s_body, attitude * g.o_body);
        let mut flux_w = [0.0; MAX_BANDS];
        self.model
            .flux_bands(
                &self.bands,
                s_rot,
                o_rot,
                g.range_m,
                self.aperture_m2,
                n_p,
                &mut flux_w[..self.n_bands],
            )
            .map_err(|e| SpectraSceneError::Model(format!("{e:?}")))?;
        for f in &mut flux_w[..self.n_bands] {
            *f *= self.band_width_nm;
        }
        Ok(Clean {
            s_body: g.s_body,
            o_body: g.o_body,
            range_m: g.range_m,
            attitude,
            flux_w,
        })
    }

    /// Sample k of the whole stream (stable samples first), with its truth, and the simulated
    /// time since the scenario start [ns].
    pub fn sample(&self, k: u64) -> Result<(Spectrum, Truth, u64), SpectraSceneError> {
        let (window, index) = self.window_of(k);
        let c = self.clean(window, index)?;
        let mut sp = Spectrum {
            frame_index: index,
            window: window as u32,
            n_bands: self.n_bands as u32,
            sun_body: c.s_body.into(),
            observer_body: c.o_body.into(),
            range_m: c.range_m,
            phase_rad: c.s_body.dot(&c.o_body).clamp(-1.0, 1.0).acos(),
            ..Default::default()
        };
        let mut rng = Xoshiro256pp::new(self.seed, SPECTRUM_STREAM + k);
        for b in 0..self.n_bands {
            sp.wavelength_nm[b] = self.bands.wavelengths_nm()[b];
            let sigma = self.sigma_w[window as usize][b];
            let noise = if sigma > 0.0 {
                sigma * inverse_normal_cdf(rng.next_open01())
            } else {
                0.0
            };
            sp.flux_w[b] = c.flux_w[b] + noise;
            sp.sigma_w[b] = sigma;
        }
        let mut truth = Truth {
            kind: Truth::KIND_SPECTRUM,
            frame_index: index,
            rate_deg_per_frame: self.rate_deg_per_frame,
            window: window as u32,
            ..Default::default()
        };
        for r in 0..3 {
            for col in 0..3 {
                truth.attitude_body_rest[3 * r + col] = c.attitude[(r, col)];
            }
        }
        Ok((sp, truth, self.t_ns(k)))
    }
}

/// Walks back from the motion start through the minimum-phase pass to the time the phase was
/// `phase_rad` on the falling branch, then refines by bisection.
fn find_stable_start(
    g: &HoverGeometry,
    sun_lon: f64,
    phase_rad: f64,
) -> Result<f64, SpectraSceneError> {
    let phase = |t: f64| {
        g.phase_angle_rad(t, sun_lon)
            .ok_or(SpectraSceneError::Degenerate { t_s: t })
    };
    let mut prev = phase(0.0)?;
    let mut passed_minimum = false;
    let mut t = 0.0;
    while t > -SEARCH_HORIZON_S {
        let t_next = t - SEARCH_STEP_S;
        let p = phase(t_next)?;
        if p > prev {
            passed_minimum = true;
        }
        if passed_minimum && p >= phase_rad {
            let (mut lo, mut hi) = (t_next, t);
            for _ in 0..60 {
                let mid = 0.5 * (lo + hi);
                if phase(mid)? >= phase_rad {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            return Ok(0.5 * (lo + hi));
        }
        prev = p;
        t = t_next;
    }
    Err(SpectraSceneError::StableStartUnreachable {
        phase_deg: phase_rad.to_degrees(),
    })
}

#[cfg(test)]
mod tests {
    use glint_physics::materials::MATERIAL_BANDS_NM;
    use shared_types::scenario::BAND_CENTRE_RANGE_NM;

    /// The scenario check lets through exactly the band centres the material tables cover.
    #[test]
    fn validation_allows_the_material_tables_range() {
        let (lo, hi) = BAND_CENTRE_RANGE_NM;
        assert_eq!(lo, MATERIAL_BANDS_NM[0]);
        assert_eq!(hi, MATERIAL_BANDS_NM[MATERIAL_BANDS_NM.len() - 1]);
    }
}
