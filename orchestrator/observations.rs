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
use serde::Deserialize;
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

/// One data row by position: the ten fixed columns, then every flux_ and sigma_ value.
#[derive(Deserialize)]
struct Row(
    String,
    u64,
    f64,
    f64,
    f64,
    f64,
    f64,
    f64,
    f64,
    f64,
    Vec<f64>,
);

/// Parses the text of an observation file (`file` names it in errors). Records are read by the
/// `csv` crate (fields trimmed, '#' lines skipped); the `truth_rate_deg_per_frame` comment is
/// picked out of the comment lines first.
pub fn parse(text: &str, file: &str) -> Result<ObservationFile> {
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
    let mut header: Option<Vec<String>> = None;
    let mut set = ObservationSet::default();
    let (mut n_flux, mut has_sigma) = (0usize, false);
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
        let row: Row = record
            .deserialize(None)
            .map_err(|e| cell_error(&e, &cells, cols, file, line_no))?;
        let Row(window, frame_index, t_s, sx, sy, sz, ox, oy, oz, range_m, values) = row;
        let finite = |k: usize, v: f64| -> Result<f64> {
            if !v.is_finite() {
                bail!(
                    "{file}:{line_no}: column `{}`: not a finite number",
                    cols[k]
                );
            }
            Ok(v)
        };
        let fixed = [t_s, sx, sy, sz, ox, oy, oz, range_m];
        for (k, v) in fixed.into_iter().enumerate() {
            finite(k + 2, v)?;
        }
        for (k, v) in values.iter().enumerate() {
            finite(FIXED.len() + k, *v)?;
        }
        let unit = |k: usize, v: Vector3<f64>| -> Result<Vector3<f64>> {
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
        if range_m <= 0.0 {
            bail!("{file}:{line_no}: column `range_m`: must be > 0");
        }
        let (flux_w, sigma_w) = values.split_at(n_flux);
        let obs = Observation {
            frame_index,
            t_s,
            sun_body: unit(3, Vector3::new(sx, sy, sz))?,
            observer_body: unit(6, Vector3::new(ox, oy, oz))?,
            range_m,
            flux_w: flux_w.to_vec(),
            // All-zero σ means noise-free data: leave the weights to the residuals.
            sigma_w: if sigma_w.iter().all(|s| *s == 0.0) {
                vec![]
            } else {
                sigma_w.to_vec()
            },
        };
        match window.as_str() {
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

/// The message for a cell that does not deserialize: file, line, column name and what it allows.
fn cell_error(
    e: &csv::Error,
    cells: &[&str],
    cols: &[String],
    file: &str,
    line_no: u64,
) -> anyhow::Error {
    let field = match e.kind() {
        csv::ErrorKind::Deserialize { err, .. } => err.field(),
        _ => None,
    };
    let Some(k) = field.map(|k| k as usize).filter(|k| *k < cells.len()) else {
        return anyhow!("{file}:{line_no}: {e}");
    };
    let (col, v) = (&cols[k], cells[k]);
    match k {
        1 => anyhow!("{file}:{line_no}: column `{col}`: `{v}` is not a whole number"),
        _ => anyhow!("{file}:{line_no}: column `{col}`: `{v}` is not a number"),
    }
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

    #[test]
    fn comments_blank_lines_and_crlf_keep_line_numbers() {
        let text = GOOD.replace('\n', "\r\n").replacen(
            "window,",
            "\r\n  # an indented comment, with \"quotes\r\n\r\nwindow,",
            1,
        );
        let f = parse(&text, "obs.csv").unwrap();
        assert_eq!((f.set.stable.len(), f.set.motion.len()), (1, 1));
        assert_eq!(f.truth_rate_deg_per_frame, Some([0.0, 0.25, 0.0]));
        let bad = text.replace("motion,0,10.0", "motion,x,10.0");
        let e = parse(&bad, "obs.csv").err().unwrap().to_string();
        assert!(
            e.contains("obs.csv:8") && e.contains("frame_index") && e.contains("whole number"),
            "{e}"
        );
        let bad = text.replace("motion,0,10.0", "motion,0,inf");
        let e = parse(&bad, "obs.csv").err().unwrap().to_string();
        assert!(e.contains("obs.csv:8") && e.contains("t_s"), "{e}");
        let bad = text.replace("window,frame_index", "win,frame_index");
        let e = parse(&bad, "obs.csv").err().unwrap().to_string();
        assert!(e.contains("obs.csv:6") && e.contains("header"), "{e}");
        let bad = text.replace("2e-14\r\n", "2e-14,5\r\n");
        let e = parse(&bad, "obs.csv").err().unwrap().to_string();
        assert!(e.contains("obs.csv:7") && e.contains("13 values"), "{e}");
    }

    #[test]
    fn exported_spectra_read_back_to_the_bit() {
        let mut sp = Spectrum {
            n_bands: 2,
            window: Window::Stable as u32,
            sun_body: [0.6, 0.0, 0.8],
            observer_body: [0.0, 1.0, 0.0],
            range_m: 2_146_000.123,
            ..Default::default()
        };
        sp.meta.t_ns = 18_437_087_945;
        sp.wavelength_nm[..2].copy_from_slice(&[650.0, 700.0]);
        sp.flux_w[..2].copy_from_slice(&[1.234_567_890_123e-14, 2.0 / 3.0 * 1e-14]);
        sp.sigma_w[..2].copy_from_slice(&[1e-16, 3e-16]);
        let motion = Spectrum {
            window: Window::Motion as u32,
            frame_index: 3,
            ..sp
        };
        let dir = std::env::temp_dir().join(format!("glint-obs-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("observations.csv");
        write(&path, &[sp, motion], Some([0.0, 0.25, 0.0])).unwrap();
        let f = read(&path).unwrap();
        let _ = std::fs::remove_dir_all(&dir);
        let o = &f.set.motion[0];
        assert_eq!(o.frame_index, 3);
        assert_eq!(o.flux_w, sp.flux_w[..2].to_vec());
        assert_eq!(o.sigma_w, sp.sigma_w[..2].to_vec());
        assert_eq!(o.range_m, sp.range_m);
        assert_eq!(o.t_s, sp.meta.t_ns as f64 * 1e-9);
        assert_eq!(f.set.wavelengths_nm, vec![650.0, 700.0]);
        assert_eq!(f.truth_rate_deg_per_frame, Some([0.0, 0.25, 0.0]));
    }
}
