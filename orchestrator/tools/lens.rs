//! LENS.toml for `glint tool earth --lens` and `earth-calibrate --lens`: a fisheye calibration
//! as OpenCV's fisheye module (`cv2.fisheye.calibrate`) and most calibration tools give it —
//! the camera matrix's `fx`, `fy`, `cx`, `cy` [px] and the Kannala–Brandt coefficients
//! `D = [k1, k2, k3, k4]` — plus, optionally, the lens's field `field_deg` and its image
//! circle `image_circle_px`.
//!
//! ```toml
//! fx = 162.34
//! fy = 162.31
//! cx = 255.5
//! cy = 255.5
//! D = [0.05, -0.01, 0.0, 0.0]
//! field_deg = 90          # optional
//! image_circle_px = 250   # optional
//! ```
//!
//! glint's fisheye has square pixels: f is the mean of fx and fy, which may differ by at most
//! 1 %. Every problem names the file and the field (line and column for TOML syntax).

use std::path::Path;

use anyhow::{anyhow, bail, Result};
use glint_earth::ring::Fisheye;
use serde::Deserialize;

/// The largest relative difference of fx and fy glint accepts.
const MAX_ASPECT_DIFFERENCE: f64 = 0.01;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct LensFile {
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
    #[serde(rename = "D", default)]
    d: [f64; 4],
    field_deg: Option<f64>,
    image_circle_px: Option<f64>,
}

/// A user's lens: the camera and what bounds its field.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lens {
    pub camera: Fisheye,
    pub field_deg: Option<f64>,
    pub image_circle_px: Option<f64>,
}

/// Reads and checks LENS.toml.
pub fn read_lens(path: &Path) -> Result<Lens> {
    let file = path.display();
    let text =
        shared_types::input::read_text_capped(path, shared_types::input::MAX_TEXT_FILE_BYTES)
            .map_err(|e| anyhow!("{file}: {e}"))?;
    let l: LensFile = toml::from_str(&text).map_err(|e| match e.span() {
        Some(span) => {
            let before = &text[..span.start.min(text.len())];
            let line = before.matches('\n').count() + 1;
            let column = before.len() - before.rfind('\n').map_or(0, |i| i + 1) + 1;
            anyhow!("{file}:{line}:{column}: {}", e.message())
        }
        None => anyhow!("{file}: {}", e.message()),
    })?;
    let range = |field: &str, v: f64, lo: f64, hi: f64| -> Result<()> {
        if !(v.is_finite() && (lo..=hi).contains(&v)) {
            bail!("{file}: field `{field}`: {v} is out of range; allowed {lo} to {hi}");
        }
        Ok(())
    };
    range("fx", l.fx, 1.0, 100_000.0)?;
    range("fy", l.fy, 1.0, 100_000.0)?;
    range("cx", l.cx, -100_000.0, 100_000.0)?;
    range("cy", l.cy, -100_000.0, 100_000.0)?;
    for (i, k) in l.d.iter().enumerate() {
        range(&format!("D[{i}]"), *k, -1.0, 1.0)?;
    }
    if let Some(v) = l.field_deg {
        range("field_deg", v, 10.0, 180.0)?;
    }
    if let Some(v) = l.image_circle_px {
        range("image_circle_px", v, 1.0, 100_000.0)?;
    }
    let aspect = (l.fx - l.fy).abs() / l.fx.max(l.fy);
    if aspect > MAX_ASPECT_DIFFERENCE {
        bail!(
            "{file}: fields `fx` {} and `fy` {} differ by {:.2} %; allowed at most {} % \
             (glint's fisheye has square pixels)",
            l.fx,
            l.fy,
            100.0 * aspect,
            100.0 * MAX_ASPECT_DIFFERENCE
        );
    }
    let camera = Fisheye {
        k: l.d,
        ..Fisheye::ideal(0.5 * (l.fx + l.fy), l.cx, l.cy)
    };
    if let Some(field) = l.field_deg {
        check_fold(path, &camera, field)?;
    }
    Ok(Lens {
        camera,
        field_deg: l.field_deg,
        image_circle_px: l.image_circle_px,
    })
}

/// θ_d must grow across the field the lens images, or two angles share one radius.
pub fn check_fold(path: &Path, camera: &Fisheye, field_deg: f64) -> Result<()> {
    match camera.fold_deg(field_deg) {
        Some(deg) => bail!(
            "{}: field `D`: θ_d stops growing at θ = {deg:.1}°, inside the field \
             ({field_deg}°): the lens would image two angles to one radius",
            path.display()
        ),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lens(text: &str) -> Result<Lens> {
        let dir = std::env::temp_dir().join(format!("glint-lens-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join(format!(
            "{:x}.toml",
            text.len() * 7919 + text.as_bytes()[0] as usize
        ));
        std::fs::write(&path, text).unwrap();
        let r = read_lens(&path);
        let _ = std::fs::remove_file(&path);
        r
    }

    #[test]
    fn an_opencv_calibration_is_read_as_it_is_written() {
        let l = lens("fx = 162.0\nfy = 162.4\ncx = 255.5\ncy = 250\nD = [0.05, -0.01, 0, 0]\n")
            .unwrap();
        assert_eq!(l.camera.f_px, 162.2);
        assert_eq!((l.camera.x0_px, l.camera.y0_px), (255.5, 250.0));
        assert_eq!(l.camera.k, [0.05, -0.01, 0.0, 0.0]);
        assert_eq!((l.field_deg, l.image_circle_px), (None, None));
    }

    #[test]
    fn a_bad_lens_names_the_field_and_the_range() {
        let e = lens("fx = 160\nfy = 170\ncx = 1\ncy = 1\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("`fx` 160 and `fy` 170 differ by 5.88 %"), "{e}");
        let e = lens("fx = 160\nfy = 160\ncx = 1\ncy = 1\nD = [2, 0, 0, 0]\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("field `D[0]`: 2 is out of range; allowed -1 to 1"),
            "{e}"
        );
        let e = lens("fx = 160\nfy = 160\ncx = 1\ncy = 1\nD = [-0.6, 0, 0, 0]\nfield_deg = 90\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("θ_d stops growing"), "{e}");
        let e = lens("fx = 160\nfy = 160\ncx = 1\ncy = 1\nk1 = 0.1\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains(":5:1: unknown field `k1`"), "{e}");
    }
}
