//! The `[campaign]` section: a one-parameter sweep, one deployment per value.

use serde::{Deserialize, Serialize};

use super::*;

/// A one-parameter sweep ([000] studies: phase, SNR, body shape, rotation axis, seed; [004]:
/// features, target size, image noise).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Campaign {
    /// One of `spectra.start_phase_deg`, `spectra.snr`, `spectra.body_shape`,
    /// `spectra.materials`, `spectra.rotation` (values "y" or "z": 0.25 deg/frame about that
    /// body axis), `stereo.n_features`, `stereo.size_m`, `stereo.sigma_norm`,
    /// `photometry.geometry`, `photometry.sigma_mag`, `seed`.
    pub parameter: String,
    /// 1–100 values of that parameter.
    pub values: Vec<toml::Value>,
    /// The paper's figure for each value (its error metric), shown beside ours; optional.
    #[serde(default)]
    pub paper: Vec<f64>,
    /// Monte-Carlo runs per value, 1–1000 (default 1), with seeds `seed`, `seed + 1`, ….
    /// [000]: each value also runs once noise-free (the reference); the summary gives the
    /// scatter about the noise-free solution against the Cramér–Rao bound and the NEES of the
    /// reported covariance. [004]: the RTMSE pooled over the runs and the runs' mean NEES.
    /// [001]: the identification's confusion table (each seed draws its own spin axis when
    /// `photometry.spin_axis` is absent).
    #[serde(default = "one")]
    pub seeds: u32,
}

fn one() -> u32 {
    1
}

/// Parameters a campaign may sweep.
pub const CAMPAIGN_PARAMETERS: [&str; 11] = [
    "spectra.start_phase_deg",
    "spectra.snr",
    "spectra.body_shape",
    "spectra.materials",
    "spectra.rotation",
    "stereo.n_features",
    "stereo.size_m",
    "stereo.sigma_norm",
    "photometry.geometry",
    "photometry.sigma_mag",
    "seed",
];

impl Scenario {
    /// The scenario of one campaign value (no campaign section, name suffixed).
    pub fn campaign_variant(&self, index: usize) -> Result<Scenario, FieldError> {
        let c = self.campaign.as_ref().ok_or(FieldError {
            field: "campaign".into(),
            message: "no campaign section".into(),
        })?;
        let v = &c.values[index];
        let field = format!("campaign.values[{index}]");
        let bad = |m: &str| FieldError {
            field: field.clone(),
            message: format!("{v} {m}"),
        };
        let mut s = self.clone();
        s.campaign = None;
        s.name = format!("{}-{index:02}", self.name);
        if c.parameter == "seed" && c.seeds > 1 {
            return Err(FieldError {
                field: "campaign.seeds".into(),
                message: "a seed sweep is itself the Monte-Carlo: give seeds = 1".into(),
            });
        }
        let num = || v.as_float().or_else(|| v.as_integer().map(|i| i as f64));
        let text = || v.as_str().map(str::to_string);
        let sp = || {
            s.spectra
                .clone()
                .ok_or_else(|| bad("needs a [spectra] section"))
        };
        let st = || {
            s.stereo
                .clone()
                .ok_or_else(|| bad("needs a [stereo] section"))
        };
        match c.parameter.as_str() {
            "seed" => {
                s.seed = v
                    .as_integer()
                    .filter(|i| *i >= 0)
                    .ok_or_else(|| bad("is not a seed (a whole number >= 0)"))?
                    as u64
            }
            "spectra.start_phase_deg" => {
                let mut x = sp()?;
                x.start_phase_deg = num().ok_or_else(|| bad("is not a number"))?;
                s.spectra = Some(x);
            }
            "spectra.snr" => {
                let mut x = sp()?;
                x.snr = Some(num().ok_or_else(|| bad("is not a number"))?);
                s.spectra = Some(x);
            }
            "spectra.body_shape" | "spectra.materials" | "spectra.rotation" => {
                let mut x = sp()?;
                let t = text().ok_or_else(|| bad("is not a string"))?;
                let parsed = toml::Value::String(t.clone());
                match c.parameter.as_str() {
                    "spectra.body_shape" => {
                        x.body_shape = parsed
                            .try_into()
                            .map_err(|_| bad("is not cube, cylinder, sphere or hexagonal-prism"))?
                    }
                    "spectra.materials" => {
                        x.materials = parsed
                            .try_into()
                            .map_err(|_| bad("is not physical or paper-like"))?
                    }
                    _ => {
                        x.rate_deg_per_frame = match t.as_str() {
                            "y" => [0.0, 0.25, 0.0],
                            "z" => [0.0, 0.0, 0.25],
                            _ => return Err(bad("is not y or z")),
                        }
                    }
                }
                s.spectra = Some(x);
            }
            "stereo.n_features" => {
                let mut x = st()?;
                x.n_features = v
                    .as_integer()
                    .and_then(|i| u32::try_from(i).ok())
                    .ok_or_else(|| bad("is not a number of features (a whole number)"))?;
                s.stereo = Some(x);
            }
            "stereo.size_m" | "stereo.sigma_norm" => {
                let mut x = st()?;
                let n = num().ok_or_else(|| bad("is not a number"))?;
                match c.parameter.as_str() {
                    "stereo.size_m" => x.size_m = n,
                    _ => x.sigma_norm = n,
                }
                s.stereo = Some(x);
            }
            "photometry.geometry" | "photometry.sigma_mag" => {
                let mut x =
                    (s.photometry.clone()).ok_or_else(|| bad("needs a [photometry] section"))?;
                match c.parameter.as_str() {
                    "photometry.geometry" => {
                        x.geometry = text().ok_or_else(|| bad("is not a shape's name"))?
                    }
                    _ => x.sigma_mag = num().ok_or_else(|| bad("is not a number"))?,
                }
                s.photometry = Some(x);
            }
            other => {
                return Err(FieldError {
                    field: "campaign.parameter".into(),
                    message: format!(
                        "`{other}` cannot be swept; allowed: {}",
                        CAMPAIGN_PARAMETERS.join(", ")
                    ),
                })
            }
        }
        Ok(s)
    }
}
