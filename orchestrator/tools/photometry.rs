//! `glint tool photometry LC.csv --shapes SHAPES.toml [--out DIR]`: the [001] chain on a light
//! curve and the user's shapes (formats fixed in docs/photometry.md, so files other tools
//! write are read as they are): the geometry, spin axis, rate and size by the database
//! (math.md §2.5–2.7), then the attitude by the UKF (§2.9) started from the best match.
//!
//! SHAPES.toml: `[[shape]]` tables of `name`, `obj` (a Wavefront OBJ file, relative to the TOML
//! file) and `material = { r_diff, r_spec, n_u, n_v }`.
//!
//! LC.csv: `t_s, mag, sigma_mag, sun_x, sun_y, sun_z, obs_x, obs_y, obs_z, range_m`, columns
//! found by name, `#` comment lines; samples in shadow or without flux are simply absent.
//!
//! Writes `DIR/identification.json` and `DIR/attitude.csv`; prints the identification.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{anyhow, bail, Context, Result};
use glint_photometry::service_core::{identify_samples, scaled_shape, start_filter};
use glint_photometry::{Sample, UkfSettings};
use glint_physics::photometry::SpecularDenominator;
use nalgebra::Vector3;
use serde_json::json;

/// Header of `attitude.csv`.
pub const ATTITUDE_HEADER: &str =
    "t_s,qw,qx,qy,qz,wx,wy,wz,sig_th_x,sig_th_y,sig_th_z,sig_w_x,sig_w_y,sig_w_z";

pub use glint_photometry::shapes::read_shapes;

/// Reads LC.csv in time order; every problem names the file, the line and the column.
pub fn read_light_curve(path: &Path) -> Result<Vec<Sample>> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let file = path.display();
    let mut lines = (text.lines().enumerate())
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
    const COLUMNS: [&str; 10] = [
        "t_s",
        "mag",
        "sigma_mag",
        "sun_x",
        "sun_y",
        "sun_z",
        "obs_x",
        "obs_y",
        "obs_z",
        "range_m",
    ];
    let (hline, header) = lines
        .next()
        .ok_or_else(|| anyhow!("{file}: no header line ({})", COLUMNS.join(", ")))?;
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    let mut at = [0usize; 10];
    for (c, name) in COLUMNS.iter().enumerate() {
        at[c] = names.iter().position(|n| n == name).ok_or_else(|| {
            anyhow!(
                "{file}: line {hline}: no column `{name}` in the header (needs {})",
                COLUMNS.join(", ")
            )
        })?;
    }
    let ranges: [(f64, f64); 10] = [
        (-1e12, 1e12),
        (-30.0, 40.0),
        (1e-6, 10.0),
        (-1.0, 1.0),
        (-1.0, 1.0),
        (-1.0, 1.0),
        (-1.0, 1.0),
        (-1.0, 1.0),
        (-1.0, 1.0),
        (1.0, 1e13),
    ];
    let mut samples: Vec<Sample> = vec![];
    for (line, l) in lines {
        let cells: Vec<&str> = l.split(',').map(str::trim).collect();
        if cells.len() != names.len() {
            bail!(
                "{file}: line {line}: {} cells; the header has {}",
                cells.len(),
                names.len()
            );
        }
        let mut v = [0.0; 10];
        for c in 0..10 {
            let s = cells[at[c]];
            let x: f64 = s.parse().map_err(|_| {
                anyhow!(
                    "{file}: line {line}, column `{}`: `{s}` is not a number",
                    COLUMNS[c]
                )
            })?;
            let (lo, hi) = ranges[c];
            if !(x.is_finite() && (lo..=hi).contains(&x)) {
                bail!(
                    "{file}: line {line}, column `{}`: {x} is out of range; allowed {lo}..={hi}",
                    COLUMNS[c]
                );
            }
            v[c] = x;
        }
        let unit = |a: usize, what: &str| -> Result<Vector3<f64>> {
            let u = Vector3::new(v[a], v[a + 1], v[a + 2]);
            if (u.norm() - 1.0).abs() > 1e-3 {
                bail!(
                    "{file}: line {line}: the {what} direction has length {:.6}; allowed 1 ± 1e-3",
                    u.norm()
                );
            }
            Ok(u.normalize())
        };
        samples.push(Sample {
            t_s: v[0],
            mag: v[1],
            sigma_mag: v[2],
            sun: unit(3, "Sun")?,
            obs: unit(6, "observer")?,
            range_m: v[9],
        });
    }
    if samples.len() < 16 {
        bail!(
            "{file}: {} samples; at least 16 are needed for a spin rate",
            samples.len()
        );
    }
    samples.sort_by(|a, b| a.t_s.total_cmp(&b.t_s));
    if let Some(w) = samples.windows(2).find(|w| w[1].t_s == w[0].t_s) {
        bail!("{file}: two samples at t_s = {}", w[0].t_s);
    }
    Ok(samples)
}

