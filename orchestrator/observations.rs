//! The observation file of `glint invert` (and `observations.csv` of every run with spectra):
//! how a user brings real light curves to the three-stage solve.
//!
//! ```text
//! # glint observations v1            ← comment lines start with '#'
//! # truth_rate_deg_per_frame = 0,0.25,0   (optional: enables the paper's error metric)
//! window,frame_index,t_s,sun_x,sun_y,sun_z,obs_x,obs_y,obs_z,range_m,flux_400,flux_410,…,sigma_400,…
//! stable,0,0.000,0.31,0.0,-0.95,0.999,0.0,-0.045,2146000.0,1.2e-14,…
//! motion,0,…
//! ```
//!
//! - `window`: `stable` (three-axis stable; stage 1) or `motion` (stage 3).
//! - `frame_index`: frame counter; in the motion window, frame 0 is the frame before the motion
//!   starts (all rotation angles 0).
//! - `sun_*`, `obs_*`: unit vectors target → Sun and target → observer in the body frame at rest.
//! - `range_m`: target–observer distance [m].
//! - `flux_<nm>`: band-integrated flux [W] of the band centred at <nm>; one column per band.
//! - `sigma_<nm>` (optional, all or none): 1σ noise of that flux [W].

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{anyhow, bail, Context, Result};
use glint_inversion::{Observation, ObservationSet};
use nalgebra::Vector3;
use shared_types::{Spectrum, Window};

const FIXED: [&str; 10] = [
    "window",
    "frame_index",
    "t_s",
    "sun_x",
    "sun_y",
    "sun_z",
    "obs_x",
    "obs_y",
    "obs_z",
    "range_m",
];

/// Observations read from a file, with the optional truth.
pub struct ObservationFile {
    pub set: ObservationSet,
    pub truth_rate_deg_per_frame: Option<[f64; 3]>,
}

/// Writes spectra (as received in a run) in the observation format.
pub fn write(path: &Path, spectra: &[Spectrum], truth: Option<[f64; 3]>) -> Result<()> {
    let Some(first) = spectra.first() else {
        return Ok(());
    };
    let n = first.n_bands as usize;
    let mut s = String::from("# glint observations v1\n");
    if let Some(p) = truth {
        let _ = writeln!(s, "# truth_rate_deg_per_frame = {},{},{}", p[0], p[1], p[2]);
    }
    s.push_str(&FIXED.join(","));
    for prefix in ["flux", "sigma"] {
        for w in &first.wavelength_nm[..n] {
            let _ = write!(s, ",{prefix}_{w}");
        }
    }
    s.push('\n');
    for sp in spectra {
        let window = if sp.window == Window::Stable as u32 {
            "stable"
        } else {
            "motion"
        };
        let _ = write!(
            s,
            "{window},{},{:?},{:?},{:?},{:?},{:?},{:?},{:?},{:?}",
            sp.frame_index,
            sp.meta.t_ns as f64 * 1e-9,
            sp.sun_body[0],
            sp.sun_body[1],
            sp.sun_body[2],
            sp.observer_body[0],
            sp.observer_body[1],
            sp.observer_body[2],
            sp.range_m
        );
        for v in sp.flux_w[..n].iter().chain(sp.sigma_w[..n].iter()) {
            let _ = write!(s, ",{v:?}");
        }
        s.push('\n');
    }
    std::fs::write(path, s).with_context(|| format!("writing {}", path.display()))
}

/// Reads an observation file; every problem names the file, the line and the column.
pub fn read(path: &Path) -> Result<ObservationFile> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read", path.display()))?;
    parse(&text, &path.display().to_string())
}

