//! Offline tools: every algorithm stage on files, without any IPC.
//!
//! - `glint tool detect FRAME.pgm [--threshold DN]`: detections of one 16-bit PGM as JSON.
//! - `glint tool render SCENARIO --frame K --out FRAME.pgm`: one frame of a scenario's camera,
//!   rendered by the sensor's renderer (the same pixels a run publishes for that seed).
//! - `glint tool tfit SAMPLES`: the t location-scale MLE of a sample file as JSON.
//! - `glint tool earth FRAME.pgm --f-px F --center X,Y`: β from a fisheye Earth image by every
//!   [003] method, as JSON.
//! - `glint tool photometry LC.csv --shapes SHAPES.toml [--out DIR]`: the [001] chain on a light
//!   curve and the user's OBJ shapes;
//! - `glint tool relnav MEAS.csv --rig RIG.toml [--out DIR]`: the [004] filter on a file of
//!   stereo measurements.

pub mod invert;
pub mod lens;
pub mod observations;
pub mod photometry;
pub mod relnav;

use std::path::Path;

use anyhow::{anyhow, Context, Result};
use glint_detector::pgm::{read_pgm, write_pgm, PgmImage};
use glint_detector::{Detector, DetectorConfig, Threshold};
use serde_json::json;
use shared_types::Scenario;

/// Detections of one frame as JSON (pixel convention: x = column, y = row, the first pixel's
/// centre at (0, 0); θ from +x toward +y).
pub fn detect(path: &Path, threshold_dn: Option<u16>) -> Result<String> {
    let img = read_pgm(path).map_err(|e| match e {
        // The read error names the file itself.
        glint_detector::pgm::PgmError::Io { .. } => anyhow!("{e}"),
        _ => anyhow!("{}: {e}", path.display()),
    })?;
    let mut cfg = DetectorConfig::default();
    if let Some(t) = threshold_dn {
        cfg.threshold = Threshold::AbsoluteDn { threshold_dn: t };
    }
    let mut detector = Detector::new(cfg).map_err(|e| anyhow!("{e}"))?;
    let found = detector
        .detect(&img.pixels, img.width, img.height)
        .map_err(|e| anyhow!("{}: {e}", path.display()))?;
    let blobs: Vec<_> = found
        .blobs
        .iter()
        .map(|b| {
            json!({
                "x": b.weighted.x_px, "y": b.weighted.y_px,
                "area": b.area_px,
                "a": b.a_px, "b": b.b_px,
                "theta_rad": b.theta_rad,
                "eccentricity": b.eccentricity,
                "flux_dn": b.flux_dn,
                "peak_dn": b.peak_dn,
                "touches_border": b.touches_border,
            })
        })
        .collect();
    let out = json!({
        "file": path.display().to_string(),
        "width": img.width,
        "height": img.height,
        "background_dn": found.background.background_dn,
        "sigma_dn": found.background.sigma_dn,
        "threshold_dn": found.threshold_dn,
        "detections": blobs,
    });
    Ok(serde_json::to_string_pretty(&out)?)
}

/// Renders frame `k` of a scenario into a 16-bit PGM.
pub fn render(scenario: &Scenario, k: u64, out: &Path, earth: bool) -> Result<()> {
    if earth {
        return render_earth(scenario, k, out);
    }
    let cam = scenario
        .camera
        .as_ref()
        .context("the scenario has no [camera] section")?;
    if k >= cam.frames {
        return Err(anyhow!(
            "--frame {k} is out of range 0..={}",
            cam.frames - 1
        ));
    }
    let scene = glint_sensor::debris_scene::DebrisScene::new(cam, scenario.seed)
        .map_err(|e| anyhow!("{e}"))?;
    let mut pixels = vec![0u16; cam.pixels()];
    scene.render(k, &mut pixels);
    let img = PgmImage {
        width: cam.width_px as usize,
        height: cam.height_px as usize,
        maxval: 65535,
        pixels,
    };
    write_pgm(out, &img).map_err(|e| anyhow!("{}: {e}", out.display()))
}

