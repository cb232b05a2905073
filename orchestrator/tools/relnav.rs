//! `glint tool relnav MEAS.csv --rig RIG.toml [--out DIR]`: the [004] filter on a file of stereo
//! measurements from a real rig or another simulator (the formats are fixed in
//! docs/relnav.md, so files other tools write are read as they are).
//!
//! RIG.toml: `mean_motion_rad_s`, `baseline_m`, `sigma_norm`, `c_co` (rows: C_CO), `features_m`
//! (feature i in the target principal frame T); optional `torque_psd`, `accel_psd`. No initial
//! state: the filter starts from the measurements.
//!
//! MEAS.csv: `t_s, feature, x_l, y_l, x_r, y_r`, one row per visible feature per epoch, columns
//! found by name (any order; others ignored), `#` comment lines; rows of one `t_s` are one
//! epoch.
//!
//! Writes `DIR/relnav.csv` (one row per epoch once the filter runs: q_ct scalar first with w ≥
//! 0, ω_t, k, ρ, v and the 14 error-state 1σ) and prints a JSON summary, the last estimate
//! first.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{anyhow, bail, Context, Result};
use glint_relnav::model::Rig;
use glint_relnav::{Estimate, FeatureObs, RelNav, Settings, Start};
use nalgebra::{Matrix3, Vector3};
use serde_json::json;

/// Header of `relnav.csv`.
pub const OUTPUT_HEADER: &str = "t_s,qw,qx,qy,qz,wx,wy,wz,k1,k2,rho_x,rho_y,rho_z,v_x,v_y,v_z,\
sig_th_x,sig_th_y,sig_th_z,sig_w_x,sig_w_y,sig_w_z,sig_k1,sig_k2,sig_rho_x,sig_rho_y,sig_rho_z,\
sig_v_x,sig_v_y,sig_v_z";

/// The filter's PSDs when the rig file gives none (the `[stereo.filter]` defaults).
const DEFAULT_TORQUE_PSD: f64 = 1e-12;
const DEFAULT_ACCEL_PSD: f64 = 1e-14;

/// Reads and checks RIG.toml: every problem names the file and the field.
pub fn read_rig(path: &Path) -> Result<Rig> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let file = path.display();
    let table: toml::Table =
        toml::from_str(&text).map_err(|e| anyhow!("{file}: not valid TOML: {e}"))?;
    const KNOWN: [&str; 7] = [
        "mean_motion_rad_s",
        "baseline_m",
        "sigma_norm",
        "c_co",
        "features_m",
        "torque_psd",
        "accel_psd",
    ];
    if let Some(k) = table.keys().find(|k| !KNOWN.contains(&k.as_str())) {
        bail!(
            "{file}: unknown field `{k}` (allowed: {})",
            KNOWN.join(", ")
        );
    }
    let num = |v: &toml::Value, field: &str| -> Result<f64> {
        match v {
            toml::Value::Float(f) => Ok(*f),
            toml::Value::Integer(i) => Ok(*i as f64),
            _ => bail!("{file}: field `{field}`: {v} is not a number"),
        }
    };
    let scalar = |field: &str, lo: f64, hi: f64, default: Option<f64>| -> Result<f64> {
        let v = match (table.get(field), default) {
            (Some(v), _) => num(v, field)?,
            (None, Some(d)) => return Ok(d),
            (None, None) => bail!("{file}: field `{field}` is missing (required)"),
        };
        if !(v.is_finite() && (lo..=hi).contains(&v)) {
            bail!("{file}: field `{field}`: {v} is out of range; allowed {lo:e}..={hi:e}");
        }
        Ok(v)
    };
    let vec3 = |v: &toml::Value, field: &str| -> Result<Vector3<f64>> {
        let a = v
            .as_array()
            .filter(|a| a.len() == 3)
            .ok_or_else(|| anyhow!("{file}: field `{field}`: not an array of 3 numbers"))?;
        let mut out = Vector3::zeros();
        for (i, x) in a.iter().enumerate() {
            out[i] = num(x, &format!("{field}[{i}]"))?;
            if !out[i].is_finite() || out[i].abs() > 1000.0 {
                bail!(
                    "{file}: field `{field}[{i}]`: {} is out of range; allowed -1000..=1000",
                    out[i]
                );
            }
        }
        Ok(out)
    };
    let c_co_rows = table
        .get("c_co")
        .and_then(|v| v.as_array())
        .filter(|a| a.len() == 3)
        .ok_or_else(|| anyhow!("{file}: field `c_co`: missing or not 3 rows of 3 numbers"))?;
    let mut c_co = Matrix3::zeros();
    for (i, row) in c_co_rows.iter().enumerate() {
        let r = vec3(row, &format!("c_co[{i}]"))?;
        c_co.set_row(i, &r.transpose());
    }
    let ortho = (c_co * c_co.transpose() - Matrix3::identity()).amax();
    if ortho > 1e-6 || c_co.determinant() < 0.0 {
        bail!(
            "{file}: field `c_co`: not a rotation (C Cᵀ differs from I by {ortho:.1e}, det {:.3}); allowed: orthonormal rows, det +1",
            c_co.determinant()
        );
    }
    let feats = table
        .get("features_m")
        .and_then(|v| v.as_array())
        .ok_or_else(|| anyhow!("{file}: field `features_m` is missing or not an array"))?;
    if !(3..=64).contains(&feats.len()) {
        bail!(
            "{file}: field `features_m`: {} features; allowed 3..=64",
            feats.len()
        );
    }
    let features_m = feats
        .iter()
        .enumerate()
        .map(|(i, f)| vec3(f, &format!("features_m[{i}]")))
        .collect::<Result<Vec<_>>>()?;
    Ok(Rig {
        mean_motion_rad_s: scalar("mean_motion_rad_s", 0.0, 0.1, None)?,
        baseline_m: scalar("baseline_m", 1e-3, 1000.0, None)?,
        sigma_norm: scalar("sigma_norm", 1e-9, 1e-1, None)?,
        c_co,
        features_m,
        torque_psd: scalar("torque_psd", 0.0, 1e-3, Some(DEFAULT_TORQUE_PSD))?,
        accel_psd: scalar("accel_psd", 0.0, 1e-3, Some(DEFAULT_ACCEL_PSD))?,
    })
}

