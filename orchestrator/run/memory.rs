//! The deployment's resident memory over the run: every process (each service's current
//! incarnation and the orchestrator) sampled about once a second, in bounded memory (a long
//! run's samples are thinned, every other one dropped, as they pass [`SAMPLES_MAX`]). The
//! report draws it (`memory.svg`) and says how much each process grew after its warm-up.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use serde::{Deserialize, Serialize};

/// Samples kept at most; past it every other one is dropped and the period doubles.
const SAMPLES_MAX: usize = 2048;

/// The warm-up: growth is measured from the samples at least this far into the run.
const WARM_UP_SHARE: f64 = 0.1;

/// Resident memory [bytes] of process `pid` ("self": the orchestrator), from /proc.
pub fn rss_bytes(pid: impl std::fmt::Display) -> Option<u64> {
    let statm = std::fs::read_to_string(format!("/proc/{pid}/statm")).ok()?;
    let pages: u64 = statm.split_ascii_whitespace().nth(1)?.parse().ok()?;
    Some(pages * rustix::param::page_size() as u64)
}

/// One process's resident memory over the run.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct MemoryTrace {
    /// Time since the services were started [s], per sample.
    pub t_s: Vec<f64>,
    /// Resident set size [MB] (10⁶ bytes), per sample.
    pub rss_mb: Vec<f64>,
    /// After the warm-up: the median between 10 % and 20 % of the run [MB].
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    #[schemars(with = "Option<f64>")]
    pub warm_mb: f64,
    /// At the end: the median over the last 10 % of the run [MB].
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    #[schemars(with = "Option<f64>")]
    pub end_mb: f64,
    /// The largest sample after the warm-up (a dying process's panic report included) [MB].
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    #[schemars(with = "Option<f64>")]
    pub peak_mb: f64,
    /// (end − warm) / warm [%]: what the process grew after its warm-up.
    #[serde(deserialize_with = "crate::report::model::f64_or_nan")]
    #[schemars(with = "Option<f64>")]
    pub growth_pct: f64,
}

/// The samples of every process, taken as the run goes.
pub struct Memory {
    start: Instant,
    period: Duration,
    last: Option<Instant>,
    t_s: Vec<f64>,
    rss_mb: BTreeMap<String, Vec<f64>>,
    /// Samples offered since the last thinning, and the thinning's stride.
    offered: u64,
    stride: u64,
}

impl Memory {
    pub fn new(start: Instant) -> Self {
        Memory {
            start,
            period: Duration::from_secs(1),
            last: None,
            t_s: vec![],
            rss_mb: BTreeMap::new(),
            offered: 0,
            stride: 1,
        }
    }

    /// Samples `processes` (name, pid) if a period has passed since the last sample.
    pub fn sample(&mut self, now: Instant, processes: impl Iterator<Item = (String, u32)>) {
        if self.last.is_some_and(|l| now - l < self.period) {
            return;
        }
        self.last = Some(now);
        self.offered += 1;
        if (self.offered - 1) % self.stride != 0 {
            return;
        }
        let n = self.t_s.len();
        self.t_s.push((now - self.start).as_secs_f64());
        let me = rss_bytes("self").map(|b| ("orchestrator".to_string(), b));
        for (name, bytes) in processes
            .filter_map(|(name, pid)| Some((name, rss_bytes(pid)?)))
            .chain(me)
        {
            let trace = self.rss_mb.entry(name).or_default();
            // A process first seen late (or missed while restarting) repeats its last value.
            let fill = trace.last().copied().unwrap_or(0.0);
            trace.resize(n, fill);
            trace.push(bytes as f64 / 1e6);
        }
        if self.t_s.len() >= SAMPLES_MAX {
            crate::plots::thin_by_half(&mut self.t_s);
            self.rss_mb
                .values_mut()
                .for_each(crate::plots::thin_by_half);
            self.stride *= 2;
        }
    }