/// Earth frame `k` of a scenario's `[earth]` sensor, as the sensor renders it.
fn render_earth(scenario: &Scenario, k: u64, out: &Path) -> Result<()> {
    let e = (scenario.earth.as_ref()).context("the scenario has no [earth] section")?;
    let frames = e.frames();
    if k >= frames {
        return Err(anyhow!("--frame {k} is out of range 0..={}", frames - 1));
    }
    let scene = glint_sensor::earth_scene::EarthScene::new(e, scenario.seed);
    let mut pixels = vec![0u16; e.pixels()];
    scene.render(k, &mut shared_types::FrameHeader::default(), &mut pixels);
    let img = PgmImage {
        width: e.width_px as usize,
        height: e.height_px as usize,
        maxval: 65535,
        pixels,
    };
    write_pgm(out, &img).map_err(|err| anyhow!("{}: {err}", out.display()))
}

/// Largest sample file `glint tool tfit` reads.
const MAX_SAMPLES_FILE_BYTES: u64 = 256 << 20;

/// The t location-scale MLE (docs/math.md §4.5) of the samples in `path` as JSON.
pub fn tfit(path: &Path) -> Result<String> {
    let len = std::fs::metadata(path)
        .with_context(|| format!("{}: cannot read", path.display()))?
        .len();
    if len > MAX_SAMPLES_FILE_BYTES {
        return Err(anyhow!(
            "{}: {len} bytes; at most {MAX_SAMPLES_FILE_BYTES} are read",
            path.display()
        ));
    }
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read as UTF-8 text", path.display()))?;
    let file = path.display().to_string();
    let x = glint_earth::samples::parse(&text, &file).map_err(|e| anyhow!("{e}"))?;
    let f = glint_earth::tfit::fit(&x).map_err(|e| anyhow!("{file}: {e}"))?;
    let out = json!({
        "n": f.n, "mu": f.mu, "sigma": f.sigma, "nu": f.nu, "nll": f.nll,
        "iterations": f.iterations,
    });
    Ok(serde_json::to_string_pretty(&out)?)
}

/// The fisheye camera and processing of `glint tool earth` and `earth-calibrate`.
pub struct EarthTool {
    pub f_px: f64,
    pub center_px: (f64, f64),
    /// Kannala–Brandt k₁…k₄ (0: the ideal `r = f θ`).
    pub k: [f64; 4],
    pub altitude_km: f64,
    /// The lens's field half-angle [deg]: nothing beyond it is imaged.
    pub field_deg: f64,
    /// The image circle [px], when the lens vignettes inside its field.
    pub image_circle_px: Option<f64>,
}

impl EarthTool {
    /// The tool's camera from --f-px and --center, or from a LENS.toml (whose field and image
    /// circle, when it gives them, stand for the flags').
    pub fn new(
        f_px: Option<f64>,
        center_px: Option<(f64, f64)>,
        lens: Option<&Path>,
        altitude_km: f64,
        field_deg: f64,
        image_circle_px: Option<f64>,
    ) -> Result<Self> {
        if let Some(path) = lens {
            let l = lens::read_lens(path)?;
            let field_deg = l.field_deg.unwrap_or(field_deg);
            // the field the tool will use, --field-deg's when the file gives none
            lens::check_fold(path, &l.camera, field_deg)?;
            return Ok(EarthTool {
                f_px: l.camera.f_px,
                center_px: (l.camera.x0_px, l.camera.y0_px),
                k: l.camera.k,
                altitude_km,
                field_deg,
                image_circle_px: l.image_circle_px.or(image_circle_px),
            });
        }
        match (f_px, center_px) {
            (Some(f_px), Some(center_px)) => Ok(EarthTool {
                f_px,
                center_px,
                k: [0.0; 4],
                altitude_km,
                field_deg,
                image_circle_px,
            }),
            _ => Err(anyhow!("give --f-px and --center, or --lens LENS.toml")),
        }
    }

    fn core(
        &self,
        table: Option<glint_earth::estimate::SigmaTable>,
    ) -> glint_earth::pipeline::EarthCore {
        let camera = glint_earth::ring::Fisheye {
            k: self.k,
            ..glint_earth::ring::Fisheye::ideal(self.f_px, self.center_px.0, self.center_px.1)
        };
        let mut config = glint_earth::pipeline::EarthConfig::new(camera, self.altitude_km);
        config.sigma_table = table;
        let field_px = camera.radius_px(self.field_deg.to_radians());
        config.edges.image_circle_px =
            Some(self.image_circle_px.map_or(field_px, |r| r.min(field_px)));
        glint_earth::pipeline::EarthCore::new(config)
    }
}

