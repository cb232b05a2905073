//! The scenario file: one TOML document that describes a whole deployment.
//!
//! Parsing is strict (`deny_unknown_fields`), and [`Scenario::validate`] checks every number
//! against its documented range, so a typo or an out-of-range value is reported with the file,
//! the field path and the allowed range instead of surfacing later as a wrong result.
//! The field docs here are the reference for the README's scenario section.

use serde::{Deserialize, Serialize};

mod camera;
mod campaign;
mod earth;
mod fault;
mod hosts;
mod matrix;
mod photometry;
mod placement;
mod replay;
mod soak;
mod spectra;
mod stereo;
mod supervision;

pub use camera::*;
pub use campaign::*;
pub use earth::*;
pub use fault::*;
pub use hosts::*;
pub use matrix::*;
pub use photometry::*;
pub use placement::*;
pub use replay::*;
pub use soak::*;
pub use spectra::*;
pub use stereo::*;
pub use supervision::*;

/// A scenario problem: where it is and what is allowed.
#[derive(Debug, Clone, PartialEq)]
pub struct FieldError {
    /// Dotted path of the field, e.g. `camera.fov_deg` or `camera.debris[2].x_m`.
    pub field: String,
    /// What is wrong and what is allowed.
    pub message: String,
}

impl std::fmt::Display for FieldError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "field `{}`: {}", self.field, self.message)
    }
}

#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    #[error("{file}: cannot read: {source}")]
    Io {
        file: String,
        source: std::io::Error,
    },
    #[error("{file}:{line}: field `{field}`: {message}")]
    Parse {
        file: String,
        line: usize,
        field: String,
        message: String,
    },
    #[error("{file}: {}", .errors.iter().map(|e| e.to_string()).collect::<Vec<_>>().join("; "))]
    Invalid {
        file: String,
        errors: Vec<FieldError>,
    },
}

/// Which clock drives the run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Clock {
    /// Simulated time in lockstep with backpressure: nothing is dropped, runs are deterministic.
    #[default]
    Sim,
    /// The sensor paces frames at the scenario rate; slow consumers drop (counted) frames.
    Realtime,
}

/// Top level of a scenario file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// Short name, used in the run directory name. 1–64 characters of `[A-Za-z0-9_-]`.
    pub name: String,
    /// Free text shown in the summary.
    #[serde(default)]
    pub description: String,
    /// Seed of every random draw in the run (noise, false targets). `--seed` overrides it.
    #[serde(default = "default_seed")]
    pub seed: u64,
    /// `sim` (default) or `realtime`.
    #[serde(default)]
    pub clock: Clock,
    /// Limits of the run itself.
    #[serde(default)]
    pub run: RunLimits,
    /// The debris camera ([002]); absent = no frames.
    pub camera: Option<CameraScenario>,
    /// The spectrometer looking at the satellite ([000]); absent = no spectra.
    pub spectra: Option<SpectraScenario>,
    /// The infrared Earth sensor ([003]); absent = no Earth frames.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub earth: Option<EarthScenario>,
    /// The chaser's stereo camera and the tumbling target ([004]); absent = no stereo epochs.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stereo: Option<StereoScenario>,
    /// A ground telescope's light curve of a spinning satellite ([001]); absent = no samples.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub photometry: Option<PhotometryScenario>,
    /// Sweep one parameter: one full deployment per value, results tabulated.
    pub campaign: Option<Campaign>,
    /// Faults to inject (`[[fault]]`; also `glint run --fault`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub fault: Vec<FaultSpec>,
    /// A fault-injection campaign (`[matrix]`): a baseline, then one deployment per
    /// (service × kind).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub matrix: Option<FaultMatrix>,
    /// A long run with faults on a schedule (`[soak]`; also `glint run --soak`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub soak: Option<Soak>,
    /// Whether in-band faults are obeyed (`[faults]`).
    #[serde(default)]
    pub faults: FaultsSection,
    /// Restarts of failed services (`[supervision]`).
    #[serde(default)]
    pub supervision: Supervision,
    /// The sensor's streams from a recording instead of rendered (`[replay]`; `glint replay`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub replay: Option<ReplayScenario>,
    /// Where each process runs (`[services.detector] cpu = 1`), by service name.
    #[serde(default, skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub services: std::collections::BTreeMap<String, ServicePlacement>,
    /// The machines of a deployment split across hosts (`[hosts.<name>]`), by name; empty:
    /// one host.
    #[serde(default, skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub hosts: std::collections::BTreeMap<String, HostSpec>,
}

