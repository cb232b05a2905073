//! Latencies in constant memory: an HDR histogram (3 significant figures) instead of a list of
//! every sample, so a run's percentiles cost the same after a minute or a day.

use hdrhistogram::Histogram;

use crate::report::Percentiles;

/// A latency distribution [ns].
#[derive(Clone)]
pub struct Latency {
    histogram: Histogram<u64>,
}

impl Default for Latency {
    fn default() -> Self {
        Latency {
            // 3 significant figures, auto-resizing: 1 ns up to any latency a run sees.
            histogram: Histogram::new(3).expect("3 significant figures is a valid precision"),
        }
    }
}

impl Latency {
    pub fn record(&mut self, ns: u64) {
        // Auto-resize makes recording infallible for any u64 short of the top bits.
        let _ = self.histogram.record(ns.max(1));
    }

    pub fn count(&self) -> u64 {
        self.histogram.len()
    }

    pub fn is_empty(&self) -> bool {
        self.histogram.is_empty()
    }

    /// p50, p90, p99 and max [µs] (`None` without samples).
    pub fn percentiles(&self) -> Option<Percentiles> {
        if self.is_empty() {
            return None;
        }
        let h = &self.histogram;
        let us = |q: f64| h.value_at_quantile(q) as f64 / 1e3;
        Some(Percentiles {
            count: h.len() as usize,
            p50: us(0.5),
            p90: us(0.9),
            p99: us(0.99),
            max: h.max() as f64 / 1e3,
        })
    }

    /// Every recorded value [µs] with its count, ascending (for histograms).
    pub fn counts_us(&self) -> Vec<(f64, u64)> {
        self.histogram
            .iter_recorded()
            .map(|v| (v.value_iterated_to() as f64 / 1e3, v.count_at_value()))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_match_the_sorted_sample_to_three_figures() {
        // 1..=100_000 ns: the exact p50 is 50 µs, p99 99 µs, max 100 µs.
        let mut l = Latency::default();
        for ns in 1..=100_000u64 {
            l.record(ns);
        }
        let p = l.percentiles().unwrap();
        assert_eq!(p.count, 100_000);
        for (got, want) in [(p.p50, 50.0), (p.p90, 90.0), (p.p99, 99.0), (p.max, 100.0)] {
            assert!((got - want).abs() / want < 1e-3, "{got} vs {want}");
        }
        let total: u64 = l.counts_us().iter().map(|(_, c)| c).sum();
        assert_eq!(total, 100_000);
        assert!(Latency::default().percentiles().is_none());
    }
}
