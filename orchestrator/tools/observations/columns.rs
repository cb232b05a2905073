//! The header of an observation file: each column found by name (case aside, common
//! spellings too), in any order; the bands from `flux_<nm>` / `sigma_<nm>`; the columns glint
//! does not read, named back to the user.

use anyhow::{anyhow, bail, Result};

use super::WAVELENGTH_RANGE_NM;

/// The fixed columns and the names they are also known by (matched without case).
const ALIASES: [(&str, &[&str]); 10] = [
    ("window", &["window", "segment"]),
    (
        "frame_index",
        &["frame_index", "frame", "frame_no", "index"],
    ),
    ("t_s", &["t_s", "t", "time", "time_s"]),
    ("sun_x", &["sun_x", "sx", "s_x"]),
    ("sun_y", &["sun_y", "sy", "s_y"]),
    ("sun_z", &["sun_z", "sz", "s_z"]),
    ("obs_x", &["obs_x", "ox", "o_x", "observer_x"]),
    ("obs_y", &["obs_y", "oy", "o_y", "observer_y"]),
    ("obs_z", &["obs_z", "oz", "o_z", "observer_z"]),
    ("range_m", &["range_m", "range", "r_m"]),
];

/// Where each column of the file goes.
pub(super) struct Columns {
    /// Position of each fixed column (in [`ALIASES`] order).
    pub fixed: [usize; 10],
    /// Position of each band's flux and σ, by band.
    pub flux: Vec<usize>,
    pub sigma: Vec<usize>,
    /// The header's names, for messages.
    pub names: Vec<String>,
    /// Columns read by nobody.
    pub ignored: Vec<String>,
}

/// `flux_<nm>` / `sigma_<nm>` (also `flux<nm>`, `err_<nm>`, `flux_err_<nm>`, `sigma<nm>`):
/// the kind and the wavelength text.
fn band_column(name: &str) -> Option<(bool, &str)> {
    for (prefix, is_flux) in [
        ("flux_err_", false),
        ("sigma_", false),
        ("err_", false),
        ("sigma", false),
        ("flux_", true),
        ("flux", true),
    ] {
        if let Some(w) = name.strip_prefix(prefix) {
            return Some((is_flux, w));
        }
    }
    None
}

pub(super) fn columns(cells: &[&str], file: &str, line: u64) -> Result<(Columns, Vec<f64>)> {
    let names: Vec<String> = cells.iter().map(|c| c.to_string()).collect();
    let mut fixed = [usize::MAX; 10];
    let mut bands: Vec<(f64, Option<usize>, Option<usize>)> = vec![];
    let mut ignored = vec![];
    for (k, raw) in cells.iter().enumerate() {
        let name = raw.to_ascii_lowercase();
        if let Some(slot) = ALIASES.iter().position(|(_, a)| a.contains(&name.as_str())) {
            if fixed[slot] != usize::MAX {
                bail!(
                    "{file}:{line}: columns {} (`{}`) and {} (`{raw}`) are both `{}`",
                    fixed[slot] + 1,
                    cells[fixed[slot]],
                    k + 1,
                    ALIASES[slot].0
                );
            }
            fixed[slot] = k;
        } else if let Some((is_flux, w)) = band_column(&name) {
            let (lo, hi) = WAVELENGTH_RANGE_NM;
            let nm: f64 = w
                .parse()
                .ok()
                .filter(|v: &f64| v.is_finite() && (lo..=hi).contains(v))
                .ok_or_else(|| {
                    anyhow!("{file}:{line}: column {} `{raw}`: the band centre must be a number of nm in {lo}..={hi}", k + 1)
                })?;
            let band = match bands.iter().position(|b| b.0 == nm) {
                Some(i) => i,
                None => {
                    bands.push((nm, None, None));
                    bands.len() - 1
                }
            };
            let slot = if is_flux {
                &mut bands[band].1
            } else {
                &mut bands[band].2
            };
            if let Some(other) = *slot {
                bail!(
                    "{file}:{line}: columns {} (`{}`) and {} (`{raw}`) are the same band",
                    other + 1,
                    cells[other],
                    k + 1
                );
            }
            *slot = Some(k);
        } else {
            ignored.push(raw.to_string());
        }
    }
    if let Some(slot) = fixed.iter().position(|&k| k == usize::MAX) {
        let (name, aliases) = ALIASES[slot];
        bail!(
            "{file}:{line}: no `{name}` column (also read as: {}); the header needs {} and flux_<nm> columns",
            aliases[1..].join(", "),
            ALIASES.map(|a| a.0).join(", ")
        );
    }
    if bands.is_empty() {
        bail!("{file}:{line}: no flux_<nm> column");
    }
    let with_sigma = bands.iter().filter(|b| b.2.is_some()).count();
    if let Some(b) = bands.iter().find(|b| b.1.is_none()) {
        bail!(
            "{file}:{line}: column `{}` has no flux column of its band",
            cells[b.2.unwrap_or(0)]
        );
    }
    if with_sigma != 0 && with_sigma != bands.len() {
        bail!("{file}:{line}: give one sigma_<nm> column per flux_<nm> column, or none");
    }
    let wavelengths = bands.iter().map(|b| b.0).collect();
    Ok((
        Columns {
            fixed,
            flux: bands.iter().filter_map(|b| b.1).collect(),
            sigma: bands.iter().filter_map(|b| b.2).collect(),
            names,
            ignored,
        },
        wavelengths,
    ))
}