/// One epoch of the measurement file.
#[derive(Debug, Clone, PartialEq)]
pub struct MeasEpoch {
    pub t_s: f64,
    pub features: Vec<FeatureObs>,
}

/// Reads MEAS.csv into epochs in time order: every problem names the file, the line and the
/// column.
pub fn read_measurements(path: &Path, n_features: usize) -> Result<Vec<MeasEpoch>> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let file = path.display();
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
    let (_, header) = lines
        .next()
        .ok_or_else(|| anyhow!("{file}: no header line (t_s, feature, x_l, y_l, x_r, y_r)"))?;
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    const COLUMNS: [&str; 6] = ["t_s", "feature", "x_l", "y_l", "x_r", "y_r"];
    let mut at = [0usize; 6];
    for (c, name) in COLUMNS.iter().enumerate() {
        at[c] = names.iter().position(|n| n == name).ok_or_else(|| {
            anyhow!("{file}: line 1: no column `{name}` in the header (needs t_s, feature, x_l, y_l, x_r, y_r)")
        })?;
    }
    let mut rows: Vec<(f64, FeatureObs)> = Vec::new();
    for (line, l) in lines {
        let cells: Vec<&str> = l.split(',').map(str::trim).collect();
        if cells.len() != names.len() {
            bail!(
                "{file}: line {line}: {} cells; the header has {}",
                cells.len(),
                names.len()
            );
        }
        let value = |c: usize| -> Result<f64> {
            let s = cells[at[c]];
            let v: f64 = s.parse().map_err(|_| {
                anyhow!(
                    "{file}: line {line}, column `{}`: `{s}` is not a number",
                    COLUMNS[c]
                )
            })?;
            if !v.is_finite() {
                bail!(
                    "{file}: line {line}, column `{}`: {v} is not finite",
                    COLUMNS[c]
                );
            }
            Ok(v)
        };
        let t = value(0)?;
        let f = cells[at[1]];
        let feature: usize = f.parse().ok().filter(|i| *i < n_features).ok_or_else(|| {
            anyhow!(
                "{file}: line {line}, column `feature`: `{f}` is not a feature of the rig; allowed 0..={}",
                n_features - 1
            )
        })?;
        let z = [value(2)?, value(3)?, value(4)?, value(5)?];
        for (v, name) in z.iter().zip(&COLUMNS[2..]) {
            if v.abs() > 100.0 {
                bail!(
                    "{file}: line {line}, column `{name}`: {v} is out of range for a normalised coordinate; allowed -100..=100"
                );
            }
        }
        rows.push((t, FeatureObs { feature, z }));
    }
    if rows.is_empty() {
        bail!("{file}: no measurements");
    }
    rows.sort_by(|a, b| a.0.total_cmp(&b.0));
    // A feature listed twice at one epoch (two detections matched to it) is kept twice: the
    // gate judges each.
    let mut epochs: Vec<MeasEpoch> = Vec::new();
    for (t, obs) in rows {
        match epochs.last_mut() {
            Some(e) if e.t_s == t => e.features.push(obs),
            _ => epochs.push(MeasEpoch {
                t_s: t,
                features: vec![obs],
            }),
        }
    }
    Ok(epochs)
}

