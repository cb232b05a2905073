//! The attitude solve's part of the report ([000]), built from the inversion's solve responses:
//! glint's answer first (the rate, its 1σ along each Fisher direction, what the data leave open,
//! the error against truth), then how the stages got there (stage 1's reconstruction error per
//! band, stage 2's separation degree and λ*, stage 3 at λ* as the paper computes it).
//!
//! `report.json`'s `inversion` object is [`InversionReport`]; scripts and the campaigns read it
//! through these types.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::Result;
use glint_inversion::rate_error_metric;
use glint_inversion::stage3::{distance, RATE_NAMES};
use serde::{Deserialize, Serialize};
use shared_types::scenario::SpectraScenario;
use shared_types::{SolveResponse, SolveStatus};

use crate::plots::{line_chart, Series, BLUE, RED};

/// `report.json` → `inversion`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct InversionReport {
    /// The windows every figure depends on.
    pub windows: Windows,
    /// Stage 1, when answered.
    pub stage1: Option<Stage1Report>,
    /// Stage 2, when answered.
    pub stage2: Option<Stage2Report>,
    /// Stage 3: glint's answer, when answered.
    pub stage3: Option<Stage3Report>,
}

/// The scenario's windows and target.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Windows {
    pub stable_samples: u64,
    pub stable_start_phase_deg: f64,
    pub motion_frames: u64,
    pub frame_interval_s: f64,
    pub start_phase_deg: f64,
    pub materials: String,
    pub body_shape: String,
    /// `None`: noise-free.
    pub snr: Option<f64>,
}

/// Stage 1: the reconstruction error per band.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Stage1Report {
    pub status: String,
    pub bands: Vec<ReconBand>,
}

/// ε_rec of one band.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct ReconBand {
    pub wavelength_nm: f64,
    pub recon_err: Option<f64>,
}

/// Stage 2: σ(λ) per band and λ*.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Stage2Report {
    pub status: String,
    pub sigma: Vec<SigmaBand>,
    /// λ* \[nm\].
    pub chosen_nm: f64,
}

/// σ of one band.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct SigmaBand {
    pub wavelength_nm: f64,
    pub sigma: Option<f64>,
}

/// One Fisher direction of the answer.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct DirectionReport {
    /// Unit vector in (w_x, w_y, w_z) (not numbers when the stage failed).
    #[serde(deserialize_with = "crate::report::model::triple_or_nan")]
    #[schemars(with = "[Option<f64>; 3]")]
    pub axis: [f64; 3],
    /// 1σ \[deg/frame\].
    pub sigma_deg_per_frame: Option<f64>,
    pub determined: bool,
}

/// Stage 3 at λ*: the paper's answer, beside glint's.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct LambdaStarReport {
    pub band_nm: f64,
    pub status: String,
    pub unobservable_reason: Option<String>,
    pub p_deg_per_frame: Option<[f64; 3]>,
    pub err_paper_metric: Option<f64>,
}

/// Stage 3: glint's answer.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Stage3Report {
    /// "ok", "unobservable", "not_ready", "failed".
    pub status: String,
    pub unobservable_reason: Option<String>,
    /// "joint" (every band) or "band" (λ* alone).
    pub fit: String,
    /// p̂ \[deg/frame\].
    pub p_deg_per_frame: Option<[f64; 3]>,
    /// The scenario's rate \[deg/frame\].
    pub truth_deg_per_frame: [f64; 3],
    /// 100·‖p̂ − p*‖ (the paper's metric).
    pub err_paper_metric: Option<f64>,
    /// Cov(p̂), row-major \[(deg/frame)²\].
    pub covariance: Option<[f64; 9]>,
    /// The Fisher directions, least informed first.
    pub directions: Vec<DirectionReport>,
    /// The rates the prior held at zero ("w_x", …).
    pub held_at_prior: Vec<String>,
    /// Whether the data fix the sense of rotation.
    pub sense_determined: bool,
    /// The mirror that fits as well, when the sense is not determined.
    pub mirror_deg_per_frame: Option<[f64; 3]>,
    pub err_paper_metric_mirror: Option<f64>,
    /// Motion frames fitted.
    pub fitted_frames: u32,
    /// The fit horizon \[deg of rotation\].
    pub fit_horizon_deg: f64,
    pub iterations: u32,
    /// Each facet's widest lobe re-fitted from the motion window.
    pub widest_lobe_refit: bool,
    /// λ*'s own fit.
    pub lambda_star: LambdaStarReport,
}

