//! The [002] debris scene: CW-propagated debris seen by the along-track camera, turned into
//! streaks for the renderer, truth for scoring, and targets for the laser.
//!
//! Frame k exposes over [k·T, k·T + t_ep] with T = t_ep + t_in (math.md §3.2, §3.9). Each debris
//! moves on the exact CW solution (§3.8 eq 25) in the observer's LVLH-nadir frame, which is also
//! the camera frame (C ≡ O, §3.1); its image is the segment between the projections at the start
//! and the end of the exposure. Brightness scales as (size / range)², normalised so that a 0.1 m
//! object at 10 km integrates `reference_signal_dn`.

use glint_physics::camera::{angles_from_position, PinholeCamera};
use glint_physics::cw::propagate_lvlhn;
use glint_physics::orbit::MU_EARTH_M3_S2;
use nalgebra::{Vector3, Vector6};
use shared_types::scenario::CameraScenario;
use shared_types::{Truth, MAX_DEBRIS};

use crate::laser::LaserTarget;
use crate::render::noise::Xoshiro256pp;
use crate::render::{FrameRenderer, RenderConfig, RenderConfigError, Streak};

const REFERENCE_SIZE_M: f64 = 0.1;
const REFERENCE_RANGE_M: f64 = 10_000.0;
/// PRNG stream offset of the false-target draws (frame noise uses stream = frame index).
const FALSE_TARGET_STREAM: u64 = 1 << 40;
/// False targets keep this far from the border [px].
const FALSE_TARGET_MARGIN_PX: f64 = 16.0;

pub struct DebrisScene {
    pub camera: PinholeCamera,
    /// Observer mean motion [rad/s].
    pub n_rad_s: f64,
    initial_states: Vec<Vector6<f64>>,
    sizes_m: Vec<f64>,
    exposure_s: f64,
    period_s: f64,
    reference_signal_dn: f64,
    false_count: u32,
    false_frames: Vec<u64>,
    false_signal_dn: f64,
    seed: u64,
    renderer: FrameRenderer,
}

impl DebrisScene {
    pub fn new(cam: &CameraScenario, seed: u64) -> Result<Self, RenderConfigError> {
        let renderer = FrameRenderer::new(RenderConfig {
            width_px: cam.width_px as usize,
            height_px: cam.height_px as usize,
            background_dn: cam.background_dn,
            read_noise_dn: cam.read_noise_dn,
            gain_e_per_dn: 1.0,
            saturation_dn: cam.saturation_dn.min(65535) as u16,
            psf_sigma_px: cam.psf_sigma_px,
            substeps_per_px: 10.0,
        })?;
        let a_m = cam.orbit_semi_major_axis_km * 1e3;
        Ok(DebrisScene {
            camera: PinholeCamera {
                width_px: cam.width_px,
                height_px: cam.height_px,
                fov_x_rad: cam.fov_deg.to_radians(),
                fov_y_rad: cam.fov_deg.to_radians(),
            },
            n_rad_s: (MU_EARTH_M3_S2 / (a_m * a_m * a_m)).sqrt(),
            initial_states: cam
                .debris
                .iter()
                .take(MAX_DEBRIS)
                .map(|d| Vector6::new(d.x_m, d.y_m, d.z_m, d.vx_mps, d.vy_mps, d.vz_mps))
                .collect(),
            sizes_m: cam.debris.iter().map(|d| d.size_m).collect(),
            exposure_s: cam.exposure_s,
            period_s: cam.exposure_s + cam.interval_s,
            reference_signal_dn: cam.reference_signal_dn,
            false_count: cam.false_targets.count,
            false_frames: cam.false_targets.frames.clone(),
            false_signal_dn: cam.false_targets.signal_dn,
            seed,
            renderer,
        })
    }

    /// Start of frame k's exposure [s].
    pub fn exposure_start_s(&self, frame_index: u64) -> f64 {
        frame_index as f64 * self.period_s
    }

    /// End of frame k's exposure [s] (the time tag of detections, §3.4 eq 9).
    pub fn exposure_end_s(&self, frame_index: u64) -> f64 {
        self.exposure_start_s(frame_index) + self.exposure_s
    }

    /// State of debris `i` at time `t_s` in the LVLH-nadir frame [m, m/s].
    pub fn state_at(&self, i: usize, t_s: f64) -> Vector6<f64> {
        propagate_lvlhn(self.initial_states[i], self.n_rad_s, t_s)
    }