/// One output row.
fn row(e: &Estimate) -> String {
    let mut q = e.x.q_ct.into_inner();
    if q.w < 0.0 {
        q = -q;
    }
    let sig = e.p.diagonal().map(|v| v.max(0.0).sqrt());
    let mut s = format!("{}", e.t_s);
    let values = [q.w, q.i, q.j, q.k]
        .into_iter()
        .chain(e.x.w_t.iter().copied())
        .chain(e.x.k.iter().copied())
        .chain(e.x.rho_o.iter().copied())
        .chain(e.x.v_o.iter().copied())
        .chain(sig.iter().copied());
    for v in values {
        let _ = write!(s, ",{v:.12e}");
    }
    s
}

/// Runs the filter over the file and writes `out/relnav.csv`; returns the JSON summary.
pub fn run(meas: &Path, rig_path: &Path, out: &Path) -> Result<String> {
    let rig = read_rig(rig_path)?;
    let epochs = read_measurements(meas, rig.features_m.len())?;
    let mut core = RelNav::new(rig.clone(), Settings::default(), Start::Measurements);
    let mut csv = String::with_capacity(epochs.len() * 400);
    csv.push_str(OUTPUT_HEADER);
    csv.push('\n');
    let mut first: Option<f64> = None;
    let mut last: Option<Estimate> = None;
    for e in &epochs {
        if let Some(est) = core.epoch(e.t_s, &e.features) {
            first.get_or_insert(est.t_s);
            csv.push_str(&row(&est));
            csv.push('\n');
            last = Some(est);
        }
    }
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let path = out.join("relnav.csv");
    std::fs::write(&path, csv).with_context(|| format!("cannot write {}", path.display()))?;
    let c = core.counters;
    let last_json = last.map(|e| {
        let sig = e.p.diagonal().map(|v| v.max(0.0).sqrt());
        let j = glint_physics::rigid_body::inertia_from_k(e.x.k);
        let mut q = e.x.q_ct.into_inner();
        if q.w < 0.0 {
            q = -q;
        }
        json!({
            "t_s": e.t_s,
            "q_ct": [q.w, q.i, q.j, q.k],
            "sigma_attitude_deg": (0..3).map(|i| sig[i].to_degrees()).collect::<Vec<_>>(),
            "w_t_rad_s": e.x.w_t.as_slice(), "sigma_w_rad_s": &sig.as_slice()[3..6],
            "k": e.x.k.as_slice(), "sigma_k": &sig.as_slice()[6..8],
            "inertia_over_trace": j.as_slice(),
            "rho_m": e.x.rho_o.as_slice(), "sigma_rho_m": &sig.as_slice()[8..11],
            "v_m_s": e.x.v_o.as_slice(), "sigma_v_m_s": &sig.as_slice()[11..14],
        })
    });
    let summary = json!({
        "last": last_json,
        "file": meas.display().to_string(),
        "out": path.display().to_string(),
        "epochs": c.epochs,
        "estimates": c.estimates,
        "started_at_s": first,
        "features_used": c.features_used,
        "features_rejected": c.features_rejected,
        "epochs_without_estimate": c.epochs_without_estimate,
        "diverged_restarts": c.diverged,
        "numerical_failures": c.numerical_failures,
    });
    Ok(serde_json::to_string_pretty(&summary)?)
}