fn status_name(code: u32) -> String {
    SolveStatus::from_u32(code)
        .map_or("unknown", |s| s.name())
        .to_string()
}

fn reason(code: u32) -> Option<String> {
    (code != 0).then(|| SolveResponse::reason_name(code).to_string())
}

fn finite(v: f64) -> Option<f64> {
    v.is_finite().then_some(v)
}

fn finite3(v: [f64; 3]) -> Option<[f64; 3]> {
    v.iter().all(|x| x.is_finite()).then_some(v)
}

impl InversionReport {
    /// The report of a run's solve responses (stages 1–3, the last answer of each).
    pub fn new(sp: &SpectraScenario, responses: &[SolveResponse]) -> Self {
        let bands = sp.wavelengths_nm();
        let get = |stage: u32| responses.iter().rev().find(|r| r.stage == stage);
        let nm = |i: usize| bands.get(i).copied().unwrap_or(f64::NAN);
        let per_band = |r: &SolveResponse, values: &[f32]| -> Vec<(f64, Option<f64>)> {
            (0..(r.n_bands as usize).min(values.len()))
                .map(|i| (nm(i), finite(values[i] as f64)))
                .collect()
        };
        let stage1 = get(1).map(|r| Stage1Report {
            status: status_name(r.status),
            bands: per_band(r, &r.recon_err)
                .into_iter()
                .map(|(wavelength_nm, recon_err)| ReconBand {
                    wavelength_nm,
                    recon_err,
                })
                .collect(),
        });
        let stage2 = get(2).map(|r| Stage2Report {
            status: status_name(r.status),
            sigma: per_band(r, &r.separation)
                .into_iter()
                .map(|(wavelength_nm, sigma)| SigmaBand {
                    wavelength_nm,
                    sigma,
                })
                .collect(),
            chosen_nm: nm(r.chosen_band as usize),
        });
        let truth = sp.rate_deg_per_frame;
        let stage3 = get(3).map(|r| {
            let p = finite3(r.rate_deg_per_frame).filter(|_| r.status == SolveStatus::Ok as u32);
            let mirror = finite3(r.mirror_deg_per_frame)
                .filter(|_| r.flags & SolveResponse::SENSE_UNDETERMINED != 0);
            let band_p = finite3(r.band_rate_deg_per_frame)
                .filter(|_| r.band_status == SolveStatus::Ok as u32);
            Stage3Report {
                status: status_name(r.status),
                unobservable_reason: reason(r.unobservable_reason),
                fit: if r.flags & SolveResponse::JOINT != 0 {
                    "joint"
                } else {
                    "band"
                }
                .to_string(),
                p_deg_per_frame: p,
                truth_deg_per_frame: truth,
                err_paper_metric: p.map(|p| rate_error_metric(p, truth)),
                covariance: p.and(
                    r.covariance
                        .iter()
                        .all(|v| v.is_finite())
                        .then_some(r.covariance),
                ),
                directions: (0..3)
                    .map(|i| DirectionReport {
                        axis: [0, 3, 6].map(|row| r.fisher_eigenvectors[row + i]),
                        sigma_deg_per_frame: finite(r.bound_1sigma_deg_per_frame[i]),
                        determined: r.observable_mask & (1 << i) != 0,
                    })
                    .collect(),
                held_at_prior: held_names(r.held_axes),
                sense_determined: mirror.is_none(),
                mirror_deg_per_frame: mirror,
                err_paper_metric_mirror: mirror.map(|m| rate_error_metric(m, truth)),
                fitted_frames: r.fitted_frames,
                fit_horizon_deg: glint_inversion::stage3::DEFAULT_MAX_ROTATION_DEG,
                iterations: r.iterations,
                widest_lobe_refit: r.flags & SolveResponse::LOBE_REFIT != 0,
                lambda_star: LambdaStarReport {
                    band_nm: nm(r.chosen_band as usize),
                    status: status_name(r.band_status),
                    unobservable_reason: reason(r.band_unobservable_reason),
                    p_deg_per_frame: band_p,
                    err_paper_metric: band_p.map(|p| rate_error_metric(p, truth)),
                },
            }
        });
        InversionReport {
            windows: Windows {
                stable_samples: sp.stable_samples,
                stable_start_phase_deg: sp.stable_start_phase_deg,
                motion_frames: sp.motion_frames,
                frame_interval_s: sp.frame_interval_s,
                start_phase_deg: sp.start_phase_deg,
                materials: format!("{:?}", sp.materials).to_lowercase(),
                body_shape: format!("{:?}", sp.body_shape).to_lowercase(),
                snr: sp.snr,
            },
            stage1,
            stage2,
            stage3,
        }
    }