/// Identification and the UKF over the light curve; writes the two files, returns the
/// identification as JSON.
pub fn run(lc: &Path, shapes_path: &Path, out: &Path) -> Result<String> {
    let shapes = read_shapes(shapes_path)?;
    let samples = read_light_curve(lc)?;
    let den = SpecularDenominator::Linares2014;
    // The database's one geometry: the arc's mean Sun and observer directions.
    let id = identify_samples(&shapes, &samples, 200, 8, den).ok_or_else(|| {
        anyhow!(
            "{}: no spin line or no database entry fits the light curve",
            lc.display()
        )
    })?;
    let b = &id.best;
    let matching: Vec<_> = id
        .matching
        .iter()
        .map(|m| {
            json!({"geometry": m.geometry, "score": m.score, "area_scale": m.area_scale,
                   "area_m2": m.area_m2, "axis": m.axis.as_slice(), "spin_rad_s": m.spin_rad_s})
        })
        .collect();
    let identification = json!({
        "file": lc.display().to_string(),
        "geometry": b.geometry,
        "axis": b.axis.as_slice(),
        "spin_rad_s": b.spin_rad_s,
        "area_scale": b.area_scale,
        "area_m2": b.area_m2,
        "score": b.score,
        "line_rad_s": id.line_rad_s,
        "matching": matching,
    });
    // The UKF from the best match: its attitude at the first sample, its rate about its axis.
    let shape =
        scaled_shape(&shapes, b).context("the identified geometry is not among the shapes")?;
    let mut ukf = start_filter(b, samples[0].t_s, UkfSettings::default());
    let mut csv = String::from(ATTITUDE_HEADER);
    csv.push('\n');
    let mut failed = None;
    for s in &samples {
        if let Err(e) = ukf.step(&shape, s) {
            failed = Some(format!("at t_s = {}: {e}", s.t_s));
            break;
        }
        let mut q = ukf.q.into_inner();
        if q.w < 0.0 {
            q = -q;
        }
        let sig = ukf.p.diagonal().map(|v| v.max(0.0).sqrt());
        let _ = write!(csv, "{}", s.t_s);
        for v in [q.w, q.i, q.j, q.k]
            .into_iter()
            .chain(ukf.w.iter().copied())
            .chain(sig.iter().copied())
        {
            let _ = write!(csv, ",{v:.12e}");
        }
        csv.push('\n');
    }
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let id_path = out.join("identification.json");
    std::fs::write(
        &id_path,
        serde_json::to_string_pretty(&identification)? + "\n",
    )
    .with_context(|| format!("cannot write {}", id_path.display()))?;
    let att_path = out.join("attitude.csv");
    std::fs::write(&att_path, csv)
        .with_context(|| format!("cannot write {}", att_path.display()))?;
    let mut summary = identification;
    summary["ukf"] = json!({
        "samples": samples.len(),
        "fallbacks_to_gamma_1": ukf.fallbacks,
        "failed": failed,
        "out": att_path.display().to_string(),
    });
    Ok(serde_json::to_string_pretty(&summary)?)
}
