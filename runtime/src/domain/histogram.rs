//! Latency histograms: preallocated HDR histograms (recording never allocates) and their
//! percentiles as written to `latency.json`.

use hdrhistogram::Histogram;
use serde::{Deserialize, Serialize};

/// The largest value a histogram holds exactly (100 s); larger values are clamped to it.
pub const MAX_NS: u64 = 100_000_000_000;

/// A latency histogram in nanoseconds, 3 significant digits, 1 ns to 100 s, allocated once.
#[derive(Clone, Debug)]
pub struct LatencyHistogram {
    h: Histogram<u64>,
}

impl Default for LatencyHistogram {
    fn default() -> Self {
        Self::new()
    }
}

impl LatencyHistogram {
    /// An empty histogram (allocates its buckets now, ~200 KiB).
    ///
    /// # Panics
    /// Never: the bounds are constants that hdrhistogram accepts.
    pub fn new() -> Self {
        #[allow(clippy::expect_used)]
        let h = Histogram::new_with_bounds(1, MAX_NS, 3).expect("constant histogram bounds are valid");
        Self { h }
    }

    /// Records one value (clamped to [`MAX_NS`]). No allocation, no system call.
    #[inline]
    pub fn record(&mut self, ns: u64) {
        self.h.saturating_record(ns);
    }

    /// The number of values recorded.
    pub fn count(&self) -> u64 {
        self.h.len()
    }

    /// How many values exceed `ns` (to the histogram's 3 significant digits: a value in the
    /// bucket that holds `ns` counts as not above it).
    pub fn count_above(&self, ns: u64) -> u64 {
        self.h.len() - self.h.count_between(0, ns.min(MAX_NS))
    }

    /// The value at quantile `q` ∈ [0, 1] (0 when empty). Scans the buckets: tens of µs, do not
    /// call it every cycle.
    pub fn quantile(&self, q: f64) -> u64 {
        if self.h.is_empty() {
            0
        } else {
            self.h.value_at_quantile(q)
        }
    }

    /// The summary written to JSON.
    pub fn percentiles(&self) -> Percentiles {
        if self.h.is_empty() {
            return Percentiles::default();
        }
        Percentiles {
            count: self.h.len(),
            min: self.h.min(),
            p50: self.h.value_at_quantile(0.5),
            p90: self.h.value_at_quantile(0.9),
            p99: self.h.value_at_quantile(0.99),
            p99_9: self.h.value_at_quantile(0.999),
            p99_99: self.h.value_at_quantile(0.9999),
            max: self.h.max(),
            mean: self.h.mean(),
        }
    }

    /// `(value_ns, count)` of every non-empty bucket, for plots.
    pub fn buckets(&self) -> Vec<(u64, u64)> {
        self.h.iter_recorded().map(|v| (v.value_iterated_to(), v.count_at_value())).collect()
    }

    /// Adds another histogram's values.
    pub fn add(&mut self, other: &Self) {
        // Same bounds on both sides: addition cannot fail; clamp just in case.
        if self.h.add(&other.h).is_err() {
            for v in other.h.iter_recorded() {
                self.h.saturating_record_n(v.value_iterated_to(), v.count_at_value());
            }
        }
    }
}

/// Percentiles of a latency distribution, in nanoseconds (3 significant digits: each value is
/// the upper edge of its histogram bucket).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Percentiles {
    /// Values recorded.
    pub count: u64,
    /// Smallest.
    pub min: u64,
    /// Median.
    pub p50: u64,
    /// 90th percentile.
    pub p90: u64,
    /// 99th percentile.
    pub p99: u64,
    /// 99.9th percentile.
    #[serde(rename = "p99.9")]
    pub p99_9: u64,
    /// 99.99th percentile.
    #[serde(rename = "p99.99")]
    pub p99_99: u64,
    /// Largest (exact).
    pub max: u64,
    /// Mean.
    pub mean: f64,
}

/// Formats nanoseconds for a table: `850 ns`, `12.3 µs`, `4.56 ms`.
pub fn fmt_ns(ns: u64) -> String {
    let x = ns as f64;
    if ns < 1_000 {
        format!("{ns} ns")
    } else if ns < 1_000_000 {
        format!("{:.1} µs", x / 1e3)
    } else if ns < 1_000_000_000 {
        format!("{:.2} ms", x / 1e6)
    } else {
        format!("{:.2} s", x / 1e9)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_of_a_known_distribution() {
        let mut h = LatencyHistogram::new();
        for v in 1..=10_000u64 {
            h.record(v * 100);
        }
        let p = h.percentiles();
        assert_eq!(p.count, 10_000);
        assert!((p.p50 as f64 - 500_000.0).abs() / 500_000.0 < 0.002, "{p:?}");
        assert!((p.p99 as f64 - 990_000.0).abs() / 990_000.0 < 0.002, "{p:?}");
        assert!(p.max >= 1_000_000 && p.max < 1_001_000, "{p:?}");
        h.record(u64::MAX);
        assert!(h.percentiles().max >= MAX_NS);
    }

    #[test]
    fn empty_histogram_reports_zeros() {
        let h = LatencyHistogram::new();
        assert_eq!(h.percentiles(), Percentiles::default());
        assert_eq!(h.quantile(0.99), 0);
    }

    #[test]
    fn formats_units() {
        assert_eq!(fmt_ns(850), "850 ns");
        assert_eq!(fmt_ns(12_345), "12.3 µs");
        assert_eq!(fmt_ns(4_560_000), "4.56 ms");
    }
}
