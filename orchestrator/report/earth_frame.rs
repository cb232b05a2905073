//! `earth-frame-NNNN.png` and `earth-frame-annotated.svg`: one Earth frame as the service saw
//! it, with its edge points (after masks and erosion), the limb ring the cross-product
//! answer implies, and the nadir — measured (red) and true (green).

use std::fmt::Write as _;
use std::path::Path;

use anyhow::Result;
use glint_earth::ring::{earth_angular_radius_rad, Fisheye};
use shared_types::scenario::EarthScenario;
use shared_types::{EarthAttitude, Truth};

/// Edge points drawn at most (every n-th beyond).
const MAX_POINTS: usize = 3000;

/// The nadir direction of an answer: β from the axis, tilted about Y_S by `tilt_deg` (the
/// component along Y_S, which the wire does not carry, taken ≥ 0).
fn nadir_of(beta_deg: f64, tilt_deg: f64) -> [f64; 3] {
    let z = beta_deg.to_radians().cos();
    let x = (z * tilt_deg.to_radians().tan()).clamp(-1.0, 1.0);
    let y = (1.0 - x * x - z * z).max(0.0).sqrt();
    [x, y, z]
}

/// The limb ring about nadir `e`: directions at the Earth's angular radius, as pixels.
fn ring_px(cam: &Fisheye, e: [f64; 3], rho_rad: f64, circle_px: f64) -> Vec<(f64, f64)> {
    // Two unit vectors orthogonal to e.
    let helper = if e[2].abs() < 0.9 {
        [0.0, 0.0, 1.0]
    } else {
        [1.0, 0.0, 0.0]
    };
    let cross = |a: [f64; 3], b: [f64; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let norm = |a: [f64; 3]| {
        let n = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
        a.map(|v| v / n)
    };
    let a = norm(cross(e, helper));
    let b = cross(e, a);
    let (sr, cr) = rho_rad.sin_cos();
    (0..=360)
        .map(|deg| {
            let (s, c) = (deg as f64).to_radians().sin_cos();
            let u = [0, 1, 2].map(|i| cr * e[i] + sr * (c * a[i] + s * b[i]));
            cam.pixel(u)
        })
        .filter(|&(x, y)| (x - cam.x0_px).hypot(y - cam.y0_px) <= circle_px)
        .collect()
}

fn cross_mark(svg: &mut String, (x, y): (f64, f64), color: &str) {
    let _ = writeln!(
        svg,
        "<path d=\"M{} {} l10 10 M{} {} l-10 10\" stroke=\"{color}\" stroke-width=\"2\"/>",
        x - 5.0,
        y - 5.0,
        x + 5.0,
        y - 5.0
    );
}

/// Writes the picture of the frame kept in `snap`.
pub fn annotated(
    dir: &Path,
    e: &EarthScenario,
    snap: &crate::run::taps::Snapshot,
    answers: &[EarthAttitude],
    truths: &[Truth],
) -> Result<()> {
    let k = snap.frame_index;
    let px = &snap.pixels;
    let (w, h) = (snap.width_px as usize, snap.height_px as usize);
    let cam = glint_earth::service_core::camera(e);
    let lo = e.space_dn;
    let hi = e.earth_dn.max(lo + 1.0);
    let img: Vec<u8> = px
        .iter()
        .map(|&v| (((v as f64 - lo) / (hi - lo)).clamp(0.0, 1.0) * 200.0) as u8)
        .collect();
    let png_name = format!("earth-frame-{k:04}.png");
    std::fs::write(dir.join(&png_name), crate::png::encode_gray8(w, h, &img)?)?;
    let mut svg = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" xmlns:xlink=\"http://www.w3.org/1999/xlink\" width=\"{w}\" height=\"{}\" viewBox=\"0 0 {w} {}\">\n<image href=\"{png_name}\" xlink:href=\"{png_name}\" x=\"0\" y=\"0\" width=\"{w}\" height=\"{h}\"/>\n",
        h + 24,
        h + 24
    );
    let config = glint_earth::service_core::config(e).map_err(|err| anyhow::anyhow!("{err}"))?;
    let edges = glint_earth::edges::EdgeExtractor::default()
        .extract(px, w, h, &cam, &config.edges)
        .map_err(|err| anyhow::anyhow!("{err}"))?;
    let step = edges.points_px.len().div_ceil(MAX_POINTS).max(1);
    for &(x, y) in edges.points_px.iter().step_by(step) {
        let _ = writeln!(
            svg,
            "<circle cx=\"{x:.1}\" cy=\"{y:.1}\" r=\"0.8\" fill=\"#ff7f0e\"/>"
        );
    }
    let rho = earth_angular_radius_rad(e.altitude_km);
    let answer = answers
        .iter()
        .find(|a| a.frame_index == k)
        .map(|a| a.methods[EarthAttitude::CROSS_PRODUCT])
        .filter(|m| m.valid == 1);
    if let Some(m) = answer {
        let nadir = nadir_of(m.beta_deg, m.tilt_deg);
        let ring = ring_px(&cam, nadir, rho, e.image_circle_px);
        let path: String = ring
            .iter()
            .enumerate()
            .map(|(i, (x, y))| format!("{}{x:.1} {y:.1}", if i == 0 { "M" } else { " L" }))
            .collect();
        let _ = writeln!(
            svg,
            "<path d=\"{path}\" fill=\"none\" stroke=\"#1f77b4\" stroke-width=\"1.2\"/>"
        );
        cross_mark(&mut svg, cam.pixel(nadir), "#d62728");
    }
    if let Some(t) = truths
        .iter()
        .find(|t| t.kind == Truth::KIND_EARTH && t.frame_index == k)
    {
        let (s, c) = t.earth_tilt_deg.to_radians().sin_cos();
        let (sa, ca) = e.turntable_azimuth_deg.to_radians().sin_cos();
        cross_mark(&mut svg, cam.pixel([s * ca, s * sa, c]), "#2ca02c");
    }
    let label = answer.map_or("no answer".to_string(), |m| {
        format!("β {:.3}°, tilt {:+.3}°", m.beta_deg, m.tilt_deg)
    });
    let _ = writeln!(
        svg,
        "<text x=\"4\" y=\"{}\" font-family=\"sans-serif\" font-size=\"13\">frame {k}: edge points (orange), the ring of the cross-product answer (blue, {label}), nadir measured (red) and true (green)</text>\n</svg>",
        h + 17
    );
    std::fs::write(dir.join("earth-frame-annotated.svg"), svg)?;
    Ok(())
}
