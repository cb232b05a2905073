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

mod columns;
mod noise;
use columns::{columns, Columns};

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
    /// Header columns glint does not read (named to the user).
    pub ignored_columns: Vec<String>,
    /// Each band's σ [W] estimated from the light curve's scatter, per window (stable,
    /// motion), when the file has no `sigma_*` columns (used to tell noise from a flux that
    /// cannot be).
    pub estimated_sigma_w: Option<[Vec<f64>; 2]>,
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

/// Largest observation file read \[bytes\]: 36 bands × 1440 rows take 1 MB.
pub const MAX_FILE_BYTES: u64 = 256 << 20;
/// Band centres accepted \[nm\]: ultraviolet to thermal infrared.
pub const WAVELENGTH_RANGE_NM: (f64, f64) = (200.0, 25_000.0);
/// Largest frame index accepted (a billion frames: 30 years at one a second).
pub const MAX_FRAME_INDEX: u64 = 1_000_000_000;
/// A flux below −this × σ is not noise about a positive flux: refused.
const MAX_NEGATIVE_SIGMAS: f64 = 5.0;

/// Reads an observation file; every problem names the file, the line and the column.
pub fn read(path: &Path) -> Result<ObservationFile> {
    let text = shared_types::input::read_text_capped(path, MAX_FILE_BYTES)
        .map_err(|e| anyhow!("{}: {e}", path.display()))?;
    parse(&text, &path.display().to_string())
}

/// Parses the text of an observation file (`file` names it in errors). Records are read by the
/// `csv` crate (fields trimmed, '#' lines skipped); the `truth_rate_deg_per_frame` comment is
/// picked out of the comment lines first. Columns are found by name, in any order.
pub fn parse(text: &str, file: &str) -> Result<ObservationFile> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut truth = None;
    for (i, raw) in text.lines().enumerate() {
        if let Some(comment) = raw.trim().strip_prefix('#') {
            if let Some(v) = comment.trim().strip_prefix("truth_rate_deg_per_frame") {
                truth = Some(parse_truth(v, file, i + 1)?);
            }
        }
    }
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .trim(csv::Trim::All)
        .comment(Some(b'#'))
        .from_reader(text.as_bytes());
    let mut header: Option<Columns> = None;
    let mut set = ObservationSet::default();
    // Without σ columns: per window, each band's lowest flux and its line, held to the σ
    // estimated from the whole file after.
    let mut lowest: [Vec<(f64, u64)>; 2] = [vec![], vec![]];
    let mut record = csv::StringRecord::new();
    // Line numbers come from byte offsets: csv's own counter loses a line per blank CRLF line.
    let mut lines = LineCounter::new(text);
    loop {
        match reader.read_record(&mut record) {
            Ok(true) => {}
            Ok(false) => break,
            Err(e) => {
                let line = lines.at(e.position().map_or(0, |p| p.byte()));
                bail!("{file}:{line}: {e}");
            }
        }
        let line_no = lines.at(record.position().map_or(0, |p| p.byte()));
        // Blank lines (whitespace only) and comments indented past column 1.
        if record.iter().all(str::is_empty) || record[0].starts_with('#') {
            continue;
        }
        let cells: Vec<&str> = record.iter().collect();
        let Some(cols) = &header else {
            let (c, wavelengths) = columns(&cells, file, line_no)?;
            set.wavelengths_nm = wavelengths;
            header = Some(c);
            continue;
        };
        if cells.len() != cols.names.len() {
            bail!(
                "{file}:{line_no}: {} values, the header has {}",
                cells.len(),
                cols.names.len()
            );
        }
        let (obs, window) = row(&cells, cols, file, line_no)?;
        if cols.sigma.is_empty() {
            let lowest = &mut lowest[window as usize];
            lowest.resize(obs.flux_w.len(), (f64::INFINITY, 0));
            for (low, &f) in lowest.iter_mut().zip(&obs.flux_w) {
                if f < low.0 {
                    *low = (f, line_no);
                }
            }
        }
        match window {
            Window::Stable => set.stable.push(obs),
            Window::Motion => set.motion.push(obs),
        }
    }
    let Some(cols) = header else {
        bail!("{file}: no header line");
    };
    if set.stable.is_empty() || set.motion.is_empty() {
        bail!(
            "{file}: needs rows of both windows (stable: {}, motion: {})",
            set.stable.len(),
            set.motion.len()
        );
    }
    let bands = set.wavelengths_nm.len();
    let estimated_sigma_w = (cols.sigma.is_empty())
        .then(|| [&set.stable, &set.motion].map(|rows| noise::estimate_sigma_w(rows, bands)));
    let held = (lowest.iter())
        .zip(estimated_sigma_w.iter().flatten())
        .flat_map(|(low, sigma)| low.iter().zip(sigma).enumerate());
    for (b, (&(flux, line), sigma)) in held {
        if flux < 0.0 && *sigma == 0.0 {
            bail!(
                "{file}:{line}: column `{}`: flux {flux} W is negative, and the file has no \
                 sigma_* columns and too few rows in this window (3 or more, not all on one \
                 line) to estimate its noise: give sigma_* columns",
                cols.names[cols.flux[b]]
            );
        }
        if flux < -MAX_NEGATIVE_SIGMAS * sigma {
            bail!(
                "{file}:{line}: column `{}`: flux {flux} W is negative beyond the noise: below \
                 −{MAX_NEGATIVE_SIGMAS}σ, with σ = {sigma:.3e} W estimated from the light curve's \
                 scatter (the file has no sigma_* columns; give them if its noise is larger)",
                cols.names[cols.flux[b]]
            );
        }
    }
    Ok(ObservationFile {
        set,
        truth_rate_deg_per_frame: truth,
        ignored_columns: cols.ignored,
        estimated_sigma_w,
    })
}