    /// The summary's section: the answer first, then the stages.
    pub fn markdown(&self, joint_bands: usize) -> String {
        let mut s = String::from("\n## Attitude rate ([000])\n\n");
        if let Some(s3) = &self.stage3 {
            s += &answer_text(s3, joint_bands);
        } else {
            s += "Stage 3 did not answer: no rate.\n";
        }
        s += "\n### How the three stages got there\n\n";
        let w = &self.windows;
        let _ = writeln!(
            s,
            "Windows: stable {} samples from phase {}°; motion {} frames, {} s apart, from phase {}°; materials `{}`, body `{}`, SNR {}.\n",
            w.stable_samples,
            w.stable_start_phase_deg,
            w.motion_frames,
            w.frame_interval_s,
            w.start_phase_deg,
            w.materials,
            w.body_shape,
            w.snr.map_or("∞ (noise-free)".to_string(), |v| v.to_string())
        );
        if let (Some(s1), Some(s2)) = (&self.stage1, &self.stage2) {
            let worst = s1
                .bands
                .iter()
                .filter_map(|b| b.recon_err)
                .fold(0.0f64, f64::max);
            let chosen_sigma = s2
                .sigma
                .iter()
                .find(|b| b.wavelength_nm == s2.chosen_nm)
                .and_then(|b| b.sigma);
            let _ = writeln!(
                s,
                "Stage 1 (NNLS reconstruction of the stable window): error ≤ {worst:.2e} over {} bands. Stage 2: λ* = {} nm (σ = {}).",
                s1.bands.len(),
                s2.chosen_nm,
                chosen_sigma.map_or("—".into(), |v| format!("{v:.4}")),
            );
        }
        if let Some(s3) = &self.stage3 {
            let l = &s3.lambda_star;
            match (l.p_deg_per_frame, l.err_paper_metric) {
                (Some(p), Some(e)) => {
                    let _ = writeln!(
                        s,
                        "Stage 3 at λ* = {} nm alone (the paper's answer): p = {}, error {e:.3}.",
                        l.band_nm,
                        vec3(p)
                    );
                }
                _ => {
                    let _ = writeln!(
                        s,
                        "Stage 3 at λ* = {} nm alone (the paper's answer): {} ({}).",
                        l.band_nm,
                        l.status,
                        l.unobservable_reason.as_deref().unwrap_or("no rate")
                    );
                }
            }
        }
        s += "\n![separation](inversion-sigma.svg)\n\n![stage-1 fit](stage1-fit.svg)\n\n![stage-3 fit](stage3-fit.svg)\n\n![stage-3 residuals](stage3-residuals.svg)\n";
        s
    }

    /// `inversion-sigma.svg`: σ(λ) and stage 1's reconstruction error per band.
    pub fn plots(&self, dir: &Path) -> Result<()> {
        let (Some(s1), Some(s2)) = (&self.stage1, &self.stage2) else {
            return Ok(());
        };
        let sigma = s2
            .sigma
            .iter()
            .filter_map(|b| b.sigma.map(|v| (b.wavelength_nm, v)))
            .collect();
        let recon = s1
            .bands
            .iter()
            .filter_map(|b| b.recon_err.map(|v| (b.wavelength_nm, 100.0 * v)))
            .collect();
        line_chart(
            &dir.join("inversion-sigma.svg"),
            "Stage 2: separation degree σ(λ); stage-1 reconstruction error ×100",
            "wavelength [nm]",
            "σ(λ); 100·ε_rec",
            &[
                Series {
                    label: "σ(λ)",
                    points: sigma,
                    color: BLUE,
                    markers: false,
                },
                Series {
                    label: "100·ε_rec",
                    points: recon,
                    color: RED,
                    markers: true,
                },
            ],
        )
    }
}