fn read_frame(path: &Path) -> Result<PgmImage> {
    read_pgm(path).map_err(|e| match e {
        glint_detector::pgm::PgmError::Io { .. } => anyhow!("{e}"),
        _ => anyhow!("{}: {e}", path.display()),
    })
}

/// A σ table file of `glint tool earth-calibrate`.
pub fn read_sigma_table(path: &Path) -> Result<glint_earth::estimate::SigmaTable> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read", path.display()))?;
    glint_earth::estimate::SigmaTable::parse(&text, &path.display().to_string())
        .map_err(|e| anyhow!("{e}"))
}

/// Noise stream of the calibration frames: other noise than any run of the same seed has.
const CALIBRATION_SEED: u64 = 0xca11_b4a7e;

/// The σ table of a scenario's `[earth]` sensor, calibrated on frames its own renderer makes
/// at 0°, 1°, …, 60° (`images` per angle, noise independent of the run's), written to `out`.
pub fn earth_calibrate_scenario(scenario: &Scenario, images: u32, out: &Path) -> Result<String> {
    let e = (scenario.earth.as_ref()).context("the scenario has no [earth] section")?;
    let mut section = e.clone();
    section.sigma_table = None;
    section.trajectory_deg = (0..=60).map(f64::from).collect();
    section.images_per_angle = images;
    let scene =
        glint_sensor::earth_scene::EarthScene::new(&section, scenario.seed ^ CALIBRATION_SEED);
    let config = glint_earth::service_core::config(&section).map_err(|err| anyhow!("{err}"))?;
    let mut core = glint_earth::pipeline::EarthCore::new(config);
    let (w, h) = (section.width_px as usize, section.height_px as usize);
    let mut px = vec![0u16; w * h];
    let mut header = shared_types::FrameHeader::default();
    let mut fits = vec![];
    for k in 0..section.frames() {
        scene.render(k, &mut header, &mut px);
        let r = core.process(&px, w, h).map_err(|err| anyhow!("{err}"))?;
        // Keyed by the turntable angle, which calibration knows: the images of one angle
        // average into one row.
        if let Some(f) = r.fit {
            fits.push((scene.tilt_deg(k), f.sigma));
        }
    }
    let table = glint_earth::estimate::SigmaTable::from_fits(&fits);
    std::fs::write(out, table.to_csv()).with_context(|| format!("writing {}", out.display()))?;
    Ok(serde_json::to_string_pretty(&json!({
        "table": out.display().to_string(),
        "angles": table.points.len(),
        "frames": section.frames(),
        "fitted": fits.len(),
    }))?)
}

/// β and tilt of one fisheye Earth frame by every [003] method, as JSON.
pub fn earth(path: &Path, tool: &EarthTool, table: Option<&Path>) -> Result<String> {
    let img = read_frame(path)?;
    let table = table.map(read_sigma_table).transpose()?;
    let calibrated = table.is_some();
    let mut core = tool.core(table);
    let r = core
        .process(&img.pixels, img.width, img.height)
        .map_err(|e| anyhow!("{}: {e}", path.display()))?;
    type Answer = Result<glint_earth::pipeline::MethodResult, glint_earth::validity::Undetermined>;
    let methods = [
        ("cross_product", &r.cross_product),
        ("lookup", &r.lookup),
        ("hough", &r.hough),
    ];
    let each =
        |f: &dyn Fn(&Answer) -> serde_json::Value| -> serde_json::Map<String, serde_json::Value> {
            methods
                .iter()
                .map(|(name, m)| (name.to_string(), f(m)))
                .collect()
        };
    let out = json!({
        "file": path.display().to_string(),
        "beta_deg": each(&|m| json!(m.as_ref().ok().map(|m| m.beta_deg))),
        "tilt_deg": r.cross_product.as_ref().ok().map(|m| m.tilt_deg),
        "valid_methods": methods.iter().filter(|(_, m)| m.is_ok()).map(|(n, _)| *n).collect::<Vec<_>>(),
        "not_determined": methods
            .iter()
            .filter_map(|(n, m)| m.as_ref().err().map(|why| (n.to_string(), json!(why.to_string()))))
            .collect::<serde_json::Map<_, _>>(),
        "edge_points": r.edge_points,
        "samples": r.samples,
        "fit": r.fit.map(|f| json!({"mu_deg": f.mu, "sigma_deg": f.sigma, "nu": f.nu,
            "standard_error_deg": r.standard_error_deg})),
        "lookup_sigma": if calibrated { "the calibrated table" } else { "the frame's fitted σ (no --sigma-table)" },
        "time_us": {
            "edges": r.edges_us,
            "cross_product": r.cross_product.as_ref().ok().map(|m| m.time_us),
            "lookup": r.lookup.as_ref().ok().map(|m| m.time_us),
            "hough": r.hough.as_ref().ok().map(|m| m.time_us),
        },
    });
    Ok(serde_json::to_string_pretty(&out)?)
}

