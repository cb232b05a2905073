//! `[soak]`: the chain kept running for a wall-clock duration, with a fault fired on a schedule
//! (every `fault_every_s`, the next (kind × service) in turn, each as the fault matrix makes
//! it), to show that recovery and memory stay bounded however long a deployment lasts. The
//! camera's stream runs until the soak's time is up (its `frames` is ignored); the orchestrator
//! then ends it, and the run accounts for every frame sent.
//!
//! ```toml
//! [soak]
//! duration_s = 600          # 1–86400
//! fault_every_s = 10        # 0: no faults; else 1–3600 (default 10)
//! services = ["detector"]   # default: every service the scenario deploys
//! kinds = ["kill", "stop"]  # default: all six
//! ```
//!
//! `glint run FILE --soak DURATION` adds (or overrides) the section's duration.

use serde::{Deserialize, Serialize};

use super::{Checker, FaultKind, FaultMatrix, FaultSpec, Scenario};

/// The frames a soak's camera is given: more than any soak sends (its end is the
/// orchestrator's order when the soak's time is up).
pub const SOAK_FRAMES: u64 = 1 << 40;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Soak {
    /// How long the chain runs [s], 1–86400.
    pub duration_s: f64,
    /// A fault every this many seconds [s]: 0 (none) or 1–3600. The last is fired at least
    /// this long before the end, so that each one's recovery is seen.
    #[serde(default = "default_fault_every_s")]
    pub fault_every_s: f64,
    /// Services to fault (default: every service the scenario deploys).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub services: Vec<String>,
    /// Kinds of fault (default: all six).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub kinds: Vec<FaultKind>,
}

fn default_fault_every_s() -> f64 {
    10.0
}

impl Soak {
    pub fn new(duration_s: f64) -> Soak {
        Soak {
            duration_s,
            fault_every_s: default_fault_every_s(),
            services: vec![],
            kinds: vec![],
        }
    }

    fn matrix(&self) -> FaultMatrix {
        FaultMatrix {
            services: self.services.clone(),
            kinds: self.kinds.clone(),
            ..Default::default()
        }
    }

    /// The faults of the schedule: at `fault_every_s`, 2·`fault_every_s`, … up to one period
    /// before the end, each kind in turn on each service in turn (kill on every service, then
    /// stop on every service, …), as the matrix makes them.
    pub fn schedule(&self, scenario: &Scenario) -> Vec<FaultSpec> {
        if self.fault_every_s <= 0.0 {
            return vec![];
        }
        let matrix = self.matrix();
        let services = matrix.services_of(scenario);
        let cases: Vec<(usize, crate::ServiceId, FaultKind)> = (matrix.kinds_of().into_iter())
            .flat_map(|k| (services.iter().enumerate()).map(move |(i, s)| (i, *s, k)))
            .collect();
        let n = ((self.duration_s / self.fault_every_s).floor() as usize).saturating_sub(1);
        (0..n)
            .zip(cases.iter().cycle())
            .map(|(k, (i, service, kind))| {
                let mut f = matrix.fault(*service, *i, *kind, 0);
                f.at_seq = None;
                f.at_s = Some((k + 1) as f64 * self.fault_every_s);
                f
            })
            .collect()
    }

    /// The scenario a soak deploys: the camera unbounded, the schedule's faults added (in-band
    /// ones obeyed), and restarts allowed as often as the schedule faults a service.
    pub fn deployed(&self, scenario: &Scenario) -> Scenario {
        let mut sc = scenario.clone();
        if let Some(cam) = &mut sc.camera {
            cam.frames = SOAK_FRAMES;
        }
        let faults = self.schedule(scenario);
        sc.faults.enabled |= faults.iter().any(|f| f.kind.in_band());
        if !faults.is_empty() {
            // Each service is faulted every `fault_every_s × services` seconds.
            let services = self.matrix().services_of(scenario).len().max(1);
            let period_s = self.fault_every_s * services as f64;
            let sup = &mut sc.supervision;
            let needed = ((sup.restart_window_s / period_s).ceil() as u32 + 1).min(100);
            sup.max_restarts = sup.max_restarts.max(needed);
            for s in sup.services.values_mut() {
                s.max_restarts = s.max_restarts.map(|m| m.max(needed));
            }
        }
        sc.fault.extend(faults);
        sc
    }
}