    pub fn debris_count(&self) -> usize {
        self.initial_states.len()
    }

    fn signal_dn(&self, i: usize, range_m: f64) -> f64 {
        let size = self.sizes_m[i] / REFERENCE_SIZE_M;
        let dist = REFERENCE_RANGE_M / range_m;
        self.reference_signal_dn * size * size * dist * dist
    }

    /// Streaks of frame k: one per debris in front of the camera, plus the false targets.
    pub fn streaks(&self, frame_index: u64) -> Vec<Streak> {
        let (t0, t1) = (
            self.exposure_start_s(frame_index),
            self.exposure_end_s(frame_index),
        );
        let mut out = Vec::with_capacity(self.debris_count() + self.false_count as usize);
        for i in 0..self.debris_count() {
            let (a, b) = (self.state_at(i, t0), self.state_at(i, t1));
            let (ra, rb) = (
                Vector3::new(a[0], a[1], a[2]),
                Vector3::new(b[0], b[1], b[2]),
            );
            if let (Some(p0), Some(p1)) = (self.camera.project(ra), self.camera.project(rb)) {
                let range_m = 0.5 * (ra.norm() + rb.norm());
                out.push(Streak {
                    x0_px: p0.0,
                    y0_px: p0.1,
                    x1_px: p1.0,
                    y1_px: p1.1,
                    total_signal_dn: self.signal_dn(i, range_m),
                });
            }
        }
        for (x, y) in self.false_targets(frame_index) {
            out.push(Streak::point(x, y, self.false_signal_dn));
        }
        out
    }

    /// Pixel positions of the false targets rendered into frame k (seeded, reproducible).
    pub fn false_targets(&self, frame_index: u64) -> Vec<(f64, f64)> {
        if !self.false_frames.contains(&frame_index) {
            return vec![];
        }
        let mut rng = Xoshiro256pp::new(self.seed, FALSE_TARGET_STREAM + frame_index);
        let (w, h) = (self.camera.width_px as f64, self.camera.height_px as f64);
        let span = |len: f64, u: f64| {
            FALSE_TARGET_MARGIN_PX + u * (len - 2.0 * FALSE_TARGET_MARGIN_PX).max(1.0)
        };
        (0..self.false_count)
            .map(|_| {
                let x = span(w, rng.next_open01());
                let y = span(h, rng.next_open01());
                (x, y)
            })
            .collect()
    }

    /// Renders frame k in place into `out` (width × height pixels, row-major).
    pub fn render(&self, frame_index: u64, out: &mut [u16]) {
        let streaks = self.streaks(frame_index);
        // The only failure is a wrong buffer length, which the caller sizes from the same scenario.
        if let Err(e) = self.renderer.render(&streaks, self.seed, frame_index, out) {
            tracing::error!(frame_index, error = %e, "render failed; frame left as background");
        }
    }

    /// Truth of frame k: debris states at the end of its exposure.
    pub fn truth(&self, frame_index: u64) -> Truth {
        let t = self.exposure_end_s(frame_index);
        let mut truth = Truth {
            kind: Truth::KIND_FRAME,
            n_debris: self.debris_count() as u32,
            frame_index,
            ..Default::default()
        };
        for i in 0..self.debris_count() {
            let s = self.state_at(i, t);
            truth.debris_state_lvlh[i].copy_from_slice(s.as_slice());
        }
        let false_targets = self.false_targets(frame_index);
        truth.n_false = false_targets.len().min(MAX_DEBRIS) as u32;
        for (slot, (x, y)) in truth.false_targets_px.iter_mut().zip(false_targets) {
            *slot = [x, y];
        }
        truth
    }

    /// Laser targets as seen at time `t_s`: (id, α, β, range).
    pub fn laser_targets(&self, t_s: f64) -> Vec<LaserTarget> {
        (0..self.debris_count())
            .map(|i| {
                let s = self.state_at(i, t_s);
                let r = Vector3::new(s[0], s[1], s[2]);
                let (az, el) = angles_from_position(r);
                LaserTarget {
                    id: i as u32,
                    azimuth_rad: az,
                    elevation_rad: el,
                    range_m: r.norm(),
                }
            })
            .collect()
    }
}