fn default_seed() -> u64 {
    1
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RunLimits {
    /// Wall-clock limit of the whole run [s], 1–86400. The run fails if it is exceeded.
    pub timeout_s: f64,
    /// Heartbeat period of every service [ms], 10–10000.
    pub heartbeat_period_ms: u64,
    /// A service that sends no heartbeat for this long is declared hung [ms], 100–600000.
    pub heartbeat_deadline_ms: u64,
    /// Grace period between `Shutdown` and SIGTERM, and between SIGTERM and SIGKILL [ms], 10–60000.
    pub shutdown_grace_ms: u64,
    /// Time allowed for every service to come up [ms], 100–600000.
    pub startup_timeout_ms: u64,
}

impl Default for RunLimits {
    fn default() -> Self {
        RunLimits {
            timeout_s: 300.0,
            heartbeat_period_ms: 100,
            heartbeat_deadline_ms: 5000,
            shutdown_grace_ms: 2000,
            startup_timeout_ms: 20000,
        }
    }
}

struct Checker {
    errors: Vec<FieldError>,
}

/// A value as a user reads it: plain, or in exponent form when very large or small (1e308,
/// not its 309 digits).
fn shown(v: f64) -> String {
    let a = v.abs();
    if a == 0.0 || !a.is_finite() || (1e-4..1e15).contains(&a) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

impl Checker {
    fn range(&mut self, field: &str, v: f64, lo: f64, hi: f64) {
        let allowed = format!("allowed {}..={}", shown(lo), shown(hi));
        if !v.is_finite() {
            self.fail(
                field,
                format!("{} is not a finite number; {allowed}", shown(v)),
            );
        } else if v < lo || v > hi {
            self.fail(field, format!("{} is out of range; {allowed}", shown(v)));
        }
    }
    fn range_u(&mut self, field: &str, v: u64, lo: u64, hi: u64) {
        if v < lo || v > hi {
            self.fail(field, format!("{v} is out of range; allowed {lo}..={hi}"));
        }
    }
    /// `name` (at `field`) is a service `scenario` deploys; else the error lists those.
    fn deployed_service(&mut self, field: &str, name: &str, scenario: &Scenario) {
        let deployed = crate::deployment::services(scenario);
        if !deployed.iter().any(|s| s.name() == name) {
            let names: Vec<&str> = deployed.iter().map(|s| s.name()).collect();
            self.fail(
                field,
                format!(
                    "`{name}` is not a service this scenario deploys; allowed: {}",
                    names.join(", ")
                ),
            );
        }
    }
    fn fail(&mut self, field: &str, message: String) {
        self.errors.push(FieldError {
            field: field.to_string(),
            message,
        });
    }
}

impl Scenario {
    /// Pixels of one camera frame; 0 without a camera (the frame topic then carries nothing).
    pub fn frame_px(&self) -> usize {
        self.camera.as_ref().map_or(0, |c| c.pixels())
    }

    /// Pixels of one Earth-sensor frame; 0 without an `[earth]` section.
    pub fn earth_px(&self) -> usize {
        self.earth.as_ref().map_or(0, |e| e.pixels())
    }

    /// Parses and validates a scenario held in memory; `file` names it in errors.
    pub fn from_toml_str(text: &str, file: &str) -> Result<Scenario, ScenarioError> {
        let scenario: Scenario = toml::from_str(text).map_err(|e| parse_error(text, file, &e))?;
        scenario
            .validate()
            .map_err(|errors| ScenarioError::Invalid {
                file: file.to_string(),
                errors,
            })?;
        Ok(scenario)
    }

    /// Reads, parses and validates a scenario file.
    pub fn from_file(path: &std::path::Path) -> Result<Scenario, ScenarioError> {
        let file = path.display().to_string();
        let text = crate::input::read_text_capped(path, crate::input::MAX_TEXT_FILE_BYTES)
            .map_err(|source| ScenarioError::Io {
                file: file.clone(),
                source,
            })?;
        let mut scenario = Self::from_toml_str(&text, &file)?;
        // Files the scenario names are relative to the scenario file.
        let dir = path.parent().unwrap_or(std::path::Path::new(""));
        if let Some(t) = scenario.earth.as_mut().and_then(|e| e.sigma_table.as_mut()) {
            if t.is_relative() {
                // Absolute: the resolved scenario is read again from the run directory.
                let joined = dir.join(&*t);
                *t = std::path::absolute(&joined).unwrap_or(joined);
            }
        }
        if let Some(p) = scenario.photometry.as_mut() {
            if p.shapes.is_relative() {
                let joined = dir.join(&p.shapes);
                p.shapes = std::path::absolute(&joined).unwrap_or(joined);
            }
        }
        if let Some(r) = scenario.replay.as_mut() {
            if std::path::Path::new(&r.recording).is_relative() {
                let joined = dir.join(&r.recording);
                r.recording = (std::path::absolute(&joined).unwrap_or(joined))
                    .display()
                    .to_string();
            }
        }
        Ok(scenario)
    }

    /// Serialises back to TOML (the resolved scenario written into the run directory).
    pub fn to_toml(&self) -> String {
        toml::to_string(self).unwrap_or_default()
    }

    /// Every range check; all problems are reported, not only the first.
    pub fn validate(&self) -> Result<(), Vec<FieldError>> {
        let mut c = Checker { errors: vec![] };
        if self.name.is_empty()
            || self.name.len() > 64
            || !self
                .name
                .chars()
                .all(|ch| ch.is_ascii_alphanumeric() || ch == '-' || ch == '_')
        {
            c.fail("name", "must be 1-64 characters of [A-Za-z0-9_-]".into());
        }
        let r = &self.run;
        c.range("run.timeout_s", r.timeout_s, 1.0, 86400.0);
        c.range_u("run.heartbeat_period_ms", r.heartbeat_period_ms, 10, 10_000);
        c.range_u(
            "run.heartbeat_deadline_ms",
            r.heartbeat_deadline_ms,
            100,
            600_000,
        );
        c.range_u("run.shutdown_grace_ms", r.shutdown_grace_ms, 10, 60_000);
        c.range_u("run.startup_timeout_ms", r.startup_timeout_ms, 100, 600_000);
        if r.heartbeat_deadline_ms < 2 * r.heartbeat_period_ms {
            c.fail(
                "run.heartbeat_deadline_ms",
                "must be at least twice run.heartbeat_period_ms".into(),
            );
        }
        if self.camera.is_none()
            && self.spectra.is_none()
            && self.earth.is_none()
            && self.stereo.is_none()
            && self.photometry.is_none()
        {
            c.fail(
                "camera",
                "a scenario needs a [camera], [spectra], [earth], [stereo] or [photometry] section (or several)"
                    .into(),
            );
        }
        if let Some(s) = &self.stereo {
            check_stereo(&mut c, s);
        }
        if let Some(p) = &self.photometry {
            check_photometry(&mut c, p);
        }
        if let Some(e) = &self.earth {
            check_earth(&mut c, e);
        }
        if let Some(cam) = &self.camera {
            check_camera(&mut c, cam, self.soak.is_some());
        }
        if let Some(sp) = &self.spectra {
            check_spectra(&mut c, sp);
        }
        fault::check_faults(&mut c, self);
        supervision::check_supervision(&mut c, self);
        matrix::check_matrix(&mut c, self);
        soak::check_soak(&mut c, self);
        replay::check_replay(&mut c, self);
        placement::check_placement(&mut c, self);
        hosts::check_hosts(&mut c, self);
        if let Some(camp) = &self.campaign {
            c.range_u("campaign.values (count)", camp.values.len() as u64, 1, 100);
            c.range_u("campaign.seeds", camp.seeds as u64, 1, 1000);
            if !camp.paper.is_empty() && camp.paper.len() != camp.values.len() {
                c.fail(
                    "campaign.paper",
                    "give one paper figure per value, or none".into(),
                );
            }
            if c.errors.is_empty() {
                for i in 0..camp.values.len() {
                    match self.campaign_variant(i) {
                        Ok(v) => {
                            if let Err(errs) = v.validate() {
                                for e in errs {
                                    c.fail(
                                        &format!("campaign.values[{i}] → {}", e.field),
                                        e.message,
                                    );
                                }
                            }
                        }
                        Err(e) => c.errors.push(e),
                    }
                }
            }
        }
        if c.errors.is_empty() {
            Ok(())
        } else {
            Err(c.errors)
        }
    }
}

/// Turns a TOML/serde error into file:line + field path.
fn parse_error(text: &str, file: &str, e: &toml::de::Error) -> ScenarioError {
    let (line, mut field) = match e.span() {
        Some(span) => locate(text, span.start),
        None => (0, String::from("(document)")),
    };
    // "missing field `x`": the field is x of the table the error points at.
    let missing = e
        .message()
        .strip_prefix("missing field `")
        .and_then(|m| m.split('`').next());
    if let Some(name) = missing {
        field = match field.as_str() {
            "(document)" => name.to_string(),
            table => format!("{table}.{name}"),
        };
    }
    ScenarioError::Parse {
        file: file.to_string(),
        line,
        field,
        message: e.message().trim().to_string(),
    }
}

/// Line number (1-based) and dotted field path at a byte offset of a TOML document.
fn locate(text: &str, offset: usize) -> (usize, String) {
    let before = &text[..offset.min(text.len())];
    let line_no = before.matches('\n').count() + 1;
    let line = text.lines().nth(line_no - 1).unwrap_or("");
    let key = line
        .split('=')
        .next()
        .map(|k| k.trim().trim_matches('"').to_string())
        .filter(|k| !k.is_empty() && !k.starts_with('['))
        .unwrap_or_default();
    // The table the offset is in: its own line when that is a table header (a missing field is
    // reported at its table's header), else the last header before it.
    let own = Some(line.trim()).filter(|l| l.starts_with('['));
    let table = own
        .or_else(|| {
            before
                .lines()
                .rev()
                .map(str::trim)
                .find(|l| l.starts_with('['))
        })
        .map(|l| {
            l.trim_matches(|ch| ch == '[' || ch == ']')
                .trim()
                .to_string()
        });
    let field = match (table, key.is_empty()) {
        (Some(t), false) => format!("{t}.{key}"),
        (Some(t), true) => t,
        (None, false) => key,
        (None, true) => "(document)".to_string(),
    };
    (line_no, field)
}