fn vec3(p: [f64; 3]) -> String {
    format!("[{:.5}, {:.5}, {:.5}]", p[0], p[1], p[2])
}

/// The answer in words: the rate with its error, its 1σ per direction, what the data leave
/// open, and the sense of rotation.
fn answer_text(s3: &Stage3Report, joint_bands: usize) -> String {
    let mut s = String::new();
    let fit = if s3.fit == "joint" {
        format!("the joint fit over {joint_bands} bands")
    } else {
        format!("the fit at λ* = {} nm", s3.lambda_star.band_nm)
    };
    let t = s3.truth_deg_per_frame;
    match (s3.p_deg_per_frame, s3.err_paper_metric) {
        (Some(p), Some(err)) => {
            let _ = writeln!(
                s,
                "**p = {} deg/frame, error {err:.3}** against the truth [{}, {}, {}] (paper metric 100·‖Δp‖); {fit}, on the first {} motion frames ({}° of rotation).\n",
                vec3(p),
                t[0],
                t[1],
                t[2],
                s3.fitted_frames,
                s3.fit_horizon_deg
            );
        }
        _ => {
            let _ = writeln!(
                s,
                "**No rate: {}** ({}; {fit}). The data do not determine the rotation; the 1σ bounds below say how little they constrain it.\n",
                s3.status,
                s3.unobservable_reason.as_deref().unwrap_or("unknown reason")
            );
        }
    }
    s += "| direction (w_x, w_y, w_z) | 1σ [deg/frame] | determined |\n|---|---|---|\n";
    for d in &s3.directions {
        let _ = writeln!(
            s,
            "| [{:.3}, {:.3}, {:.3}] | {} | {} |",
            d.axis[0],
            d.axis[1],
            d.axis[2],
            d.sigma_deg_per_frame
                .map_or("—".into(), |v| format!("{v:.2e}")),
            if d.determined { "yes" } else { "**no**" }
        );
    }
    if !s3.held_at_prior.is_empty() {
        let _ = writeln!(
            s,
            "\nThe data do not determine {}: the prior holds {} = 0, and only the determined combinations come from the light curve.",
            if s3.held_at_prior.len() == 1 {
                "one direction"
            } else {
                "some directions"
            },
            s3.held_at_prior.join(", ")
        );
    }
    if let Some(p) = s3.p_deg_per_frame {
        if let Some(i) = s3
            .directions
            .iter()
            .position(|d| d.determined && speed_if_own_axis(&d.axis, p).is_some())
        {
            let _ = writeln!(
                s,
                "\nDirection {} is the rate's own axis: the light curve fixes the spin rate |p| = {:.5} deg/frame there.",
                i + 1,
                distance(p, [0.0; 3])
            );
        }
    }
    match (s3.mirror_deg_per_frame, s3.err_paper_metric_mirror) {
        (Some(m), Some(e)) => {
            let _ = writeln!(
                s,
                "\n**Sense of rotation: not determined.** The mirror {} (error {e:.3}) fits the data within the noise: with the Sun a fraction of a degree off the body XZ plane, a rate and its mirror image (−w_x, w_y, −w_z) give nearly the same light curves.",
                vec3(m)
            );
        }
        _ if s3.p_deg_per_frame.is_some() => {
            s += "\nSense of rotation: determined (no mirror fits as well).\n";
        }
        _ => {}
    }
    s
}

/// A determined direction this close to the rate's own axis is its speed \[cos 1°\].
const SPEED_DIRECTION_MIN_COS: f64 = 0.999_85;

