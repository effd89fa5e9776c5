//! Per-module timing: named duration samples with mean, percentiles and the
//! frame rate they allow.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

#[derive(Debug, Clone, Copy, PartialEq)]
/// Summary of one stage's durations, s.
pub struct TimingStats {
    /// Number of samples.
    pub count: usize,
    /// Sum.
    pub total_s: f64,
    /// Mean.
    pub mean_s: f64,
    /// Median.
    pub median_s: f64,
    /// 90th percentile.
    pub p90_s: f64,
    /// 99th percentile.
    pub p99_s: f64,
    /// Largest.
    pub max_s: f64,
    /// 1 / mean (frames per second if one sample is one frame); infinite for a zero mean.
    pub fps: f64,
}

/// Collects durations per module name.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TimingAccumulator {
    samples: BTreeMap<String, Vec<Duration>>,
}

/// Percentile by linear interpolation between order statistics (numpy's
/// default): `p` in [0, 100] is clamped; `sorted` must be non-empty and sorted.
fn percentile_sorted(sorted: &[f64], p: f64) -> f64 {
    let p = if p.is_nan() {
        50.0
    } else {
        p.clamp(0.0, 100.0)
    };
    let pos = p / 100.0 * (sorted.len() - 1) as f64;
    let lo = pos.floor() as usize;
    let hi = pos.ceil() as usize;
    sorted[lo] + (sorted[hi] - sorted[lo]) * (pos - lo as f64)
}

impl TimingAccumulator {
    /// An empty accumulator.
    pub fn new() -> TimingAccumulator {
        TimingAccumulator::default()
    }

    /// Adds one duration of stage `name`.
    pub fn record(&mut self, name: &str, duration: Duration) {
        self.samples
            .entry(name.to_string())
            .or_default()
            .push(duration);
    }

    /// Runs `f`, records its wall time under `name`, returns its result.
    pub fn time<T>(&mut self, name: &str, f: impl FnOnce() -> T) -> T {
        let start = Instant::now();
        let out = f();
        self.record(name, start.elapsed());
        out
    }

    /// Adds all samples of another accumulator.
    pub fn merge(&mut self, other: &TimingAccumulator) {
        for (name, durations) in &other.samples {
            self.samples
                .entry(name.clone())
                .or_default()
                .extend_from_slice(durations);
        }
    }

    /// Stage names in first-recorded order.
    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.samples.keys().map(String::as_str)
    }

    /// Every duration recorded for `name` (empty when unknown).
    pub fn samples(&self, name: &str) -> &[Duration] {
        self.samples.get(name).map_or(&[], Vec::as_slice)
    }

    /// `p`-th percentile in seconds; `None` for an unknown name.
    pub fn percentile_s(&self, name: &str, p: f64) -> Option<f64> {
        let mut v: Vec<f64> = self
            .samples(name)
            .iter()
            .map(Duration::as_secs_f64)
            .collect();
        if v.is_empty() {
            return None;
        }
        v.sort_by(f64::total_cmp);
        Some(percentile_sorted(&v, p))
    }

    /// Statistics of one module; `None` when it has no samples.
    pub fn stats(&self, name: &str) -> Option<TimingStats> {
        let mut v: Vec<f64> = self
            .samples(name)
            .iter()
            .map(Duration::as_secs_f64)
            .collect();
        if v.is_empty() {
            return None;
        }
        v.sort_by(f64::total_cmp);
        let total_s: f64 = v.iter().sum();
        let mean_s = total_s / v.len() as f64;
        Some(TimingStats {
            count: v.len(),
            total_s,
            mean_s,
            median_s: percentile_sorted(&v, 50.0),
            p90_s: percentile_sorted(&v, 90.0),
            p99_s: percentile_sorted(&v, 99.0),
            max_s: v[v.len() - 1],
            fps: if mean_s > 0.0 {
                1.0 / mean_s
            } else {
                f64::INFINITY
            },
        })
    }

    /// All modules with their statistics, sorted by name.
    pub fn all_stats(&self) -> Vec<(String, TimingStats)> {
        self.samples
            .keys()
            .filter_map(|n| self.stats(n).map(|s| (n.clone(), s)))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stats_hand_case() {
        let mut acc = TimingAccumulator::new();
        for ms in [40, 10, 30, 20] {
            acc.record("match", Duration::from_millis(ms));
        }
        let s = acc.stats("match").unwrap();
        assert_eq!(s.count, 4);
        assert!((s.mean_s - 0.025).abs() < 1e-12);
        assert!((s.median_s - 0.025).abs() < 1e-12);
        assert!((s.p90_s - 0.037).abs() < 1e-12);
        assert!((s.max_s - 0.040).abs() < 1e-12);
        assert!((s.fps - 40.0).abs() < 1e-9);
        assert!((acc.percentile_s("match", 0.0).unwrap() - 0.010).abs() < 1e-12);
        assert!(acc.stats("other").is_none());
        let v = acc.time("other", || 7);
        assert_eq!(v, 7);
        let mut all = TimingAccumulator::new();
        all.merge(&acc);
        all.merge(&acc);
        assert_eq!(all.samples("match").len(), 8);
        assert_eq!(all.names().collect::<Vec<_>>(), vec!["match", "other"]);
    }
}
