//! `glint run` and `glint validate`: loading a scenario (or the built-in default) with the
//! command line's seed and faults, and the exit code of a run.

use std::io::IsTerminal;
use std::path::PathBuf;
use std::process::ExitCode;

use shared_types::scenario::{ScenarioError, Soak};
use shared_types::Scenario;

use crate::cli::RunArgs;
use crate::report;
use crate::run::{self, matrix, run_dir};

/// The scenario `glint run` uses without an argument.
const DEFAULT_SCENARIO: &str = include_str!("../../scenarios/default.toml");

pub(crate) fn load(path: Option<&PathBuf>) -> Result<(Scenario, String), ScenarioError> {
    match path {
        Some(p) => {
            let sc = Scenario::from_file(p)?;
            // The files a scenario names are read now, not by a service after deployment.
            let invalid = |field: &str, message: String| ScenarioError::Invalid {
                file: p.display().to_string(),
                errors: vec![shared_types::scenario::FieldError {
                    field: field.into(),
                    message,
                }],
            };
            if let Some(Err(e)) = (sc.earth.as_ref()).map(glint_earth::service_core::sigma_table) {
                return Err(invalid("earth.sigma_table", e.to_string()));
            }
            if let Some(ph) = &sc.photometry {
                let shapes = glint_photometry::shapes::read_shapes(&ph.shapes)
                    .map_err(|e| invalid("photometry.shapes", format!("{e:#}")))?;
                if !shapes.iter().any(|(n, _)| *n == ph.geometry) {
                    let names: Vec<&str> = shapes.iter().map(|(n, _)| n.as_str()).collect();
                    return Err(invalid(
                        "photometry.geometry",
                        format!(
                            "`{}` is not a shape of {}; allowed: {}",
                            ph.geometry,
                            ph.shapes.display(),
                            names.join(", ")
                        ),
                    ));
                }
            }
            if let Err((field, message)) = host_has_cpus(&sc) {
                return Err(invalid(&field, message));
            }
            if let Some(r) = &sc.replay {
                let path = std::path::Path::new(&r.recording);
                glint_sensor::recording::Recording::open(path)
                    .and_then(|rec| crate::run::replay::complete(&rec, &sc))
                    .map_err(|e| invalid("replay.recording", format!("{e:#}")))?;
            }
            Ok((sc, p.display().to_string()))
        }
        None => Ok((
            Scenario::from_toml_str(DEFAULT_SCENARIO, "(built-in default)")?,
            "(built-in default)".to_string(),
        )),
    }
}

/// Every CPU the scenario pins a service to is one this host gives glint; else the field and
/// what is wrong.
pub(crate) fn host_has_cpus(sc: &Scenario) -> Result<(), (String, String)> {
    let cpus = glint_runtime::placement::allowed_cpus();
    for (name, place) in &sc.services {
        if let Some(cpu) = place.cpu.filter(|c| !cpus.contains(c)) {
            return Err((
                format!("services.{name}.cpu"),
                format!(
                    "CPU {cpu} is not one glint may run on here; allowed: {cpus:?} (the host's \
                     CPUs, or the affinity glint was started with: taskset, a cpuset)"
                ),
            ));
        }
    }
    Ok(())
}

/// The built-in default scenario.
#[cfg(test)]
pub(crate) fn default_scenario() -> Scenario {
    Scenario::from_toml_str(DEFAULT_SCENARIO, "(built-in default)").expect("the default scenario")
}

/// The scenario (or the default) with `seed` applied; exit code 2 with the error printed.
pub(crate) fn load_with_seed(
    path: Option<&PathBuf>,
    seed: Option<u64>,
) -> Result<(Scenario, String), ExitCode> {
    let (mut sc, file) = load(path).map_err(|e| {
        eprintln!("error: {e}");
        ExitCode::from(2)
    })?;
    if let Some(seed) = seed {
        sc.seed = seed;
    }
    Ok((sc, file))
}

