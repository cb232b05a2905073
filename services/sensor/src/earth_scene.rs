//! The [003] Earth sensor's scene: the scenario's turntable angles, one rendered frame per
//! (angle, image), and each frame's truth (β and the signed tilt).

use glint_physics::fisheye::Fisheye;
use shared_types::scenario::EarthScenario;
use shared_types::{FrameHeader, Meta, Truth};

use crate::earth_hazards::{Hazards, SunInField};
use crate::earth_render::{nadir, EarthRenderConfig, EarthRenderer};

pub struct EarthScene {
    renderer: EarthRenderer,
    /// Turntable angle of each step [deg].
    angles_deg: Vec<f64>,
    section: EarthScenario,
    seed: u64,
}

impl EarthScene {
    pub fn new(e: &EarthScenario, seed: u64) -> Self {
        let renderer = EarthRenderer::new(EarthRenderConfig {
            width_px: e.width_px as usize,
            height_px: e.height_px as usize,
            camera: camera(e),
            altitude_km: e.altitude_km,
            image_circle_px: e.image_circle_px,
            earth_dn: e.earth_dn,
            space_dn: e.space_dn,
            psf_sigma_px: e.psf_sigma_px,
            noise_dn: e.noise_dn,
            saturation_dn: e.saturation_dn.min(u16::MAX as u32) as u16,
            hazards: hazards(e),
        });
        EarthScene {
            renderer,
            angles_deg: e.angles_deg(),
            section: e.clone(),
            seed,
        }
    }

    pub fn frames(&self) -> u64 {
        self.angles_deg.len() as u64 * self.section.images_per_angle as u64
    }

    /// The end of frame `k`'s exposure [ns].
    pub fn t_ns(&self, k: u64) -> u64 {
        self.section.exposure_end_ns(k)
    }

    /// The nadir's tilt about the turntable axis in frame `k` [deg].
    pub fn tilt_deg(&self, k: u64) -> f64 {
        self.section.tilt_deg(&self.angles_deg, k)
    }

    /// Renders frame `k` into `pixels` (every pixel written) and fills the header's frame fields.
    pub fn render(&self, k: u64, header: &mut FrameHeader, pixels: &mut [u16]) {
        let period_ns = (self.section.frame_period_s * 1e9).round().max(1.0) as u64;
        let end_ns = self.t_ns(k);
        header.frame_index = k;
        header.exposure_ns = period_ns;
        header.exposure_start_ns = end_ns.saturating_sub(period_ns);
        header.interval_ns = 0;
        header.width_px = self.section.width_px;
        header.height_px = self.section.height_px;
        let e = nadir(self.tilt_deg(k), self.section.turntable_azimuth_deg);
        if !self.renderer.render(e, self.seed, k, pixels) {
            // A loan of another size: a header that cannot validate rather than stale pixels.
            pixels.fill(0);
            header.width_px = 0;
        }
    }

    /// The truth of frame `k`.
    pub fn truth(&self, k: u64) -> Truth {
        let tilt = self.tilt_deg(k);
        Truth {
            meta: Meta::default(),
            kind: Truth::KIND_EARTH,
            frame_index: k,
            earth_beta_deg: tilt.abs(),
            earth_tilt_deg: tilt,
            ..Default::default()
        }
    }
}

/// The harder conditions an `[earth]` section asks for.
fn hazards(e: &EarthScenario) -> Hazards {
    let [theta, phi] = e.sun_direction_deg.map(f64::to_radians);
    Hazards {
        flattening: e.flattening,
        limb_radiance_amplitude: e.limb_radiance_amplitude,
        limb_height_km: e.limb_height_km,
        limb_height_seasonal_km: e.limb_height_seasonal_km,
        limb_height_latitude_km: e.limb_height_latitude_km,
        sun: (e.sun_dn > 0.0).then(|| SunInField {
            direction: [
                theta.sin() * phi.cos(),
                theta.sin() * phi.sin(),
                theta.cos(),
            ],
            radiance_dn: e.sun_dn,
        }),
    }
}