/// The lookup version's σ(μ) table from calibration frames: the t fit of each frame's signed
/// β_k, written to `out` as CSV; returns a JSON summary.
pub fn earth_calibrate(
    frames: &[std::path::PathBuf],
    tool: &EarthTool,
    out: &Path,
) -> Result<String> {
    let mut core = tool.core(None);
    let mut fits = vec![];
    let mut rows = vec![];
    for path in frames {
        let img = read_frame(path)?;
        let r = core
            .process(&img.pixels, img.width, img.height)
            .map_err(|e| anyhow!("{}: {e}", path.display()))?;
        let f = r.fit.ok_or_else(|| {
            anyhow!(
                "{}: {} edge points gave {} angle samples: no limb found to calibrate on",
                path.display(),
                r.edge_points,
                r.samples
            )
        })?;
        fits.push((f.mu, f.sigma));
        rows.push(json!({"file": path.display().to_string(), "mu_deg": f.mu, "sigma_deg": f.sigma, "nu": f.nu}));
    }
    let table = glint_earth::estimate::SigmaTable::from_fits(&fits);
    std::fs::write(out, table.to_csv()).with_context(|| format!("writing {}", out.display()))?;
    Ok(serde_json::to_string_pretty(&json!({
        "table": out.display().to_string(),
        "angles": table.points.len(),
        "frames": rows,
    }))?)
}

/// `glint tool …`.
pub(crate) fn command(tool: crate::cli::ToolCmd) -> std::process::ExitCode {
    use crate::cli::ToolCmd;
    use std::process::ExitCode;
    let result = match tool {
        ToolCmd::Layouts => serde_json::to_string_pretty(&crate::run::record::layouts_document())
            .map(|j| println!("{j}"))
            .map_err(anyhow::Error::from),
        ToolCmd::Detect { frame, threshold } => {
            detect(&frame, threshold).map(|json| println!("{json}"))
        }
        ToolCmd::Earth {
            frame,
            f_px,
            center,
            lens,
            altitude_km,
            field_deg,
            image_circle_px,
            sigma_table,
        } => EarthTool::new(
            f_px,
            center,
            lens.as_deref(),
            altitude_km,
            field_deg,
            image_circle_px,
        )
        .and_then(|tool| earth(&frame, &tool, sigma_table.as_deref()))
        .map(|j| println!("{j}")),
        ToolCmd::EarthCalibrate {
            frames,
            scenario,
            images,
            f_px,
            center,
            lens,
            altitude_km,
            field_deg,
            image_circle_px,
            out,
        } => match scenario {
            Some(file) => match Scenario::from_file(&file) {
                Ok(sc) => earth_calibrate_scenario(&sc, images, &out).map(|j| println!("{j}")),
                Err(e) => Err(anyhow::anyhow!("{e}")),
            },
            None => EarthTool::new(
                f_px,
                center,
                lens.as_deref(),
                altitude_km,
                field_deg,
                image_circle_px,
            )
            .and_then(|tool| earth_calibrate(&frames, &tool, &out))
            .map(|j| println!("{j}")),
        },
        ToolCmd::Tfit { samples } => tfit(&samples).map(|json| println!("{json}")),
        ToolCmd::Photometry { lc, shapes, out } => {
            photometry::run(&lc, &shapes, &out).map(|json| println!("{json}"))
        }
        ToolCmd::Relnav { meas, rig, out } => {
            relnav::run(&meas, &rig, &out).map(|json| println!("{json}"))
        }
        ToolCmd::Render {
            scenario,
            frame,
            out,
            seed,
            earth,
        } => match Scenario::from_file(&scenario) {
            Ok(mut sc) => {
                if let Some(s) = seed {
                    sc.seed = s;
                }
                render(&sc, frame, &out, earth)
            }
            Err(e) => Err(anyhow::anyhow!("{e}")),
        },
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
    }
}