    /// Every process's trace.
    pub fn traces(&self) -> BTreeMap<String, MemoryTrace> {
        let end_s = self.t_s.last().copied().unwrap_or(0.0);
        (self.rss_mb.iter())
            .map(|(name, rss)| {
                let t_s: Vec<f64> = self.t_s[..rss.len()].to_vec();
                let from = |share: f64| {
                    (t_s.iter().position(|t| *t >= share * end_s)).unwrap_or(rss.len())
                };
                let (warm_i, settled_i, last_i) = (
                    from(WARM_UP_SHARE),
                    from(2.0 * WARM_UP_SHARE),
                    from(1.0 - WARM_UP_SHARE),
                );
                // Medians: a sample read while a restarted process was starting (low) or
                // while a dying one printed its panic (high) moves neither; a leak moves both.
                let warm_mb = median(rss.get(warm_i..settled_i.max(warm_i + 1)).unwrap_or(&[]));
                let end_mb = median(
                    rss.get(last_i.min(rss.len().saturating_sub(1))..)
                        .unwrap_or(&[]),
                );
                let peak_mb = (rss.get(warm_i..).unwrap_or(&[]).iter())
                    .copied()
                    .fold(f64::NAN, f64::max);
                let trace = MemoryTrace {
                    growth_pct: 100.0 * (end_mb - warm_mb) / warm_mb,
                    t_s,
                    rss_mb: rss.clone(),
                    warm_mb,
                    end_mb,
                    peak_mb,
                };
                (name.clone(), trace)
            })
            .collect()
    }
}

/// The median of `v` (NaN if empty; zero samples, a process not yet seen, are left out).
fn median(v: &[f64]) -> f64 {
    let mut s: Vec<f64> = v.iter().copied().filter(|x| *x > 0.0).collect();
    if s.is_empty() {
        return f64::NAN;
    }
    s.sort_by(f64::total_cmp);
    let n = s.len();
    if n % 2 == 1 {
        s[n / 2]
    } else {
        0.5 * (s[n / 2 - 1] + s[n / 2])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_orchestrator_reads_its_own_resident_memory() {
        let rss = rss_bytes("self").unwrap();
        // A test binary holds at least a megabyte and less than a terabyte.
        assert!((1 << 20..1 << 40).contains(&rss), "{rss}");
    }

    #[test]
    fn growth_is_measured_after_the_warm_up_and_samples_stay_bounded() {
        let t0 = Instant::now();
        let mut m = Memory::new(t0);
        // 10 000 one-second samples: the traces keep at most SAMPLES_MAX of them.
        for k in 0..10_000u64 {
            m.sample(t0 + Duration::from_secs(k), std::iter::empty());
        }
        let tr = &m.traces()["orchestrator"];
        assert!(tr.t_s.len() < SAMPLES_MAX && tr.t_s.len() > SAMPLES_MAX / 4);
        assert_eq!(tr.t_s.len(), tr.rss_mb.len());
        assert!(tr.t_s.windows(2).all(|w| w[0] < w[1]));
        assert!(*tr.t_s.last().unwrap() > 9_000.0);
        // The same process throughout: it did not grow 10 % after its warm-up.
        assert!(tr.growth_pct.abs() < 10.0, "{}", tr.growth_pct);
    }

    #[test]
    fn a_restart_or_a_panic_report_is_not_growth_and_a_leak_is() {
        let trace = |rss: &[f64]| {
            let mut m = Memory::new(Instant::now());
            m.t_s = (0..rss.len()).map(|i| i as f64).collect();
            m.rss_mb.insert("detector".into(), rss.to_vec());
            m.traces()["detector"].clone()
        };
        // 50 MB throughout, but 9 MB at the end of the warm-up (restarting then) and 190 MB
        // near the end (a panic's report): flat.
        let mut flat = vec![50.0; 100];
        flat[10] = 9.0;
        flat[95] = 190.0;
        let t = trace(&flat);
        assert!(t.growth_pct.abs() < 1e-9, "{t:?}");
        assert_eq!(t.peak_mb, 190.0);
        // 50 MB growing 0.1 MB per sample: +16 % after the warm-up.
        let leak: Vec<f64> = (0..100).map(|i| 50.0 + 0.1 * i as f64).collect();
        let g = trace(&leak).growth_pct;
        assert!(g > 10.0, "{g}");
    }
}