/// |p| \[deg/frame\] when the unit direction `v` is p's own axis (within 1°), else `None`.
pub(crate) fn speed_if_own_axis(v: &[f64; 3], p: [f64; 3]) -> Option<f64> {
    let speed = distance(p, [0.0; 3]);
    if !(speed > 0.0 && speed.is_finite()) {
        return None;
    }
    let cos: f64 = (0..3).map(|k| v[k] * p[k] / speed).sum();
    (cos.abs() >= SPEED_DIRECTION_MIN_COS).then_some(speed)
}

/// The rates `SolveResponse::held_axes` says the prior held at zero.
fn held_names(bits: u32) -> Vec<String> {
    let mut held: Vec<String> = (0..3)
        .filter(|k| bits & (1 << k) != 0)
        .map(|k| RATE_NAMES[k].to_string())
        .collect();
    if bits & SolveResponse::HELD_OTHER != 0 {
        held.push("the weak direction itself".to_string());
    }
    held
}

#[cfg(test)]
mod tests {
    use super::*;
    use shared_types::Scenario;

    fn scenario() -> SpectraScenario {
        let text = include_str!("../../scenarios/geo-hover-zspin.toml");
        Scenario::from_toml_str(text, "geo-hover-zspin.toml")
            .expect("shipped scenario")
            .spectra
            .expect("spectra")
    }

    fn answered(flags: u32, mirror: [f64; 3]) -> SolveResponse {
        SolveResponse {
            stage: 3,
            status: SolveStatus::Ok as u32,
            flags,
            rate_deg_per_frame: [0.0, -0.00025, 0.25013],
            covariance: [1e-6; 9],
            fisher_eigenvectors: [1.0, 0.0, 0.0, 0.0, 0.971, 0.239, 0.0, -0.239, 0.971],
            bound_1sigma_deg_per_frame: [0.5, 5.41e-4, 6.02e-5],
            observable_mask: 0b110,
            held_axes: 1,
            mirror_deg_per_frame: mirror,
            band_status: SolveStatus::Ok as u32,
            band_rate_deg_per_frame: [0.0, -0.00054, 0.24848],
            ..Default::default()
        }
    }

    #[test]
    fn the_summary_leads_with_the_answer_and_its_error_against_truth() {
        let sp = scenario();
        let report = InversionReport::new(&sp, &[answered(SolveResponse::JOINT, [f64::NAN; 3])]);
        let s3 = report.stage3.as_ref().expect("stage 3");
        // |Δp| = sqrt(0.00025² + 0.00013²) → 100·|Δp| = 0.0282.
        let err = s3.err_paper_metric.expect("error");
        assert!(
            (err - 100.0 * (0.00025f64.hypot(0.00013))).abs() < 1e-9,
            "{err}"
        );
        assert_eq!(s3.fit, "joint");
        assert_eq!(s3.held_at_prior, vec!["w_x".to_string()]);
        assert!(s3.sense_determined);
        let md = report.markdown(36);
        let first = md
            .lines()
            .find(|l| l.starts_with("**"))
            .expect("a bold first line");
        assert!(
            first.contains("p = [0.00000, -0.00025, 0.25013]") && first.contains("error 0.028"),
            "{first}"
        );
        assert!(first.contains("joint fit over 36 bands"), "{first}");
        assert!(md.contains("Sense of rotation: determined"), "{md}");
    }

    #[test]
    fn a_mirror_that_fits_as_well_says_the_sense_is_not_determined() {
        let sp = scenario();
        let flags = SolveResponse::JOINT | SolveResponse::SENSE_UNDETERMINED;
        let report = InversionReport::new(&sp, &[answered(flags, [0.0, -0.004, -0.249])]);
        let s3 = report.stage3.as_ref().expect("stage 3");
        assert!(!s3.sense_determined);
        let e = s3.err_paper_metric_mirror.expect("mirror error");
        assert!(e > 40.0, "{e}");
        assert!(report
            .markdown(36)
            .contains("**Sense of rotation: not determined.**"));
        // A mirror on the wire without the flag is not the answer's.
        let report =
            InversionReport::new(&sp, &[answered(SolveResponse::JOINT, [0.0, 0.0, -0.25])]);
        assert!(report.stage3.expect("stage 3").sense_determined);
    }
}