/// One data row: the observation and its window.
fn row(cells: &[&str], cols: &Columns, file: &str, line: u64) -> Result<(Observation, Window)> {
    let at = |k: usize| (cols.names[k].as_str(), cells[k]);
    let number = |k: usize| -> Result<f64> {
        let (name, v) = at(k);
        let x: f64 = v
            .parse()
            .map_err(|_| anyhow!("{file}:{line}: column `{name}`: `{v}` is not a number"))?;
        if !x.is_finite() {
            bail!("{file}:{line}: column `{name}`: `{v}` is not a finite number");
        }
        Ok(x)
    };
    let [window, frame, t, sx, sy, sz, ox, oy, oz, range] = cols.fixed;
    let window = match at(window).1 {
        "stable" => Window::Stable,
        "motion" => Window::Motion,
        other => bail!(
            "{file}:{line}: column `{}`: `{other}` (allowed: stable, motion)",
            at(window).0
        ),
    };
    let (frame_name, frame_text) = at(frame);
    let frame_index: u64 = frame_text
        .parse()
        .ok()
        .filter(|f| *f <= MAX_FRAME_INDEX)
        .ok_or_else(|| {
            anyhow!("{file}:{line}: column `{frame_name}`: `{frame_text}` is not a whole number in 0..={MAX_FRAME_INDEX}")
        })?;
    let unit = |k: [usize; 3]| -> Result<Vector3<f64>> {
        let v = Vector3::new(number(k[0])?, number(k[1])?, number(k[2])?);
        if (v.norm() - 1.0).abs() > 1e-6 {
            bail!(
                "{file}:{line}: columns `{}`..`{}`: not a unit vector (norm {})",
                at(k[0]).0,
                at(k[2]).0,
                v.norm()
            );
        }
        Ok(v)
    };
    let range_m = number(range)?;
    if range_m <= 0.0 {
        bail!("{file}:{line}: column `{}`: must be > 0", at(range).0);
    }
    let flux_w: Vec<f64> = cols
        .flux
        .iter()
        .map(|&k| number(k))
        .collect::<Result<_>>()?;
    let sigma_w: Vec<f64> = cols
        .sigma
        .iter()
        .map(|&k| number(k))
        .collect::<Result<_>>()?;
    // All-zero σ means noise-free data: leave the weights to the residuals.
    let noise_free = sigma_w.iter().all(|s| *s == 0.0);
    for (b, &k) in cols.sigma.iter().enumerate() {
        if !noise_free && sigma_w[b] <= 0.0 {
            bail!(
                "{file}:{line}: column `{}`: σ {} must be > 0 (or 0 in every band of noise-free data)",
                at(k).0,
                sigma_w[b]
            );
        }
    }
    for (b, &k) in cols.flux.iter().enumerate() {
        // Without σ columns, the floor comes from the σ the whole file gives (after it is read).
        let floor = if cols.sigma.is_empty() {
            f64::NEG_INFINITY
        } else if noise_free {
            0.0
        } else {
            -MAX_NEGATIVE_SIGMAS * sigma_w[b]
        };
        if flux_w[b] < floor {
            bail!(
                "{file}:{line}: column `{}`: flux {} W is negative beyond the noise (allowed ≥ −{MAX_NEGATIVE_SIGMAS}σ; σ all 0 declares noise-free data, ≥ 0)",
                at(k).0,
                flux_w[b]
            );
        }
    }
    let obs = Observation {
        frame_index,
        t_s: number(t)?,
        sun_body: unit([sx, sy, sz])?,
        observer_body: unit([ox, oy, oz])?,
        range_m,
        flux_w,
        sigma_w: if noise_free { vec![] } else { sigma_w },
    };
    Ok((obs, window))
}

/// 1-based line numbers of csv record positions, for positions met in increasing order. A
/// record's position can sit before the line terminator that precedes it, or before the blank
/// and comment lines csv skipped to reach it, so those are stepped over first.
struct LineCounter<'a> {
    text: &'a [u8],
    byte: usize,
    line: u64,
}

impl<'a> LineCounter<'a> {
    fn new(text: &'a str) -> Self {
        Self {
            text: text.as_bytes(),
            byte: 0,
            line: 1,
        }
    }

    fn at(&mut self, byte: u64) -> u64 {
        let t = self.text;
        let mut i = usize::try_from(byte).unwrap_or(usize::MAX).min(t.len());
        loop {
            while i < t.len() && matches!(t[i], b'\r' | b'\n') {
                i += 1;
            }
            let line_start = i == 0 || t[i - 1] == b'\n';
            if !(line_start && t.get(i) == Some(&b'#')) {
                break;
            }
            while i < t.len() && t[i] != b'\n' {
                i += 1;
            }
        }
        if i < self.byte {
            (self.byte, self.line) = (0, 1);
        }
        self.line += t[self.byte..i].iter().filter(|&&b| b == b'\n').count() as u64;
        self.byte = i;
        self.line
    }
}

/// `# truth_rate_deg_per_frame = a,b,c` (the text after the key).
fn parse_truth(v: &str, file: &str, line_no: usize) -> Result<[f64; 3]> {
    let v = v.trim().trim_start_matches('=').trim();
    let p: Vec<f64> = v
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| anyhow!("{file}:{line_no}: truth_rate_deg_per_frame must be three numbers"))?;
    if p.len() != 3 || p.iter().any(|x| !x.is_finite()) {
        bail!("{file}:{line_no}: truth_rate_deg_per_frame must be three finite numbers");
    }
    Ok([p[0], p[1], p[2]])
}

#[cfg(test)]
mod tests;