pub fn parse(text: &str, file: &str) -> Result<ObservationFile> {
    let mut truth = None;
    let mut header: Option<Vec<String>> = None;
    let mut set = ObservationSet::default();
    let (mut n_flux, mut has_sigma) = (0usize, false);
    for (i, raw) in text.lines().enumerate() {
        let line_no = i + 1;
        let line = raw.trim();
        if line.is_empty() {
            continue;
        }
        if let Some(comment) = line.strip_prefix('#') {
            if let Some(v) = comment.trim().strip_prefix("truth_rate_deg_per_frame") {
                let v = v.trim().trim_start_matches('=').trim();
                let p: Vec<f64> = v
                    .split(',')
                    .map(|x| x.trim().parse::<f64>())
                    .collect::<Result<_, _>>()
                    .map_err(|_| {
                        anyhow!("{file}:{line_no}: truth_rate_deg_per_frame must be three numbers")
                    })?;
                if p.len() != 3 || p.iter().any(|x| !x.is_finite()) {
                    bail!(
                        "{file}:{line_no}: truth_rate_deg_per_frame must be three finite numbers"
                    );
                }
                truth = Some([p[0], p[1], p[2]]);
            }
            continue;
        }
        let cells: Vec<&str> = line.split(',').map(str::trim).collect();
        let Some(cols) = &header else {
            if cells.len() < FIXED.len() + 1 || cells[..FIXED.len()] != FIXED {
                bail!(
                    "{file}:{line_no}: header must start with {} followed by flux_<nm> columns",
                    FIXED.join(",")
                );
            }
            for c in &cells[FIXED.len()..] {
                if let Some(w) = c.strip_prefix("flux_") {
                    if has_sigma {
                        bail!("{file}:{line_no}: flux_ columns must come before sigma_ columns");
                    }
                    let w: f64 = w.parse().map_err(|_| {
                        anyhow!("{file}:{line_no}: column `{c}`: wavelength is not a number")
                    })?;
                    set.wavelengths_nm.push(w);
                    n_flux += 1;
                } else if c.starts_with("sigma_") {
                    has_sigma = true;
                } else {
                    bail!(
                        "{file}:{line_no}: unknown column `{c}` (allowed: flux_<nm>, sigma_<nm>)"
                    );
                }
            }
            if has_sigma && cells.len() != FIXED.len() + 2 * n_flux {
                bail!("{file}:{line_no}: give one sigma_<nm> column per flux_<nm> column, or none");
            }
            header = Some(cells.iter().map(|c| c.to_string()).collect());
            continue;
        };
        if cells.len() != cols.len() {
            bail!(
                "{file}:{line_no}: {} values, the header has {}",
                cells.len(),
                cols.len()
            );
        }
        let num = |k: usize| -> Result<f64> {
            let v: f64 = cells[k].parse().map_err(|_| {
                anyhow!(
                    "{file}:{line_no}: column `{}`: `{}` is not a number",
                    cols[k],
                    cells[k]
                )
            })?;
            if !v.is_finite() {
                bail!(
                    "{file}:{line_no}: column `{}`: not a finite number",
                    cols[k]
                );
            }
            Ok(v)
        };
        let frame_index: u64 = cells[1].parse().map_err(|_| {
            anyhow!(
                "{file}:{line_no}: column `frame_index`: `{}` is not a whole number",
                cells[1]
            )
        })?;
        let unit = |k: usize| -> Result<Vector3<f64>> {
            let v = Vector3::new(num(k)?, num(k + 1)?, num(k + 2)?);
            if (v.norm() - 1.0).abs() > 1e-6 {
                bail!(
                    "{file}:{line_no}: columns `{}`..`{}`: not a unit vector (norm {})",
                    cols[k],
                    cols[k + 2],
                    v.norm()
                );
            }
            Ok(v)
        };
        let range_m = num(9)?;
        if range_m <= 0.0 {
            bail!("{file}:{line_no}: column `range_m`: must be > 0");
        }
        let flux_w = (0..n_flux)
            .map(|b| num(FIXED.len() + b))
            .collect::<Result<Vec<_>>>()?;
        let sigma_w = if has_sigma {
            (0..n_flux)
                .map(|b| num(FIXED.len() + n_flux + b))
                .collect::<Result<Vec<_>>>()?
        } else {
            vec![]
        };
        let obs = Observation {
            frame_index,
            t_s: num(2)?,
            sun_body: unit(3)?,
            observer_body: unit(6)?,
            range_m,
            flux_w,
            // All-zero σ means noise-free data: leave the weights to the residuals.
            sigma_w: if sigma_w.iter().all(|s| *s == 0.0) {
                vec![]
            } else {
                sigma_w
            },
        };
        match cells[0] {
            "stable" => set.stable.push(obs),
            "motion" => set.motion.push(obs),
            other => {
                bail!("{file}:{line_no}: column `window`: `{other}` (allowed: stable, motion)")
            }
        }
    }
    if header.is_none() {
        bail!("{file}: no header line");
    }
    if set.stable.is_empty() || set.motion.is_empty() {
        bail!(
            "{file}: needs rows of both windows (stable: {}, motion: {})",
            set.stable.len(),
            set.motion.len()
        );
    }
    Ok(ObservationFile {
        set,
        truth_rate_deg_per_frame: truth,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = "# glint observations v1\n# truth_rate_deg_per_frame = 0,0.25,0\nwindow,frame_index,t_s,sun_x,sun_y,sun_z,obs_x,obs_y,obs_z,range_m,flux_650,flux_700\nstable,0,0.0,1,0,0,0,0,1,2.1e6,1e-14,2e-14\nmotion,0,10.0,1,0,0,0,0,1,2.1e6,3e-14,4e-14\n";

    #[test]
    fn parses_windows_bands_and_truth() {
        let f = parse(GOOD, "obs.csv").unwrap();
        assert_eq!(f.set.wavelengths_nm, vec![650.0, 700.0]);
        assert_eq!((f.set.stable.len(), f.set.motion.len()), (1, 1));
        assert_eq!(f.set.motion[0].flux_w, vec![3e-14, 4e-14]);
        assert_eq!(f.truth_rate_deg_per_frame, Some([0.0, 0.25, 0.0]));
    }

    #[test]
    fn errors_name_file_line_and_column() {
        let bad = GOOD.replace("stable,0,0.0,1,0,0", "stable,0,0.0,2,0,0");
        let e = parse(&bad, "obs.csv").err().unwrap().to_string();
        assert!(e.contains("obs.csv:4") && e.contains("sun_x"), "{e}");
        let bad = GOOD.replace("1e-14,2e-14", "1e-14,abc");
        let e = parse(&bad, "obs.csv").err().unwrap().to_string();
        assert!(e.contains("obs.csv:4") && e.contains("flux_700"), "{e}");
        let bad = GOOD.replace("motion,0", "moving,0");
        let e = parse(&bad, "obs.csv").err().unwrap().to_string();
        assert!(e.contains("window") && e.contains("moving"), "{e}");
    }
}
