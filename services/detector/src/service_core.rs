//! The detector service's core: one frame's pixels in, that frame's matched detections out
//! (the wire message). No IPC: the node ([`crate::node`]) hands it frames read in place from
//! shared memory; a test hands it rendered buffers.

use glint_physics::camera::PinholeCamera;
use shared_types::scenario::CameraScenario;
use shared_types::{Detection, Detections, DropReason, FrameHeader, MAX_DETECTIONS};

use crate::angles::line_of_sight;
use crate::matching::{MatchResult, Matcher, MatcherConfig};
use crate::moments::Blob;
use crate::{ConfigError, Detector, DetectorConfig, Threshold};

/// Detector and matcher settings from the scenario.
pub fn configs(cam: &CameraScenario) -> (DetectorConfig, MatcherConfig) {
    let d = &cam.detector;
    let det = DetectorConfig {
        threshold: Threshold::Sigma {
            k: d.threshold_k_sigma,
        },
        min_area_px: d.min_area_px,
        saturation_dn: cam.saturation_dn.min(u16::MAX as u32) as u16,
        ..Default::default()
    };
    let mat = MatcherConfig {
        exposure_s: cam.exposure_s,
        interval_s: cam.interval_s,
        m00_tol_frac: d.area_tol_frac,
        a_tol_frac: d.semi_axis_tol_frac,
        theta_tol_rad: d.theta_tol_deg.to_radians(),
        ecc_tol: d.ecc_tol,
        round_ecc: d.round_ecc,
        gate_margin_px: d.gate_margin_px,
        max_coast_frames: d.max_coast_frames,
        ..Default::default()
    };
    (det, mat)
}

/// The camera of the scenario.
pub fn camera(cam: &CameraScenario) -> PinholeCamera {
    PinholeCamera {
        width_px: cam.width_px,
        height_px: cam.height_px,
        fov_x_rad: cam.fov_deg.to_radians(),
        fov_y_rad: cam.fov_deg.to_radians(),
    }
}

/// Builds the wire message of one frame from the matcher's result.
/// Eq (9) extrapolates the end point from two centroids: u_t = (1+k) u_c − k u_c' with
/// k = t_ep / (2 (t_ep + t_in)), so its variance is ((1+k)² + k²) times a centroid's.
fn end_point_sigma_factor(exposure_s: f64, interval_s: f64) -> f64 {
    let k = exposure_s / (2.0 * (exposure_s + interval_s));
    ((1.0 + k).powi(2) + k * k).sqrt()
}

fn to_message(
    camera: &PinholeCamera,
    blobs: &[Blob],
    m: &MatchResult,
    frame_index: u64,
    exposure_end_ns: u64,
    background_sigma_dn: f64,
    end_point_factor: f64,
) -> Detections {
    let mut out = Detections {
        frame_index,
        exposure_end_ns,
        blobs_found: blobs.len() as u32,
        rejected: m.rejected_previous.len() as u32,
        ..Default::default()
    };
    for (slot, md) in out
        .items
        .iter_mut()
        .zip(m.matched.iter().take(MAX_DETECTIONS))
    {
        let Some(b) = blobs.get(md.blob_index) else {
            continue;
        };
        let los = line_of_sight(camera, md.end_point_px[0], md.end_point_px[1]);
        // Gain 1 e⁻/DN: the sensor's renderer uses it; a real camera would configure it.
        let sigma_px = b.centroid_sigma_px(background_sigma_dn, 1.0) * end_point_factor;
        let sigma_rad = sigma_px * camera.ifov_rad();
        let mut flags = Detection::FLAG_MATCHED;
        if b.touches_border {
            flags |= Detection::FLAG_BORDER;
        }
        if b.saturated_px > 0 {
            flags |= Detection::FLAG_SATURATED;
        }
        *slot = Detection {
            track_id: md.track_id.min(u32::MAX as u64) as u32,
            flags,
            x_px: md.centroid_px[0],
            y_px: md.centroid_px[1],
            end_x_px: md.end_point_px[0],
            end_y_px: md.end_point_px[1],
            area_px: b.area_px as f64,
            a_px: b.a_px,
            b_px: b.b_px,
            theta_rad: b.theta_rad,
            eccentricity: b.eccentricity,
            flux_dn: b.flux_dn,
            azimuth_rad: los.azimuth_rad,
            elevation_rad: los.elevation_rad,
            sigma_rad: if sigma_rad.is_finite() {
                sigma_rad
            } else {
                0.0
            },
        };
        out.n += 1;
    }
    out
}

/// The detector and matcher of one camera, and what a frame's message needs besides.
pub struct DetectorCore {
    detector: Detector,
    matcher: Matcher,
    camera: PinholeCamera,
    width_px: usize,
    height_px: usize,
    /// σ(end point) / σ(centroid) of eq (9).
    end_point_factor: f64,
}

impl DetectorCore {
    pub fn new(cam: &CameraScenario) -> Result<Self, ConfigError> {
        let (det_cfg, match_cfg) = configs(cam);
        Ok(DetectorCore {
            detector: Detector::new(det_cfg)?,
            matcher: Matcher::new(match_cfg)?,
            camera: camera(cam),
            width_px: cam.width_px as usize,
            height_px: cam.height_px as usize,
            end_point_factor: end_point_sigma_factor(cam.exposure_s, cam.interval_s),
        })
    }

    /// Detects and matches the streaks of one frame. A frame the detector cannot read is
    /// dropped as malformed; one the matcher refuses (out of order) as stale.
    /// What the detector carries from frame to frame (the matcher's objects and track ids;
    /// detection itself is per frame).
    pub fn state(&self) -> crate::matching::MatcherState {
        self.matcher.state()
    }

    /// Carries `state` instead: a restored checkpoint.
    pub fn restore(&mut self, state: crate::matching::MatcherState) {
        self.matcher.restore(state);
    }

    pub fn process(
        &mut self,
        header: &FrameHeader,
        pixels: &[u16],
    ) -> Result<Detections, DropReason> {
        let found = self
            .detector
            .detect(pixels, self.width_px, self.height_px)
            .map_err(|_| DropReason::Malformed)?;
        let result = self
            .matcher
            .update(found.blobs, header.frame_index)
            .map_err(|_| DropReason::Stale)?;
        Ok(to_message(
            &self.camera,
            found.blobs,
            &result,
            header.frame_index,
            header.meta.t_ns,
            found.background.sigma_dn,
            self.end_point_factor,
        ))
    }
}
