//! The earth service's core: one Earth frame's pixels in, that frame's [`EarthAttitude`] out
//! (every method's β and tilt, and what each took). No IPC: the node ([`crate::node`]) hands it
//! frames read in place from shared memory; a test hands it rendered buffers.

use shared_types::scenario::EarthScenario;
use shared_types::{DropReason, EarthAttitude, EarthMethod, FrameHeader};

use crate::estimate::{SigmaTable, TableError};
use crate::pipeline::{EarthConfig, EarthCore, MethodResult};
use crate::ring::Fisheye;
use crate::validity::Undetermined;

/// Why the σ table `earth.sigma_table` names cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum SetupError {
    #[error("{file}: cannot read: {error}")]
    Io { file: String, error: std::io::Error },
    #[error("{0}")]
    Table(#[from] TableError),
}

/// The fisheye of an `[earth]` section as the earth service knows it: its calibration's
/// distortion, or the lens's own when it has none.
pub fn camera(e: &EarthScenario) -> Fisheye {
    Fisheye {
        k: e.calibration_k.unwrap_or(e.lens_k),
        ..Fisheye::ideal(e.f_px, e.center_px[0], e.center_px[1])
    }
}

/// The σ table an `[earth]` section names, if any.
pub fn sigma_table(e: &EarthScenario) -> Result<Option<SigmaTable>, SetupError> {
    let Some(path) = &e.sigma_table else {
        return Ok(None);
    };
    let file = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|error| SetupError::Io {
        file: file.clone(),
        error,
    })?;
    Ok(Some(SigmaTable::parse(&text, &file)?))
}

/// The processing settings of an `[earth]` section.
pub fn config(e: &EarthScenario) -> Result<EarthConfig, SetupError> {
    let mut c = EarthConfig::new(camera(e), e.altitude_km);
    c.edges.threshold_dn = e.edge_threshold_dn.map(|t| t as f32);
    c.edges.image_circle_px = Some(e.image_circle_px);
    // The circle's own edge, blurred by the PSF, reaches ~3σ inward; the Sobel kernel 1 px more.
    c.edges.field_margin_px = 1.0 + 3.0 * e.psf_sigma_px;
    c.sigma_table = sigma_table(e)?;
    Ok(c)
}

pub struct EarthServiceCore {
    core: EarthCore,
    width_px: u32,
    height_px: u32,
}

fn method(m: Result<MethodResult, Undetermined>) -> EarthMethod {
    match m {
        Ok(m) => EarthMethod {
            beta_deg: m.beta_deg,
            tilt_deg: m.tilt_deg,
            time_us: m.time_us,
            valid: 1,
            undetermined: 0,
        },
        Err(why) => EarthMethod {
            undetermined: why.code(),
            ..EarthMethod::default()
        },
    }
}

impl EarthServiceCore {
    pub fn new(e: &EarthScenario) -> Result<Self, SetupError> {
        Ok(Self {
            core: EarthCore::new(config(e)?),
            width_px: e.width_px,
            height_px: e.height_px,
        })
    }

    /// Every method on one frame. A frame of another size than the scenario's is malformed.
    pub fn process(
        &mut self,
        header: &FrameHeader,
        pixels: &[u16],
    ) -> Result<EarthAttitude, DropReason> {
        if (header.width_px, header.height_px) != (self.width_px, self.height_px) {
            return Err(DropReason::Malformed);
        }
        let (w, h) = (self.width_px as usize, self.height_px as usize);
        let r = (self.core)
            .process(pixels, w, h)
            .map_err(|_| DropReason::Malformed)?;
        let fit = r.fit.map_or((0.0, 0.0, 0.0), |f| (f.mu, f.sigma, f.nu));
        Ok(EarthAttitude {
            frame_index: header.frame_index,
            edge_points: r.edge_points.min(u32::MAX as usize) as u32,
            samples: r.samples.min(u32::MAX as usize) as u32,
            fit_mu_deg: fit.0,
            fit_sigma_deg: fit.1,
            fit_nu: fit.2,
            methods: [method(r.cross_product), method(r.lookup), method(r.hough)],
            samples_hist: EarthAttitude::histogram(&r.signed_beta_deg, fit.0, fit.1),
            ..Default::default()
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header(w: u32, h: u32) -> FrameHeader {
        FrameHeader {
            frame_index: 7,
            width_px: w,
            height_px: h,
            ..Default::default()
        }
    }

    /// The message with the header its sender gives it.
    fn sealed(mut m: EarthAttitude) -> EarthAttitude {
        m.meta = shared_types::Meta::new(0, 0, 0, shared_types::ServiceId::Earth);
        m
    }

    #[test]
    fn a_frame_at_a_known_tilt_gives_it_by_every_method() {
        let e = EarthScenario::default();
        let px = crate::synthetic::blurred_earth(512, 512, &camera(&e), 12.0);
        let mut core = EarthServiceCore::new(&e).unwrap();
        let m = core.process(&header(512, 512), &px).unwrap();
        assert_eq!(m.frame_index, 7);
        assert!(m.edge_points > 500 && m.samples > 100, "{m:?}");
        for (name, r) in EarthAttitude::METHOD_NAMES.iter().zip(m.methods) {
            assert_eq!(r.valid, 1, "{name}: {m:?}");
            assert!((r.beta_deg - 12.0).abs() < 0.1, "{name}: {r:?}");
            assert!((r.tilt_deg - 12.0).abs() < 0.1, "{name}: {r:?}");
            assert!(r.time_us > 0.0, "{name}");
        }
        assert!(sealed(m).validate().is_ok());
    }

    #[test]
    fn a_frame_of_another_size_is_malformed() {
        let e = EarthScenario::default();
        let mut core = EarthServiceCore::new(&e).unwrap();
        let px = vec![0u16; 256 * 256];
        assert_eq!(
            core.process(&header(256, 256), &px),
            Err(DropReason::Malformed)
        );
    }

    #[test]
    fn a_space_only_frame_is_answered_with_no_method_valid() {
        let e = EarthScenario::default();
        let mut core = EarthServiceCore::new(&e).unwrap();
        let m = core
            .process(&header(512, 512), &vec![20u16; 512 * 512])
            .unwrap();
        assert!(m.methods.iter().all(|r| r.valid == 0), "{m:?}");
        assert!(sealed(m).validate().is_ok());
    }

    #[test]
    fn a_bad_sigma_table_names_its_file_and_line() {
        let dir = std::env::temp_dir().join(format!("glint-earth-table-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("t.csv");
        std::fs::write(&file, "mu_deg,sigma_deg\n1,0.1\n2,-3\n").unwrap();
        let e = EarthScenario {
            sigma_table: Some(file.clone()),
            ..Default::default()
        };
        let err = sigma_table(&e).unwrap_err().to_string();
        assert!(err.contains("t.csv:3"), "{err}");
        let e = EarthScenario {
            sigma_table: Some(dir.join("missing.csv")),
            ..Default::default()
        };
        let err = sigma_table(&e).unwrap_err().to_string();
        assert!(
            err.contains("missing.csv") && err.contains("cannot read"),
            "{err}"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}
