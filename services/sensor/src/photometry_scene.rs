//! The [001] ground telescope's light curve (`[photometry]`; docs/math.md §2): a satellite of
//! one of the library's shapes, scaled, spinning about an axis fixed in ECI, on the
//! geostationary orbit over its longitude, watched from a ground station. Sample `k` — its
//! geometry from the almanac and the orbit, its magnitude from the facets (Ashikhmin–Shirley,
//! shadowing by ray casts) and noise drawn from a generator keyed by (seed, k) — is a function
//! of `k`, as a restarted consumer's replay needs. A sample in the Earth's shadow, below the
//! station's minimum elevation, or with no lit facet facing the station has no magnitude:
//! the message says why.

use anyhow::{anyhow, Context, Result};
use glint_photometry::spin::spin_attitude;
use glint_physics::orbit::CircularOrbit;
use glint_physics::photometry::{
    apparent_magnitude, geometry, geostationary, normalised_flux, Shape, SpecularDenominator,
    Station, Unseen,
};
use glint_physics::rng::SeededRng;
use nalgebra::{Unit, UnitQuaternion, Vector3};
use shared_types::scenario::PhotometryScenario;
use shared_types::{PhotometrySample, Truth};

/// The σ a noise-free sample reports [mag] (a filter needs one above 0).
const SIGMA_FLOOR_MAG: f64 = 1e-3;

pub struct PhotometryScene {
    shape: Shape,
    /// The shape's index in the library and its total facet area at scale [m²].
    shape_index: usize,
    area_m2: f64,
    axis: Unit<Vector3<f64>>,
    spin_rad_s: f64,
    phase0_rad: f64,
    orbit: CircularOrbit,
    station: Station,
    min_elevation_deg: f64,
    jd0: f64,
    sigma_mag: f64,
    samples: u64,
    cadence_s: f64,
    seed: u64,
}

fn sample_rng(seed: u64, k: u64) -> SeededRng {
    SeededRng::new(xxhash_rust::xxh3::xxh3_64(
        &[seed.to_le_bytes(), k.to_le_bytes(), *b"photomet"].concat(),
    ))
}

/// A spin axis drawn from the seed, uniform on the sphere.
fn drawn_axis(seed: u64) -> Unit<Vector3<f64>> {
    let mut rng = SeededRng::new(seed ^ 0x5048_4f54_4f4d_4554);
    loop {
        let v = Vector3::new(rng.gaussian(), rng.gaussian(), rng.gaussian());
        if v.norm() > 1e-6 {
            return Unit::new_normalize(v);
        }
    }
}

impl PhotometryScene {
    pub fn new(p: &PhotometryScenario, seed: u64) -> Result<Self> {
        let shapes = glint_photometry::shapes::read_shapes(&p.shapes)?;
        let shape_index =
            (shapes.iter().position(|(n, _)| *n == p.geometry)).with_context(|| {
                format!(
                    "photometry.geometry: `{}` is not in {} (it has {})",
                    p.geometry,
                    p.shapes.display(),
                    shapes
                        .iter()
                        .map(|(n, _)| n.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                )
            })?;
        let shape = shapes[shape_index].1.scaled(p.scale);
        let jd0 = (p.start_jd()).ok_or_else(|| anyhow!("photometry.start_utc: not a time"))?;
        let axis = match p.spin_axis {
            Some(a) => Unit::new_normalize(Vector3::from(a)),
            None => drawn_axis(seed),
        };
        let s = &p.station;
        Ok(PhotometryScene {
            area_m2: shape.area_m2(),
            shape,
            shape_index,
            axis,
            spin_rad_s: std::f64::consts::TAU / p.spin_period_s,
            phase0_rad: p.phase0_deg.to_radians(),
            orbit: geostationary(p.satellite_longitude_deg, jd0),
            station: Station {
                latitude_deg: s.latitude_deg,
                longitude_deg: s.longitude_deg,
                altitude_m: s.altitude_m,
            },
            min_elevation_deg: s.min_elevation_deg,
            jd0,
            sigma_mag: p.sigma_mag,
            samples: p.samples(),
            cadence_s: p.cadence_s,
            seed,
        })
    }

    pub fn len(&self) -> u64 {
        self.samples
    }

    pub fn is_empty(&self) -> bool {
        self.samples == 0
    }

    pub fn t_ns(&self, k: u64) -> u64 {
        (k as f64 * self.cadence_s * 1e9).round() as u64
    }

    /// q_IB at `t_s`.
    fn attitude(&self, t_s: f64) -> UnitQuaternion<f64> {
        spin_attitude(&self.axis, self.phase0_rad + self.spin_rad_s * t_s)
    }

    /// Sample `k`.
    pub fn sample(&self, k: u64) -> PhotometrySample {
        let t_s = self.t_ns(k) as f64 * 1e-9;
        let g = geometry(&self.orbit, &self.station, self.jd0, t_s);
        let mut msg = PhotometrySample {
            sample_index: k,
            sun: g.sun.into(),
            obs: g.obs.into(),
            range_m: g.range_m,
            ..PhotometrySample::default()
        };
        msg.status = match g.visible(self.min_elevation_deg) {
            Err(Unseen::Shadow) => PhotometrySample::SHADOW,
            Err(Unseen::BelowHorizon) => PhotometrySample::BELOW_HORIZON,
            Ok(()) => {
                let inv = self.attitude(t_s).inverse();
                let m = normalised_flux(
                    &self.shape,
                    &(inv * g.sun),
                    &(inv * g.obs),
                    SpecularDenominator::Linares2014,
                );
                match apparent_magnitude(m, g.range_m) {
                    Some(mag) => {
                        msg.mag = mag + self.sigma_mag * sample_rng(self.seed, k).gaussian();
                        msg.sigma_mag = self.sigma_mag.max(SIGMA_FLOOR_MAG);
                        PhotometrySample::SEEN
                    }
                    None => PhotometrySample::NO_FLUX,
                }
            }
        };
        msg
    }

    /// What sample `k` shows: the attitude, the body rate, the shape, its area, the spin.
    pub fn truth(&self, k: u64) -> Truth {
        let t_s = self.t_ns(k) as f64 * 1e-9;
        let q = self.attitude(t_s);
        let w_body = q.inverse() * (self.axis.into_inner() * self.spin_rad_s);
        let q = q.into_inner();
        let q = if q.w < 0.0 { -q } else { q };
        let mut state = [0.0; 15];
        let values = [q.w, q.i, q.j, q.k]
            .into_iter()
            .chain(w_body.iter().copied())
            .chain([self.shape_index as f64, self.area_m2, self.spin_rad_s]);
        for (slot, v) in state.iter_mut().zip(values) {
            *slot = v;
        }
        Truth {
            kind: Truth::KIND_PHOTOMETRY,
            frame_index: k,
            target_state: state,
            ..Truth::default()
        }
    }
}