/// The fisheye of an `[earth]` section: the lens as it is, its distortion included.
pub fn camera(e: &EarthScenario) -> Fisheye {
    Fisheye {
        k: e.lens_k,
        ..Fisheye::ideal(e.f_px, e.center_px[0], e.center_px[1])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn section() -> EarthScenario {
        EarthScenario {
            width_px: 128,
            height_px: 128,
            f_px: 32.0,
            center_px: [63.5, 63.5],
            image_circle_px: 63.0,
            images_per_angle: 3,
            trajectory_deg: vec![-4.0, 0.0, 25.0],
            ..Default::default()
        }
    }

    #[test]
    fn the_sun_of_the_section_is_where_its_direction_images() {
        let mut e = section();
        e.noise_dn = 0.0;
        e.sun_dn = 1e6;
        e.sun_direction_deg = [100.0, 90.0];
        let scene = EarthScene::new(&e, 5);
        let mut px = vec![0u16; 128 * 128];
        scene.render(0, &mut FrameHeader::default(), &mut px);
        // θ = 100° toward +Y: r = f θ below the principal point.
        let (x, y) = (63.5, 63.5 + 32.0 * 100f64.to_radians());
        let at = |px: &[u16], x: f64, y: f64| px[y.round() as usize * 128 + x.round() as usize];
        // It saturates the detector.
        assert_eq!(at(&px, x, y), e.saturation_dn as u16);
        assert_eq!(at(&px, x + 12.0, y), e.space_dn as u16);
        // Without it, space there.
        e.sun_dn = 0.0;
        EarthScene::new(&e, 5).render(0, &mut FrameHeader::default(), &mut px);
        assert_eq!(at(&px, x, y), e.space_dn as u16);
    }

    #[test]
    fn frames_follow_the_trajectory_k_images_per_angle() {
        let scene = EarthScene::new(&section(), 5);
        assert_eq!(scene.frames(), 9);
        let tilts: Vec<f64> = (0..9).map(|k| scene.tilt_deg(k)).collect();
        assert_eq!(tilts, [-4.0, -4.0, -4.0, 0.0, 0.0, 0.0, 25.0, 25.0, 25.0]);
        let t = scene.truth(1);
        assert_eq!(t.kind, Truth::KIND_EARTH);
        assert_eq!((t.earth_beta_deg, t.earth_tilt_deg), (4.0, -4.0));
        assert_eq!(t.frame_index, 1);
        // Frame k's exposure ends (k + 1) frame periods in.
        assert_eq!(scene.t_ns(0), 100_000_000);
        assert_eq!(scene.t_ns(8), 900_000_000);
    }

    #[test]
    fn a_frame_is_written_whole_with_its_header_and_differs_only_by_noise_between_images() {
        let scene = EarthScene::new(&section(), 5);
        let mut h = FrameHeader {
            meta: Meta::new(0, 0, 0, shared_types::ServiceId::Sensor),
            ..Default::default()
        };
        let mut a = vec![u16::MAX; 128 * 128];
        scene.render(6, &mut h, &mut a);
        assert_eq!((h.frame_index, h.width_px, h.height_px), (6, 128, 128));
        assert!(h.exposure_ns > 0 && h.exposure_start_ns + h.exposure_ns == scene.t_ns(6));
        assert!(h.validate(a.len()).is_ok());
        assert!(!a.contains(&u16::MAX), "every pixel written");
        let mut b = vec![0u16; 128 * 128];
        scene.render(7, &mut h, &mut b);
        assert_ne!(a, b, "another image, other noise");
        let mut again = vec![0u16; 128 * 128];
        scene.render(6, &mut h, &mut again);
        assert_eq!(a, again, "deterministic");
        // A buffer of another size gets a header that cannot validate.
        let mut small = vec![1u16; 10];
        scene.render(0, &mut h, &mut small);
        assert!(h.validate(small.len()).is_err());
    }
}