pub(super) fn check_soak(c: &mut Checker, scenario: &Scenario) {
    let Some(s) = &scenario.soak else {
        return;
    };
    c.range("soak.duration_s", s.duration_s, 1.0, 86_400.0);
    if s.fault_every_s != 0.0 {
        c.range("soak.fault_every_s", s.fault_every_s, 1.0, 3600.0);
    }
    if scenario.camera.is_none() {
        c.fail(
            "soak",
            "a soak runs the debris camera's stream: the scenario needs a [camera]".into(),
        );
    }
    if scenario.matrix.is_some() || scenario.campaign.is_some() {
        c.fail(
            "soak",
            "a soak is one deployment: not with [matrix] or [campaign]".into(),
        );
    }
    super::matrix::check_services(c, "soak", &s.services, scenario);
}

#[cfg(test)]
mod tests {
    use super::*;

    fn debris() -> Scenario {
        let text = include_str!("../../../scenarios/debris-geo.toml");
        Scenario::from_toml_str(text, "debris-geo.toml").unwrap()
    }

    #[test]
    fn the_schedule_fires_each_kind_on_each_service_in_turn_and_stops_a_period_early() {
        let sc = debris();
        let soak = Soak::new(65.0);
        let f = soak.schedule(&sc);
        // 65 s every 10 s: faults at 10 … 50 s (none in the last period).
        let at: Vec<f64> = f.iter().map(|f| f.at_s.unwrap()).collect();
        assert_eq!(at, [10.0, 20.0, 30.0, 40.0, 50.0]);
        let which: Vec<(String, &str)> = f
            .iter()
            .map(|f| (f.service.clone(), f.kind.name()))
            .collect();
        assert_eq!(which[0], ("sensor".into(), "kill"));
        assert_eq!(which[1], ("detector".into(), "kill"));
        assert_eq!(which[2], ("tracker".into(), "kill"));
        assert_eq!(which[3], ("sensor".into(), "stop"));
        assert!(f.iter().all(|f| f.at_seq.is_none()));
        let deployed = soak.deployed(&sc);
        assert_eq!(deployed.camera.as_ref().unwrap().frames, SOAK_FRAMES);
        assert!(!deployed.faults.enabled, "kill and stop are signals");
        assert!(Soak::new(600.0).deployed(&sc).faults.enabled);
        // One service faulted every 10 s: six restarts a minute must be allowed.
        let mut one = Soak::new(600.0);
        one.services = vec!["detector".into()];
        let deployed = one.deployed(&sc);
        assert!(deployed.supervision.max_restarts >= 7);
        assert!(deployed.fault.iter().all(|f| f.service == "detector"));
        let mut none = Soak::new(600.0);
        none.fault_every_s = 0.0;
        assert!(none.schedule(&sc).is_empty());
    }

    #[test]
    fn a_soak_without_a_camera_or_with_a_bad_duration_is_refused_by_field() {
        let mut sc = debris();
        sc.soak = Some(Soak::new(0.5));
        let errs = sc.validate().unwrap_err();
        assert!(
            errs.iter().any(|e| e.field == "soak.duration_s"),
            "{errs:?}"
        );
        sc.soak = Some(Soak::new(60.0));
        sc.camera = None;
        sc.spectra = None;
        let errs = sc.validate().unwrap_err();
        assert!(errs.iter().any(|e| e.field == "soak"), "{errs:?}");
    }

    #[test]
    fn a_soaks_deployed_scenario_validates_its_frames_are_unbounded() {
        let mut sc = debris();
        sc.soak = Some(Soak::new(600.0));
        let deployed = sc.soak.clone().unwrap().deployed(&sc);
        assert!(deployed.validate().is_ok());
        let mut plain = deployed.clone();
        plain.soak = None;
        assert!(plain.validate().is_err(), "frames past 10⁷ outside a soak");
    }
}