/// Appends the `--fault` arguments to the scenario's faults and validates them with it; an
/// error names the argument.
fn add_faults(sc: &mut Scenario, args: &[String]) -> Result<(), String> {
    let from_file = sc.fault.len();
    for a in args {
        let spec = shared_types::scenario::FaultSpec::parse(a)
            .map_err(|e| format!("--fault `{a}`: {e}"))?;
        // Asked for on the command line: the in-band kinds are wanted, so obeyed.
        sc.faults.enabled |= spec.kind.in_band();
        sc.fault.push(spec);
    }
    sc.validate().map_err(|errors| {
        errors
            .iter()
            .map(|e| {
                // `fault[i].x` of an argument reads as the argument's own field.
                let arg = e
                    .field
                    .strip_prefix("fault[")
                    .and_then(|r| r.split_once("]."))
                    .and_then(|(i, f)| Some((i.parse::<usize>().ok()?, f)))
                    .filter(|(i, _)| *i >= from_file);
                match arg {
                    Some((i, f)) => {
                        format!("--fault `{}`: {f}: {}", args[i - from_file], e.message)
                    }
                    None => e.to_string(),
                }
            })
            .collect::<Vec<_>>()
            .join("; ")
    })
}

/// Prints where the summary is and maps the outcome to the exit code.
pub(crate) fn finish(result: anyhow::Result<(PathBuf, bool)>) -> ExitCode {
    match result {
        Ok((dir, ok)) => {
            println!("{}", dir.join("summary.md").display());
            if ok {
                ExitCode::SUCCESS
            } else {
                eprintln!("run failed: see {}", dir.join("summary.md").display());
                ExitCode::from(1)
            }
        }
        Err(e) => {
            eprintln!("error: {e:#}");
            // A bad --out is the user's to fix, like a bad scenario.
            if e.downcast_ref::<run_dir::OutDirError>().is_some() {
                ExitCode::from(2)
            } else {
                ExitCode::from(1)
            }
        }
    }
}

/// `glint run`.
pub(crate) fn command(args: RunArgs) -> ExitCode {
    let RunArgs {
        scenario,
        out,
        force,
        seed,
        faults,
        soak,
        record,
        host,
    } = args;
    glint_runtime::init_tracing("orchestrator");
    let (mut sc, file) = match load_with_seed(scenario.as_ref(), seed) {
        Ok(x) => x,
        Err(code) => return code,
    };
    if let Some(duration_s) = soak {
        let mut s = sc.soak.take().unwrap_or_else(|| Soak::new(duration_s));
        s.duration_s = duration_s;
        sc.soak = Some(s);
    }
    if let Err(e) = add_faults(&mut sc, &faults) {
        eprintln!("error: {file}: {e}");
        return ExitCode::from(2);
    }
    // A soak deploys its camera unbounded, with its schedule's faults.
    if let Some(s) = &sc.soak {
        sc = s.deployed(&sc);
    }
    if sc.campaign.is_some() {
        eprintln!("error: {file}: a [campaign] scenario runs with `glint lab campaign {file}`");
        return ExitCode::from(2);
    }
    let host = match run::hosts::resolve(&sc, host.as_deref()) {
        Ok(h) => h,
        Err(e) => {
            eprintln!("error: {file}: {e}");
            return ExitCode::from(2);
        }
    };
    let opts = run::RunOptions {
        scenario: sc,
        scenario_file: file,
        out_dir: out,
        replace: force,
        progress: std::io::stderr().is_terminal(),
        record,
        host,
    };
    if opts.scenario.matrix.is_some() {
        return finish(matrix::run_matrix(opts));
    }
    let result = run::run(opts);
    if let Ok((dir, _)) = &result {
        let report = report::Report::read(&dir.join("report.json")).ok();
        if let Some(text) = report.as_ref().and_then(report::earth::console) {
            eprint!("{text}");
        }
    }
    finish(result)
}

/// `glint validate SCENARIO`.
pub(crate) fn validate(scenario: PathBuf) -> ExitCode {
    match load(Some(&scenario)) {
        Ok((s, _)) => {
            let services: Vec<&str> = (shared_types::deployment::services(&s).iter())
                .map(|id| id.name())
                .collect();
            println!(
                "{}: ok ({}: deploys {})",
                scenario.display(),
                s.name,
                services.join(", ")
            );
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(2)
        }
    }
}
